"""Indenter recordings in, stiffness tables out (docs/model.md section 7).

Input layouts
-------------
- **A folder** of per-trial files named ``<label>_<trial>.csv`` (``B3_2.csv``:
  row letters ``B``, angle index ``3``, trial ``2``), each with the columns
  ``time`` [s], ``displacement`` [mm or m] and ``force`` [N] (further columns are
  ignored; header names are matched without regard to case or surrounding
  spaces). MATLAB files ``<label>_<trial>.mat`` holding the variables ``time``,
  ``displacement`` and ``force`` are read too (optional dependency
  ``pymatreader``: ``pip install 'phri-spring[lab]'``).

  The folder rule: every ``*.csv`` and ``*.mat`` file directly in the folder
  is a trial and must be named ``<label>_<trial>``; anything else (README,
  ``TRUTH.md``, hidden files, sub-folders) is ignored.
- **One long CSV** (or Parquet) with the columns ``location, trial, time,
  displacement, force``, one row per sample; the rows of a trial need not be
  contiguous, but their times must increase.
- **One per-trial file** ``<label>_<trial>.csv`` (or ``.mat``) without a
  ``location`` column is read as a single trial.

Every problem raises :class:`~phri_spring.errors.DataError` naming the file, the
column and what was expected.
"""

from __future__ import annotations

import io
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ...errors import DataError
from ..outputs.atomic import atomic_file

__all__ = ["LABEL_RE", "TRIAL_NAME_RE", "IndenterTrial", "SkippedTrial", "IndenterRecording",
           "split_label", "read_indenter", "read_trial_file", "read_long_table",
           "STIFFNESS_COLUMNS", "write_stiffness_csv", "write_trials_csv"]

#: an element label: row letters then angle index (``B3``, ``AA12``)
LABEL_RE = re.compile(r"^([A-Z]+)([0-9]+)$")
#: a per-trial file stem: ``<label>_<trial>``
TRIAL_NAME_RE = re.compile(r"^([A-Z]+)([0-9]+)_([0-9]+)$")
_TRIAL_SUFFIXES = (".csv", ".mat")
_COLUMNS = ("time", "displacement", "force")
_UNITS = {"mm": 1e-3, "m": 1.0}
_NAME_HINT = ("expected <label>_<trial>.csv, e.g. B3_2.csv (row letters, angle index, "
              "underscore, trial number)")

#: the first columns of the fit CSV, in order (docs/model.md section 7)
STIFFNESS_COLUMNS = ("location", "row", "angle_index", "stiffness_N_per_m", "std_N_per_m",
                     "n_trials")


@dataclass(frozen=True)
class IndenterTrial:
    """One recorded trial, displacement already in metres.

    Attributes
    ----------
    location : str
        Element label (``B3``).
    row : str
        Row letters (``B``).
    angle_index : int
        Angle index (3).
    trial : int
        Trial number.
    time : ndarray
        [s]
    displacement : ndarray
        [m]
    force : ndarray
        [N]
    source : str
        The file it came from.
    where : str
        Where in the file (``location B3 trial 2`` for a long CSV; empty otherwise).
    """

    location: str
    row: str
    angle_index: int
    trial: int
    time: np.ndarray
    displacement: np.ndarray
    force: np.ndarray
    source: str
    where: str = ""


@dataclass(frozen=True)
class SkippedTrial:
    """A trial (or file) left out because of bad data.

    ``location`` and ``trial`` are None when the file name could not be parsed.
    """

    location: str | None
    trial: int | None
    error: DataError


@dataclass(frozen=True)
class IndenterRecording:
    """What :func:`read_indenter` found: the trials and, with ``skip_bad``, the skipped ones."""

    trials: list
    skipped: list
    layout: str  # 'folder', 'long' or 'single'


def split_label(label: str) -> tuple[str, int]:
    """``'B3'`` -> ``('B', 3)``.

    Raises
    ------
    ValueError
        If the label is not row letters followed by an angle index.
    """
    m = LABEL_RE.match(str(label))
    if not m:
        raise ValueError(f"location {label!r}: expected row letters and an angle index, "
                         "e.g. B3")
    return m.group(1), int(m.group(2))


def _unit_scale(unit: str) -> float:
    try:
        return _UNITS[unit]
    except KeyError:
        from ...errors import UsageError
        raise UsageError(f"expected 'mm' or 'm', got {unit!r}", key="displacement_unit") from None


# --------------------------------------------------------------------------- numbers


def _numbers(values, file, column: str, where: str = "", line_offset: int = 2,
             index=None, word: str = "line") -> np.ndarray:
    """Convert a column to float, or raise a DataError naming the line of the first bad value.

    ``index`` holds each value's row position in the file (0 = first data row);
    the line is ``index + line_offset`` (header on line 1).
    """
    import pandas as pd

    s = pd.Series(values)
    pos = np.arange(len(s)) if index is None else np.asarray(index)
    prefix = f"{where}: " if where else ""
    if s.dtype.kind in "fiub":
        arr = s.to_numpy(dtype=float)
        bad_text = np.zeros(arr.size, bool)
    else:
        conv = pd.to_numeric(s, errors="coerce").to_numpy(dtype=float)
        text = s.astype(str).str.strip()
        empty = text.str.lower().isin(["", "nan", "na", "n/a", "null"]).to_numpy()
        missing = s.isna().to_numpy() | empty
        bad_text = np.isnan(conv) & ~missing
        arr = conv
    if bad_text.any():
        i = int(np.argmax(bad_text))
        raise DataError(f"{prefix}{word} {pos[i] + line_offset}: expected a number, got "
                        f"{str(s.iloc[i])!r}", file=file, key=column)
    nonfinite = ~np.isfinite(arr)
    if nonfinite.any():
        i = int(np.argmax(nonfinite))
        what = "missing value (empty or NaN)" if np.isnan(arr[i]) else f"value {arr[i]}"
        raise DataError(f"{prefix}{word} {pos[i] + line_offset}: {what}; expected a finite number",
                        file=file, key=column)
    return arr


def _check_time(t: np.ndarray, file, where: str = "", index=None, line_offset: int = 2,
                word: str = "line") -> None:
    dt = np.diff(t)
    if (dt <= 0).any():
        i = int(np.argmax(dt <= 0)) + 1
        pos = i if index is None else int(np.asarray(index)[i])
        prefix = f"{where}: " if where else ""
        raise DataError(f"{prefix}{word} {pos + line_offset}: time {t[i]:.6g} s does not increase "
                        f"(previous {t[i - 1]:.6g} s); expected strictly increasing time",
                        file=file, key="time")


def _columns_map(columns, file, required, layout_hint: str) -> dict:
    norm = {}
    for c in columns:
        key = str(c).strip().lower()
        norm.setdefault(key, c)
    out = {}
    for col in required:
        if col not in norm:
            raise DataError(f"missing column; expected columns {layout_hint}", file=file, key=col)
        out[col] = norm[col]
    return out


def _read_table(path: Path):
    import pandas as pd

    from ..logs.textio import read_text

    try:
        if path.suffix.lower() in (".parquet", ".pq"):
            return pd.read_parquet(path)
        text = read_text(path, what="a CSV indenter table")
        return pd.read_csv(io.StringIO(text), skipinitialspace=True)
    except pd.errors.EmptyDataError:
        raise DataError("empty file; expected a CSV header and data rows", file=path) from None
    except pd.errors.ParserError as exc:
        msg = str(exc).strip().splitlines()[-1] if str(exc).strip() else "parse error"
        raise DataError(f"not a readable CSV ({msg})", file=path) from None
    except UnicodeDecodeError:
        raise DataError("not a text CSV file (cannot decode it)", file=path) from None
    except DataError:
        raise
    except (OSError, ValueError) as exc:
        msg = str(exc).replace("\n", " ")
        raise DataError(f"cannot read the file ({msg})", file=path) from None
    except Exception as exc:  # noqa: BLE001 - any other reader failure (pyarrow) is bad data
        msg = str(exc).replace("\n", " ")
        raise DataError(f"cannot read the file ({type(exc).__name__}: {msg})",
                        file=path) from None


# --------------------------------------------------------------------------- per-trial files


def _parse_trial_name(path: Path) -> tuple[str, str, int, int]:
    m = TRIAL_NAME_RE.match(path.stem)
    if not m:
        raise DataError(f"file name {path.name!r}: {_NAME_HINT}", file=path)
    row, angle, trial = m.group(1), int(m.group(2)), int(m.group(3))
    return f"{row}{angle}", row, angle, trial


def _read_mat(path: Path) -> dict:
    try:
        from pymatreader import read_mat
    except ImportError:
        raise DataError("reading MATLAB .mat files needs the optional package pymatreader; "
                        "install it with: pip install 'phri-spring[lab]'", file=path) from None
    try:
        data = read_mat(str(path))
    except Exception as exc:  # noqa: BLE001 - any reader failure is bad data
        raise DataError(f"not a readable MATLAB file ({type(exc).__name__}: {exc})",
                        file=path) from None
    norm = {str(k).strip().lower(): v for k, v in data.items() if not str(k).startswith("__")}
    out = {}
    for col in _COLUMNS:
        if col not in norm:
            raise DataError("missing variable; expected variables time [s], displacement, "
                            "force [N]", file=path, key=col)
        v = np.asarray(norm[col])
        if v.dtype.kind not in "fiub":
            raise DataError(f"expected a numeric vector, got {v.dtype} data", file=path, key=col)
        if v.ndim > 1 and sum(s > 1 for s in v.shape) > 1:
            raise DataError(f"expected a vector, got an array of shape {v.shape}",
                            file=path, key=col)
        out[col] = v.astype(float).ravel()
    n = {c: out[c].size for c in _COLUMNS}
    if len(set(n.values())) != 1:
        raise DataError(f"time, displacement and force differ in length {tuple(n.values())}",
                        file=path, key="displacement")
    for col in _COLUMNS:
        _numbers(out[col], path, col, line_offset=1, word="sample")
    return out


def read_trial_file(path, displacement_unit: str = "mm") -> IndenterTrial:
    """Read one ``<label>_<trial>.csv`` or ``.mat`` file.

    Parameters
    ----------
    path : str or Path
    displacement_unit : {'mm', 'm'}
        Unit of the displacement column.

    Returns
    -------
    IndenterTrial
        Displacement converted to metres.
    """
    path = Path(path)
    scale = _unit_scale(displacement_unit)
    label, row, angle, trial = _parse_trial_name(path)
    if path.suffix.lower() == ".mat":
        cols = _read_mat(path)
        t, x, f = cols["time"], cols["displacement"], cols["force"]
        line_offset, word = 1, "sample"
    else:
        df = _read_table(path)
        cmap = _columns_map(df.columns, path, _COLUMNS,
                            "time [s], displacement [mm or m], force [N]")
        if len(df) == 0:
            raise DataError("no data rows; expected one row per sample", file=path, key="time")
        t = _numbers(df[cmap["time"]], path, "time")
        x = _numbers(df[cmap["displacement"]], path, "displacement")
        f = _numbers(df[cmap["force"]], path, "force")
        line_offset, word = 2, "line"
    _check_time(t, path, line_offset=line_offset, word=word)
    return IndenterTrial(location=label, row=row, angle_index=angle, trial=trial, time=t,
                         displacement=x * scale, force=f, source=str(path))


def _read_folder(folder: Path, displacement_unit: str, skip_bad: bool) -> IndenterRecording:
    files = sorted(p for p in folder.iterdir()
                   if p.is_file() and not p.name.startswith(".")
                   and p.suffix.lower() in _TRIAL_SUFFIXES)
    if not files:
        raise DataError("no trial files in this folder; expected files named "
                        "<label>_<trial>.csv (e.g. B3_2.csv) or <label>_<trial>.mat",
                        file=folder)
    trials, skipped, seen = [], [], {}
    for p in files:
        try:
            tr = read_trial_file(p, displacement_unit)
            key = (tr.location, tr.trial)
            if key in seen:
                raise DataError(f"trial {tr.trial} of {tr.location} also in {seen[key].name}; "
                                "expected one file per location and trial", file=p)
            seen[key] = p
            trials.append(tr)
        except DataError as err:
            if not skip_bad:
                raise
            m = TRIAL_NAME_RE.match(p.stem)
            skipped.append(SkippedTrial(
                location=f"{m.group(1)}{int(m.group(2))}" if m else None,
                trial=int(m.group(3)) if m else None, error=err))
    trials.sort(key=lambda tr: (len(tr.row), tr.row, tr.angle_index, tr.trial))
    return IndenterRecording(trials=trials, skipped=skipped, layout="folder")


# --------------------------------------------------------------------------- long table


def read_long_table(path, displacement_unit: str = "mm", skip_bad: bool = False
                    ) -> IndenterRecording:
    """Read one long CSV (or Parquet) with ``location, trial, time, displacement, force``.

    Parameters
    ----------
    path : str or Path
    displacement_unit : {'mm', 'm'}
    skip_bad : bool
        Leave out trials with bad values (recorded in ``skipped``) instead of raising.
        A missing column is always an error.

    Returns
    -------
    IndenterRecording
    """
    path = Path(path)
    scale = _unit_scale(displacement_unit)
    df = _read_table(path)
    required = ("location", "trial") + _COLUMNS
    cmap = _columns_map(df.columns, path, required,
                        "location, trial, time [s], displacement [mm or m], force [N]")
    if len(df) == 0:
        raise DataError("no data rows; expected one row per sample", file=path, key="location")
    loc = df[cmap["location"]]
    loc_txt = loc.astype(str).str.strip()
    bad = loc.isna().to_numpy() | ~loc_txt.str.fullmatch(LABEL_RE.pattern[1:-1]).to_numpy()
    if bad.any():
        i = int(np.argmax(bad))
        raise DataError(f"line {i + 2}: location {str(loc.iloc[i])!r}; expected row letters and "
                        "an angle index, e.g. B3", file=path, key="location")
    tri = _numbers(df[cmap["trial"]], path, "trial")
    bad_trial = (tri != np.round(tri)) | (np.abs(tri) >= 2.0 ** 53)   # beyond exact integers
    if bad_trial.any():
        i = int(np.argmax(bad_trial))
        raise DataError(f"line {i + 2}: trial {tri[i]:g}; expected an integer trial number",
                        file=path, key="trial")
    tri = tri.astype(int)

    # group rows by (location, trial), in order of first appearance
    import pandas as pd

    keys = pd.MultiIndex.from_arrays([loc_txt.to_numpy(), tri])
    codes, uniques = pd.factorize(keys)
    order = np.argsort(codes, kind="stable")
    bounds = np.flatnonzero(np.diff(codes[order])) + 1
    groups = np.split(order, bounds)
    trials, skipped = [], []
    raw = {c: df[cmap[c]] for c in _COLUMNS}
    numeric = {c: raw[c].dtype.kind in "fiub" for c in _COLUMNS}
    for rows in groups:
        label, trial = uniques[codes[rows[0]]]
        where = f"location {label} trial {trial}"
        try:
            vals = {}
            for c in _COLUMNS:
                col = raw[c].to_numpy()[rows] if numeric[c] else raw[c].iloc[rows]
                vals[c] = _numbers(col, path, c, where=where, index=rows)
            _check_time(vals["time"], path, where=where, index=rows)
        except DataError as err:
            if not skip_bad:
                raise
            skipped.append(SkippedTrial(location=label, trial=int(trial), error=err))
            continue
        row, angle = split_label(label)
        trials.append(IndenterTrial(location=f"{row}{angle}", row=row, angle_index=angle,
                                    trial=int(trial), time=vals["time"],
                                    displacement=vals["displacement"] * scale,
                                    force=vals["force"], source=str(path), where=where))
    trials.sort(key=lambda tr: (len(tr.row), tr.row, tr.angle_index, tr.trial))
    return IndenterRecording(trials=trials, skipped=skipped, layout="long")


def _has_location_column(path: Path) -> bool:
    if path.suffix.lower() != ".csv":
        return True
    from ..logs.textio import open_text

    try:
        fh, _ = open_text(path, what="a CSV indenter table")
        with fh:
            header = fh.readline()
    except (DataError, OSError, UnicodeDecodeError):
        return True  # read_long_table reports it
    return "location" in [h.strip().lower() for h in header.split(",")]


def read_indenter(path, displacement_unit: str = "mm", skip_bad: bool = False
                  ) -> IndenterRecording:
    """Read indenter recordings from a folder, a long CSV/Parquet, or one trial file.

    Parameters
    ----------
    path : str or Path
        A folder of ``<label>_<trial>.csv``/``.mat`` files, a long CSV or Parquet
        file with ``location, trial, time, displacement, force``, or a single
        ``<label>_<trial>.csv``/``.mat`` file.
    displacement_unit : {'mm', 'm'}
        Unit of the displacement [default mm]; converted to metres.
    skip_bad : bool
        Leave out bad trials (listed in ``skipped``) instead of raising. A
        missing or empty folder, or a missing column of a long CSV, is always
        an error.

    Returns
    -------
    IndenterRecording

    Raises
    ------
    DataError
        Naming the file and column of the problem.
    """
    path = Path(path)
    _unit_scale(displacement_unit)
    if not path.exists():
        raise DataError("no such file or folder; expected a folder of <label>_<trial>.csv "
                        "files or one long CSV", file=path)
    if path.is_dir():
        rec = _read_folder(path, displacement_unit, skip_bad)
    elif TRIAL_NAME_RE.match(path.stem) and (path.suffix.lower() == ".mat"
                                              or not _has_location_column(path)):
        try:
            rec = IndenterRecording([read_trial_file(path, displacement_unit)], [], "single")
        except DataError as err:
            if not skip_bad:
                raise
            rec = IndenterRecording([], [SkippedTrial(None, None, err)], "single")
    elif path.suffix.lower() in (".csv", ".parquet", ".pq", ".txt"):
        rec = read_long_table(path, displacement_unit, skip_bad)
    else:
        raise DataError("unknown input; expected a folder, a long .csv or .parquet file, or a "
                        "<label>_<trial>.csv/.mat file", file=path)
    if not rec.trials:
        first = rec.skipped[0].error if rec.skipped else None
        raise DataError("no usable trials" + (f" (first problem: {first})" if first else ""),
                        file=path)
    return rec


# --------------------------------------------------------------------------- writers


def write_stiffness_csv(table, path, float_format: str = "%.8g", atomic: bool = True) -> Path:
    """Write the fit table (docs/model.md section 7 columns first) atomically.

    Parameters
    ----------
    table : pandas.DataFrame
        Must start with :data:`STIFFNESS_COLUMNS`; further (quality) columns follow.
    path : str or Path
        Output CSV; written to a temporary file and renamed on success.
    atomic : bool
        False writes ``path`` directly (for a caller that already holds a
        temporary path from :func:`~phri_spring.io.outputs.atomic.atomic_file`).

    Returns
    -------
    Path
    """
    cols = list(table.columns)
    if tuple(cols[:len(STIFFNESS_COLUMNS)]) != STIFFNESS_COLUMNS:
        raise ValueError(f"the fit table must start with {STIFFNESS_COLUMNS}, got {cols}")
    return _write_csv(table, path, float_format, atomic)


def write_trials_csv(table, path, float_format: str = "%.8g", atomic: bool = True) -> Path:
    """Write the per-trial table (columns as given), atomically unless ``atomic=False``."""
    return _write_csv(table, path, float_format, atomic)


def _write_csv(table, path, float_format: str, atomic: bool) -> Path:
    path = Path(path)
    if not atomic:
        table.to_csv(path, index=False, float_format=float_format)
        return path
    with atomic_file(path, suffix=".csv") as tmp:
        table.to_csv(tmp, index=False, float_format=float_format)
    return path
