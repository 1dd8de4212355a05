"""``phri fit-stiffness`` as a library call: indenter recordings -> stiffness map.

The bundled synthetic recordings (42 trials, 21 locations), fitted and written:

>>> import tempfile
>>> from pathlib import Path
>>> import phri_spring
>>> from phri_spring.workflows.fit.stiffness import fit_stiffness, write_fit
>>> examples = Path(phri_spring.__file__).resolve().parents[1] / "examples" / "indenter"
>>> result = fit_stiffness(examples)
>>> result.summary_line()
'stiffness over 21 locations: 4242 +- 251.7 N/m (mean +- SD)'
>>> with tempfile.TemporaryDirectory() as tmp:
...     [p.name for p in write_fit(result, Path(tmp) / "stiffness.csv")]
['stiffness.csv']

With ``law="exponential"`` the exponential (Fung-type) law
F = (k0/beta)(exp(beta (d - d0)) - 1) is fitted to the same unloading strokes
instead (:mod:`phri_spring.physics.indentation.exponential`): the CSV's stiffness
is then k0 and it gains the stiffening rate beta [1/m] and its SD over trials.

With ``law="qlv"`` the trials must follow the force over time (a hold after the
ramp, or several ramp rates): quasi-linear viscoelastic tissue, an elastic part
and a Prony series, is fitted per location (:mod:`phri_spring.workflows.fit.qlv`).

The method is in :mod:`phri_spring.physics.indentation.linear`; the file formats in
:mod:`phri_spring.io.recordings.indenter`. Nothing here prints: warnings come back in
``result.warnings``.
"""

from __future__ import annotations

import math
from contextlib import ExitStack
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ...errors import DataError, UsageError
from ...io.outputs.atomic import atomic_directory, atomic_file, check_output_path, naming
from ...io.recordings.indenter import (STIFFNESS_COLUMNS, SkippedTrial, read_indenter, split_label,
                           write_stiffness_csv, write_trials_csv)
from ...physics.indentation.linear import (DEFAULT_MAX_SPREAD, DEFAULT_MIN_R2, TrialError,
                                   fit_location, fit_trial, location_statistics)
from ...physics.indentation.exponential import (ExponentialLocationFit,
                                               fit_location_exponential,
                                               fit_trial_exponential)
from ...physics.laws import ExponentialLaw
from .laws import ELASTIC_PARTS, law_names

__all__ = ["FitStiffnessResult", "fit_stiffness", "write_fit", "write_plots",
           "check_fit_outputs", "QUALITY_COLUMNS", "PLOT_FILES", "LAWS",
           "STIFFENING_COLUMNS", "QLV_PLOT_FILES", "plot_files"]

#: quality columns of the fit CSV, after :data:`~phri_spring.io.recordings.indenter.STIFFNESS_COLUMNS`
QUALITY_COLUMNS = ("n_strokes", "r2_min", "loading_slope_N_per_m", "hysteresis_ratio",
                   "peak_force_N", "peak_depth_mm", "trial_spread", "n_trials_skipped",
                   "flags")
#: files written by :func:`write_plots`
PLOT_FILES = ("force_displacement.png", "stiffness_map.png")
#: files written by :func:`write_plots` for the ``qlv`` law
QLV_PLOT_FILES = ("force_time.png", "stiffness_map.png")
#: the indenter laws :func:`fit_stiffness` fits (the registry of :mod:`.fit_laws`)
LAWS = law_names()
#: columns the exponential law adds after the stiffness columns: the column the config reads
#: for ``tissue.stiffening`` (the law's own ``csv_column``), then its SD over the trials
STIFFENING_COLUMNS = (ExponentialLaw.parameters[0].csv_column, "stiffening_std_per_m")


@dataclass
class FitStiffnessResult:
    """Everything :func:`fit_stiffness` found.

    Attributes
    ----------
    input_path : Path
    locations : list of LocationFit, ExponentialLocationFit or QlvLocationFit
        Row-major order (A0, A1, ..., C6); ExponentialLocationFit with the exponential law,
        QlvLocationFit with the qlv law.
    skipped : list of SkippedTrial
        Trials left out with ``skip_bad_trials``.
    table : pandas.DataFrame
        The fit CSV (docs/model.md section 7 columns, with the exponential law
        :data:`STIFFENING_COLUMNS`, with the qlv law the relaxation columns, then
        :data:`QUALITY_COLUMNS`).
    trials_table : pandas.DataFrame
        One row per trial.
    warnings : list of str
        One line each.
    settings : dict
        The options used.
    """

    input_path: Path
    locations: list
    skipped: list
    table: object
    trials_table: object
    warnings: list = field(default_factory=list)
    settings: dict = field(default_factory=dict)

    @property
    def law(self) -> str:
        """The law fitted, ``linear``, ``exponential`` or ``qlv``."""
        return self.settings.get("law", "linear")

    @property
    def stiffness(self) -> np.ndarray:
        """Location stiffnesses [N/m] (k0 with the exponential law), row-major."""
        return np.array([loc.stiffness for loc in self.locations], dtype=float)

    @property
    def stiffening(self) -> np.ndarray:
        """Location stiffening rates beta [1/m] (0 with the linear law), row-major."""
        return np.array([getattr(loc, "stiffening", 0.0) for loc in self.locations],
                        dtype=float)

    @property
    def labels(self) -> list:
        return [loc.location for loc in self.locations]

    def summary(self) -> tuple[float, float, int]:
        """Mean and sample SD (ddof = 1) of the location stiffnesses [N/m], and their count."""
        return location_statistics(self.stiffness)

    def summary_line(self) -> str:
        """``stiffness over 21 locations: 4242 +- 251.5 N/m (mean +- SD)``."""
        if self.law == "qlv":
            from .qlv import qlv_summary

            return qlv_summary(self.locations, self.settings.get("elastic", "linear"))
        mean, sd, n = self.summary()
        if self.law == "exponential":
            b_mean, b_sd, _ = location_statistics(self.stiffening)
            if n == 1:
                return (f"exponential law at 1 location: k0 {mean:.0f} N/m, "
                        f"stiffening {b_mean:.1f} 1/m")
            return (f"exponential law over {n} locations: k0 {mean:.0f} +- {sd:.1f} N/m, "
                    f"stiffening {b_mean:.1f} +- {b_sd:.1f} 1/m (mean +- SD)")
        if n == 1:
            return f"stiffness over 1 location: {mean:.0f} N/m"
        return f"stiffness over {n} locations: {mean:.0f} +- {sd:.1f} N/m (mean +- SD)"


def _positive(value, name: str, allow_none: bool = False):
    if value is None and allow_none:
        return None
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise UsageError(f"expected a number, got {value!r}", key=name) from None
    if not (math.isfinite(v) and v > 0):
        raise UsageError(f"expected a finite number > 0, got {value!r}", key=name)
    return v


def fit_stiffness(input_path, *, zero_window: float = 3.0, onset_threshold: float | None = None,
                  displacement_unit: str = "mm", skip_bad_trials: bool = False,
                  min_r2: float = DEFAULT_MIN_R2, max_trial_spread: float = DEFAULT_MAX_SPREAD,
                  reversal: float | None = None, law: str = "linear",
                  elastic: str | None = None,
                  relaxation_terms: int | None = None) -> FitStiffnessResult:
    """Fit the tissue stiffness of every location from indenter recordings.

    Parameters
    ----------
    input_path : str or Path
        A folder of ``<label>_<trial>.csv`` (or ``.mat``) files, or one long CSV
        with ``location, trial, time, displacement, force``.
    zero_window : float
        Rest period at the start of each trial over which the force is zeroed [s].
    onset_threshold : float, optional
        Difference threshold on the zeroed force for the onset and for contact [N].
        Default per trial: ``max(5 * noise SD in the zero window, 0.05 N)``.
    displacement_unit : {'mm', 'm'}
        Unit of the displacement in the files.
    skip_bad_trials : bool
        Leave bad trials out with a warning (``n_trials`` shows it) instead of failing.
    min_r2 : float
        Flag locations with an unloading fit whose R^2 is below this [-].
    max_trial_spread : float
        Flag locations whose trials differ by more than this fraction of their mean [-].
    reversal : float, optional
        Depth reversal that ends a stroke [m]; default
        ``max(0.1 mm, 10 % of the trial's peak depth)``.
    law : {'linear', 'exponential'}
        ``linear``: the unloading slope (the paper). ``exponential``: k0 and the
        stiffening rate beta of F = (k0/beta)(exp(beta (d - d0)) - 1) on the same
        unloading strokes, d0 free per stroke; a fit that fails or ends on beta's
        bound is a warning and a flag, not an error. ``qlv``: quasi-linear
        viscoelastic tissue over time, fitted per location to all its trials (a hold
        after the ramp, or loading rates 2x apart); ``reversal`` and
        ``max_trial_spread`` do not enter it (one joint fit per location).
    elastic : {'linear', 'exponential'}, optional
        The elastic part of the ``qlv`` law (default linear); only with ``law="qlv"``.
    relaxation_terms : int, optional
        Prony terms of the ``qlv`` law, 1 to 4 (default 2); only with ``law="qlv"``.

    Returns
    -------
    FitStiffnessResult

    Raises
    ------
    DataError
        Bad input (naming the file and column), unless skipped.
    UsageError
        Bad option values.
    """
    import pandas as pd

    zero_window = _positive(zero_window, "zero_window")
    onset_threshold = _positive(onset_threshold, "onset_threshold", allow_none=True)
    reversal = _positive(reversal, "reversal", allow_none=True)
    if not (isinstance(min_r2, (int, float)) and min_r2 <= 1):
        raise UsageError(f"expected a number <= 1, got {min_r2!r}", key="min_r2")
    if not (isinstance(max_trial_spread, (int, float)) and max_trial_spread >= 0):
        raise UsageError(f"expected a fraction >= 0, got {max_trial_spread!r}",
                         key="max_trial_spread")
    if displacement_unit not in ("mm", "m"):
        raise UsageError(f"expected 'mm' or 'm', got {displacement_unit!r}",
                         key="displacement_unit")
    if law not in LAWS:
        raise UsageError(f"expected one of {', '.join(LAWS)}, got {law!r}", key="law")
    elastic, relaxation_terms = _qlv_options(law, elastic, relaxation_terms)
    input_path = Path(input_path)
    warnings: list[str] = []

    rec = read_indenter(input_path, displacement_unit=displacement_unit,
                        skip_bad=skip_bad_trials)
    skipped = list(rec.skipped)
    if law == "qlv":
        return _fit_qlv(rec, input_path, skipped, zero_window=zero_window,
                        onset_threshold=onset_threshold, displacement_unit=displacement_unit,
                        skip_bad_trials=skip_bad_trials, min_r2=min_r2,
                        terms=relaxation_terms, elastic=elastic)

    by_location: dict[str, list] = {}
    trial_rows = []
    for tr in rec.trials:
        try:
            fit = fit_trial(tr.time, tr.displacement, tr.force, zero_window=zero_window,
                            onset_threshold=onset_threshold, reversal=reversal)
        except TrialError as exc:
            msg = f"{tr.where}: {exc}" if tr.where else str(exc)
            err = DataError(msg, file=tr.source, key=exc.key)
            if not skip_bad_trials:
                raise err from None
            skipped.append(SkippedTrial(tr.location, tr.trial, err))
            continue
        if fit.sign < 0:
            where = f" ({tr.where})" if tr.where else ""
            warnings.append(f"{tr.source}{where}: the displacement decreases into the arm; "
                            "its sign was flipped")
        efit = fit_trial_exponential(fit) if law == "exponential" else None
        by_location.setdefault(tr.location, []).append((tr, fit, efit))
        trial_rows.append({
            "location": tr.location, "trial": tr.trial, "file": tr.source,
            "stiffness_N_per_m": fit.stiffness, "n_strokes": fit.n_strokes,
            "r2_min": fit.r2_min, "loading_slope_N_per_m": fit.loading_slope,
            "hysteresis_ratio": fit.hysteresis_ratio, "peak_force_N": fit.peak_force,
            "peak_depth_mm": fit.peak_depth * 1e3, "zero_level_N": fit.zero_level,
            "noise_sd_N": fit.noise_sd, "onset_threshold_N": fit.threshold,
            "onset_time_s": fit.onset_time - float(fit.time[0]),
            "sampling_rate_Hz": fit.sampling_rate, "displacement_sign": fit.sign,
            "unloading_slopes_N_per_m": ";".join(f"{s:.6g}" for s in fit.unloading.slope),
        })
        if efit is not None:
            trial_rows[-1] = _exponential_trial_row(trial_rows[-1], efit)

    skip_lines = []
    for sk in skipped:
        who = f"{sk.location} trial {sk.trial}" if sk.location is not None else "a file"
        skip_lines.append(f"skipped {who}: {sk.error}")
    warnings[:0] = skip_lines
    if not by_location:
        first = skipped[0].error if skipped else None
        raise DataError("no usable trials" + (f" (first problem: {first})" if first else ""),
                        file=input_path)

    def order(label):
        row, angle = split_label(label)
        return (len(row), row, angle)

    n_skipped: dict[str, int] = {}
    for sk in skipped:
        if sk.location is not None:
            n_skipped[sk.location] = n_skipped.get(sk.location, 0) + 1
    for lab in sorted(set(n_skipped) - set(by_location), key=order):
        warnings.append(f"{lab}: no usable trial; left out of the output")

    exponential = law == "exponential"
    locations: list = []
    rows = []
    for lab in sorted(by_location, key=order):
        pairs = sorted(by_location[lab], key=lambda p: p[0].trial)
        lin = fit_location([p[1] for p in pairs], location=lab,
                           trial_ids=[p[0].trial for p in pairs],
                           min_r2=min_r2, max_spread=max_trial_spread)
        loc = (fit_location_exponential([p[2] for p in pairs], lin, min_r2=min_r2,
                                        max_spread=max_trial_spread) if exponential else lin)
        locations.append(loc)
        row, angle = split_label(lab)
        if exponential:
            warnings.extend(_exponential_warnings(loc))
        if "low_r2" in loc.flags:
            what, r2s = (("exponential", [f.r2_min for f in loc.fits]) if exponential
                         else ("unloading", [t.r2_min for t in loc.trials]))
            worst = int(np.nanargmin(r2s))
            warnings.append(f"{lab}: {what} fit R^2 {loc.r2_min:.3f} below {min_r2:g} "
                            f"(trial {loc.trial_ids[worst]})")
        if "trial_spread" in loc.flags:
            ks = ", ".join(f"{k:.0f}" for k in loc.trial_stiffness)
            warnings.append(f"{lab}: trials differ by {loc.spread:.1%} of their mean, more than "
                            f"{max_trial_spread:.1%} ({ks} N/m)")
        if "single_trial" in loc.flags:
            empty = "std_N_per_m and stiffening_std_per_m" if exponential else "std_N_per_m"
            warnings.append(f"{lab}: one trial only; {empty} left empty")
        rows.append({
            "location": lab, "row": row, "angle_index": angle,
            "stiffness_N_per_m": loc.stiffness, "std_N_per_m": loc.std,
            "n_trials": loc.n_trials, "n_strokes": lin.n_strokes, "r2_min": loc.r2_min,
            "loading_slope_N_per_m": lin.loading_slope,
            "hysteresis_ratio": lin.hysteresis_ratio, "peak_force_N": lin.peak_force,
            "peak_depth_mm": lin.peak_depth * 1e3, "trial_spread": loc.spread,
            "n_trials_skipped": n_skipped.get(lab, 0), "flags": ";".join(loc.flags),
        })
        if exponential:
            rows[-1].update(zip(STIFFENING_COLUMNS, (loc.stiffening, loc.stiffening_std)))
    extra = list(STIFFENING_COLUMNS) if exponential else []
    table = pd.DataFrame(rows, columns=list(STIFFNESS_COLUMNS) + extra + list(QUALITY_COLUMNS))
    trials_table = pd.DataFrame(trial_rows)
    settings = {"zero_window_s": zero_window, "onset_threshold_N": onset_threshold,
                "displacement_unit": displacement_unit, "skip_bad_trials": skip_bad_trials,
                "min_r2": min_r2, "max_trial_spread": max_trial_spread,
                "reversal_m": reversal, "layout": rec.layout, "law": law}
    return FitStiffnessResult(input_path=input_path, locations=locations, skipped=skipped,
                              table=table, trials_table=trials_table, warnings=warnings,
                              settings=settings)


def _qlv_options(law, elastic, terms):
    """(elastic, terms) checked: defaults with ``qlv``, refused with another law."""
    from ...physics.indentation.qlv import DEFAULT_TERMS, MAX_TERMS

    if law != "qlv":
        for key, value in (("elastic", elastic), ("relaxation_terms", terms)):
            if value is not None:
                raise UsageError(f"applies to the qlv law only (the {law} law has no "
                                 "relaxation); expected it with law qlv", key=key)
        return None, None
    elastic = "linear" if elastic is None else elastic
    if elastic not in ELASTIC_PARTS:
        raise UsageError(f"expected one of {', '.join(ELASTIC_PARTS)}, got {elastic!r}",
                         key="elastic")
    terms = DEFAULT_TERMS if terms is None else terms
    if isinstance(terms, bool) or not isinstance(terms, (int, np.integer)) \
            or not 1 <= terms <= MAX_TERMS:
        raise UsageError(f"expected a whole number from 1 to {MAX_TERMS}, got {terms!r}",
                         key="relaxation_terms")
    return elastic, int(terms)


def _fit_qlv(rec, input_path, skipped, *, zero_window, onset_threshold, displacement_unit,
             skip_bad_trials, min_r2, terms, elastic) -> FitStiffnessResult:
    """The ``qlv`` branch of :func:`fit_stiffness` (:mod:`.fit_stiffness_qlv`)."""
    import pandas as pd

    from .qlv import fit_qlv_locations, relaxation_columns

    locations, rows, trial_rows, warnings, more = fit_qlv_locations(
        rec.trials, zero_window=zero_window, onset_threshold=onset_threshold,
        skip_bad_trials=skip_bad_trials, min_r2=min_r2, terms=terms, elastic=elastic)
    skipped = skipped + more
    warnings[:0] = [f"skipped {sk.location} trial {sk.trial}: {sk.error}"
                    if sk.location is not None else f"skipped a file: {sk.error}"
                    for sk in skipped]
    if not locations:
        first = skipped[0].error if skipped else None
        raise DataError("no usable trials" + (f" (first problem: {first})" if first else ""),
                        file=input_path)
    n_skipped: dict[str, int] = {}
    for sk in skipped:
        if sk.location is not None:
            n_skipped[sk.location] = n_skipped.get(sk.location, 0) + 1
    for row in rows:
        row["n_trials_skipped"] = n_skipped.get(row["location"], 0)
    extra = list(STIFFENING_COLUMNS) if elastic == "exponential" else []
    columns = (list(STIFFNESS_COLUMNS) + extra + relaxation_columns(terms)
               + list(QUALITY_COLUMNS))
    settings = {"zero_window_s": zero_window, "onset_threshold_N": onset_threshold,
                "displacement_unit": displacement_unit, "skip_bad_trials": skip_bad_trials,
                "min_r2": min_r2, "layout": rec.layout, "law": "qlv", "elastic": elastic,
                "relaxation_terms": terms}
    return FitStiffnessResult(input_path=input_path, locations=locations, skipped=skipped,
                              table=pd.DataFrame(rows, columns=columns),
                              trials_table=pd.DataFrame(trial_rows), warnings=warnings,
                              settings=settings)


def _exponential_trial_row(row: dict, efit) -> dict:
    """A trials-table row with the exponential fit's k0, beta, contact points and R^2."""
    out = {}
    for key, value in row.items():
        if key == "stiffness_N_per_m":
            out[key] = efit.k0
            out[STIFFENING_COLUMNS[0]] = efit.stiffening
        else:
            out[key] = efit.r2_min if key == "r2_min" else value
    out["contact_offsets_mm"] = ";".join(f"{d * 1e3:.6g}" for d in efit.offset)
    out["fit_status"] = efit.status
    return out


def _exponential_warnings(loc: ExponentialLocationFit) -> list[str]:
    """One line per trial whose fit failed or ended on beta's bound, one if none converged."""
    out = []
    for fit, trial in zip(loc.fits, loc.trial_ids):
        if fit.status == "failed":
            out.append(f"{loc.location} trial {trial}: exponential fit failed: {fit.message}; "
                       "left out of the means")
        elif fit.status == "at_bound":
            out.append(f"{loc.location} trial {trial}: exponential fit: {fit.message}")
    if not loc.n_trials:
        out.append(f"{loc.location}: no exponential fit converged; its values are left empty")
    return out


def check_fit_outputs(input_path, output, *, plots=None, trials_csv=None) -> None:
    """Refuse outputs that are (or sit inside) the input, or collide with each other.

    Raises
    ------
    UsageError
        Naming the option at fault.
    """
    input_path = Path(input_path)
    outs = [("-o/--output", output), ("--trials-csv", trials_csv)]
    for option, path in outs:
        if path is None:
            continue
        check_output_path(path, [input_path], option=option)
        path = Path(path)
        if input_path.is_dir() and path.resolve().parent == input_path.resolve():
            raise UsageError(f"output {str(path)!r} is inside the input folder "
                             f"{str(input_path)!r}, where it would be read as a trial; "
                             "expected a path outside it", key=option)
    if output is not None and trials_csv is not None and \
            Path(output).resolve() == Path(trials_csv).resolve():
        raise UsageError("the trials table and the fit CSV are the same file; expected two "
                         "paths", key="--trials-csv")
    if plots is not None:
        check_output_path(plots, [input_path], option="--plots", directory=True)
        p = Path(plots)
        if p.exists() and not p.is_dir():
            raise UsageError(f"{str(p)!r} is a file; expected a folder for the plots",
                             key="--plots")
        for option, path in outs:
            if path is not None and Path(path).resolve() == p.resolve():
                raise UsageError(f"the plots folder is the output {str(path)!r}",
                                 key="--plots")


def plot_files(law: str = "linear") -> tuple:
    """The files :func:`write_plots` writes for ``law``."""
    return QLV_PLOT_FILES if law == "qlv" else PLOT_FILES


def _save_plots(result: FitStiffnessResult, folder: Path, dpi: int) -> list[Path]:
    from ...reports.indenter_figures import force_displacement_grid, stiffness_map

    if result.law == "qlv":
        from ...reports.indenter_qlv_figures import force_time_grid

        first = force_time_grid
    else:
        first = force_displacement_grid
    files = []
    for name, make in zip(plot_files(result.law), (first, stiffness_map)):
        fig = make(result.locations)
        path = folder / name
        with naming(path):
            fig.savefig(path, dpi=dpi)
        files.append(path)
    return files


def write_plots(result: FitStiffnessResult, directory, *, dpi: int = 150) -> list[Path]:
    """Write :func:`plot_files` into ``directory`` (created if missing), all or nothing.

    ``force_displacement.png``: Fig. 6a-like force-depth curves of every location
    with the fitted unloading lines (exponential curves with that law);
    ``stiffness_map.png``: Fig. 6b-like rows x angles heat map with the values
    (k0 with the exponential law, k with the qlv law) written in. With the qlv law
    ``force_time.png`` replaces ``force_displacement.png``: the force of every
    trial over time with the fitted model, one panel per location.
    """
    directory = Path(directory)
    with atomic_directory(directory) as tmp:
        _save_plots(result, Path(tmp), dpi)
    return [directory / n for n in plot_files(result.law)]


def write_fit(result: FitStiffnessResult, output, *, plots=None, trials_csv=None,
              dpi: int = 150) -> list[Path]:
    """Write the fit CSV, and optionally the per-trial CSV and the plots, all or nothing.

    Parameters
    ----------
    result : FitStiffnessResult
    output : str or Path
        The fit CSV (docs/model.md section 7 columns, with the exponential law
        :data:`STIFFENING_COLUMNS`, then :data:`QUALITY_COLUMNS`).
    plots : str or Path, optional
        Folder for :data:`PLOT_FILES`.
    trials_csv : str or Path, optional
        Per-trial table.
    dpi : int
        Resolution of the plots.

    Returns
    -------
    list of Path
        The files written. If anything fails, none of them is left behind.
    """
    check_fit_outputs(result.input_path, output, plots=plots, trials_csv=trials_csv)
    written = []
    with ExitStack() as stack:
        # entered first, committed last: the plots folder, then the trials table, then the CSV
        if plots is not None:
            pdir = Path(stack.enter_context(atomic_directory(plots)))
            _save_plots(result, pdir, dpi)
            written += [Path(plots) / n for n in plot_files(result.law)]
        if trials_csv is not None:
            tmp = stack.enter_context(atomic_file(trials_csv, suffix=".csv"))
            write_trials_csv(result.trials_table, tmp, atomic=False)
            written.append(Path(trials_csv))
        tmp = stack.enter_context(atomic_file(output, suffix=".csv"))
        write_stiffness_csv(result.table, tmp, atomic=False)
        written.insert(0, Path(output))
    return written
