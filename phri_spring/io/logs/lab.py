"""Lab file formats: National Instruments TDMS and MATLAB ``.mat`` (docs/model.md section 7).

Wrench logs (``phri simulate``) and trial tables (``phri compare``) may be
written by the lab's own acquisition software instead of as CSV:

- **TDMS** (npTDMS, the ``lab`` extra): one channel per column, named like
  the CSV columns (``time``, ``Fx`` ... ``Mz``, element labels,
  ``condition``; other names through ``--column`` / ``load_cell.columns``),
  in one group, chosen with ``--group`` / ``load_cell.group`` when the file
  has several. The time [s] is the ``time`` channel if there is one, else the
  waveform properties of the force channels: ``wf_start_offset + i *
  wf_increment``.
- **MAT** (v4/v5/v7 through scipy, v7.3 through pymatreader, the ``lab``
  extra): one vector per column, named like the CSV columns, at the top level
  or inside the struct chosen with ``--group`` / ``load_cell.group``.

The checks are those of the CSV reader, as one-line :class:`DataError`\\ s
naming the file and the channel: a missing channel (with the closest name), a
channel of another length than the others, text in a numeric channel, NaN or
infinity, a group or struct that does not exist, a missing optional package
(naming the extra to install).

The group is a parameter of its own (``group=``), passed from ``--group`` or
``load_cell.group`` (:attr:`phri_spring.io.config.Config.log_group`) beside
the column map; a map that still carries it under the deprecated
:data:`LOG_GROUP_KEY` is honoured (:func:`phri_spring.io.logs.base.take_group`).

The wrench-log recipes :data:`TDMS` and :data:`MAT` (see
:class:`phri_spring.io.logs.base.LogFormat`) are registered with the CSV and
Parquet ones in :data:`phri_spring.io.logs.formats.LOG_FORMATS`. This module
imports :mod:`phri_spring.io.logs.base` only, never the registry above it.
"""

from __future__ import annotations

import difflib
from pathlib import Path
from typing import Iterator, Optional

import numpy as np

from ...errors import DataError
from .columns import LOG_COLUMNS, LOG_GROUP_KEY  # noqa: F401 - deprecated, importable here
from .base import LogFormat, WrenchChunk, check_chunk, take_group

__all__ = ["LAB_FORMATS", "TDMS", "MAT", "lab_format", "iter_lab_log", "lab_row_count",
           "read_lab_frame", "LOG_GROUP_KEY"]

_EXTRA = "install it with: pip install -e '.[lab]' (or pip install 'phri-spring[lab]')"
_HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"


def lab_format(path) -> Optional[str]:
    """``'tdms'``, ``'mat'`` or None, from a file's extension."""
    return LAB_FORMATS.get(Path(path).suffix.lower())


def _names_hint(available, wanted: str) -> str:
    close = difflib.get_close_matches(wanted, list(available), n=1, cutoff=0.6)
    return f"; did you mean {close[0]!r}?" if close else ""


def _listing(names) -> str:
    names = list(names)
    return ", ".join(map(repr, names[:12])) + (" ..." if len(names) > 12 else "") \
        if names else "none"


# --------------------------------------------------------------------------- sources
class _Source:
    """The channels of one group of a lab file, read lazily by name.

    One subclass per lab format; its class attributes ``name`` and
    ``suffixes`` make that format's recipe (:func:`_recipe`).

    Attributes
    ----------
    names : list of str
        Channel (or variable) names.
    where : str
        How the group is named in messages (``group 'wrench'``), or ''.
    """

    kind = ""
    name = ""
    suffixes: tuple = ()
    names: list
    where = ""

    @staticmethod
    def row_count(path: Path, group: Optional[str]) -> int:
        """Samples in the group (the longest channel; of the whole file when None)."""
        raise NotImplementedError

    def length(self, name: str) -> int:
        raise NotImplementedError

    def read(self, name: str, start: int = 0, stop: Optional[int] = None) -> np.ndarray:
        raise NotImplementedError

    def waveform_time(self, name: str, n: int) -> Optional[np.ndarray]:
        return None

    def close(self) -> None:
        pass


class _TdmsSource(_Source):
    kind = "TDMS"
    name = "tdms"
    suffixes = (".tdms",)

    def __init__(self, path: Path, group: Optional[str]):
        try:
            from nptdms import TdmsFile
        except ImportError:
            raise DataError(f"reading TDMS files needs the optional package npTDMS; {_EXTRA}",
                            file=path) from None
        try:
            self._file = TdmsFile.open(path)
        except Exception as exc:  # noqa: BLE001 - any reader failure is bad data
            raise DataError(f"cannot read as TDMS ({exc.__class__.__name__}: {exc})"
                            .replace("\n", " "), file=path) from None
        groups = [g.name for g in self._file.groups()]
        if group is None:
            if len(groups) != 1:
                self.close()
                what = "no group" if not groups else \
                    f"{len(groups)} groups ({_listing(groups)})"
                raise DataError(f"the file has {what}; expected one group of channels, or "
                                "choose one with --group or load_cell.group", file=path)
            group = groups[0]
        elif group not in groups:
            self.close()
            raise DataError(f"group {group!r} not found{_names_hint(groups, group)}; the file "
                            f"has {_listing(groups)}", file=path, key="--group")
        self._group = self._file[group]
        self.names = [c.name for c in self._group.channels()]
        self.where = f" in group {group!r}"

    def length(self, name):
        return len(self._group[name])

    def read(self, name, start=0, stop=None):
        ch = self._group[name]
        stop = len(ch) if stop is None else stop
        return np.asarray(ch[start:stop])

    def waveform_time(self, name, n):
        props = self._group[name].properties
        if "wf_increment" not in props:
            return None
        inc = float(props["wf_increment"])
        start = float(props.get("wf_start_offset", 0.0))
        return start + np.arange(n, dtype=float) * inc

    def close(self):
        f, self._file = getattr(self, "_file", None), None
        if f is not None:
            f.close()

    @staticmethod
    def row_count(path, group):
        """The longest channel of the group (of every group when None), from the metadata."""
        from nptdms import TdmsFile

        meta = TdmsFile.read_metadata(path)
        groups = [g for g in meta.groups() if group is None or g.name == group]
        return max((len(c) for g in groups for c in g.channels()), default=0)


class _MatSource(_Source):
    kind = "MAT"
    name = "mat"
    suffixes = (".mat",)

    def __init__(self, path: Path, group: Optional[str]):
        data = _load_mat(path)
        variables = {k: v for k, v in data.items() if not str(k).startswith("__")}
        if group is not None:
            structs = [k for k, v in variables.items() if isinstance(v, dict)]
            if group not in variables:
                raise DataError(f"struct {group!r} not found{_names_hint(structs, group)}; the "
                                f"file has structs {_listing(structs)}", file=path,
                                key="--group")
            if not isinstance(variables[group], dict):
                raise DataError(f"{group!r} is not a struct; expected a struct of one vector "
                                "per column (or no --group for top-level vectors)", file=path,
                                key="--group")
            variables = variables[group]
            self.where = f" in struct {group!r}"
        self._vars = variables
        self._structs = [k for k, v in variables.items() if isinstance(v, dict)]
        self.names = [k for k, v in variables.items() if not isinstance(v, dict)]
        self._path = path

    def missing_hint(self) -> str:
        if self._structs and not self.where:
            return (f" (the file has structs {_listing(self._structs)}: choose one with "
                    "--group or load_cell.group)")
        return ""

    def _vector(self, name):
        v = self._vars[name]
        if isinstance(v, (list, tuple)):
            v = np.array(v, dtype=object if any(isinstance(x, str) for x in v) else None)
        arr = np.asarray(v)
        if arr.dtype.kind in "US" and arr.ndim == 2:      # char matrix: one string per row
            arr = np.array(["".join(r).strip() for r in arr], dtype=object)
        if arr.ndim == 2 and 1 in arr.shape:
            arr = arr.ravel()
        arr = np.atleast_1d(arr)
        if arr.dtype == object:       # cell array: MATLAB's empty '' loads as an empty array
            arr = np.array([("" if x.size == 0 else x.item() if x.size == 1 else x)
                            if isinstance(x, np.ndarray) else x for x in arr], dtype=object)
        if arr.ndim != 1:
            raise DataError(f"expected a vector (one value per sample){self.where}, got an "
                            f"array of shape {arr.shape}", file=self._path, key=name)
        return arr

    def length(self, name):
        return len(self._vector(name))

    def read(self, name, start=0, stop=None):
        return self._vector(name)[start:stop]

    @staticmethod
    def row_count(path, group):
        """The longest vector in the struct (in the whole file, structs too, when None)."""
        data = _load_mat(path)
        if group is not None:
            data = data[group]

        def longest(d):
            return max((longest(v) if isinstance(v, dict) else np.size(v)
                        for k, v in d.items() if not str(k).startswith("__")), default=0)
        return int(longest(data))


def _load_mat(path: Path) -> dict:
    """The variables of a .mat file: v4/v5/v7 through scipy, v7.3 (HDF5) through pymatreader."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(520)
    except OSError as exc:
        raise DataError(f"cannot read ({exc.strerror or exc})", file=path) from None
    if _HDF5_SIGNATURE not in (head[:8], head[512:520]):
        import scipy.io

        try:
            return scipy.io.loadmat(path, squeeze_me=True, simplify_cells=True)
        except NotImplementedError:   # v7.3 without the HDF5 signature where we look
            pass
        except Exception as exc:  # noqa: BLE001 - any reader failure is bad data
            raise DataError(f"cannot read as a MATLAB .mat file ({exc.__class__.__name__}: "
                            f"{exc})".replace("\n", " "), file=path) from None
    try:
        from pymatreader import read_mat
    except ImportError:
        raise DataError(f"reading MATLAB v7.3 .mat files needs the optional package "
                        f"pymatreader; {_EXTRA}", file=path) from None
    try:
        return read_mat(str(path))
    except Exception as exc:  # noqa: BLE001 - any reader failure is bad data
        raise DataError(f"cannot read as a MATLAB v7.3 .mat file ({exc.__class__.__name__}: "
                        f"{exc})".replace("\n", " "), file=path) from None


#: extension -> source class
_SOURCES = {suffix: cls for cls in (_TdmsSource, _MatSource) for suffix in cls.suffixes}
#: extension -> lab format
LAB_FORMATS = {suffix: cls.name for suffix, cls in _SOURCES.items()}


def _open(path: Path, group: Optional[str]) -> _Source:
    if not path.exists():
        raise DataError("file not found", file=path)
    if path.is_dir():
        raise DataError("is a folder; expected a file", file=path)
    return _SOURCES.get(path.suffix.lower(), _MatSource)(path, group)


def _require(src: _Source, path: Path, name: str, spec: Optional[str], mapped: bool) -> None:
    if name in src.names:
        return
    how = f" (mapped from {spec!r})" if mapped else \
        (f"; map another name with --column {spec}=NAME or load_cell.columns" if spec else "")
    extra = src.missing_hint() if isinstance(src, _MatSource) else ""
    what = "channel" if src.kind == "TDMS" else "variable"
    raise DataError(f"missing {what} {name!r}{src.where}{how}{_names_hint(src.names, name)}; "
                    f"the file has {_listing(src.names)}{extra}", file=path, key=name)


def _numeric(src: _Source, path: Path, name: str, values) -> np.ndarray:
    arr = np.asarray(values)
    if arr.dtype.kind not in "fiub":
        what = "channel" if src.kind == "TDMS" else "variable"
        raise DataError(f"expected numbers, the {what} holds {arr.dtype}", file=path, key=name)
    return arr.astype(np.float64, copy=False)


def _time_and_length(src: _Source, path: Path, names: list, time_name: str, mapped_time: bool):
    """``(time source, n)``: the time channel's name, or None when waveform timing is used."""
    if time_name in src.names:
        return time_name, src.length(time_name)
    n = src.length(names[0])
    if src.waveform_time(names[0], 0) is not None:
        return None, n
    what = "channel" if src.kind == "TDMS" else "variable"
    wave = (f", and {names[0]!r} has no waveform timing (wf_increment)"
            if src.kind == "TDMS" else "")
    how = " (mapped from 'time')" if mapped_time else ""
    raise DataError(f"missing {what} {time_name!r}{src.where}{how}{wave}; expected the sample "
                    f"times [s]{_names_hint(src.names, time_name)}; the file has "
                    f"{_listing(src.names)}", file=path, key=time_name)


def _check_lengths(src: _Source, path: Path, names, n: int, ref: str) -> None:
    for name in names:
        m = src.length(name)
        if m != n:
            what = "channel" if src.kind == "TDMS" else "variable"
            raise DataError(f"{what} has {m} values; expected {n}, like {ref!r}{src.where}",
                            file=path, key=name)


# --------------------------------------------------------------------------- wrench logs
def iter_lab_log(path, columns: Optional[dict] = None, *, group: Optional[str] = None,
                 chunk_rows: int = 131072, wanted=LOG_COLUMNS) -> Iterator:
    """Stream a TDMS or MAT wrench log in chunks of ``chunk_rows`` samples.

    Parameters
    ----------
    path : str or path-like
        A ``.tdms`` or ``.mat`` file.
    columns : dict, optional
        Map from spec names (``time``, ``Fx`` ... ``Mz``) to the file's channel names.
    group : str, optional
        The TDMS group or MAT struct holding the channels (needed when a TDMS
        file has several groups; without it a MAT file's top level is read).
    chunk_rows : int
        Samples per chunk (TDMS is read chunk by chunk; a MAT file is loaded whole).
    wanted : sequence of str
        Spec columns to read, ``time`` first.

    Yields
    ------
    phri_spring.io.logs.base.WrenchChunk
        time (k,) [s] and the other wanted columns (k, len(wanted) - 1) in the
        file's units.

    Raises
    ------
    DataError
        Missing file, group, struct or channel, a channel of another length,
        text, NaN or infinity in a channel, no samples, a missing optional package.
    """
    path = Path(path)
    columns, group = take_group(columns, group)
    src = _open(path, group)
    try:
        names = []
        for spec in wanted[1:]:
            optional = spec.endswith("?")
            spec = spec.rstrip("?")
            name = columns.get(spec, spec)
            if optional and spec not in columns:
                try:                     # an optional channel the file may not have
                    _require(src, path, name, spec, False)
                except DataError:
                    continue
            _require(src, path, name, spec, spec in columns)
            names.append(name)
        time_name = columns.get(wanted[0], wanted[0])
        tsrc, n = _time_and_length(src, path, names, time_name, wanted[0] in columns)
        _check_lengths(src, path, names + ([tsrc] if tsrc else []), n, tsrc or names[0])
        if n == 0:
            raise DataError(f"no samples{src.where}; expected at least one", file=path)
        all_names = [time_name] + names
        step = max(1, int(chunk_rows))
        wave = None if tsrc else src.waveform_time(names[0], n)
        for start in range(0, n, step):
            stop = min(n, start + step)
            arr = np.empty((stop - start, len(all_names)))
            arr[:, 0] = wave[start:stop] if wave is not None else \
                _numeric(src, path, time_name, src.read(time_name, start, stop))
            for j, name in enumerate(names, start=1):
                arr[:, j] = _numeric(src, path, name, src.read(name, start, stop))
            check_chunk(arr, all_names, path, first=start + 1)
            yield WrenchChunk(start, arr[:, 0].copy(), arr[:, 1:])
    finally:
        src.close()


def lab_row_count(path, group: Optional[str] = None) -> Optional[int]:
    """Samples in a lab file's group (the length of its longest channel), or None.

    Without ``group``, the longest channel of the whole file: that is the
    group's count only when the file has one group (pass the group read).
    """
    try:
        path = Path(path)
        return _SOURCES.get(path.suffix.lower(), _MatSource).row_count(path, group)
    except Exception:  # noqa: BLE001 - best effort (progress, plot bins); reading reports errors
        return None


def _count_log_rows(path, columns: Optional[dict] = None, *,
                    group: Optional[str] = None) -> Optional[int]:
    """:func:`lab_row_count` in the group that is read (see LogFormat.count_rows)."""
    return lab_row_count(path, take_group(columns, group)[1])


def _recipe(source: type) -> LogFormat:
    """The wrench-log recipe of a lab format, from its source class."""
    return LogFormat(source.name, source.suffixes, read=iter_lab_log,
                     count_rows=_count_log_rows, grouped=True)


#: National Instruments TDMS wrench logs (npTDMS)
TDMS = _recipe(_TdmsSource)
#: MATLAB .mat wrench logs (scipy; v7.3 through pymatreader)
MAT = _recipe(_MatSource)


# --------------------------------------------------------------------------- trial tables
def read_lab_frame(path, group: Optional[str] = None, *, time_name: str = "time"):
    """A trial table from a TDMS or MAT file, as a pandas DataFrame of its channels.

    Every channel (vector) of the group becomes a column; all must have the
    same length. Without a ``time_name`` channel, TDMS waveform timing gives
    the ``time_name`` column.

    Raises
    ------
    DataError
        Missing file or group, channels of different lengths, no channel.
    """
    import pandas as pd

    path = Path(path)
    src = _open(path, group)
    try:
        if not src.names:
            raise DataError(f"no channel{src.where}; expected one per column (time, Fx ... Mz, "
                            "the element labels, condition)", file=path)
        ref = time_name if time_name in src.names else src.names[0]
        n = src.length(ref)
        _check_lengths(src, path, src.names, n, ref)
        data = {}
        if time_name not in src.names:
            for name in src.names:
                wave = src.waveform_time(name, n)
                if wave is not None:
                    data[time_name] = wave
                    break
        for name in src.names:
            values = np.asarray(src.read(name))
            if values.dtype.kind in "US":
                values = values.astype(object)
            data[name] = values
        return pd.DataFrame(data)
    finally:
        src.close()
