"""``phri live`` as library calls: the pressure map while the experiment runs (docs/live.md).

:class:`LiveRun` reads samples from a :class:`~phri_spring.io.live.sources.LiveSource`,
turns each into the cuff wrench (:func:`~phri_spring.workflows.common.cuff_wrench`)
and the forces of every element through the single-sample
:class:`~phri_spring.physics.contact.solver.Solver` (warm-started from the previous
sample, so friction follows the loading path), zeroes them by the baseline as
``phri simulate`` does, and hands the results to its outputs: the forces table
(the columns of ``phri simulate``, :class:`~phri_spring.io.live.outputs.LiveTable`),
an LSL outlet, alarm lines when the peak pressure ratio reaches a threshold and
when it has come back below a lower clear level for long enough (hysteresis: no
chatter), and any number of observers (:meth:`LiveRun.subscribe`:
a dashboard gets a :class:`LiveSnapshot` per sample).

A stream that carries a muscle activation (a CSV header's ``activation`` column,
:attr:`~phri_spring.io.live.sources.LiveSource.has_activation`) is solved with the
tissue's history from its first sample on, as ``phri simulate`` solves a log with that
column (docs/model.md section 15.2): the tissue stiffness is scaled by 1 + (c - 1) a.

A ``first:SECONDS`` or ``window:T0:T1`` baseline is the mean wrench of the
stream over that window: samples are held until the window has passed (a
sample later than its end, or the end of the stream), then solved in order,
so the forces equal those of ``phri simulate`` on the same samples.

The run stops at the end of the stream, after ``duration`` seconds, after
``max_samples`` samples, or on :meth:`LiveRun.request_stop` (SIGINT, SIGTERM
and SIGHUP call it while the loop runs): outputs are then completed and the
summary tells why it stopped.
"""

from __future__ import annotations

import math
import signal
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, List, Optional

import numpy as np

from ..errors import DataError
from ..io.outputs.atomic import check_output_path
from ..io.config import Config
from ..io.live.outputs import LiveTable, LslMarkers, LslOutlet
from ..io.live.sources import LiveSource
from ..io.logs import table_format
from ..physics.contact.solver import Solver
from ..io.config.tolerance import curve_option
from .common import cuff_wrench, history_model, model_from_config
from .columns.tolerance import LiveDose
from .live_alarm import (ALARM_CLEAR_FRACTION, ALARM_HOLD_S, Alarm, check_alarm_settings,
                         check_dose_alarm)
from .pipeline import (Baseline, baseline_forces, extra_arrow_types, parse_baseline,
                       per_sample_extras)

__all__ = ["LiveRun", "LiveSnapshot", "LiveSummary", "StreamHealth", "ALARM_CLEAR_FRACTION",
           "ALARM_HOLD_S", "check_alarm_settings", "check_dose_alarm"]

#: rows per batch written to the table (also written every _FLUSH_S seconds)
_BATCH_ROWS = 2048
_FLUSH_S = 0.25
#: longest wait for a sample before the loop checks its stop conditions [s]
_TICK_S = 0.1


@dataclass(frozen=True)
class StreamHealth:
    """How the stream is doing: counts, sample rate, gaps, processing time."""

    samples: int
    lost: int
    malformed: int
    gaps: int
    rate_hz: float              # samples per second over the last second of wall time
    processing_s: float         # time from reading a sample to its outputs [s]


@dataclass(frozen=True)
class LiveSnapshot:
    """One processed sample, as observers (a dashboard) get it.

    Attributes
    ----------
    time : float
        The input sample's time [s].
    wrench : ndarray (6,)
        The load-cell reading, in the config's units.
    forces : ndarray (n,)
        Normal force of every element [N], zeroed by the baseline.
    absolute_forces : ndarray (n,)
        [N], preload included.
    labels : tuple
    peak_pressure_kpa : float
    peak_element : str
    ratio : float
        Peak pressure / pain threshold [-] (NaN if the solver did not converge).
    contacts_in_touch : int
    converged : bool
    alarm : bool
        True while the ratio is at or above the alarm threshold.
    health : StreamHealth
    dose_max : float
        With a tolerance curve: the largest dose over the elements so far [-] (may be
        infinite against a time-independent curve); NaN without a curve.
    dose_element : str
        Its element ('' without a curve).
    dose_alarm : bool
        True once the dose alarm was raised (it stays raised).
    activation : float
        The sample's muscle activation (0..1), NaN when the stream carries none.
    """

    time: float
    wrench: np.ndarray
    forces: np.ndarray
    absolute_forces: np.ndarray
    labels: tuple
    peak_pressure_kpa: float
    peak_element: str
    ratio: float
    contacts_in_touch: int
    converged: bool
    alarm: bool
    health: StreamHealth
    dose_max: float = math.nan
    dose_element: str = ""
    dose_alarm: bool = False
    activation: float = math.nan


@dataclass
class LiveSummary:
    """What a :class:`LiveRun` did."""

    source: str
    samples: int = 0
    lost: int = 0
    malformed: int = 0
    gaps: list = field(default_factory=list)   # (time [s, monotonic], length [s])
    not_converged: int = 0
    max_ratio: float = -math.inf
    max_ratio_time: float = math.nan
    max_ratio_element: str = ""
    alarms: int = 0
    #: with a tolerance curve: every element's exposure (physics.tolerance.Exposure) and
    #: how many times the dose alarm was raised (docs/tolerance.md)
    exposure: Optional[object] = None
    dose_alarms: int = 0
    output: Optional[Path] = None
    #: 'end' of the stream, 'duration', 'max-samples', 'signal'
    stopped_by: str = "end"
    signum: Optional[int] = None
    baseline_forces: Optional[np.ndarray] = None


class LiveRun:
    """A live run: a source through a config's model into outputs.

    Parameters
    ----------
    config : Config
    source : LiveSource
        Not opened yet (:meth:`run` opens and closes it).
    arm : str
        An arm of :data:`~phri_spring.workflows.common.ARMS`.
    baseline : str or Baseline
        ``none``, ``zero``, ``first:SECONDS`` or ``window:T0:T1``.
    output : path, optional
        Forces table (CSV or Parquet by the extension).
    decimals : int or None
        CSV only: decimals kept (as ``phri simulate --decimals``).
    lsl_out : str, optional
        Name of an LSL outlet of the results (and ``NAME-markers`` for alarms and gaps).
    alarm : float, optional
        Peak pressure ratio [-] that raises the alarm.
    alarm_clear : float, optional
        Ratio [-] below which the alarm clears (0 < alarm_clear <= alarm); default
        :data:`ALARM_CLEAR_FRACTION` times ``alarm``.
    alarm_hold : float
        Shortest time the alarm stays raised [s] of the stream's time (>= 0).
    duration : float, optional
        Stop after this many seconds of wall time [s].
    max_samples : int, optional
        Stop after this many samples.
    notify : callable(str), optional
        Gets a line for the user for every event (alarms, stream faults).
    model : optional
        A prebuilt model of this config and arm.
    cache_dir : path, optional
        ``coupled`` only: where the built-in FE is cached.
    tolerance : ToleranceCurve or str, optional
        Default the config's ``tolerance.curve``: follow every element's dose against
        it (the table gets ``dose_max`` and ``dose_element``; docs/tolerance.md).
    dose_alarm : float, optional
        Dose [-] that raises the dose alarm (needs a curve; hysteresis as ``alarm``).

    Raises
    ------
    UsageError
        A bad output path or baseline (before anything is opened).
    """

    def __init__(self, config: Config, source: LiveSource, *, arm: str = "compliant",
                 baseline="none", output=None, decimals: Optional[int] = 6,
                 lsl_out: Optional[str] = None, alarm: Optional[float] = None,
                 alarm_clear: Optional[float] = None, alarm_hold: float = ALARM_HOLD_S,
                 duration: Optional[float] = None, max_samples: Optional[int] = None,
                 notify: Optional[Callable[[str], None]] = None, model=None, cache_dir=None,
                 tolerance=None, dose_alarm: Optional[float] = None):
        self.cfg = config
        self.source = source
        self.arm = arm
        self.baseline: Baseline = parse_baseline(baseline)
        self.output = None if output is None else Path(output)
        self.out_fmt = None
        if self.output is not None:
            self.out_fmt = table_format(self.output, role="output", option="--out")
            check_output_path(self.output, [config.path, *config.stiffness_files],
                              option="--out")
        self.decimals = decimals
        self.lsl_out = lsl_out
        self.duration = duration
        self.max_samples = max_samples
        self.notify = notify or (lambda line: None)
        check_alarm_settings(alarm, alarm_clear, alarm_hold)
        self.model = model if model is not None else model_from_config(config, arm,
                                                                       cache_dir=cache_dir)
        self.labels = tuple(self.model.labels)
        self._alarm = Alarm(alarm, alarm_clear, alarm_hold)
        curve = check_dose_alarm(curve_option(tolerance, config), dose_alarm)
        #: the tolerance curve the dose is followed against (None: no dose)
        self.curve = curve
        self._dose = None if curve is None else LiveDose(
            self.model, curve, Alarm(dose_alarm, None, alarm_hold))
        self._observers: List[Callable[[LiveSnapshot], None]] = []
        self._stop_signal: Optional[int] = None
        self._stop_event = threading.Event()
        self._table = self._outlet = self._markers = None
        self._batch = None
        self._summary = None

    # ------------------------------------------------------------------ public
    def subscribe(self, observer: Callable[[LiveSnapshot], None]) -> None:
        """Call ``observer(snapshot)`` for every processed sample (on the run's thread:
        it must be quick, e.g. keep the latest and return)."""
        self._observers.append(observer)

    def request_stop(self, signum: Optional[int] = None) -> None:
        """Ask the loop to stop after the sample in hand (safe from a signal handler)."""
        if signum is not None and self._stop_signal is None:
            self._stop_signal = int(signum)
        self._stop_event.set()

    def run(self, *, catch_signals: bool = True,
            status: Optional[Callable[[StreamHealth, float], None]] = None) -> LiveSummary:
        """Run until the stream ends, the duration or sample count is reached, or a stop.

        Parameters
        ----------
        catch_signals : bool
            While the loop runs (main thread only), SIGINT, SIGTERM and SIGHUP stop
            it cleanly (outputs completed; ``LiveSummary.signum`` tells which).
        status : callable(health, max_ratio), optional
            Called about twice a second (a progress line).
        """
        summary = LiveSummary(source=self.source.name)
        table = outlet = markers = None
        self._summary = summary
        try:
            self.source.open()
            self._events(None)
            if self.output is not None:
                table = LiveTable(self.output, self.out_fmt, self.labels,
                                  extra_arrow_types(tolerance=self._dose is not None),
                                  decimals=self.decimals).open()
            if self.lsl_out is not None:
                outlet = LslOutlet(self.lsl_out, self.labels, self.source.nominal_rate)
                markers = LslMarkers(self.lsl_out)
            self._table, self._outlet, self._markers = table, outlet, markers
            with _StopOnSignals(self, catch_signals):
                self._loop(summary, status)
            self._flush()
        except BaseException:
            self._finish_outputs(summary, failed=True)
            raise
        finally:
            self.source.close()
        self._finish_outputs(summary, failed=False)
        return summary

    # ------------------------------------------------------------------ the loop
    def _loop(self, summary: LiveSummary, status) -> None:
        cfg, model = self.cfg, self.model
        self._solver = self._make_solver()
        self._inv_area = np.asarray(model.inv_area_kpa, dtype=float)
        self._batch = {"time": [], "forces": [], "abs": [], "contact": [], "its": [],
                       "conv": []}
        self._last_flush = time.monotonic()
        self._f_base = None
        base = self.baseline
        held = [] if base.kind in ("first", "window") else None
        if base.kind == "zero":
            self._f_base = baseline_forces(model, cfg, base, None, cfg.max_iterations)
        t_end = None
        start = time.monotonic()
        self._rate = _Rate()
        last_status = start
        received = 0
        while not self._stop_event.is_set():
            now = time.monotonic()
            if self.duration is not None and now - start >= self.duration:
                summary.stopped_by = "duration"
                break
            if self.max_samples is not None and received >= self.max_samples:
                summary.stopped_by = "max-samples"
                break
            wait = _TICK_S if self.duration is None else \
                max(min(_TICK_S, self.duration - (now - start)), 0.0)
            sample = self.source.read(wait)
            self._events(sample[0] if sample is not None else None)
            if sample is not None and len(sample) == 3 and not self._history:
                self._take_activation()
            if sample is None:
                if self.source.ended:
                    break
            elif held is not None:
                received += 1
                t = sample[0]
                if t_end is None:
                    t_end = t + base.t1 if base.kind == "first" else base.t1
                held.append(sample)
                if t > t_end:
                    self._release(held, t_end, summary)
                    held = None
            else:
                received += 1
                self._process(sample, summary)
            if time.monotonic() - self._last_flush >= _FLUSH_S:
                self._flush()
            if status is not None and time.monotonic() - last_status >= 0.5:
                last_status = time.monotonic()
                status(self._health(0.0), summary.max_ratio)
        if held:
            self._release(held, t_end, summary)
        if self._stop_event.is_set():
            summary.stopped_by = "signal" if self._stop_signal is not None else "stop"
            summary.signum = self._stop_signal

    @property
    def _history(self) -> bool:
        return getattr(self.model, "has_history", False)

    def _make_solver(self):
        if self._history:    # relaxing tissue or an activation: samples in order
            from ..physics.history.model import HistorySolver

            return HistorySolver(self.model, max_iterations=self.cfg.max_iterations)
        return Solver(self.model, max_iterations=self.cfg.max_iterations)

    def _take_activation(self) -> None:
        """The stream carries an activation: the tissue's history model from now on, as
        ``phri simulate`` does (a baseline stays the one of activation 0; the rigid arm has
        no tissue and stays as it is; the others are refused in one line)."""
        model = history_model(self.model, self.cfg)
        if model is not self.model:
            self.model = model
            self._solver = self._make_solver()

    def _release(self, held: list, t_end: float, summary: LiveSummary) -> None:
        """Solve the samples held for a first:/window: baseline, once its window is known."""
        base = self.baseline
        times = np.array([s[0] for s in held])
        wrenches = np.array([s[1] for s in held])
        if base.kind == "first":
            mask = times <= t_end
        else:
            mask = (times >= base.t0) & (times <= base.t1)
        if not mask.any():
            raise DataError(f"no sample in the baseline window {base} (the stream spans "
                            f"{times.min():g} to {times.max():g} s)", key="--baseline")
        self._f_base = baseline_forces(self.model, self.cfg, base, wrenches[mask].mean(axis=0),
                                       self.cfg.max_iterations)
        summary.baseline_forces = self._f_base
        for sample in held:
            self._process(sample, summary)

    def _process(self, sample, summary: LiveSummary) -> None:
        """One sample ``(time [s], wrench (6,)[, activation])``: solve it, hand it out."""
        t0 = time.monotonic()
        t, w = sample[0], sample[1]
        a = sample[2] if len(sample) == 3 else None
        solver = self._solver
        W = cuff_wrench(self.cfg, w[None])[0]
        f_abs = solver.forces(W, t, a) if self._history else solver.forces(W)
        forces = f_abs if self._f_base is None else f_abs - self._f_base
        contact = solver.last_contact
        conv = solver.last_converged
        b = self._batch
        b["time"].append(t)
        b["forces"].append(forces)
        b["abs"].append(f_abs)
        b["contact"].append(contact.copy())
        b["its"].append(solver.last_iterations)
        b["conv"].append(conv)
        if conv:
            pressure = f_abs * self._inv_area
            j = int(np.argmax(pressure))
            peak = float(pressure[j])
            ratio = peak / self.model.pain_threshold_kpa
        else:
            j, peak, ratio = 0, math.nan, math.nan
            summary.not_converged += 1
        contacts = int(np.count_nonzero(contact))
        summary.samples += 1
        if ratio > summary.max_ratio:
            summary.max_ratio, summary.max_ratio_time = ratio, t
            summary.max_ratio_element = self.labels[j]
        change = self._alarm.update(ratio, t)
        if change is not None:
            thr = self._alarm.threshold
            if change == "on":
                line = (f"ALARM: peak pressure ratio {ratio:.3f} >= {thr:g} at t = {t:.3f} s "
                        f"(element {self.labels[j]}, {peak:.4g} kPa)")
            else:
                line = (f"alarm cleared: peak pressure ratio {ratio:.3f} < {self._alarm.clear:g} "
                        f"at t = {t:.3f} s")
            self.notify(line)
            if self._markers is not None:
                self._markers.push(f"alarm {change}: ratio {ratio:.4f}", t)
        dose, dose_j = math.nan, None
        if self._dose is not None:
            dose, dose_j = self._dose_sample(t, f_abs if conv else np.full(len(f_abs), np.nan))
        if self._outlet is not None:
            self._outlet.push([*forces.tolist(), ratio, float(contacts)], t)
        self._rate.tick()
        if self._observers:
            snap = LiveSnapshot(time=t, wrench=w, forces=forces, absolute_forces=f_abs,
                                labels=self.labels, peak_pressure_kpa=peak,
                                peak_element=self.labels[j], ratio=ratio,
                                contacts_in_touch=contacts, converged=conv,
                                alarm=self._alarm.on,
                                health=self._health(time.monotonic() - t0),
                                dose_max=dose,
                                dose_element="" if dose_j is None else self.labels[dose_j],
                                dose_alarm=self._dose is not None and self._dose.alarm.on,
                                activation=math.nan if a is None else float(a))
            for observer in self._observers:
                observer(snap)
        if len(b["time"]) >= _BATCH_ROWS:
            self._flush()

    def _dose_sample(self, t: float, f_abs):
        """Add the sample to the dose; ``(largest dose so far, its element index)``."""
        dose, j, change = self._dose.update(t, f_abs)
        if change == "on":
            line = (f"DOSE ALARM: dose {dose:.3g} >= {self._dose.alarm.threshold:g} against "
                    f"{self._dose.tally.curve.name} at t = {t:.3f} s (element {self.labels[j]})")
            self.notify(line)
            if self._markers is not None:
                self._markers.push(f"dose alarm on: {dose:.4g}", t)
        return dose, j

    def _flush(self) -> None:
        """Write the batch of processed rows to the table."""
        self._last_flush = time.monotonic()
        b = self._batch
        if not b or not b["time"]:
            return
        if self._table is not None:
            f_abs = np.array(b["abs"])
            extras, _ = per_sample_extras(self.model, f_abs, np.array(b["contact"]),
                                          np.array(b["its"]), np.array(b["conv"]))
            if self._dose is not None:
                extras.update(self._dose.columns())
            self._table.write(np.array(b["time"]), np.array(b["forces"]), extras)
        if self._dose is not None:
            self._dose.rows.clear()       # (written above, or no table)
        for rows in b.values():
            rows.clear()

    def _health(self, processing_s: float) -> StreamHealth:
        st = self.source.stats
        return StreamHealth(samples=self._summary.samples, lost=st.lost, malformed=st.malformed,
                            gaps=len(st.gaps), rate_hz=self._rate.rate(),
                            processing_s=processing_s)

    def _events(self, t: Optional[float]) -> None:
        for line in self.source.pop_events():
            self.notify(line)
            if self._markers is not None and t is not None:
                self._markers.push(line, t)

    def _finish_outputs(self, summary: LiveSummary, failed: bool) -> None:
        """Complete the outputs (or drop them when nothing was computed); fill the counts."""
        st = self.source.stats
        summary.lost, summary.malformed, summary.gaps = st.lost, st.malformed, list(st.gaps)
        summary.alarms = self._alarm.count
        if self._dose is not None:
            summary.exposure, summary.dose_alarms = self._dose.exposure, self._dose.alarm.count
        table = self._table
        if table is not None:
            if failed:
                try:
                    self._flush()
                except Exception:  # noqa: BLE001 - keep what was written before
                    pass
            self._table = None
            if table.rows > 0:
                summary.output = table.commit()
            else:
                table.discard()
        for out in (self._outlet, self._markers):
            if out is not None:
                out.close()
        self._outlet = self._markers = None


class _Rate:
    """Samples per second over the last second of wall time."""

    def __init__(self):
        self._times: list = []

    def tick(self) -> None:
        now = time.monotonic()
        self._times.append(now)
        if len(self._times) > 4096 or now - self._times[0] > 2.0:
            cut = now - 1.0
            self._times = [t for t in self._times if t >= cut]

    def rate(self) -> float:
        if not self._times:
            return 0.0
        now = time.monotonic()
        return float(sum(1 for t in self._times if t >= now - 1.0))


class _StopOnSignals:
    """While the loop runs, SIGINT, SIGTERM and SIGHUP ask it to stop instead of raising."""

    SIGNALS = tuple(getattr(signal, n) for n in ("SIGINT", "SIGTERM", "SIGHUP")
                    if hasattr(signal, n))

    def __init__(self, run: LiveRun, enabled: bool):
        self.run = run
        self.enabled = enabled and threading.current_thread() is threading.main_thread()
        self._old: dict = {}

    def _handler(self, signum, frame):
        self.run.request_stop(signum)

    def __enter__(self):
        if self.enabled:
            for sig in self.SIGNALS:
                old = signal.getsignal(sig)
                if sig != signal.SIGINT and old == signal.SIG_IGN:
                    continue       # nohup: SIGHUP stays ignored
                self._old[sig] = signal.signal(sig, self._handler)
        return self

    def __exit__(self, *exc):
        for sig, old in self._old.items():
            signal.signal(sig, old)
        return False
