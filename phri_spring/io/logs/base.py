"""What every wrench-log format shares: the recipe, the chunk and the checks.

A log format is one :class:`LogFormat` (its *recipe*): its suffixes, a
chunked reader, a row counter and, for the formats the forces table may be
written in, a table sink. The recipes live beside their readers
(:mod:`phri_spring.io.logs.arrow` for CSV and Parquet,
:mod:`phri_spring.io.logs.lab` for TDMS and MAT) and are registered in one
table, :data:`phri_spring.io.logs.formats.LOG_FORMATS`, which every dispatch on
a file's suffix reads. This module is the bottom of that stack: it imports
none of them, so the format modules can share it without importing each other.
"""

from __future__ import annotations

import difflib
from dataclasses import dataclass
from typing import Callable, Iterator, Optional

import numpy as np

from ...errors import DataError, UsageError
from .columns import LOG_COLUMNS, LOG_GROUP_KEY, OPTIONAL_LOG_COLUMNS

__all__ = ["LogFormat", "WrenchChunk", "check_chunk", "parse_column_map", "resolve_columns",
           "take_group", "reader_options"]


@dataclass
class WrenchChunk:
    """Rows ``start .. start + len`` of a log."""

    start: int
    time: np.ndarray          # (k,) [s]
    wrench: np.ndarray        # (k, 6) in the log's units
    activation: Optional[np.ndarray] = None   # (k,) muscle activation 0..1, if the log has it


@dataclass(frozen=True)
class LogFormat:
    """The recipe of one log format: how to find, read, count and (maybe) write it.

    Attributes
    ----------
    name : str
        Format name (``'csv'``, ``'parquet'``, ``'tdms'``, ``'mat'``), as
        :func:`phri_spring.io.logs.formats.table_format` returns it.
    suffixes : tuple of str
        Lower-case file extensions, the usual one first (it is the one named
        in the message for an unknown extension).
    read : callable
        ``read(path, columns, *, chunk_rows, wanted) -> Iterator[WrenchChunk]``
        (``grouped`` formats also take ``group=``): time [s] and the other
        ``wanted`` columns in the file's units, chunk by chunk. ``columns`` maps
        spec names to the file's names. The path is known to exist and not to
        be a folder.
    count_rows : callable
        ``count_rows(path, columns) -> int or None`` (``grouped`` formats also
        take ``group=``): data rows, best effort (None when they cannot be
        counted). It takes the same column map and group as ``read``, so that a
        file of several groups is counted in the group that is read.
    writer : type, optional
        Sink class the forces table is written through
        (:class:`phri_spring.io.outputs.forces.ForcesWriter`); None for the
        formats read only. A sink is built as ``writer(path, schema, labels)``
        and has ``encode(table)`` (safe on several threads at once when the
        class's ``parallel`` is true), which writes the chunk or returns its
        bytes, ``write(data)`` (called in order with the bytes ``encode``
        returned; needed only when it returns any) and ``close()``; ``encode``
        must not keep the table (or its arrays) once it returns, as the writer
        reuses their memory for its next chunk; the class's
        ``rounds`` tells whether floats are rounded to the writer's
        ``decimals`` first.
    grouped : bool
        Whether the file holds its channels in groups (TDMS groups, MAT
        structs): only then are ``read`` and ``count_rows`` given the group.
    """

    name: str
    suffixes: tuple
    read: Callable[..., Iterator[WrenchChunk]]
    count_rows: Callable[..., Optional[int]]
    writer: Optional[type] = None
    grouped: bool = False


def check_chunk(arr: np.ndarray, names, path, *, first: int, unit: str = "row") -> None:
    """Raise a :class:`DataError` on the first NaN or infinite value of a chunk.

    Parameters
    ----------
    arr : ndarray, shape (k, len(names))
        The chunk's columns (time [s] first, then the log's units).
    names : sequence of str
        The file's name of each column (the error's key).
    path : path-like
        The file, for the message.
    first : int
        Number of the chunk's first row in the message (1-based).
    unit : str
        What is counted: ``'row'``, or ``'line'`` for text files (where
        ``first`` then counts the header and comment lines too).
    """
    bad = ~np.isfinite(arr)
    if bad.any():
        i, j = np.argwhere(bad)[0]
        val = arr[i, j]
        what = "an empty cell or NaN" if np.isnan(val) else \
            f"{float(val)!r} (beyond the range of a double, e.g. 1e999)"
        raise DataError(f"expected a finite number on {unit} {first + i}, got {what}",
                        file=path, key=names[j])


def parse_column_map(items) -> dict:
    """``["Fx=Fx (N)", ...]`` -> ``{"Fx": "Fx (N)", ...}`` (the ``--column`` option)."""
    out = {}
    for item in items or ():
        if "=" not in item:
            raise UsageError(f"expected SPEC_NAME=LOG_NAME (e.g. 'Fx=Fx (N)'), got {item!r}",
                             key="--column")
        name, col = item.split("=", 1)
        name = name.strip()
        known = LOG_COLUMNS + tuple(c.rstrip("?") for c in OPTIONAL_LOG_COLUMNS)
        if name not in known:
            close = difflib.get_close_matches(name, known, n=1, cutoff=0.5)
            hint = f"; did you mean {close[0]!r}?" if close else ""
            raise UsageError(f"unknown column name {name!r}{hint} (expected one of "
                             f"{', '.join(known)})", key="--column")
        out[name] = col
    return out


def resolve_columns(available, mapping: Optional[dict] = None, *, file=None,
                    wanted=LOG_COLUMNS) -> list:
    """The log's column name for each wanted spec column, in order.

    A wanted name ending in ``?`` is optional: left out when the log has no such column
    and the map names none."""
    mapping = dict(mapping or {})
    available = list(available)
    out = []
    for name in wanted:
        if name.endswith("?"):
            name = name[:-1]
            if name not in mapping and mapping.get(name, name) not in available:
                continue
        col = mapping.get(name, name)
        if available.count(col) > 1:
            raise DataError(f"column {col!r} appears {available.count(col)} times; expected "
                            "one column of that name", file=file, key=col)
        if col not in available:
            close = difflib.get_close_matches(col, available, n=1, cutoff=0.6)
            hint = f"; did you mean {close[0]!r}?" if close else ""
            how = (f" (mapped from {name!r})" if name in mapping else
                   f"; map another name with --column {name}=NAME or load_cell.columns")
            raise DataError(f"missing column {col!r}{how}{hint}; the file has "
                            f"{', '.join(map(repr, available[:12]))}"
                            f"{' ...' if len(available) > 12 else ''}", file=file, key=col)
        out.append(col)
    return out


def take_group(columns: Optional[dict], group: Optional[str] = None):
    """``(column map, group)``: the map without the deprecated group entry, and the group.

    The group is ``group`` when given, else the one a column map written before
    the readers took ``group=`` carries under
    :data:`phri_spring.io.config.LOG_GROUP_KEY` (None when neither has one).
    """
    columns = dict(columns or {})
    legacy = columns.pop(LOG_GROUP_KEY, None)
    return columns, (legacy if group is None else group)


def reader_options(cfg, columns: Optional[dict] = None, group: Optional[str] = None):
    """``(column map, group)`` a config's logs and trial tables are read with.

    The map is ``load_cell.columns`` (``cfg.log_columns``) overridden by
    ``columns``; the group is ``group``, else the deprecated entry of
    ``columns`` (:func:`take_group`), else ``load_cell.group`` (``cfg.log_group``).
    """
    colmap, group = take_group({**cfg.log_columns, **(columns or {})}, group)
    return colmap, (cfg.log_group if group is None else group)
