"""How long a pressure is tolerated: published pressure-time curves and the dose of a log.

A :class:`ToleranceCurve` is a published limit on the contact pressure as a
function of how long it is held, kept as data with its citation and its limits
(docs/tolerance.md). :class:`Exposure` follows every element of a cuff through
a log, chunk by chunk: the time each element spends above a threshold [s] and
its cumulative dose against a curve,

    dose_e(t_n) = sum_{k <= n} dt_k / t_allowed(p_e(t_k)),

a Miner-like damage sum where 1.0 means the curve's limit is reached, with
``dt_k = t_k - t_{k-1}`` (0 for the first sample of the log: a sample weighs
the step that led to it). Pure numpy, pressures in kPa, times in s.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ...errors import ModelInputError

__all__ = ["ToleranceCurve", "TOLERANCE_CURVES", "tolerance_curve", "Exposure",
           "MMHG_KPA", "DEFAULT_CURVE"]

#: one millimetre of mercury in kPa (133.322 Pa)
MMHG_KPA = 0.133322387415
_HOUR = 3600.0


def _bad(message: str) -> ModelInputError:
    return ModelInputError(message, "tolerance")


_MIN = 60.0


@dataclass(frozen=True)
class ToleranceCurve:
    """A pressure limit as a function of exposure time.

    The limit is given at points ``(times_s[i], limits_kpa[i])`` with times
    increasing and limits not increasing; between two points the limit is
    linear in log(time). Before the first time the curve says nothing: a
    pressure at or above the first limit is allowed ``times_s[0]`` (no
    extrapolation to shorter times); after the last time the limit stays at the
    last (the curve's floor): a pressure below the floor is allowed forever. A
    curve with one point and ``times_s[0] == 0`` is time-independent: nothing at
    or above its limit is allowed (its dose is infinite from the first step
    above it).

    Attributes
    ----------
    name : str
        The key of :data:`TOLERANCE_CURVES`.
    kind : {'pain', 'discomfort', 'damage'}
    site : str
        Body site (and species) the data come from.
    contact : str
        How the pressure was applied (cuff, probe size, support surface).
    times_s : tuple of float
        Exposure times [s], increasing.
    limits_kpa : tuple of float
        Pressure limits [kPa] at those times, not increasing.
    citation : str
        Authors, year, title, journal, volume:pages.
    doi : str
        "" when none is known reliably.
    notes : str
        Where the numbers come from and what they do not cover.
    """

    name: str
    kind: str
    site: str
    contact: str
    times_s: tuple
    limits_kpa: tuple
    citation: str
    doi: str = ""
    notes: str = ""
    _log_t: np.ndarray = field(init=False, repr=False, compare=False)
    _p_up: np.ndarray = field(init=False, repr=False, compare=False)
    _log_t_up: np.ndarray = field(init=False, repr=False, compare=False)
    _neg_log_t_up: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self):
        t = np.asarray(self.times_s, dtype=float)
        p = np.asarray(self.limits_kpa, dtype=float)
        if self.kind not in ("pain", "discomfort", "damage"):
            raise _bad(f"curve {self.name!r}: kind must be pain, discomfort or "
                                  f"damage, got {self.kind!r}")
        if t.ndim != 1 or t.shape != p.shape or len(t) == 0:
            raise _bad(f"curve {self.name!r}: expected as many times as limits")
        if not (np.all(np.isfinite(t)) and np.all(np.isfinite(p)) and np.all(p > 0)
                and np.all(t >= 0)):
            raise _bad(f"curve {self.name!r}: expected finite times >= 0 s and "
                                  f"limits > 0 kPa")
        if np.any(np.diff(t) <= 0) or np.any(np.diff(p) > 0):
            raise _bad(f"curve {self.name!r}: expected increasing times and "
                                  f"limits that do not increase")
        if t[0] == 0 and len(t) > 1:
            raise _bad(f"curve {self.name!r}: only a one-point curve starts at 0 s")
        object.__setattr__(self, "times_s", tuple(float(x) for x in t))
        object.__setattr__(self, "limits_kpa", tuple(float(x) for x in p))
        log_t = np.log(t) if t[0] > 0 else np.array([-np.inf])
        object.__setattr__(self, "_log_t", log_t)
        # the inverse t_allowed(p) interpolates log t against p; np.interp needs the
        # pressures increasing, so the points go in reverse (a plateau keeps its shortest time)
        object.__setattr__(self, "_p_up", p[::-1].copy())
        object.__setattr__(self, "_log_t_up", log_t[::-1].copy())
        object.__setattr__(self, "_neg_log_t_up", -log_t[::-1])

    @property
    def time_independent(self) -> bool:
        return self.times_s[0] == 0.0

    @property
    def floor_kpa(self) -> float:
        """The lowest limit [kPa]: below it, the curve allows any time."""
        return self.limits_kpa[-1]

    def limit_kpa(self, time_s) -> np.ndarray:
        """The pressure limit [kPa] for an exposure of ``time_s`` [s] (array-like)."""
        t = np.asarray(time_s, dtype=float)
        if self.time_independent:
            return np.full(t.shape, self.limits_kpa[0])
        with np.errstate(divide="ignore"):
            lt = np.log(np.maximum(t, 0.0))
        return np.interp(lt, self._log_t, np.asarray(self.limits_kpa))

    def allowed_time_s(self, pressure_kpa) -> np.ndarray:
        """How long [s] the pressure ``pressure_kpa`` (array-like) may be held: ``inf``
        below the floor, ``times_s[0]`` at or above the first limit, in between the
        shortest time whose limit is at or below the pressure. NaN stays NaN."""
        p = np.asarray(pressure_kpa, dtype=float)
        if self.time_independent:
            out = np.where(p >= self.limits_kpa[0], 0.0, np.inf)
        else:
            out = np.exp(np.interp(p, self._p_up, self._log_t_up))
            out = np.where(p < self.floor_kpa, np.inf, out)
        return np.where(np.isnan(p), np.nan, out)

    def rate(self, pressure_kpa, at_or_above_floor: bool = False) -> np.ndarray:
        """Dose per second ``1 / t_allowed`` [1/s] at ``pressure_kpa`` (0 below the floor,
        ``inf`` at or above a time-independent limit, 0 where the pressure is NaN);
        ``at_or_above_floor``: the caller knows every pressure is (no check)."""
        p = np.asarray(pressure_kpa, dtype=float)
        if self.time_independent:
            return np.where(p >= self.limits_kpa[0], np.inf, 0.0)
        r = np.interp(p, self._p_up, self._neg_log_t_up)
        r = np.exp(r, out=r) if isinstance(r, np.ndarray) else np.exp(r)
        if at_or_above_floor:
            return r
        return np.where(p >= self.floor_kpa, r, 0.0)   # NaN >= floor is False: 0


def _constant(name, kind, site, contact, limit_kpa, citation, doi, notes):
    return ToleranceCurve(name, kind, site, contact, (0.0,), (limit_kpa,), citation, doi, notes)


_CURVES = (
    ToleranceCurve(
        "linder_ganz_2006", "damage", "rat skeletal muscle (gracilis), in vivo",
        "pressure applied through the skin by an indentor over the muscle",
        (15 * _MIN, 1 * _HOUR, 2 * _HOUR), (32.0, 32.0, 9.0),
        "Linder-Ganz E, Engelberg S, Scheinowitz M, Gefen A (2006). Pressure-time cell death "
        "threshold for albino rat skeletal muscles as related to pressure sore biomechanics. "
        "J. Biomech. 39(14):2725-2732",
        "10.1016/j.jbiomech.2005.08.010",
        "Cell death above 32 kPa (240 mmHg) within 15 min to 1 h, above 9 kPa (67 mmHg) for "
        "2 h or more; between 1 and 2 h the threshold drops from 32 to 9 kPa. The paper fits "
        "a sigmoid in time through pooled histology; we keep its two plateaus and join them "
        "linearly in log(time) between 1 and 2 h instead of its fitted coefficients. Animal "
        "data (albino rats, muscle under the skin): a damage limit of deep tissue, not a "
        "comfort limit of human skin; no data shorter than 15 min."),
    ToleranceCurve(
        "reswick_rogers_1976", "damage", "human soft tissue over bony prominences, "
        "seated and lying patients",
        "interface pressure between the body and a support surface (mattress, cushion)",
        (1 * _HOUR, 2 * _HOUR, 4 * _HOUR, 8 * _HOUR),
        tuple(round(v * MMHG_KPA, 3) for v in (500.0, 250.0, 125.0, 60.0)),
        "Reswick JB, Rogers JE (1976). Experience at Rancho Los Amigos Hospital with devices "
        "and techniques to prevent pressure sores. In: Kenedi RM, Cowden JM, Scales JT (eds), "
        "Bedsore Biomechanics, Macmillan, London, pp. 301-310",
        "",
        "A clinical guideline from about 980 patients, not a measured threshold. Approximate: "
        "about 500 mmHg for 1 h down to about 60 mmHg for 8 h are the curve's ends as it is "
        "usually quoted; the 2 h and 4 h points (250, 125 mmHg) are our reading of its roughly "
        "hyperbolic shape (pressure x time about constant), not digitized values. Interface "
        "pressure under the whole body, not under a cuff; nothing shorter than 1 h."),
    _constant(
        "cuff_calf_pain_2001", "pain", "human calf (gastrocnemius)",
        "pneumatic tourniquet cuff, ramped pressure", 26.0,
        "Polianskis R, Graven-Nielsen T, Arendt-Nielsen L (2001). Computer-controlled "
        "pneumatic pressure algometry - a new technique for quantitative sensory testing. "
        "Eur. J. Pain 5(3):267-277",
        "10.1053/eujp.2001.0245",
        "Pressure-pain detection threshold 26 +- 1.6 kPa with a cuff against 482 +- 19 kPa "
        "with a hand-held probe over the same muscle (12 healthy volunteers): the threshold "
        "depends on the contact size far more than on anything else. A threshold at onset, "
        "not a function of time."),
    _constant(
        "cuff_knee_discomfort_2020", "discomfort", "human knee",
        "pneumatic cuff around the knee, continuous compression while standing", 13.7,
        "Kermavnar T et al. (2020), University of Limerick: circumferential compression at "
        "the knee with a pneumatic cuff, standing and walking. Ergonomics 63(5):618-628",
        "10.1080/00140139.2020.1743373",
        "Discomfort detection from 13.7 kPa (continuous compression) to 30.4 kPa "
        "(intermittent); this curve takes the lower, continuous value. A threshold at onset. "
        "Values and DOI checked against the abstract; the author list was not."),
    _constant(
        "cuff_knee_pain_2020", "pain", "human knee",
        "pneumatic cuff around the knee, continuous compression while standing", 52.9,
        "Kermavnar T et al. (2020), University of Limerick: circumferential compression at "
        "the knee with a pneumatic cuff, standing and walking. Ergonomics 63(5):618-628",
        "10.1080/00140139.2020.1743373",
        "Pain detection from 52.9 kPa (continuous compression) to 60.6 kPa (intermittent); "
        "this curve takes the lower, continuous value. A threshold at onset. Values and DOI "
        "checked against the abstract; the author list was not."),
    _constant(
        "paper_upper_arm_pain", "pain", "human upper arm",
        "small hand-held probe (pressure algometer)", 120.0,
        "Yousaf et al., A Method for the Analysis of Physical Human-Robot Interaction (the "
        "paper phri-spring implements): the lowest upper-arm pressure pain threshold it "
        "cites, interface.pain_threshold_kpa's default",
        "",
        "Measured with a small probe: a cuff spreads the load over a larger area, where the "
        "threshold is far lower (see cuff_calf_pain_2001). A threshold at onset."),
)

#: the curves by name (docs/tolerance.md)
TOLERANCE_CURVES = {c.name: c for c in _CURVES}
DEFAULT_CURVE = "linder_ganz_2006"


def tolerance_curve(name) -> ToleranceCurve:
    """The curve of :data:`TOLERANCE_CURVES` named ``name`` (a curve passes through).

    Raises
    ------
    ModelInputError
        An unknown name; the message lists the known ones.
    """
    if isinstance(name, ToleranceCurve):
        return name
    try:
        return TOLERANCE_CURVES[str(name)]
    except KeyError:
        raise _bad(f"unknown tolerance curve {name!r} (expected one of "
                              f"{', '.join(TOLERANCE_CURVES)})") from None


class Exposure:
    """Every element's exposure over a log fed in order, chunk by chunk.

    Parameters
    ----------
    curve : ToleranceCurve or str
    n_elements : int
    pain_threshold_kpa : float
        The threshold whose time above is counted with the curve's floor [kPa].
    edges_kpa : array_like, optional
        Increasing pressure bin edges [kPa]: also keep ``time_in_bin_s`` (n, len-1), the
        time each element spent at a pressure in each bin (for the exposure figure;
        pressures outside the edges are not binned).

    Attributes (per element, shape (n,))
    ------------------------------------
    dose : cumulative dose [-]
    time_above_pain_s, time_above_floor_s : time [s] above the pain threshold and
        above the curve's floor (strictly above)
    dose_reached_s : time [s] of the first sample whose dose is >= 1, NaN if none
    pain_first_s : time [s] of the first sample above the pain threshold, NaN if none

    A sample whose pressure is NaN (not converged) adds nothing; a step backwards in
    time (an unsorted log) counts as 0 s.
    """

    def __init__(self, curve, n_elements: int, pain_threshold_kpa: float, edges_kpa=None):
        self.curve = tolerance_curve(curve)
        self.pain_threshold_kpa = float(pain_threshold_kpa)
        n = int(n_elements)
        self.dose = np.zeros(n)
        self.time_above_pain_s = np.zeros(n)
        self.time_above_floor_s = np.zeros(n)
        self.dose_reached_s = np.full(n, np.nan)
        self.pain_first_s = np.full(n, np.nan)
        self.samples = 0
        self._t_prev = math.nan
        self._best, self._best_idx = 0.0, 0      # the largest dose and its element
        self.edges_kpa = None if edges_kpa is None else np.asarray(edges_kpa, dtype=float)
        self.time_in_bin_s = None if edges_kpa is None else \
            np.zeros((n, len(self.edges_kpa) - 1))

    def steps(self, time) -> np.ndarray:
        """``dt`` [s] of each sample of the next chunk (not stored)."""
        t = np.asarray(time, dtype=float)
        dt = np.empty_like(t)
        if len(t) == 0:
            return dt
        dt[0] = t[0] - self._t_prev if math.isfinite(self._t_prev) else 0.0
        np.subtract(t[1:], t[:-1], out=dt[1:])
        return np.where(dt > 0, dt, 0.0)     # NaN and backwards steps: 0

    def add(self, time, pressure_kpa, scale=None):
        """Feed the next chunk: times (m,) [s], pressures (m, n) [kPa].

        With ``scale`` (n,) > 0, ``pressure_kpa`` holds values whose pressure is
        ``value * scale`` (forces [N] and ``1 / area`` [kPa/N]): only the entries at or
        above a threshold are scaled.

        Returns ``(dose_max, dose_element)``: per sample, the largest cumulative dose
        over the elements (m,) [-] and its element (m,); on a tie, the element that
        reached that dose first (the lowest index within one sample).
        """
        t = np.asarray(time, dtype=float)
        v = np.asarray(pressure_kpa, dtype=float)
        m, n = len(t), len(self.dose)
        if v.shape != (m, n):
            raise _bad(f"pressure: expected shape ({m}, {n}), got {v.shape}")
        if m == 0:
            return np.zeros(0), np.zeros(0, dtype=np.intp)
        dt = self.steps(t)
        if self.edges_kpa is not None:
            self._bin(v if scale is None else v * scale, dt[:, None])
        self._t_prev = float(t[-1]) if math.isfinite(t[-1]) else self._t_prev
        self.samples += m
        # everything below follows the entries at or above a threshold, element by element
        floor, pain = self.curve.floor_kpa, self.pain_threshold_kpa
        low = min(floor, pain)
        mask_t = np.ascontiguousarray((v >= (low if scale is None else low / scale)).T)
        rows = np.flatnonzero(mask_t)                     # NaN compares False: not there
        bounds = np.searchsorted(rows, np.arange(n + 1) * m)
        heads, counts = bounds[:-1], np.diff(bounds)      # each element's entries
        cols = np.repeat(np.arange(n), counts)            # by element, then in time order
        rows -= cols * m
        p = v.ravel()[rows * n + cols] if v.flags.c_contiguous else v[rows, cols]
        if scale is not None:
            p *= np.repeat(scale, counts)
        w = dt[rows]
        # every entry above the floor (unless the pain threshold is lower, or at the floor)
        clean = low >= floor and not (p <= floor).any()
        some = np.flatnonzero(counts)
        if len(some):
            above = w if clean else np.where(p > floor, w, 0.0)
            self.time_above_floor_s[some] += np.add.reduceat(above, heads[some])
        hit = p > pain
        if hit.any():
            self.time_above_pain_s += np.bincount(cols[hit], weights=w[hit], minlength=n)
            ch, rh = cols[hit], rows[hit]
            k = np.flatnonzero(np.r_[True, ch[1:] != ch[:-1]])       # each one's first
            new = np.isnan(self.pain_first_s[ch[k]])
            self.pain_first_s[ch[k][new]] = t[rh[k][new]]
        if len(p) == 0:
            return np.full(m, self._best), np.full(m, self._best_idx, dtype=np.intp)
        if self.curve.time_independent:            # no time allowed: infinite once pressed
            inc = np.where((p >= floor) & (w > 0), np.inf, 0.0)
        else:                                      # (0 below the floor: adds nothing)
            inc = self.curve.rate(p, at_or_above_floor=clean)
            inc *= w
        # an element whose dose ends the chunk at or below the largest dose at its start
        # can neither lead nor reach 1 within it: its sum is enough
        end = self.dose.copy()
        end[some] += np.add.reduceat(inc, heads[some])
        follow = (end > self._best) | ((end >= 1.0) & np.isnan(self.dose_reached_s))
        follow &= counts > 0
        self.dose[~follow] = end[~follow]
        if not follow.any():
            return np.full(m, self._best), np.full(m, self._best_idx, dtype=np.intp)
        if not follow[some].all():
            keep = np.repeat(follow, counts)
            rows, cols, inc = rows[keep], cols[keep], inc[keep]
        c = self._accumulate(rows, cols, inc, t)
        # the largest dose over the elements at each sample: each element's dose only grows,
        # so it is the running maximum of the doses reached so far (and the chunk's start)
        per_row = np.full(m, -np.inf)
        np.maximum.at(per_row, rows, c)
        at_max = c == per_row[rows]
        per_row_idx = np.full(m, n, dtype=np.intp)
        np.minimum.at(per_row_idx, rows[at_max], cols[at_max])      # lowest index in a row
        run = np.maximum.accumulate(np.r_[self._best, per_row])
        new = per_row > run[:-1]                                     # a strictly larger dose
        last = np.maximum.accumulate(np.where(new, np.arange(1, m + 1), 0))
        idx = np.r_[self._best_idx, per_row_idx][last]
        best = run[1:]
        self._best, self._best_idx = float(best[-1]), int(idx[-1])
        return best, idx

    def add_sample(self, t: float, pressure_kpa, scale=None):
        """:meth:`add` for one sample (a live stream): pressures (n,) [kPa] (or values
        times ``scale``); returns ``(dose_max, dose_element)`` of that sample."""
        p = np.asarray(pressure_kpa, dtype=float)
        if scale is not None:
            p = p * scale
        t = float(t)
        dt = t - self._t_prev if math.isfinite(self._t_prev) else 0.0
        dt = dt if dt > 0 else 0.0                        # NaN and backwards steps: 0
        if math.isfinite(t):
            self._t_prev = t
        self.samples += 1
        if self.edges_kpa is not None:
            self._bin(p[None], np.array([[dt]]))
        above = p > self.pain_threshold_kpa
        if above.any():
            self.time_above_pain_s[above] += dt
            first = above & np.isnan(self.pain_first_s)
            self.pain_first_s[first] = t
        if dt > 0:
            self.time_above_floor_s[p > self.curve.floor_kpa] += dt
            rate = self.curve.rate(p)
            if self.curve.time_independent:
                rate[rate > 0] = np.inf
                self.dose += rate
            else:
                self.dose += rate * dt
            reached = (self.dose >= 1.0) & np.isnan(self.dose_reached_s)
            if reached.any():
                self.dose_reached_s[reached] = t
            j = int(np.argmax(self.dose))
            if self.dose[j] > self._best:
                self._best, self._best_idx = float(self.dose[j]), j
        return self._best, self._best_idx

    def _accumulate(self, rows, cols, inc, t) -> np.ndarray:
        """Each entry's cumulative dose after it (entries in column order, then row);
        updates ``dose`` and ``dose_reached_s``."""
        heads = np.flatnonzero(np.r_[True, cols[1:] != cols[:-1]])
        out = np.empty_like(inc)
        for a, b in zip(heads, np.r_[heads[1:], len(cols)]):
            e = cols[a]
            seg = np.cumsum(inc[a:b], out=out[a:b])
            seg += self.dose[e]
            self.dose[e] = seg[-1]
            if seg[-1] >= 1.0 and np.isnan(self.dose_reached_s[e]):
                self.dose_reached_s[e] = t[rows[a + int(np.argmax(seg >= 1.0))]]
        return out

    def _bin(self, p, col) -> None:
        nb = len(self.edges_kpa) - 1
        b = np.searchsorted(self.edges_kpa, p, side="right") - 1     # NaN: past the end
        ok = (b >= 0) & (b < nb)
        flat = (np.arange(p.shape[1]) * nb + b)[ok]
        w = np.broadcast_to(col, p.shape)[ok]
        self.time_in_bin_s += np.bincount(flat, weights=w,
                                          minlength=self.time_in_bin_s.size).reshape(-1, nb)

    def time_at_or_above_s(self) -> np.ndarray:
        """(n, bins) the time each element spent at or above each bin's lower edge [s]."""
        return np.cumsum(self.time_in_bin_s[:, ::-1], axis=1)[:, ::-1]

    def worst(self):
        """``(index, dose)`` of the element with the largest dose (the first to reach it)."""
        return self._best_idx, float(self.dose[self._best_idx])
