"""``phri design``: parameter studies of a cuff over a load set, with Pareto fronts.

A design is the study's base config (its YAML mapping) with the varied values
put at their dotted paths, validated by the config schema itself. Each design
is simulated over the whole load set with the vectorised solver (one pass per
design), and reduced to the objectives of :data:`~phri_spring.io.study.OBJECTIVES`:

``peak_pressure_to_pain_threshold``
    max over samples of the per-sample peak pressure / pain threshold (the
    numbers ``phri simulate`` writes in its column of that name) [-].
``peak_pressure_to_pain_threshold_p99``
    the 99th percentile over samples of the same column (numpy's default
    linear interpolation between order statistics) [-].
``lift_off_fraction``
    (samples x elements out of contact) / (samples x elements) [-].
``stiffness_translational_N_per_mm``, ``stiffness_rotational_Nm_per_deg``
    smallest principal value of the translational [N/mm] and rotational
    [N*m/deg] blocks of the interface stiffness at the preloaded state,
    expressed at the load cell (docs/model.md, sections 4 and 5).
``peak_cuff_displacement_mm``
    max over samples of the largest displacement of an element point of the
    cuff, |t + w x p_e| [mm].

Load-set shrinking: identical load-cell rows are merged into one row with a
weight (exact: every objective is a weighted max, percentile or fraction);
an optional tolerance merges rows that agree to within it (approximate).

The load set, the objectives and the Pareto mask live in
:mod:`phri_spring.workflows.design_objectives` (re-exported here).
"""

from __future__ import annotations

import copy
import difflib
import hashlib
import itertools
import json
import math
import os
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Optional

import numpy as np

from ..errors import ConfigError, UsageError
from ..io.atomic import atomic_file, check_output_path
from ..io.config import Config, config_from_dict
from ..io.study import OBJECTIVES, Parameter, Study, load_study, parse_path
from .common import ARMS, model_from_config
from .design_objectives import (LoadSet, evaluate_batch, evaluate_design, load_set,
                                pareto_mask, weighted_percentile)

__all__ = ["LoadSet", "load_set", "design_values", "design_mapping", "build_designs",
           "evaluate_batch", "evaluate_design", "pareto_mask", "weighted_percentile",
           "run_study", "StudyResult", "STATE_DIR"]

#: the folder inside OUTDIR that holds the finished batches of a study (for resuming)
STATE_DIR = ".phri-design"


# --------------------------------------------------------------------------- parameters
def _walk(raw, parts, path_text, study_file, create: bool):
    """(container, last key) of a dotted path in a config mapping."""
    node = raw
    key = f"vary.{path_text}"
    done = []
    for j, part in enumerate(parts[:-1]):
        nxt = parts[j + 1]
        if isinstance(part, int):
            if not isinstance(node, list) or part >= len(node):
                have = f"a list of {len(node)} values" if isinstance(node, list) else \
                    f"{type(node).__name__}"
                raise ConfigError(f"index [{part}] after {'.'.join(map(str, done))} is out of "
                                  f"range ({have})", file=study_file, key=key)
            node = node[part]
        else:
            if not isinstance(node, dict):
                raise ConfigError(f"{'.'.join(map(str, done)) or 'the config'} is not a "
                                  f"mapping; expected a numeric config key", file=study_file,
                                  key=key)
            if part not in node:
                if not create:
                    close = difflib.get_close_matches(part, [str(k) for k in node], n=1,
                                                      cutoff=0.5)
                    hint = f"; did you mean {close[0]!r}?" if close else ""
                    raise ConfigError(f"the config has no key {part!r} here{hint}",
                                      file=study_file, key=key)
                node[part] = [] if isinstance(nxt, int) else {}
            node = node[part]
        done.append(part)
    return node, parts[-1]


def _is_number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _check_parameter(raw_cfg: dict, p: Parameter, study_file) -> None:
    """A parameter's path must hold a number (a list of numbers for ``scale``)."""
    parts = parse_path(p.path, file=study_file)
    node, last = _walk(copy.deepcopy(raw_cfg), parts, p.path, study_file, create=True)
    key = f"vary.{p.path}"
    if isinstance(last, int):
        if not isinstance(node, list) or last >= len(node):
            n = len(node) if isinstance(node, list) else 0
            raise ConfigError(f"index [{last}] is out of range (the config's list has {n} "
                              "values)", file=study_file, key=key)
        cur = node[last]
    else:
        if not isinstance(node, dict):
            raise ConfigError("the parent is not a mapping; expected a numeric config key",
                              file=study_file, key=key)
        cur = node.get(last)
    if cur is None:
        if p.kind == "scale":
            raise ConfigError(f"the config has no value at {p.path!r} to scale; expected a key "
                              "the config sets", file=study_file, key=key)
        return  # a key the config leaves at its default: the schema checks each value
    if p.kind == "scale":
        ok = _is_number(cur) or (isinstance(cur, list) and cur and
                                 all(_is_number(v) for v in cur))
        if not ok:
            raise ConfigError(f"expected a number or a list of numbers to scale, found "
                              f"{_describe(cur)}", file=study_file, key=key)
    elif not _is_number(cur):
        raise ConfigError(f"expected a numeric config key, found {_describe(cur)}"
                          + (" (scale a whole list with {scale: [...]}, or vary one item "
                             f"as {p.path}[i])" if isinstance(cur, list) else ""),
                          file=study_file, key=key)


def _describe(v) -> str:
    if isinstance(v, dict):
        return f"a mapping with keys {', '.join(map(str, v))}"
    if isinstance(v, list):
        return f"a list of {len(v)} items"
    return f"{type(v).__name__} {v!r}"


def _set(raw_cfg: dict, p: Parameter, value: float, study_file) -> None:
    parts = parse_path(p.path, file=study_file)
    node, last = _walk(raw_cfg, parts, p.path, study_file, create=True)
    if p.kind == "scale":
        cur = node[last]
        node[last] = [float(v) * value for v in cur] if isinstance(cur, list) \
            else float(cur) * value
    else:
        node[last] = float(value)


def design_values(study: Study) -> np.ndarray:
    """The parameter values of every design, shape (designs, parameters).

    ``grid``: every combination (the first parameter varies slowest); a ``range``
    gives ``count`` levels, evenly spaced (in log space with ``log``). ``lhs:N``
    and ``sobol:N``: N points of scipy.stats.qmc's LatinHypercube or scrambled
    Sobol sequence with the study's seed; a ``values``/``scale`` list is
    sampled as a discrete choice among its levels. Factors of ``scale`` are
    reported as such.
    """
    params = study.parameters
    if study.plan == "grid":
        levels = []
        for p in params:
            if p.kind == "range":
                if p.log:
                    lv = np.logspace(math.log10(p.low), math.log10(p.high), p.count)
                else:
                    lv = np.linspace(p.low, p.high, p.count)
                lv[0], lv[-1] = p.low, (p.high if p.count > 1 else p.low)
                levels.append(lv)
            else:
                levels.append(np.array(p.levels))
        return np.array(list(itertools.product(*levels)), dtype=float).reshape(-1, len(params))
    from scipy.stats import qmc

    d = len(params)
    cls = qmc.LatinHypercube if study.plan == "lhs" else qmc.Sobol
    kw = {} if study.plan == "lhs" else {"scramble": True}
    try:
        sampler = cls(d, rng=np.random.default_rng(study.seed), **kw)
    except TypeError:  # scipy < 1.15
        sampler = cls(d, seed=np.random.default_rng(study.seed), **kw)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # Sobol's balance warning for N not a power of 2
        u = sampler.random(study.n_samples)
    out = np.empty_like(u)
    for j, p in enumerate(params):
        if p.kind == "range":
            if p.log:
                a, b = math.log(p.low), math.log(p.high)
                out[:, j] = np.exp(a + u[:, j] * (b - a))
            else:
                out[:, j] = p.low + u[:, j] * (p.high - p.low)
        else:
            lv = np.array(p.levels)
            out[:, j] = lv[np.minimum((u[:, j] * len(lv)).astype(int), len(lv) - 1)]
    return out


def design_mapping(base_raw: dict, study: Study, values) -> dict:
    """The base config mapping with one design's values put at their paths."""
    raw = copy.deepcopy(base_raw)
    for p, v in zip(study.parameters, values):
        _set(raw, p, float(v), study.path)
    return raw


def build_designs(study: Study, base: Config) -> tuple:
    """Validate every design; returns (values (d, p), [Config, ...]).

    Raises
    ------
    ConfigError
        Naming the parameter path (a missing or non-numeric key) or, for a value
        the config schema rejects, the design, its values and the config key.
    """
    if study.arm not in ARMS:
        close = difflib.get_close_matches(study.arm, ARMS, n=1, cutoff=0.5)
        hint = f"; did you mean {close[0]!r}?" if close else ""
        raise ConfigError(f"unknown arm model {study.arm!r}{hint} (expected one of "
                          f"{', '.join(ARMS)})", file=study.path, key="arm")
    for p in study.parameters:
        _check_parameter(base.raw, p, study.path)
    values = design_values(study)
    if len(values) == 0:
        raise ConfigError("the plan gives no design", file=study.path, key="plan")
    cfg_dir = base.path.parent if base.path is not None else Path(".")
    configs = []
    for i, row in enumerate(values):
        raw = design_mapping(base.raw, study, row)
        try:
            cfg = config_from_dict(raw, path=base.path, base_dir=cfg_dir)
            model_from_config(cfg, study.arm)
        except ConfigError as exc:
            what = ", ".join(f"{p.path}={'x' if p.kind == 'scale' else ''}{v:g}"
                             for p, v in zip(study.parameters, row))
            raise type(exc)(f"design {i} ({what}) is not a valid config: {exc.message}",
                            file=study.path, key=exc.key) from None
        configs.append(cfg)
    return values, configs


# --------------------------------------------------------------------------- running
@dataclass
class StudyResult:
    """What :func:`run_study` produced."""

    study: Study
    table: object                  # pandas DataFrame, one row per design
    best: int                      # design id of the best design (-1 if none is feasible)
    best_config: Optional[dict]    # its config mapping
    element_peak_kpa: np.ndarray   # (d, n)
    labels: tuple
    row_labels: tuple
    n_angles: int
    loads: LoadSet
    outdir: Path
    resumed_batches: int = 0
    total_batches: int = 0
    compute_seconds: float = 0.0   # sum over the batches computed in this run [s]
    map_seconds: float = 0.0       # wall time of running those batches [s]
    workers: int = 1
    wall_seconds: float = 0.0
    files: list = field(default_factory=list)
    uncertainty: Optional[dict] = None
    pain_threshold_kpa: float = 120.0


def _batch_size(study: Study, n_designs: int) -> int:
    if study.batch_size:
        return study.batch_size
    return int(min(50, max(1, math.ceil(n_designs / 100))))


def _fingerprint(study: Study, base: Config, values: np.ndarray, loads: LoadSet, bs: int) -> str:
    h = hashlib.sha256()
    # only what the batches depend on: objectives, constraints, best and the uncertainty
    # section can change and the finished batches still count
    h.update(json.dumps({"config": base.raw, "arm": study.arm, "batch": bs,
                         "parameters": [p.path + ":" + p.kind for p in study.parameters]},
                        sort_keys=True, default=str).encode())
    h.update(np.ascontiguousarray(values).tobytes())
    for f in base.stiffness_files:
        try:
            h.update(Path(f).read_bytes())
        except OSError:
            pass
    h.update(loads.digest().encode())
    return h.hexdigest()


def _save_npz(path: Path, data: dict) -> None:
    with atomic_file(path, suffix=".npz") as tmp:
        with open(tmp, "wb") as fh:
            np.savez(fh, **data)


def _load_npz(path: Path) -> Optional[dict]:
    try:
        with np.load(path) as z:
            return {k: z[k] for k in z.files}
    except Exception:  # noqa: BLE001 - a damaged batch file is simply recomputed
        return None


def prepare_study(study_path) -> tuple:
    """Load a study, its base config, its load set and its designs (nothing written).

    Returns ``(study, base_config, loads, values, configs)``.
    """
    from ..io.config import load_config

    study = load_study(study_path) if not isinstance(study_path, Study) else study_path
    base = load_config(study.config)
    loads = load_set(study.loads, base.log_columns, force_tol=study.merge_force_N,
                     moment_tol=study.merge_moment_Nm)
    values, configs = build_designs(study, base)
    return study, base, loads, values, configs


def run_study(study_path, outdir, *, scheduler: Optional[str] = None,
              workers: Optional[int] = None, figures: bool = True, dpi: int = 150,
              progress: Optional[Callable[[int, int], None]] = None,
              message: Optional[Callable[[str], None]] = None) -> StudyResult:
    """Run (or resume) a study and write its outputs into ``outdir``.

    Parameters
    ----------
    study_path : path or Study
    outdir : path
        Output folder: created if missing; a folder holding the batches of the
        same study resumes from them; one holding another study is refused.
    scheduler, workers
        See :func:`phri_spring.workflows.executors.batch_executor`.
    figures : bool
        Write the PNG figures.
    progress : callable(done_designs, total_designs), optional
    message : callable(str), optional
        Receives one-line notes for the user (e.g. that the study resumed).

    Raises
    ------
    ConfigError, DataError, UsageError
        Before anything is written.
    """
    from .executors import batch_executor

    t_wall = time.perf_counter()
    outdir = Path(outdir)
    study, base, loads, values, configs = prepare_study(study_path)
    check_output_path(outdir, [study.path, study.config, *study.loads, *base.stiffness_files],
                      option="-o/--output", directory=True)
    if outdir.exists() and not outdir.is_dir():
        raise UsageError(f"output {str(outdir)!r} is a file; expected a folder",
                         key="-o/--output")
    bs = _batch_size(study, len(configs))
    fp = _fingerprint(study, base, values, loads, bs)
    state = outdir / STATE_DIR
    state_file = state / "state.json"
    done: dict = {}
    if state_file.exists():
        try:
            old = json.loads(state_file.read_text())
        except (OSError, ValueError):
            old = {}
        if old.get("fingerprint") != fp:
            raise UsageError(f"{str(outdir)!r} holds the results of another study (other "
                             "designs, arm, config or loads); expected a new folder, or the "
                             "same study to resume", key="-o/--output")
        for f in sorted(state.glob("batch_*.npz")):
            data = _load_npz(f)
            if data is not None:
                done[int(f.stem.split("_")[1])] = data
    elif outdir.exists() and any(outdir.iterdir()):
        raise UsageError(f"{str(outdir)!r} is not empty and holds no study; expected a new or "
                         "empty folder", key="-o/--output")

    batches = [(b, [(i, configs[i]) for i in range(s, min(s + bs, len(configs)))])
               for b, s in enumerate(range(0, len(configs), bs))]
    for b, payload in batches:   # a batch file that does not hold its designs is recomputed
        if b in done and not np.array_equal(done[b].get("design"), [i for i, _ in payload]):
            del done[b]
    done = {b: d for b, d in done.items() if b < len(batches)}
    todo = [(b, payload) for b, payload in batches if b not in done]
    n_total = len(configs)

    with batch_executor(scheduler, workers) as run:  # connects first: errors before writing
        state.mkdir(parents=True, exist_ok=True)
        if not state_file.exists():
            with atomic_file(state_file) as tmp:
                tmp.write_text(json.dumps({"fingerprint": fp, "designs": n_total,
                                           "batches": len(batches)}))
        if done and message is not None:
            message(f"resuming: {len(done)} of {len(batches)} batches "
                    f"({sum(len(done[b]['design']) for b in done)} designs) already in "
                    f"{state}; computing the other {len(todo)}")
        count = [sum(len(d["design"]) for d in done.values())]
        if progress is not None:
            progress(count[0], n_total)

        def on_result(b, res):
            _save_npz(state / f"batch_{b:06d}.npz", res)
            done[b] = res
            count[0] += len(res["design"])
            if progress is not None:
                progress(count[0], n_total)

        t_map = time.perf_counter()
        run(evaluate_batch, todo, (loads, study.arm), on_result=on_result)
        map_seconds = time.perf_counter() - t_map

    result = _assemble(study, base, values, configs, loads, done, outdir)
    result.resumed_batches = len(batches) - len(todo)
    result.total_batches = len(batches)
    result.compute_seconds = float(sum(float(done[b]["seconds"]) for b, _ in todo))
    result.map_seconds = map_seconds
    if study.uncertainty is not None and result.best >= 0:
        from .uncertainty import study_uncertainty

        result.uncertainty = study_uncertainty(configs[result.best], loads, study.arm,
                                               study.uncertainty, study.objectives)
    write_outputs(result, figures=figures, dpi=dpi)
    result.wall_seconds = time.perf_counter() - t_wall
    return result


def _assemble(study, base, values, configs, loads, done, outdir) -> StudyResult:
    import pandas as pd

    parts = [done[b] for b in sorted(done)]
    ids = np.concatenate([p["design"] for p in parts])
    order = np.argsort(ids)
    if not np.array_equal(ids[order], np.arange(len(configs))):
        raise RuntimeError("the batches do not cover every design exactly once")
    cols = {"design": ids[order]}
    for j, p in enumerate(study.parameters):
        cols[p.path] = values[:, j]
    for name in study.objectives:
        cols[name] = np.concatenate([p[name] for p in parts])[order]
    for name in OBJECTIVES:
        if name not in cols and any(c.objective == name for c in study.constraints):
            cols[name] = np.concatenate([p[name] for p in parts])[order]
    for name in OBJECTIVES:
        if name not in cols:
            cols[name] = np.concatenate([p[name] for p in parts])[order]
    nc = np.concatenate([p["not_converged_samples"] for p in parts])[order]
    peaks = np.concatenate([p["element_peak_pressure_kPa"] for p in parts])[order]
    feasible = nc == 0
    for c in study.constraints:
        feasible &= np.array([c.holds(v) for v in cols[c.objective]], dtype=bool)
    F = np.column_stack([s * np.asarray(cols[o]) for o, s in zip(study.objectives,
                                                                  study.senses)])
    pareto = pareto_mask(F, feasible)
    cols["not_converged_samples"] = nc
    cols["feasible"] = feasible
    cols["pareto"] = pareto
    table = pd.DataFrame(cols)
    best = -1
    best_cfg = None
    if pareto.any():
        s = study.senses[study.objectives.index(study.best)]
        key = s * table[study.best].to_numpy()
        cand = np.flatnonzero(pareto)
        best = int(cand[np.argmin(key[cand])])        # ties: the lowest design id
        best_cfg = design_mapping(base.raw, study, values[best])
    thr = configs[best].pain_threshold_kpa if best >= 0 else base.pain_threshold_kpa
    return StudyResult(pain_threshold_kpa=thr, study=study, table=table, best=best, best_config=best_cfg,
                       element_peak_kpa=peaks, labels=tuple(base.labels),
                       row_labels=tuple(base.row_labels), n_angles=base.angle_count,
                       loads=loads, outdir=outdir)


# --------------------------------------------------------------------------- outputs
def _portable_config(cfg_raw: dict, base: Optional[Path], outdir: Path) -> dict:
    """The config mapping with stiffness-file paths made relative to ``outdir``."""
    raw = copy.deepcopy(cfg_raw)
    base_dir = base.parent if base is not None else Path(".")
    for sec in ("tissue", "cuff"):
        v = raw.get(sec, {}).get("stiffness") if isinstance(raw.get(sec), dict) else None
        if isinstance(v, str):
            src = Path(v) if Path(v).is_absolute() else base_dir / v
            try:
                raw[sec]["stiffness"] = os.path.relpath(src.resolve(), outdir.resolve())
            except ValueError:  # another drive (Windows)
                raw[sec]["stiffness"] = str(src.resolve())
    return raw


def _fmt(v) -> str:
    if isinstance(v, (bool, np.bool_)):
        return "yes" if v else "no"
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    try:
        f = float(v)
    except (TypeError, ValueError):
        return str(v)
    if not math.isfinite(f):
        return "-"
    return f"{f:.4g}"


def _md_table(df) -> str:
    cols = list(df.columns)
    lines = ["| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
    for _, row in df.iterrows():
        lines.append("| " + " | ".join(_fmt(row[c]) for c in cols) + " |")
    return "\n".join(lines)


def _report(result: StudyResult, figs: list) -> str:
    st = result.study
    t = result.table
    n = len(t)
    lines = [f"# Design study{': ' + st.name if st.name else ''}", ""]
    lines.append(f"- base config: `{st.config.name}`; arm model: {st.arm}")
    lines.append(f"- load set: {', '.join(f'`{f.name}`' for f in st.loads)}: "
                 f"{result.loads.n_samples:,} samples, {len(result.loads.weights):,} distinct "
                 + ("(identical rows merged, exact)" if result.loads.tolerance == (0.0, 0.0) else
                    f"(rows merged within {result.loads.tolerance[0]:g} N / "
                    f"{result.loads.tolerance[1]:g} N*m: approximate)"))
    plan = st.plan if st.plan == "grid" else f"{st.plan}:{st.n_samples} (seed {st.seed})"
    lines.append(f"- plan: {plan}, {n} designs; varied: "
                 + ", ".join(f"`{p.path}` ({_param_text(p)})" for p in st.parameters))
    obj = ", ".join(("minimise " if s > 0 else "maximise ") + f"`{o}`"
                    for o, s in zip(st.objectives, st.senses))
    lines.append(f"- objectives: {obj}")
    if st.constraints:
        lines.append("- constraints: " + ", ".join(f"`{c}`" for c in st.constraints))
    nf, npar = int(t["feasible"].sum()), int(t["pareto"].sum())
    lines.append(f"- feasible designs: {nf} of {n}; Pareto-optimal (non-dominated among the "
                 f"feasible): {npar}")
    if result.resumed_batches:
        lines.append(f"- resumed: {result.resumed_batches} of {result.total_batches} batches "
                     "came from an earlier, interrupted run")
    lines.append("")
    lines.append("## Best design")
    lines.append("")
    if result.best < 0:
        lines.append("No design is feasible: relax the constraints or widen the ranges. "
                     "`best.yaml` was not written.")
    else:
        b = t.iloc[result.best]
        lines.append(f"Design {result.best} (the lowest `{st.best}` among the Pareto designs), "
                     "written as a complete config to `best.yaml`, ready for `phri simulate`:")
        lines.append("")
        keep = [p.path for p in st.parameters] + list(OBJECTIVES)
        lines.append(_md_table(t.loc[[result.best], ["design"] + keep]))
        r = float(b["peak_pressure_to_pain_threshold"])
        if math.isfinite(r):
            verdict = "stays under" if r < 1 else "exceeds"
            lines.append("")
            lines.append(f"Its peak pressure {verdict} the pain threshold "
                         f"({100 * r:.0f}% of it at the worst sample).")
    lines.append("")
    lines.append("## Pareto designs")
    lines.append("")
    par = t[t["pareto"]]
    cols = ["design"] + [p.path for p in st.parameters] + list(st.objectives)
    lines.append(_md_table(par[cols].head(50)) if len(par) else "(none)")
    if len(par) > 50:
        lines.append(f"\n({len(par) - 50} more in designs.csv)")
    if result.uncertainty is not None:
        lines.append("")
        lines.append(result.uncertainty["markdown"])
    if figs:
        lines.append("")
        lines.append("## Figures")
        lines.append("")
        for name, caption in figs:
            lines.append(f"![{caption}]({name})")
            lines.append("")
    lines.append("")
    lines.append("Objectives: peak_pressure_to_pain_threshold = max over samples of the peak "
                 "element pressure / pain threshold; _p99 = its 99th percentile over samples "
                 "(numpy's linear interpolation); lift_off_fraction = samples x elements out of "
                 "contact / all; stiffness_* = smallest principal stiffness at the load cell at "
                 "the preloaded state [N/mm, N*m/deg]; peak_cuff_displacement_mm = max over "
                 "samples and elements of |t + w x p_e|. Parameters of kind `scale` are factors "
                 "on the base config's values. See docs/design.md.")
    return "\n".join(lines) + "\n"


def _param_text(p: Parameter) -> str:
    if p.kind == "range":
        return f"{'log ' if p.log else ''}range {p.low:g}..{p.high:g}"
    return f"{p.kind} {', '.join(f'{v:g}' for v in p.levels)}"


def write_outputs(result: StudyResult, *, figures: bool = True, dpi: int = 150) -> list:
    """Write designs.csv, designs.parquet, best.yaml, report.md and the figures (atomically)."""
    import yaml

    out = result.outdir
    files = []
    with atomic_file(out / "designs.csv") as tmp:
        result.table.to_csv(tmp, index=False, float_format="%.10g")
    files.append(out / "designs.csv")
    with atomic_file(out / "designs.parquet") as tmp:
        result.table.to_parquet(tmp, index=False)
    files.append(out / "designs.parquet")
    for name in ("uncertainty_objectives.csv", "uncertainty_patches.csv", "sobol.csv"):
        if result.uncertainty is None or name not in result.uncertainty["tables"]:
            (out / name).unlink(missing_ok=True)    # from an earlier run of this study
    if result.uncertainty is not None:
        for name, df in result.uncertainty["tables"].items():
            with atomic_file(out / name) as tmp:
                df.to_csv(tmp, index=False, float_format="%.10g")
            files.append(out / name)
    if result.best_config is not None:
        raw = _portable_config(result.best_config, result.study.config, out)
        head = (f"# best design {result.best} of the study "
                f"{result.study.path.name if result.study.path else ''} "
                f"(phri design); a complete config for phri simulate\n")
        with atomic_file(out / "best.yaml") as tmp:
            tmp.write_text(head + yaml.safe_dump(raw, sort_keys=False, allow_unicode=True),
                           encoding="utf-8")
        files.append(out / "best.yaml")
    else:   # a best design of an earlier ranking of this study would contradict report.md
        (out / "best.yaml").unlink(missing_ok=True)
        (out / "best_peak_pressure.png").unlink(missing_ok=True)
    figs = []
    if figures:
        from ..reports.compare_figures import save_figure
        from ..reports import design_figures as dfig

        st = result.study
        made = [("pareto.png", "Pareto front",
                 dfig.pareto_figure(result.table, st.objectives, st.senses, best=result.best)),
                ("objectives_vs_parameters.png", "Objectives against parameters",
                 dfig.objectives_vs_parameters_figure(result.table,
                                                      [p.path for p in st.parameters],
                                                      st.objectives))]
        if result.best >= 0:
            made.append(("best_peak_pressure.png", "Peak pressure of the best design",
                         dfig.peak_pressure_heatmap_figure(
                             result.element_peak_kpa[result.best], row_labels=result.row_labels,
                             n_angles=result.n_angles,
                             pain_threshold_kpa=result.pain_threshold_kpa,
                             title=f"Best design {result.best}: peak pressure over the load "
                                   "set [kPa]")))
        for name, caption, fig in made:
            with atomic_file(out / name) as tmp:
                save_figure(fig, tmp, dpi=dpi)
            files.append(out / name)
            figs.append((name, caption))
    with atomic_file(out / "report.md") as tmp:
        tmp.write_text(_report(result, figs), encoding="utf-8")
    files.append(out / "report.md")
    result.files = files
    return files
