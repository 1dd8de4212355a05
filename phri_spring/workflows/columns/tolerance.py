"""The forces table's dose columns and the per-element exposure table (docs/tolerance.md).

With a tolerance curve (``tolerance.curve`` in the config or ``--tolerance NAME``), a
streamed run adds two columns after the standard ones: ``dose_max`` [-], the largest
cumulative dose over the elements up to each sample, and ``dose_element``, its element.
Every element's totals (time above the pain threshold and above the curve's floor [s],
its dose, when the dose reached 1 and when the pain threshold was first passed [s]) go
into the summary and into a small CSV beside the output (:func:`exposure_table_path`).
Without a curve nothing is added: the table is the paper model's.
"""

from __future__ import annotations

import math
import threading
from pathlib import Path
from typing import Optional

import numpy as np

from ...io.outputs.atomic import atomic_file
from ...physics.response.tolerance import Exposure

__all__ = ["TOLERANCE_COLUMN_TYPES", "TOLERANCE_COLUMNS", "ExposureTally",
           "exposure_table_path", "write_exposure_table", "exposure_text",
           "EXPOSURE_TABLE_COLUMNS"]

#: the columns and their types (as EXTRA_COLUMN_TYPES of :mod:`.simulate`)
TOLERANCE_COLUMN_TYPES = (("dose_max", "float64"), ("dose_element", "label"))
TOLERANCE_COLUMNS = tuple(name for name, _ in TOLERANCE_COLUMN_TYPES)
#: the per-element exposure table's columns (times in s, dose unitless)
EXPOSURE_TABLE_COLUMNS = ("element", "time_above_pain_threshold_s", "time_above_curve_floor_s",
                          "dose", "dose_reached_s", "first_above_pain_threshold_s")


#: pressure bins of the exposure figure [kPa]: 0.1 kPa to 10 MPa, 100 per decade
EXPOSURE_EDGES_KPA = np.geomspace(0.1, 1.0e4, 501)


class ExposureTally:
    """An :class:`~phri_spring.physics.response.tolerance.Exposure` of a model's elements, fed the
    absolute forces of each chunk in log order (on the solving thread); ``binned`` also
    keeps the time at each pressure for the exposure figure."""

    def __init__(self, model, curve, binned: bool = False):
        self._turn = threading.Condition()
        self._next, self._failed = 0, False
        self.labels = tuple(model.labels)
        self.inv_area_kpa = np.asarray(model.inv_area_kpa, dtype=float)
        self.exposure = Exposure(curve, len(self.labels), model.pain_threshold_kpa,
                                 edges_kpa=EXPOSURE_EDGES_KPA if binned else None)

    @property
    def curve(self):
        return self.exposure.curve

    def add_in_order(self, number: int, time, absolute_forces) -> dict:
        """:meth:`add` for chunk ``number`` (0, 1, ...), from any thread: waits until the
        chunks before it are added. Chunks must be handed to threads in order (a FIFO
        pool), so that the one waited for is already running."""
        with self._turn:
            self._turn.wait_for(lambda: self._next == number or self._failed)
            if self._failed:
                raise RuntimeError("the dose of an earlier chunk failed")
            try:
                out = self.add(time, absolute_forces)
            except BaseException:
                self._failed = True
                raise
            finally:
                self._next += 1
                self._turn.notify_all()
        return out

    def add(self, time, absolute_forces) -> dict:
        """The dose columns of the next chunk: times (m,) [s], absolute forces (m, n) [N]."""
        dose, idx = self.exposure.add(time, absolute_forces, scale=self.inv_area_kpa)
        return {"dose_max": dose, "dose_element": (idx, self.labels)}


def exposure_table_path(output) -> Path:
    """Where the per-element table of a run writing ``output`` goes: beside it, its stem
    + ``_exposure.csv``."""
    out = Path(output)
    return out.with_name(out.stem + "_exposure.csv")


def write_exposure_table(path, labels, exposure: Exposure) -> Path:
    """Write every element's totals (:data:`EXPOSURE_TABLE_COLUMNS`) as CSV, atomically;
    times that never happened are empty."""
    def fmt(x):
        return "" if not math.isfinite(x) else ("inf" if x == math.inf else f"{x:.6g}")

    rows = [",".join(EXPOSURE_TABLE_COLUMNS)]
    for j, lab in enumerate(labels):
        d = float(exposure.dose[j])
        rows.append(",".join([str(lab), fmt(float(exposure.time_above_pain_s[j])),
                              fmt(float(exposure.time_above_floor_s[j])),
                              "inf" if d == math.inf else fmt(d),
                              fmt(float(exposure.dose_reached_s[j])),
                              fmt(float(exposure.pain_first_s[j]))]))
    path = Path(path)
    with atomic_file(path) as tmp:
        Path(tmp).write_text("\n".join(rows) + "\n", encoding="utf-8")
    return path


def exposure_plot_path(plot) -> Path:
    """The exposure figure of ``simulate --plot FILE``: FILE's stem + ``_exposure``."""
    p = Path(plot)
    return p.with_name(p.stem + "_exposure" + p.suffix)


def write_exposure_plot(exposure: Exposure, labels, path, *, title: str = "",
                        dpi: int = 150) -> Path:
    """Draw :func:`~phri_spring.reports.tolerance_figure.exposure_figure` of a binned
    exposure and write it atomically (PNG, SVG or PDF by the extension)."""
    from ...reports.compare.figures import save_figure
    from ...reports.tolerance_figure import exposure_figure

    fig = exposure_figure(exposure.edges_kpa, exposure.time_at_or_above_s(), labels=labels,
                          curve=exposure.curve, dose=exposure.dose,
                          pain_threshold_kpa=exposure.pain_threshold_kpa, title=title)
    path = Path(path)
    with atomic_file(path) as tmp:
        save_figure(fig, tmp, dpi)
    return path


def exposure_text(labels, exposure: Optional[Exposure]) -> str:
    """The summary clause of a run with a tolerance curve: the largest dose and where, where
    and when the curve's limit was first reached, and the time above the pain threshold."""
    if exposure is None:
        return ""
    curve = exposure.curve
    j, dose = exposure.worst()
    text = f"dose ({curve.name}) max {dose:.3g} at {labels[j]}"
    reached = exposure.dose_reached_s
    if np.isfinite(reached).any():
        k = int(np.nanargmin(reached))
        text += f", limit reached first at {labels[k]}, t = {reached[k]:g} s"
    else:
        text += ", limit not reached"
    above = exposure.time_above_pain_s
    k = int(np.argmax(above))
    first = exposure.pain_first_s
    if np.isfinite(first).any():
        f = int(np.nanargmin(first))
        text += (f"; above the pain threshold ({exposure.pain_threshold_kpa:g} kPa) first at "
                 f"{labels[f]}, t = {first[f]:g} s, longest {above[k]:.4g} s at {labels[k]}")
    else:
        text += f"; never above the pain threshold ({exposure.pain_threshold_kpa:g} kPa)"
    return text


# --------------------------------------------------------------------------- compare
#: columns of a comparison's exposure.csv
COMPARE_EXPOSURE_COLUMNS = ("experiment", "direction", "trial", "arm", "element",
                            "time_above_pain_threshold_s", "time_above_curve_floor_s", "dose",
                            "dose_reached_s")


def compare_exposure(trials, models: dict, curve):
    """Every element's exposure predicted by each arm over each trial of a comparison: the
    condition's predicted absolute pressure held over every row of its window, nothing
    between windows (so a dose is a lower bound there). A DataFrame of
    :data:`COMPARE_EXPOSURE_COLUMNS`."""
    import pandas as pd

    rows = []
    for tc in trials:
        d, s = tc.data, tc.spec
        index = {c: j for j, c in enumerate(tc.conditions)}
        idx = np.array([index.get(str(c), -1) for c in d.condition_series], dtype=np.intp)
        outside = idx < 0
        for arm, model in models.items():
            pressure = tc.simulated_abs[arm][np.maximum(idx, 0)] * model.inv_area_kpa
            pressure[outside] = np.nan
            ex = Exposure(curve, len(model.labels), model.pain_threshold_kpa)
            ex.add(d.time, pressure)
            for j, lab in enumerate(model.labels):
                rows.append((s.experiment, s.direction, s.trial, arm, lab,
                             ex.time_above_pain_s[j], ex.time_above_floor_s[j], ex.dose[j],
                             ex.dose_reached_s[j]))
    return pd.DataFrame(rows, columns=list(COMPARE_EXPOSURE_COLUMNS))


def compare_exposure_markdown(table, curve) -> str:
    """The comparison report's lines on the predicted exposure (per arm: the largest dose,
    where and in which trial, and the longest time above the pain threshold)."""
    lines = ["", "## Exposure against a tolerance curve", "",
             f"Curve `{curve.name}` ({curve.kind}, {curve.site}; docs/tolerance.md), applied to "
             "each arm's predicted pressures held over every condition's window "
             "(`exposure.csv`):", ""]
    for arm, part in table.groupby("arm", sort=False):
        k = int(np.argmax(part["dose"].to_numpy()))
        r = part.iloc[k]
        a = part.iloc[int(np.argmax(part["time_above_pain_threshold_s"].to_numpy()))]
        reached = part["dose_reached_s"].notna().sum()
        pain = ("never above the pain threshold" if not a["time_above_pain_threshold_s"] > 0
                else f"longest time above the pain threshold "
                     f"{a['time_above_pain_threshold_s']:.4g} s ({a['element']}, "
                     f"{a['experiment']} {a['direction']}, trial {a['trial']})")
        lines.append(f"- {arm}: largest dose {r['dose']:.3g} at {r['element']} "
                     f"({r['experiment']} {r['direction']}, trial {r['trial']}); the limit is "
                     f"reached by {reached} of {len(part)} element-trials; {pain}")
    return "\n".join(lines) + "\n"


# --------------------------------------------------------------------------- live
class LiveDose:
    """The dose of a live run, sample by sample, and its alarm (``phri live --dose-alarm``).

    ``alarm`` is the live run's alarm object (raise level, clear level, hold; the same
    hysteresis as the pressure alarm) or None. A dose never goes down, so once raised
    the dose alarm stays on: the clear level only matters to keep the interface alike.
    """

    def __init__(self, model, curve, alarm=None):
        self.tally = ExposureTally(model, curve)
        self.alarm = alarm
        self.rows = []          # (dose_max, element index) of the samples not yet written

    @property
    def exposure(self) -> Exposure:
        return self.tally.exposure

    def update(self, t: float, absolute_forces):
        """Add one sample (absolute forces (n,) [N], NaN when not converged); returns
        ``(dose, element index, alarm change or None)``."""
        dose, j = self.tally.exposure.add_sample(t, absolute_forces, self.tally.inv_area_kpa)
        self.rows.append((dose, j))
        change = None if self.alarm is None else self.alarm.update(dose, t)
        return dose, j, change

    def columns(self) -> dict:
        """The dose columns of the samples added since the last call (then forgotten)."""
        d = np.array([r[0] for r in self.rows], dtype=float)
        i = np.array([r[1] for r in self.rows], dtype=np.intp)
        self.rows.clear()
        return {"dose_max": d, "dose_element": (i, self.tally.labels)}
