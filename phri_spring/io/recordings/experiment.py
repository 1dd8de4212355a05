"""Experiment files for ``phri compare`` (docs/model.md section 7): manifest and trial tables.

Manifest (YAML, loaded safely; unknown keys are an error)::

    baseline: no_load          # condition both sides are zeroed on (default no_load)
    description: ...           # optional free text, shown in the report
    trials:
      - {file: iact_horizontal_1.csv, experiment: I-Act, direction: horizontal, trial: 1}
      - {file: ipass_vertical_2.csv, experiment: II-Pass, direction: vertical, trial: 2,
         baseline: start}      # optional per-trial baseline (overrides the top-level one)

Trial files are relative to the manifest's folder. Each trial table (CSV, or
Parquet by extension) holds ``time`` [s], ``Fx Fy Fz`` [load-cell force unit],
``Mx My Mz`` [load-cell moment unit], one column per element label with the
measured load [N], and ``condition`` (the label of a steady window, empty
between windows). Other columns are ignored, except ones that look like an
element label the config does not have (an error). A condition's mean wrench
and mean loads are taken over all of its rows; conditions keep their order of
first appearance.
"""

from __future__ import annotations

import csv
import difflib
import io
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional, Union

import numpy as np

from ...errors import ConfigError, ConfigTypeError, DataError
from ..config import LOG_COLUMNS, load_yaml
from ..logs.base import take_group

__all__ = ["TrialSpec", "Manifest", "TrialData", "load_manifest", "read_trial",
           "WRENCH_COLUMNS", "DEFAULT_BASELINE"]

#: the wrench columns of a trial table, as the load cell reads them
WRENCH_COLUMNS = LOG_COLUMNS[1:]
#: the default baseline condition
DEFAULT_BASELINE = "no_load"

_TOP_KEYS = ("baseline", "description", "trials")
_TRIAL_KEYS = ("file", "experiment", "direction", "trial", "baseline")
_TRIAL_REQUIRED = ("file", "experiment", "direction", "trial")


@dataclass(frozen=True)
class TrialSpec:
    """One entry of the manifest's ``trials`` list.

    Attributes
    ----------
    file : Path
        The trial table, resolved against the manifest's folder.
    experiment, direction : str
        Grouping labels (e.g. ``I-Act``, ``horizontal``).
    trial : int or str
        Trial number (or name) within its experiment and direction.
    baseline : str
        The condition this trial is zeroed on.
    index : int
        Position in the manifest's list (0-based).
    """

    file: Path
    experiment: str
    direction: str
    trial: Union[int, str]
    baseline: str
    index: int = 0

    @property
    def key(self) -> str:
        """Where this entry sits in the manifest, e.g. ``trials[3]``."""
        return f"trials[{self.index}]"


@dataclass(frozen=True)
class Manifest:
    """A validated experiment manifest."""

    path: Path
    baseline: str
    trials: tuple
    description: str = ""


@dataclass(eq=False)
class TrialData:
    """The steady windows of one trial, reduced to their means.

    Attributes
    ----------
    spec : TrialSpec
    conditions : tuple of str
        Condition labels in order of first appearance.
    wrench : ndarray, shape (c, 6)
        Mean load-cell reading of each condition (Fx Fy Fz, Mx My Mz) in the
        log's units (the config's ``load_cell.force_unit`` and ``moment_unit``).
    loads : ndarray, shape (c, n)
        Mean measured load of each element [N], columns in the config's label order.
    n_samples : ndarray of int, shape (c,)
        Rows in each condition.
    time : ndarray, shape (m,)
        Every sample time [s] of the file (for plots).
    wrench_series : ndarray, shape (m, 6)
        Every load-cell reading (NaN where unreadable outside the windows).
    condition_series : ndarray of str, shape (m,)
        Condition of every row ('' between windows).
    """

    spec: TrialSpec
    conditions: tuple
    wrench: np.ndarray
    loads: np.ndarray
    n_samples: np.ndarray
    time: np.ndarray = field(repr=False, default=None)
    wrench_series: np.ndarray = field(repr=False, default=None)
    condition_series: np.ndarray = field(repr=False, default=None)

    @property
    def baseline_index(self) -> int:
        return self.conditions.index(self.spec.baseline)


# --------------------------------------------------------------------------- manifest
def _unknown_key(bad, valid, where, path, key) -> ConfigError:
    close = difflib.get_close_matches(str(bad), valid, n=1, cutoff=0.5)
    hint = f"; did you mean {close[0]!r}?" if close else ""
    return ConfigError(f"unknown key {bad!r} in {where}{hint} (valid keys: {', '.join(valid)})",
                       file=path, key=key)


def _label(value, path, key, what) -> str:
    if isinstance(value, bool) or value is None or isinstance(value, (dict, list)):
        raise ConfigTypeError(f"expected {what} (text), got {value!r}", file=path, key=key)
    text = str(value).strip()
    if not text:
        raise ConfigError(f"expected {what} (non-empty text)", file=path, key=key)
    return text


def load_manifest(path) -> Manifest:
    """Read and validate an experiment manifest (YAML).

    Parameters
    ----------
    path : str or path-like
        The manifest. Trial files in it are relative to its folder.

    Returns
    -------
    Manifest

    Raises
    ------
    ConfigError
        One line naming the file and the key (``trials[2].direction``): a
        missing file, invalid YAML, an unknown key (with the closest valid
        name), a missing or empty value, a duplicate trial.
    DataError
        A trial file that does not exist (naming it and its manifest entry).
    """
    path = Path(path)
    data = load_yaml(path)
    if not isinstance(data, dict):
        raise ConfigError(f"expected a mapping with keys {', '.join(_TOP_KEYS)}, got "
                          f"{type(data).__name__}", file=path)
    for k in data:
        if k not in _TOP_KEYS:
            raise _unknown_key(k, list(_TOP_KEYS), "the top level", path, str(k))
    baseline = _label(data.get("baseline", DEFAULT_BASELINE), path, "baseline",
                      "a condition label")
    description = data.get("description") or ""
    if not isinstance(description, str):
        raise ConfigTypeError(f"expected text, got {description!r}", file=path, key="description")
    trials_raw = data.get("trials")
    if trials_raw is None:
        raise ConfigError("missing required key; expected a list of {file, experiment, "
                          "direction, trial}", file=path, key="trials")
    if not isinstance(trials_raw, list) or not trials_raw:
        raise ConfigError("expected a non-empty list of {file, experiment, direction, trial}",
                          file=path, key="trials")
    base_dir = path.parent
    trials = []
    seen = {}
    for i, entry in enumerate(trials_raw):
        where = f"trials[{i}]"
        if not isinstance(entry, dict):
            raise ConfigError(f"expected a mapping {{file, experiment, direction, trial}}, got "
                              f"{entry!r}", file=path, key=where)
        for k in entry:
            if k not in _TRIAL_KEYS:
                raise _unknown_key(k, list(_TRIAL_KEYS), where, path, f"{where}.{k}")
        for k in _TRIAL_REQUIRED:
            if k not in entry:
                raise ConfigError("missing required key", file=path, key=f"{where}.{k}")
        file_txt = _label(entry["file"], path, f"{where}.file", "a file path")
        experiment = _label(entry["experiment"], path, f"{where}.experiment", "an experiment name")
        direction = _label(entry["direction"], path, f"{where}.direction", "a direction")
        trial = entry["trial"]
        if isinstance(trial, bool) or not isinstance(trial, (int, str)) or \
                (isinstance(trial, str) and not trial.strip()):
            raise ConfigTypeError(f"expected a trial number or name, got {trial!r}", file=path,
                                  key=f"{where}.trial")
        trial = trial.strip() if isinstance(trial, str) else int(trial)
        t_base = _label(entry.get("baseline", baseline), path, f"{where}.baseline",
                        "a condition label")
        ident = (experiment, direction, str(trial))
        if ident in seen:
            raise ConfigError(f"experiment {experiment!r}, direction {direction!r}, trial "
                              f"{trial!r} is listed twice (also trials[{seen[ident]}]); expected "
                              "one entry per trial", file=path, key=f"{where}.trial")
        seen[ident] = i
        fpath = Path(file_txt)
        if not fpath.is_absolute():
            fpath = base_dir / fpath
        if not fpath.is_file():
            raise DataError(f"trial file not found (listed in {path} {where}.file; paths are "
                            "relative to the manifest's folder)", file=fpath)
        trials.append(TrialSpec(file=fpath, experiment=experiment, direction=direction,
                                trial=trial, baseline=t_base, index=i))
    return Manifest(path=path, baseline=baseline, trials=tuple(trials), description=description)


# --------------------------------------------------------------------------- trial tables
def _header(text: str, path: Path) -> list:
    try:
        return [c.strip() for c in next(csv.reader(io.StringIO(text)), [])]
    except csv.Error as exc:
        raise DataError(f"cannot read as CSV ({exc.__class__.__name__}: {exc})",
                        file=path) from None


def _read_table(path: Path, group: Optional[str] = None, time_name: str = "time"):
    """The trial table as a DataFrame of text (CSV) or its own types (Parquet, TDMS, MAT)."""
    import pandas as pd

    if path.suffix.lower() in (".tdms", ".mat"):
        from ..logs.lab import read_lab_frame

        return read_lab_frame(path, group, time_name=time_name), False
    from ..logs.textio import read_text

    if path.suffix.lower() in (".parquet", ".pq"):
        try:
            df = pd.read_parquet(path)
        except Exception as exc:  # noqa: BLE001 - any reader failure is bad data
            msg = str(exc).replace("\n", " ")
            raise DataError(f"cannot read as Parquet ({msg})", file=path) from None
        df.columns = [str(c).strip() for c in df.columns]
        return df, False
    text = read_text(path, what="a CSV trial table")
    cols = _header(text, path)
    if not any(cols):
        raise DataError("empty file; expected a header with time, Fx, Fy, Fz, Mx, My, Mz, the "
                        "element labels and condition", file=path)
    dup = sorted({c for c in cols if cols.count(c) > 1})
    if dup:
        raise DataError(f"column {dup[0]!r} appears more than once; expected each column once",
                        file=path, key=dup[0])
    try:
        df = pd.read_csv(io.StringIO(text), dtype=str, keep_default_na=False, na_filter=False,
                         skipinitialspace=True)
    except Exception as exc:  # noqa: BLE001 - any parser failure is bad data
        msg = str(exc).replace("\n", " ")
        raise DataError(f"cannot read as CSV ({msg})", file=path) from None
    df.columns = [str(c).strip() for c in df.columns]
    return df, True


def _numeric(df, col):
    import pandas as pd

    return pd.to_numeric(df[col], errors="coerce").to_numpy(dtype=float, na_value=np.nan)


def _conditions(values) -> np.ndarray:
    """Condition of every row, '' for a missing one in any spelling (empty, NaN, NA, null,
    pandas' ``<NA>``, ...: :data:`~phri_spring.io.logs.textio.NA_STRINGS`)."""
    from ..logs.textio import is_missing

    out = np.empty(len(values), dtype=object)
    for i, v in enumerate(values):
        out[i] = "" if is_missing(v) else str(v).strip()
    return out


def read_trial(spec: Union[TrialSpec, str, Path], labels, *, baseline: Optional[str] = None,
               columns: Optional[dict] = None, row_labels=(),
               group: Optional[str] = None) -> TrialData:
    """Read one trial table and reduce each condition window to its means.

    Parameters
    ----------
    spec : TrialSpec or path
        The manifest entry, or a bare path (then ``baseline`` is required).
    labels : sequence of str
        The config's element labels (A0 ... C6); the table must have exactly these.
    baseline : str, optional
        Baseline condition (default: the spec's).
    columns : dict, optional
        Map from spec names (``time``, ``Fx`` ...) to the table's names
        (the config's ``load_cell.columns``).
    row_labels : sequence of str
        The config's row labels, to recognise an extra element column such as ``D0``.
    group : str, optional
        TDMS and MAT tables: the group or struct holding the channels
        (``--group``, the config's ``load_cell.group``).

    Returns
    -------
    TrialData

    Raises
    ------
    DataError
        Naming the file and the column or condition: a missing file, a missing
        ``condition`` column, a baseline condition absent from the file, an
        element column missing or not in the config, a NaN or text in a
        condition window.
    """
    if not isinstance(spec, TrialSpec):
        if baseline is None:
            raise ValueError("read_trial: give a TrialSpec or a baseline")
        spec = TrialSpec(file=Path(spec), experiment="", direction="", trial=0,
                         baseline=baseline)
    elif baseline is not None and baseline != spec.baseline:
        spec = TrialSpec(spec.file, spec.experiment, spec.direction, spec.trial, baseline,
                         spec.index)
    path = Path(spec.file)
    labels = tuple(labels)
    if not path.is_file():
        raise DataError("file not found; expected a trial table (CSV)", file=path)
    columns, group = take_group(columns, group)
    df, is_csv = _read_table(path, group, columns.get("time", "time"))

    rename = {v: k for k, v in columns.items() if k in LOG_COLUMNS}
    if rename:
        df = df.rename(columns=rename)
    cols = list(df.columns)
    if "condition" not in cols:
        raise DataError("missing column 'condition'; expected the condition of each row "
                        "(e.g. no_load, L1, L2; empty between windows)", file=path,
                        key="condition")
    for c in LOG_COLUMNS:
        if c not in cols:
            raise DataError(f"missing column {c!r}; expected time [s], Fx Fy Fz, Mx My Mz (the "
                            "load-cell wrench), one column per element and condition",
                            file=path, key=c)
    missing = [lab for lab in labels if lab not in cols]
    if missing:
        more = f" (and {len(missing) - 1} more: {', '.join(missing[1:6])}" \
               f"{', ...' if len(missing) > 6 else ''})" if len(missing) > 1 else ""
        raise DataError(f"missing element column{more}; expected one column of measured load [N] "
                        f"per element of the config ({labels[0]}..{labels[-1]}, {len(labels)} "
                        "in all)", file=path, key=missing[0])
    pattern = "|".join([re.escape(r) for r in row_labels if r] + ["[A-Z]"])
    label_like = re.compile(rf"^(?:{pattern})\d+$")
    extra = [c for c in cols if c not in labels and c not in LOG_COLUMNS and c != "condition"
             and label_like.match(c)]
    if extra:
        raise DataError(f"element column not in the config's geometry; expected only "
                        f"{labels[0]}..{labels[-1]} ({len(labels)} elements)", file=path,
                        key=extra[0])

    cond = _conditions(df["condition"].tolist())
    order = list(dict.fromkeys(c for c in cond if c))
    if not order:
        raise DataError("no row has a condition; expected steady windows labelled e.g. "
                        f"{spec.baseline}, L1, L2 (empty between windows)", file=path,
                        key="condition")
    if spec.baseline not in order:
        raise DataError(f"baseline condition {spec.baseline!r} not found; the file has "
                        f"{', '.join(order)} (set 'baseline' in the manifest)", file=path,
                        key="condition")

    in_window = cond != ""
    num_cols = list(LOG_COLUMNS) + list(labels)
    values = {}
    for c in num_cols:
        v = _numeric(df, c)
        bad = in_window & ~np.isfinite(v)
        if bad.any():
            i = int(np.argmax(bad))
            raw = df[c].iloc[i]
            where = f"line {i + 2}" if is_csv else f"row {i + 1}"
            unit = "[s]" if c == "time" else ("[N]" if c in labels else "")
            got = "an empty cell" if (isinstance(raw, str) and not raw.strip()) else repr(raw)
            unit = f" {unit}" if unit else ""
            raise DataError(f"condition {cond[i]!r}, {where}: expected a finite number{unit}, "
                            f"got {got}", file=path, key=c)
        values[c] = v

    wrench = np.column_stack([values[c] for c in WRENCH_COLUMNS])
    loads = np.column_stack([values[c] for c in labels])
    nc = len(order)
    w_mean = np.empty((nc, 6))
    l_mean = np.empty((nc, len(labels)))
    counts = np.empty(nc, dtype=np.int64)
    for j, c in enumerate(order):
        mask = cond == c
        counts[j] = int(mask.sum())
        w_mean[j] = wrench[mask].mean(axis=0)
        l_mean[j] = loads[mask].mean(axis=0)
    return TrialData(spec=spec, conditions=tuple(order), wrench=w_mean, loads=l_mean,
                     n_samples=counts, time=values["time"], wrench_series=wrench,
                     condition_series=cond)
