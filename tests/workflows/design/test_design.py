"""``phri design``: objectives against ``simulate``, Pareto sets, bad input, resuming.

Expected objectives come from the real :func:`simulate` on each design's config
written out as YAML (peak pressure ratio, its 99th percentile with plain
np.percentile over every sample, lift-off from its contact flags), from the
displacement formula |t + w x p_e| evaluated directly with np.cross, and from
a finite-difference compliance at the load cell (stiffness); the Pareto set
from a brute-force O(n^2) dominance check.
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml
from click.testing import CliRunner
from hypothesis import given, settings
from hypothesis import strategies as st

from support.design_study import make_study, write_log  # noqa: F401
from support.helpers import one_line
from phri_cli.main import phri
from phri_spring.io.config import load_config
from phri_spring.io.logs import read_wrench_log
from phri_spring.physics.contact.solver import solve
from phri_spring.workflows.common import cuff_wrench, model_from_config
from phri_spring.workflows.design.study import (STATE_DIR, design_mapping, load_set, pareto_mask,
                                          prepare_study, run_study, weighted_percentile)
from phri_spring.workflows.simulate import simulate

COLS = ["time", "Fx", "Fy", "Fz", "Mx", "My", "Mz"]


# --------------------------------------------------------------------------- helpers
def snapshot(folder: Path) -> dict:
    out = {}
    if not folder.exists():
        return out
    for root, _dirs, files in os.walk(folder):
        for f in files:
            p = Path(root) / f
            out[str(p.relative_to(folder))] = (p.read_bytes(), p.stat().st_mtime_ns)
    return out


def invoke(*args):
    return CliRunner().invoke(phri, ["design", *map(str, args)], catch_exceptions=False)


def expected_objectives(cfg_path: Path, logs, arm="compliant") -> dict:
    """Objectives from the real simulate (and independent formulas) on a config file."""
    cfg = load_config(cfg_path)
    w = np.concatenate([read_wrench_log(f)[1] for f in logs])
    res = simulate(cfg, w, arm=arm)
    out = {"peak_pressure_to_pain_threshold": float(np.max(res.pain_ratio)),
           "peak_pressure_to_pain_threshold_p99": float(np.percentile(res.pain_ratio, 99)),
           "lift_off_fraction": float(np.mean(~res.contact))}
    model = model_from_config(cfg, arm)
    u = solve(model, cuff_wrench(cfg, w)).u
    d = u[:, None, :3] + np.cross(u[:, None, 3:], model.geometry.points[None])
    out["peak_cuff_displacement_mm"] = 1000.0 * float(np.max(np.linalg.norm(d, axis=2)))
    # load-cell compliance by central differences (exact within one contact set)
    R, p = cfg.loadcell_rotation, cfg.loadcell_position
    C = np.zeros((6, 6))
    h = 1e-3
    for j in range(6):
        us = []
        for s in (h, -h):
            e = np.zeros(6)
            e[j] = s
            uc = solve(model, cuff_wrench(cfg, e[None]))
            t, wv = uc.u[0, :3], uc.u[0, 3:]
            us.append(np.concatenate([R.T @ (t + np.cross(wv, p)), R.T @ wv]))
        C[:, j] = (us[0] - us[1]) / (2 * h)
    K = np.linalg.inv(C)
    K = 0.5 * (K + K.T)
    out["stiffness_translational_N_per_mm"] = float(np.linalg.eigvalsh(K[:3, :3])[0]) / 1000
    out["stiffness_rotational_Nm_per_deg"] = float(np.linalg.eigvalsh(K[3:, 3:])[0]) * \
        math.pi / 180
    return out


# --------------------------------------------------------------------------- objectives
@pytest.fixture(scope="module")
def study_run(tmp_path_factory):
    folder = tmp_path_factory.mktemp("design")
    path = make_study(folder)
    result = run_study(path, folder / "out", workers=2)
    return folder, path, result


def test_objectives_equal_simulate_on_written_configs(study_run):
    folder, path, result = study_run
    study, base, _loads, values, _cfgs = prepare_study(path)
    t = result.table
    assert len(t) == 12 and list(t["design"]) == list(range(12))
    picks = sorted({result.best, 0, 5, 11})
    for i in picks:
        raw = design_mapping(base.raw, study, values[i])
        cfg_path = folder / f"design_{i}.yaml"
        cfg_path.write_text(yaml.safe_dump(raw, sort_keys=False))
        exp = expected_objectives(cfg_path, study.loads)
        for name in ("peak_pressure_to_pain_threshold", "peak_pressure_to_pain_threshold_p99",
                     "lift_off_fraction", "peak_cuff_displacement_mm"):
            assert t[name].iloc[i] == pytest.approx(exp[name], rel=1e-9, abs=1e-15), (i, name)
        for name in ("stiffness_translational_N_per_mm", "stiffness_rotational_Nm_per_deg"):
            assert t[name].iloc[i] == pytest.approx(exp[name], rel=1e-6), (i, name)
    # the parameters are in the table under their dotted paths
    assert sorted(t["strap.tension"].unique()) == [4.0, 15.0, 40.0]
    assert sorted(t["cuff.stiffness.per_angle"].unique()) == [0.5, 2.0]
    assert t["cuff.stiffness.per_angle[5]"].min() == 1.0e5
    assert t["cuff.stiffness.per_angle[5]"].max() == 2.0e6


def test_best_yaml_simulates_to_its_row(study_run):
    folder, path, result = study_run
    out = folder / "out"
    t = pd.read_csv(out / "designs.csv")
    tp = pd.read_parquet(out / "designs.parquet")
    assert list(t.columns) == list(tp.columns)
    assert t["pareto"].dtype == bool and t["feasible"].dtype == bool
    b = result.best
    assert bool(tp["pareto"].iloc[b])
    # the lowest first objective among the Pareto designs
    par = tp[tp["pareto"]]
    assert tp["peak_pressure_to_pain_threshold"].iloc[b] == \
        par["peak_pressure_to_pain_threshold"].min()
    exp = expected_objectives(out / "best.yaml", prepare_study(path)[0].loads)
    for name in ("peak_pressure_to_pain_threshold", "lift_off_fraction",
                 "peak_pressure_to_pain_threshold_p99"):
        assert tp[name].iloc[b] == pytest.approx(exp[name], rel=1e-9, abs=1e-15)
    for f in ("report.md", "pareto.png", "objectives_vs_parameters.png",
              "best_peak_pressure.png"):
        assert (out / f).stat().st_size > 0
    assert "Best design" in (out / "report.md").read_text()


def test_pareto_column_is_the_non_dominated_feasible_set(study_run):
    _folder, _path, result = study_run
    t = result.table
    F = t[["peak_pressure_to_pain_threshold", "lift_off_fraction"]].to_numpy()
    feas = (t["stiffness_translational_N_per_mm"] >= 2).to_numpy() & \
        (t["not_converged_samples"] == 0).to_numpy()
    assert np.array_equal(t["feasible"].to_numpy(), feas)
    assert np.array_equal(t["pareto"].to_numpy(), brute_force_pareto(F, feas))


def test_exact_merging_keeps_every_sample(tmp_path):
    log = write_log(tmp_path / "l.csv", 300, seed=1, repeat_every=3)
    ls = load_set([log, log])
    w = read_wrench_log(log)[1]
    assert ls.n_samples == 600 and ls.weights.sum() == 600
    assert len(ls.wrench_lc) == len(np.unique(w, axis=0)) < 300
    # every row is reproduced with its count, in first-occurrence order
    rebuilt = {tuple(r): c for r, c in zip(ls.wrench_lc, ls.weights)}
    uniq, counts = np.unique(np.concatenate([w, w]), axis=0, return_counts=True)
    assert all(rebuilt[tuple(r)] == c for r, c in zip(uniq, counts))
    # a tolerance snaps each component by at most half its step
    lt = load_set([log], force_tol=0.5, moment_tol=0.02)
    assert len(lt.wrench_lc) < len(ls.wrench_lc)


# --------------------------------------------------------------------------- properties
def brute_force_pareto(F, feasible):
    n = len(F)
    out = np.zeros(n, dtype=bool)
    for a in range(n):
        if not feasible[a] or not np.all(np.isfinite(F[a])):
            continue
        dominated = False
        for b in range(n):
            if b == a or not feasible[b] or not np.all(np.isfinite(F[b])):
                continue
            if all(F[b][k] <= F[a][k] for k in range(F.shape[1])) and \
                    any(F[b][k] < F[a][k] for k in range(F.shape[1])):
                dominated = True
                break
        out[a] = not dominated
    return out


@settings(max_examples=150, deadline=None)
@given(st.integers(1, 40).flatmap(lambda n: st.tuples(
    st.lists(st.lists(st.sampled_from([0.0, 1.0, 2.0, 3.0, 2.5, math.nan]), min_size=3,
                      max_size=3), min_size=n, max_size=n),
    st.lists(st.booleans(), min_size=n, max_size=n),
    st.integers(1, 3))))
def test_pareto_mask_matches_brute_force(case):
    rows, feas, k = case
    F = np.array(rows)[:, :k]
    feas = np.array(feas)
    assert np.array_equal(pareto_mask(F, feas), brute_force_pareto(F, feas))


@settings(max_examples=200, deadline=None)
@given(st.lists(st.tuples(st.floats(-1e3, 1e3), st.integers(1, 6)), min_size=1, max_size=30),
       st.floats(0, 100))
def test_weighted_percentile_is_numpy_percentile_of_the_repeated_values(rows, q):
    v = np.array([r[0] for r in rows])
    w = np.array([r[1] for r in rows])
    expected = np.percentile(np.repeat(v, w), q)
    assert weighted_percentile(v, w, q) == pytest.approx(expected, rel=1e-12, abs=1e-12)


# --------------------------------------------------------------------------- plans
def test_lhs_and_sobol_plans_are_seeded_and_in_range(tmp_path):
    p1 = make_study(tmp_path / "a", plan="lhs:9", seed=5)
    p2 = make_study(tmp_path / "b", plan="sobol:8", seed=5)
    v1a = prepare_study(p1)[3]
    v1b = prepare_study(p1)[3]
    v2 = prepare_study(p2)[3]
    assert v1a.shape == (9, 3) and np.array_equal(v1a, v1b)
    assert v2.shape == (8, 3)
    for v in (v1a, v2):
        assert set(v[:, 0]) <= {4.0, 15.0, 40.0} and set(v[:, 1]) <= {0.5, 2.0}
        assert np.all((v[:, 2] >= 1e5) & (v[:, 2] <= 2e6))
    # LHS: one point per stratum of the continuous range (log space)
    strata = np.floor(9 * np.log(v1a[:, 2] / 1e5) / np.log(20)).astype(int)
    assert sorted(strata) == list(range(9))


# --------------------------------------------------------------------------- bad input
BAD = [
    ({"minimize": ["lift_off_fraction"]}, "minimize", "did you mean 'minimise'"),
    ({"vary": {"strap.tensoin": {"values": [1, 2]}}}, "strap.tensoin", "tension"),
    ({"vary": {"strap.model": {"values": [1, 2]}}}, "strap.model", "expected"),
    ({"vary": {"cuff.stiffness": {"values": [1, 2]}}}, "cuff.stiffness", "numeric"),
    ({"vary": {"strap.tension": {"values": [10, -5]}}}, "strap.tension", "design 1"),
    ({"vary": {"cuff.stiffness.per_angle[9]": {"values": [1e5]}}}, "per_angle[9]", "range"),
    ({"loads": []}, "loads", "at least one"),
    ({"minimise": ["peak_pressure"]}, "minimise[0]", "unknown objective"),
    ({"plan": "random:5"}, "plan", "grid, lhs:N or sobol:N"),
    ({"arm": "rigdi"}, "arm", "rigid"),
    ({"constraints": {"lift_off_fraction": "about 0"}}, "constraints.lift_off_fraction", "'>= 2'"),
]


@pytest.fixture(scope="module")
def finished_small_study(tmp_path_factory):
    folder = tmp_path_factory.mktemp("small") / "s"
    good = make_study(folder, n=60)
    assert invoke(good, "-o", folder / "out", "--no-figures", "--workers", "1").exit_code == 0
    return folder


@pytest.mark.parametrize("over,key,fragment", BAD, ids=[b[1] for b in BAD])
def test_bad_study_one_line_nothing_written_resumable_untouched(tmp_path, finished_small_study,
                                                                over, key, fragment):
    import shutil

    folder = tmp_path / "s"
    shutil.copytree(finished_small_study, folder)     # a finished, resumable study
    out = folder / "out"
    before = snapshot(folder)
    bad = make_study(tmp_path / "bad", n=60, extra=over)
    bad.replace(folder / "bad.yaml")
    for f in (tmp_path / "bad").iterdir():
        f.unlink()
    res = invoke(folder / "bad.yaml", "-o", out, "--no-figures")
    err = res.stderr
    assert res.exit_code in (1, 2), res.output
    assert one_line(err) and "Traceback" not in err, err
    assert key in err and fragment in err, err
    after = snapshot(folder)
    after.pop("bad.yaml")
    assert after == before
    # and into a new folder: nothing created
    res = invoke(folder / "bad.yaml", "-o", tmp_path / "new")
    assert res.exit_code in (1, 2) and not (tmp_path / "new").exists()


def test_empty_log_and_unreachable_scheduler(tmp_path):
    folder = tmp_path / "s"
    path = make_study(folder, n=60)
    (folder / "log_b.csv").write_text(",".join(COLS) + "\n")
    res = invoke(path, "-o", folder / "out")
    assert res.exit_code == 1 and one_line(res.stderr) and "log_b.csv" in res.stderr
    assert not (folder / "out").exists()
    write_log(folder / "log_b.csv", 30, seed=2)
    pytest.importorskip("distributed")
    res = invoke(path, "-o", folder / "out", "--scheduler", "tcp://127.0.0.1:9")
    assert res.exit_code == 2 and one_line(res.stderr), res.stderr
    assert "--scheduler" in res.stderr and "cannot reach" in res.stderr
    assert not (folder / "out").exists()


def test_other_study_in_outdir_is_refused(tmp_path):
    folder = tmp_path / "s"
    path = make_study(folder, n=60)
    assert invoke(path, "-o", folder / "out", "--no-figures").exit_code == 0
    before = snapshot(folder / "out")
    other = make_study(tmp_path / "t", n=60, plan="lhs:3")
    res = invoke(other, "-o", folder / "out")
    assert res.exit_code == 2 and "another study" in res.stderr and one_line(res.stderr)
    assert snapshot(folder / "out") == before


# --------------------------------------------------------------------------- resume
def test_interrupted_study_resumes_from_written_batches(tmp_path):
    folder = tmp_path / "s"
    path = make_study(folder, n=200, batch_size=2)
    full = run_study(path, tmp_path / "ref", workers=1, figures=False).table

    class Stop(Exception):
        pass

    def stop_after_two_batches(done, total):
        if done >= 4:
            raise Stop

    with pytest.raises(Stop):
        run_study(path, folder / "out", workers=1, figures=False,
                  progress=stop_after_two_batches)
    written = sorted((folder / "out" / STATE_DIR).glob("batch_*.npz"))
    assert 2 <= len(written) < 6
    assert not list((folder / "out").rglob("*.tmp*"))        # nothing half-written
    assert not (folder / "out" / "designs.csv").exists()
    notes = []
    again = run_study(path, folder / "out", workers=1, figures=False, message=notes.append)
    assert again.resumed_batches == len(written) and again.total_batches == 6
    assert notes and notes[0].startswith(f"resuming: {len(written)} of 6 batches")
    pd.testing.assert_frame_equal(again.table, full, check_exact=True)


def test_new_constraints_reuse_the_finished_batches(tmp_path):
    folder = tmp_path / "s"
    path = make_study(folder, n=60)
    first = run_study(path, folder / "out", workers=1, figures=False)
    path2 = make_study(folder, n=60, constraints={"stiffness_translational_N_per_mm": ">= 1e9"})
    notes = []
    again = run_study(path2, folder / "out", workers=1, figures=False, message=notes.append)
    assert again.resumed_batches == again.total_batches and notes
    assert not again.table["feasible"].any() and not again.table["pareto"].any()
    # no best design now: the earlier ranking's best.yaml is gone, report.md says why
    assert again.best == -1 and not (folder / "out" / "best.yaml").exists()
    assert "No design is feasible" in (folder / "out" / "report.md").read_text()
    objectives = [c for c in first.table.columns if c not in ("feasible", "pareto")]
    pd.testing.assert_frame_equal(again.table[objectives], first.table[objectives])
