"""Wrench logs in (docs/model.md section 7): the registry of log formats and the chunked reader.

Each log format is one recipe (:class:`phri_spring.io.logs.base.LogFormat`):
its suffixes, a chunked reader, a row counter and, when the forces table may
be written in it, a sink. :data:`LOG_FORMATS` registers them by suffix, and
every choice made from a file's extension (:func:`table_format`,
:func:`iter_wrench_log`, :func:`count_rows`, the forces writer) is a lookup in
it; a new format is one recipe and one line in :data:`_RECIPES`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Iterator, Optional

import numpy as np

from ...errors import DataError, UsageError
from .arrow import CSV, PARQUET
from .columns import ACTIVATION, LOG_COLUMNS
from .lab import MAT, TDMS
from .base import LogFormat, WrenchChunk, take_group

__all__ = ["LOG_FORMATS", "log_format", "format_named", "table_format", "iter_wrench_log",
           "read_wrench_log", "count_rows"]

# the formats, in the order the message for an unknown extension names them
_RECIPES = (CSV, PARQUET, TDMS, MAT)

#: extension (lower case, with the dot) -> recipe
LOG_FORMATS = {suffix: recipe for recipe in _RECIPES for suffix in recipe.suffixes}


def _unknown_message(ext: str, role: str) -> str:
    """One line naming the usual extension of each format ``role`` accepts."""
    written = " or ".join(r.suffixes[0] for r in _RECIPES if r.writer is not None)
    read_only = " or ".join(r.suffixes[0] for r in _RECIPES if r.writer is None)
    return f"unknown file type {ext or '(none)'!r}; expected {written}" + \
        (f", {read_only}" if role == "input" and read_only else "")


def log_format(path, *, role: str = "input", option: Optional[str] = None) -> LogFormat:
    """The recipe of a file, from its extension.

    Parameters
    ----------
    path : str or path-like
        The file (it need not exist).
    role : {'input', 'output'}
        ``'output'`` accepts only the formats with a writer.
    option : str, optional
        The command-line option that named an output (for the message).

    Raises
    ------
    DataError
        An input of unknown extension.
    UsageError
        An output of unknown (or read-only) extension.
    """
    ext = Path(path).suffix.lower()
    recipe = LOG_FORMATS.get(ext)
    if recipe is not None and (role == "input" or recipe.writer is not None):
        return recipe
    msg = _unknown_message(ext, role)
    if role == "output":
        raise UsageError(msg, file=path, key=option)
    raise DataError(msg, file=path)


def format_named(name: str) -> LogFormat:
    """The recipe of the format called ``name`` (``'csv'``, ``'parquet'``, ...)."""
    for recipe in _RECIPES:
        if recipe.name == name:
            return recipe
    raise ValueError(f"unknown log format {name!r}; expected one of "
                     f"{', '.join(r.name for r in _RECIPES)}")


def table_format(path, *, role: str = "input", option: Optional[str] = None) -> str:
    """``'csv'`` or ``'parquet'`` from a file's extension (inputs also ``'tdms'``, ``'mat'``)."""
    return log_format(path, role=role, option=option).name


def iter_wrench_log(path, columns: Optional[dict] = None, *, group: Optional[str] = None,
                    chunk_rows: int = 131072, wanted=LOG_COLUMNS) -> Iterator[WrenchChunk]:
    """Stream a wrench log in chunks of about ``chunk_rows`` rows.

    Parameters
    ----------
    path : str or path-like
        CSV (``.csv``, ``.txt``) or Parquet (``.parquet``, ``.pq``) file, or a
        lab file (``.tdms``, ``.mat``: see :mod:`phri_spring.io.logs.lab`).
    columns : dict, optional
        Map from spec names (``time``, ``Fx`` ... ``Mz``) to the log's names.
    group : str, optional
        Lab files: the TDMS group or MAT struct holding the channels
        (``--group``, ``load_cell.group``); other formats have none and ignore it.
    chunk_rows : int
        Rows per chunk (CSV chunks follow pyarrow's blocks and are approximate).
    wanted : sequence of str
        Spec columns to read, ``time`` first.

    Yields
    ------
    WrenchChunk
        time [s] and wrench in the log's units (docs/model.md section 5 converts).

    Raises
    ------
    DataError
        Missing file or column, text or NaN in a number, no data rows.
    """
    path = Path(path)
    recipe = log_format(path)
    if not path.exists():
        raise DataError("file not found; expected a wrench log (.csv or .parquet)", file=path)
    if path.is_dir():
        raise DataError("is a folder; expected a wrench log file", file=path)
    columns, group = take_group(columns, group)
    chunks = recipe.read(path, columns, chunk_rows=chunk_rows, wanted=wanted,
                         **_group_of(recipe, group))
    if ACTIVATION + "?" not in wanted:
        yield from chunks
        return
    # the optional activation column: split off, checked to be within 0..1
    name = columns.get(ACTIVATION, ACTIVATION)
    for ch in chunks:
        if ch.wrench.shape[1] == 6:
            yield ch
            continue
        a = ch.wrench[:, 6]
        bad = np.flatnonzero((a < 0.0) | (a > 1.0))
        if len(bad):
            raise DataError(f"expected a muscle activation from 0 to 1, got {a[bad[0]]:g} in "
                            f"data row {ch.start + int(bad[0]) + 1:,}", file=path, key=name)
        yield WrenchChunk(ch.start, ch.time, ch.wrench[:, :6], a.copy())


def _group_of(recipe: LogFormat, group: Optional[str]) -> dict:
    """The group keyword of a recipe's reader and counter: only grouped formats take one."""
    return {"group": group} if recipe.grouped else {}


def read_wrench_log(path, columns: Optional[dict] = None, *, group: Optional[str] = None):
    """Read a whole wrench log: ``(time (m,) [s], wrench (m, 6) [log units])``.

    ``columns`` and ``group`` as in :func:`iter_wrench_log`.
    """
    chunks = list(iter_wrench_log(path, columns, group=group))
    return (np.concatenate([c.time for c in chunks]),
            np.concatenate([c.wrench for c in chunks]))


def count_rows(path, group: Optional[str] = None, *,
               columns: Optional[dict] = None) -> Optional[int]:
    """Number of data rows, best effort, or None (for progress and plot bins only).

    A fast newline count for CSV, the metadata for Parquet and TDMS.

    Parameters
    ----------
    path : str or path-like
        The log.
    group : str, optional
        TDMS group or MAT struct, as given to :func:`iter_wrench_log`: passing
        the same keeps the count in the group that is read. Without it a lab
        file of several groups counts its longest channel of any group.
    columns : dict, optional
        The column map the log is read with (:func:`iter_wrench_log`).
    """
    columns, group = take_group(columns, group)
    try:
        path = Path(path)
        recipe = log_format(path)
        return recipe.count_rows(path, columns, **_group_of(recipe, group))
    except Exception:  # noqa: BLE001 - best effort (progress only); reading reports errors
        return None
