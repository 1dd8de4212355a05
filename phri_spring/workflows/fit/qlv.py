"""``phri fit-stiffness --law qlv``: quasi-linear viscoelastic tissue from indenter trials.

Per location, its trials are fitted together (:mod:`phri_spring.physics.indentation.qlv`):
the elastic part (k, and beta with ``elastic="exponential"``) and a Prony series of
``terms`` terms. The fit CSV has the columns of the other laws (the stiffness is k, the
instantaneous stiffness of the elastic part), with the exponential part the stiffening
columns, then ``relaxation_fraction_<i>`` [-] and ``relaxation_time_<i>_s`` [s] per term
(sorted by time), then the quality columns.

Called by :func:`phri_spring.workflows.fit.stiffness.fit_stiffness`; nothing here prints.
"""

from __future__ import annotations

import numpy as np

from ...errors import DataError
from ...io.recordings.indenter import SkippedTrial, split_label
from ...physics.indentation.qlv import QlvLocationFit, fit_qlv
from ...physics.indentation.qlv_window import check_identifiable, qlv_window
from ...physics.indentation.signal import TrialError

__all__ = ["relaxation_columns", "fit_qlv_locations", "relaxation_snippet", "qlv_summary"]


def relaxation_columns(terms: int) -> list:
    """``relaxation_fraction_1, relaxation_time_1_s, ...`` for ``terms`` terms."""
    out = []
    for i in range(1, terms + 1):
        out += [f"relaxation_fraction_{i}", f"relaxation_time_{i}_s"]
    return out


def _order(label):
    row, angle = split_label(label)
    return (len(row), row, angle)


def fit_qlv_locations(trials, *, zero_window, onset_threshold, skip_bad_trials, min_r2,
                      terms, elastic):
    """Fit every location; (locations, rows, trial_rows, warnings, skipped).

    ``rows`` holds the fit CSV's values by column name (quality columns included);
    ``skipped`` the trials left out (with ``skip_bad_trials``; otherwise a DataError).
    """
    by_location: dict[str, list] = {}
    skipped, warnings = [], []
    for tr in trials:
        try:
            w = qlv_window(tr.time, tr.displacement, tr.force, zero_window=zero_window,
                           onset_threshold=onset_threshold)
        except TrialError as exc:
            err = DataError(f"{tr.where}: {exc}" if tr.where else str(exc), file=tr.source,
                            key=exc.key)
            if not skip_bad_trials:
                raise err from None
            skipped.append(SkippedTrial(tr.location, tr.trial, err))
            continue
        if w.sign < 0:
            where = f" ({tr.where})" if tr.where else ""
            warnings.append(f"{tr.source}{where}: the displacement decreases into the arm; "
                            "its sign was flipped")
        by_location.setdefault(tr.location, []).append((tr, w))

    locations, rows, trial_rows = [], [], []
    for lab in sorted(by_location, key=_order):
        pairs = sorted(by_location[lab], key=lambda p: p[0].trial)
        windows = [w for _, w in pairs]
        try:
            check_identifiable(windows)
        except TrialError as exc:
            sources = sorted({tr.source for tr, _ in pairs})
            files = "" if len(sources) == 1 else f" (also {', '.join(sources[1:])})"
            err = DataError(f"location {lab}{files}: {exc}", file=sources[0], key=exc.key)
            if not skip_bad_trials:
                raise err from None
            skipped += [SkippedTrial(lab, tr.trial, err) for tr, _ in pairs]
            continue
        fit = fit_qlv(windows, terms=terms, elastic=elastic)
        flags = []
        if fit.status == "failed":
            flags.append("fit_failed")
            warnings.append(f"{lab}: QLV fit failed: {fit.message}; its values are left empty")
        elif fit.status == "at_bound":
            flags.append("at_bound")
            warnings.append(f"{lab}: QLV fit: {fit.message}")
        if fit.prony is not None and not fit.r2_min >= min_r2:
            flags.append("low_r2")
            worst = int(np.nanargmin(fit.r2))
            warnings.append(f"{lab}: QLV fit R^2 {fit.r2_min:.3f} below {min_r2:g} "
                            f"(trial {pairs[worst][0].trial})")
        loc = QlvLocationFit(location=lab, trial_ids=np.array([tr.trial for tr, _ in pairs]),
                             windows=tuple(windows), fit=fit, flags=tuple(flags))
        locations.append(loc)
        row, angle = split_label(lab)
        values = {"location": lab, "row": row, "angle_index": angle,
                  "stiffness_N_per_m": fit.stiffness, "std_N_per_m": float("nan"),
                  "n_trials": len(windows)}
        if elastic == "exponential":
            values["stiffening_per_m"] = fit.stiffening
            values["stiffening_std_per_m"] = float("nan")
        g = fit.fractions if fit.prony is not None else np.full(terms, np.nan)
        tau = fit.times_s if fit.prony is not None else np.full(terms, np.nan)
        values.update(zip(relaxation_columns(terms),
                          [v for pair in zip(g, tau) for v in pair]))
        values.update({
            "n_strokes": len(windows), "r2_min": fit.r2_min,
            "loading_slope_N_per_m": float("nan"), "hysteresis_ratio": float("nan"),
            "peak_force_N": max(w.peak_force for w in windows),
            "peak_depth_mm": max(w.peak_depth for w in windows) * 1e3,
            "trial_spread": float("nan"), "flags": ";".join(flags)})
        rows.append(values)
        for i, (tr, w) in enumerate(pairs):
            trial_rows.append({
                "location": lab, "trial": tr.trial, "file": tr.source,
                "r2": float(fit.r2[i]), "contact_mm": float(fit.contacts[i]) * 1e3,
                "peak_force_N": w.peak_force, "peak_depth_mm": w.peak_depth * 1e3,
                "hold_s": w.hold_s, "loading_rate_mm_per_s": w.loading_rate * 1e3,
                "window_start_s": float(w.time[0]), "window_end_s": float(w.time[-1]),
                "zero_level_N": w.zero_level, "noise_sd_N": w.noise_sd,
                "onset_threshold_N": w.threshold, "displacement_sign": w.sign,
                "fit_status": fit.status})
    return locations, rows, trial_rows, warnings, skipped


def _mean_relaxation(locations):
    """Mean fractions and times over the locations whose fit converged (terms by time)."""
    fits = [loc.fit for loc in locations if loc.fit.prony is not None]
    if not fits:
        return None, None
    g = np.mean([f.fractions for f in fits], axis=0)
    tau = np.exp(np.mean([np.log(f.times_s) for f in fits], axis=0))
    return g, tau


def relaxation_snippet(locations) -> str:
    """``tissue.relaxation: {fractions: [...], times_s: [...]}`` of the mean over locations.

    Fractions averaged, times averaged on a log scale (geometric mean), term by term.
    """
    g, tau = _mean_relaxation(locations)
    if g is None:
        return ""
    return ("tissue.relaxation: {fractions: [" + ", ".join(f"{v:.4g}" for v in g)
            + "], times_s: [" + ", ".join(f"{v:.4g}" for v in tau) + "]}")


def qlv_summary(locations, elastic: str) -> str:
    """The summary line: k (and beta) mean +- SD, the mean relaxation with units."""
    from ...physics.indentation.linear import location_statistics

    k = [loc.fit.stiffness for loc in locations if loc.fit.prony is not None]
    mean, sd, n = location_statistics(k)
    where = "at 1 location" if n == 1 else f"over {n} locations"
    text = f"qlv law {where}: k {mean:.0f}" + ("" if n == 1 else f" +- {sd:.1f}") + " N/m"
    if elastic == "exponential":
        b = [loc.fit.stiffening for loc in locations if loc.fit.prony is not None]
        b_mean, b_sd, _ = location_statistics(b)
        text += f", stiffening {b_mean:.1f}" + ("" if n == 1 else f" +- {b_sd:.1f}") + " 1/m"
    g, tau = _mean_relaxation(locations)
    if g is None:
        return text + ", no converged relaxation fit"
    terms = ", ".join(f"{gi:.3f} at {ti:.3g} s" for gi, ti in zip(g, tau))
    return (f"{text}{'' if n == 1 else ' (mean +- SD)'}; relaxation fractions {terms}"
            + ("" if n == 1 else " (mean over locations)") + "; "
            + relaxation_snippet(locations))
