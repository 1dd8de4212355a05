"""`phri compare` as a library: reading, zeroing, RMSE, tables, figures and an end-to-end check.

The end-to-end test recomputes everything from docs/model.md formulas with numpy (its own
geometry, springs, preload, load-cell transform and active-set solver), so it
does not share code with the implementation it checks.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

from phri_spring.errors import ConfigError, DataError, UsageError
from phri_spring.io.recordings.experiment import load_manifest, read_trial
from phri_spring.reports.compare.figures import heatmap_figure, rmse_bars_figure, wrench_figure
from phri_spring.synthetic.experiment import make_experiment
from phri_spring.workflows.compare.run import compare, parse_arms, summary_markdown, write_compare

# --------------------------------------------------------------------------- a test config
CFG = {
    "name": "test cuff",
    "geometry": {"radius": [0.044, 0.046, 0.045], "rows": {"A": -0.025, "B": 0.0, "C": 0.025},
                 "row_width": 0.025, "angles": {"start": 75.0, "step": 35.0, "count": 7}},
    "load_cell": {"position": [0.005, -0.07, 0.01], "euler_xyz_deg": [10.0, 0.0, 0.0]},
    "tissue": {"stiffness": {"per_row": [4000.0, 4300.0, 4500.0]}, "basis": "indenter",
               "indenter_diameter": 0.009, "poisson_ratio": 0.45},
    "cuff": {"stiffness": {"per_angle": [31250.0, 62500.0, 125000.0, 250000.0, 500000.0,
                                         1000000.0, 500000.0]}},
    "strap": {"tension": 12.0, "model": "hoop"},
}
ROWS = ("A", "B", "C")
LABELS = tuple(f"{r}{j}" for r in ROWS for j in range(7))
COLS = ["time", "Fx", "Fy", "Fz", "Mx", "My", "Mz"]


@pytest.fixture
def cfg_path(tmp_path):
    p = tmp_path / "cuff.yaml"
    p.write_text(yaml.safe_dump(CFG), encoding="utf-8")
    return p


# --------------------------------------------------------------------------- independent model
def _rot_x(deg):
    a = math.radians(deg)
    return np.array([[1, 0, 0], [0, math.cos(a), -math.sin(a)], [0, math.sin(a), math.cos(a)]])


def spec_model(arm):
    """Arrays of docs/model.md sections 1-3 for CFG, written out from the formulas."""
    g = CFG["geometry"]
    xs = np.array([g["rows"][r] for r in ROWS])
    R = np.array(g["radius"])
    w = np.full(3, g["row_width"])
    th = np.radians(75.0 + 35.0 * np.arange(7))
    span = math.radians(35.0)
    p, nrm, area, kt, kc, f0 = [], [], [], [], [], []
    for r in range(3):
        for j in range(7):
            p.append([xs[r], R[r] * math.cos(th[j]), R[r] * math.sin(th[j])])
            nrm.append([0.0, -math.cos(th[j]), -math.sin(th[j])])
            a = w[r] * R[r] * span
            area.append(a)
            kt.append(CFG["tissue"]["stiffness"]["per_row"][r] * a / (math.pi * 0.009 ** 2 / 4))
            kc.append(CFG["cuff"]["stiffness"]["per_angle"][j])
            f0.append(12.0 * span * w[r] / w.sum())
    p, nrm, kt, kc, f0 = map(np.array, (p, nrm, kt, kc, f0))
    k = 1.0 / (1.0 / kt + 1.0 / kc) if arm == "compliant" else kc.copy()
    b = np.hstack([nrm, np.cross(p, nrm)])
    eta = 1.0 / (2.0 * (1.0 + 0.45))
    Ks = np.zeros((6, 6))
    for e in range(21):
        px = np.array([[0, -p[e, 2], p[e, 1]], [p[e, 2], 0, -p[e, 0]], [-p[e, 1], p[e, 0], 0]])
        B = np.hstack([np.eye(3), -px])
        P = np.eye(3) - np.outer(nrm[e], nrm[e])
        Ks += eta * k[e] * B.T @ P @ B
    d0 = f0 / k
    return {"k": k, "b": b, "Ks": Ks, "d0": d0, "Wpre": f0 @ b}


def spec_forces(model, W):
    """Normal forces at cuff wrench W (6,) by the active-set equations (docs/model.md section 4)."""
    k, b, Ks, d0 = model["k"], model["b"], model["Ks"], model["d0"]
    S = np.ones(len(k), dtype=bool)
    for _ in range(60):
        H = Ks + (b[S].T * k[S]) @ b[S]
        u = np.linalg.solve(H, W + model["Wpre"] - (k[S] * d0[S]) @ b[S])
        g = d0 + b @ u
        if np.array_equal(g > 0, S):
            break
        S = g > 0
    else:  # pragma: no cover - a failure of this reference, not of the code under test
        raise AssertionError("reference active-set loop did not settle")
    f = k * np.maximum(g, 0.0)
    resid = f @ b + Ks @ u - W - model["Wpre"]
    assert np.max(np.abs(resid)) < 1e-8
    return f


def lc_to_cuff(w_lc):
    R = _rot_x(10.0)
    pos = np.array(CFG["load_cell"]["position"])
    F = R @ w_lc[:3]
    return np.concatenate([F, R @ w_lc[3:] + np.cross(pos, F)])


def cuff_to_lc(W):
    R = _rot_x(10.0)
    pos = np.array(CFG["load_cell"]["position"])
    F = W[:3]
    return np.concatenate([R.T @ F, R.T @ (W[3:] - np.cross(pos, F))])


# --------------------------------------------------------------------------- writing trials
def write_trial(path, conditions, *, rows=4, gap=2, labels=LABELS, extra=None, drop=()):
    """A trial CSV: for each (name, wrench_lc (6,), loads (n,)) ``rows`` identical rows,
    ``gap`` transition rows with an empty condition between windows."""
    recs = []
    t = 0.0
    for i, (name, wlc, loads) in enumerate(conditions):
        if i:
            for _ in range(gap):
                recs.append([t, *np.asarray(wlc) * 0.5, *np.zeros(len(labels)), ""])
                t += 0.01
        for _ in range(rows):
            recs.append([t, *wlc, *loads, name])
            t += 0.01
    df = pd.DataFrame(recs, columns=COLS + list(labels) + ["condition"])
    for c in drop:
        del df[c]
    for k, v in (extra or {}).items():
        df[k] = v
    df.to_csv(path, index=False)
    return path


def write_manifest(folder, entries, baseline=None):
    data = {"trials": entries}
    if baseline is not None:
        data["baseline"] = baseline
    p = Path(folder) / "manifest.yaml"
    p.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    return p


def three_conditions():
    """Load-cell wrenches of no_load, L1, L2 (a nonzero baseline wrench on purpose)."""
    base = cuff_to_lc(np.array([0.5, 4.0, -3.0, 0.02, -0.05, 0.01]))
    l1 = cuff_to_lc(np.array([0.5, 4.0, 9.0, 0.02, -0.17, 0.01]))
    l2 = cuff_to_lc(np.array([1.5, 12.0, 21.0, 0.05, -0.3, 0.03]))
    return [("no_load", base), ("L1", l1), ("L2", l2)]


# --------------------------------------------------------------------------- hand-made cases
def test_measured_equal_to_rigid_model_gives_zero_rmse_for_rigid(cfg_path, tmp_path):
    rigid = spec_model("rigid")
    conds = three_conditions()
    offset = np.linspace(0.3, 2.0, 21)          # FSR zero offset, removed by zeroing
    rows = [(n, w, spec_forces(rigid, lc_to_cuff(w)) + offset) for n, w in conds]
    write_trial(tmp_path / "t1.csv", rows)
    man = write_manifest(tmp_path, [{"file": "t1.csv", "experiment": "E", "direction": "h",
                                     "trial": 1}])
    res = compare(cfg_path, man)
    r = res.rmse.set_index(["condition", "arm"])["rmse_N"]
    assert list(res.rmse["condition"].unique()) == ["L1", "L2"]     # baseline left out
    assert r["L1", "rigid"] < 1e-9 and r["L2", "rigid"] < 1e-9
    assert r["L1", "compliant"] > 0.05 and r["L2", "compliant"] > 0.05


def test_simulation_is_zeroed_on_the_baseline_wrench_not_on_zero(cfg_path, tmp_path):
    comp = spec_model("compliant")
    conds = three_conditions()
    f_base = spec_forces(comp, lc_to_cuff(conds[0][1]))
    f_zero = spec_forces(comp, np.zeros(6))
    assert np.max(np.abs(f_base - f_zero)) > 0.2          # the baseline wrench matters
    rows = [(n, w, spec_forces(comp, lc_to_cuff(w)) - f_base + 5.0) for n, w in conds]
    write_trial(tmp_path / "t1.csv", rows)
    man = write_manifest(tmp_path, [{"file": "t1.csv", "experiment": "E", "direction": "h",
                                     "trial": 1}])
    res = compare(cfg_path, man, arms="compliant")
    assert res.rmse["rmse_N"].max() < 1e-9
    assert list(res.rmse["arm"].unique()) == ["compliant"]


def test_constant_measurement_offset_does_not_change_rmse(cfg_path, tmp_path):
    rng = np.random.default_rng(11)
    conds = three_conditions()
    loads = [rng.uniform(0, 8, 21) for _ in conds]
    offset = rng.uniform(-3, 3, 21)
    write_trial(tmp_path / "a.csv", [(n, w, f) for (n, w), f in zip(conds, loads)])
    write_trial(tmp_path / "b.csv", [(n, w, f + offset) for (n, w), f in zip(conds, loads)])
    ra = compare(cfg_path, write_manifest(tmp_path, [
        {"file": "a.csv", "experiment": "E", "direction": "h", "trial": 1}])).rmse
    rb = compare(cfg_path, write_manifest(tmp_path, [
        {"file": "b.csv", "experiment": "E", "direction": "h", "trial": 1}])).rmse
    np.testing.assert_allclose(ra["rmse_N"], rb["rmse_N"], atol=1e-9)
    # and measured zeroing is real: the RMSE equals one computed by hand from zeroed loads
    comp = spec_model("compliant")
    f = [spec_forces(comp, lc_to_cuff(w)) for _, w in conds]
    want = math.sqrt(np.sum(((loads[2] - loads[0]) - (f[2] - f[0])) ** 2) / 21)
    got = ra.set_index(["condition", "arm"]).loc[("L2", "compliant"), "rmse_N"]
    assert got == pytest.approx(want, abs=1e-9)


def test_summary_mean_and_se_over_three_trials(cfg_path, tmp_path):
    # three trials whose L1 RMSE (rigid) is 1, 2 and 4 N: a uniform error of c N on every
    # element gives RMSE c. SE = sqrt(7)/3 (worked out in test_metrics).
    rigid = spec_model("rigid")
    conds = three_conditions()[:2]
    f = [spec_forces(rigid, lc_to_cuff(w)) for _, w in conds]
    entries = []
    for t, c in enumerate((1.0, 2.0, 4.0), start=1):
        write_trial(tmp_path / f"t{t}.csv", [("no_load", conds[0][1], f[0]),
                                             ("L1", conds[1][1], f[1] + c)])
        entries.append({"file": f"t{t}.csv", "experiment": "E", "direction": "h", "trial": t})
    res = compare(cfg_path, write_manifest(tmp_path, entries), arms=["rigid"])
    np.testing.assert_allclose(res.rmse["rmse_N"], [1.0, 2.0, 4.0], atol=1e-9)
    row = res.summary.iloc[0]
    assert row["mean_rmse_N"] == pytest.approx(7.0 / 3.0, abs=1e-9)
    assert row["se_rmse_N"] == pytest.approx(math.sqrt(7.0) / 3.0, abs=1e-9)
    assert row["n_trials"] == 3
    assert list(res.summary.columns[:7]) == ["experiment", "direction", "condition", "arm",
                                             "mean_rmse_N", "se_rmse_N", "n_trials"]


def test_load_is_magnitude_of_force_change(cfg_path, tmp_path):
    # cuff-frame forces (0,0,1) -> (3,0,5): |(3,0,4)| = 5 N whatever the load-cell rotation
    base = cuff_to_lc(np.array([0.0, 0.0, 1.0, 0, 0, 0]))
    l1 = cuff_to_lc(np.array([3.0, 0.0, 5.0, 0, 0, 0]))
    write_trial(tmp_path / "t.csv", [("no_load", base, np.ones(21)), ("L1", l1, np.ones(21))])
    res = compare(cfg_path, write_manifest(tmp_path, [
        {"file": "t.csv", "experiment": "E", "direction": "h", "trial": 1}]))
    assert res.summary["load_N"].iloc[0] == pytest.approx(5.0, abs=1e-9)
    assert "| E | h | L1 | 5.0 |" in summary_markdown(res)


def test_conditions_keep_order_and_windows_are_pooled(cfg_path, tmp_path):
    w0, w1, w2 = (w for _, w in three_conditions())
    loads_a, loads_b = np.full(21, 2.0), np.full(21, 4.0)
    # L2 appears before L1, and no_load comes back at the end with different loads
    write_trial(tmp_path / "t.csv", [("no_load", w0, loads_a), ("L2", w2, np.ones(21)),
                                     ("L1", w1, np.ones(21)), ("no_load", w0, loads_b)])
    res = compare(cfg_path, write_manifest(tmp_path, [
        {"file": "t.csv", "experiment": "E", "direction": "h", "trial": 1}]))
    assert list(dict.fromkeys(res.rmse["condition"])) == ["L2", "L1"]
    tc = res.trials[0]
    assert tc.conditions == ("no_load", "L2", "L1")
    np.testing.assert_allclose(tc.data.loads[0], 3.0)        # mean of both no_load windows
    assert tc.data.n_samples.tolist() == [8, 4, 4]


def test_per_trial_baseline_and_loads_table(cfg_path, tmp_path):
    conds = three_conditions()
    write_trial(tmp_path / "a.csv", [(n, w, np.full(21, 1.0 + i)) for i, (n, w) in
                                     enumerate(conds)])
    pass_conds = [("start", conds[0][1], np.full(21, 1.0)), ("max", conds[2][1], np.ones(21))]
    write_trial(tmp_path / "b.csv", pass_conds)
    man = write_manifest(tmp_path, [
        {"file": "a.csv", "experiment": "I-Act", "direction": "h", "trial": 1},
        {"file": "b.csv", "experiment": "II-Pass", "direction": "v", "trial": 1,
         "baseline": "start"}])
    res = compare(cfg_path, man)
    assert len(res.loads) == (3 + 2) * 21
    base_rows = res.loads[res.loads["is_baseline"]]
    assert set(base_rows["condition"]) == {"no_load", "start"}
    assert np.all(base_rows[["measured_N", "rigid_N", "compliant_N"]].to_numpy() == 0.0)
    l2 = res.loads[(res.loads["condition"] == "L2")]
    np.testing.assert_allclose(l2["measured_N"], 2.0)          # 3 N minus the 1 N baseline
    np.testing.assert_allclose(l2["measured_abs_N"], 3.0)
    for c in ("Fx", "Fy", "Fz", "Mx", "My", "Mz", "element", "row", "location", "rigid_abs_N"):
        assert c in res.loads.columns
    np.testing.assert_allclose(l2["Fz"], conds[2][1][2])


# --------------------------------------------------------------------------- errors
def test_bad_inputs_raise_one_line_errors(cfg_path, tmp_path):
    conds = three_conditions()
    good = [(n, w, np.ones(21)) for n, w in conds]

    def run(entries, baseline=None):
        return compare(cfg_path, write_manifest(tmp_path, entries, baseline))

    e = {"file": "t.csv", "experiment": "E", "direction": "h", "trial": 1}
    write_trial(tmp_path / "t.csv", good)
    with pytest.raises(DataError, match=r"baseline condition 'rest' not found"):
        run([e], baseline="rest")
    write_trial(tmp_path / "t.csv", good, drop=["B3"])
    with pytest.raises(DataError, match=r"t\.csv: B3: missing element column"):
        run([e])
    write_trial(tmp_path / "t.csv", good, extra={"C7": 0.0})
    with pytest.raises(DataError, match=r"t\.csv: C7: element column not in the config"):
        run([e])
    write_trial(tmp_path / "t.csv", good, drop=["condition"])
    with pytest.raises(DataError, match=r"t\.csv: condition: missing column 'condition'"):
        run([e])
    with pytest.raises(ConfigError, match=r"trials\[0\]\.trail: unknown key 'trail'.*"
                                          r"did you mean 'trial'"):
        run([{"file": "t.csv", "experiment": "E", "direction": "h", "trail": 1}])
    with pytest.raises(ConfigError, match=r"trials\[1\]\.trial: .*listed twice"):
        write_trial(tmp_path / "t.csv", good)
        run([e, dict(e)])
    with pytest.raises(DataError, match=r"nope\.csv: trial file not found"):
        run([dict(e, file="nope.csv")])
    with pytest.raises(UsageError):
        parse_arms("rigid,stiff")


def test_nan_or_text_in_window_is_an_error_but_not_between_windows(cfg_path, tmp_path):
    conds = three_conditions()
    write_trial(tmp_path / "t.csv", [(n, w, np.ones(21)) for n, w in conds])
    df = pd.read_csv(tmp_path / "t.csv", dtype=str, keep_default_na=False)
    gap = df.index[df["condition"] == ""][0]
    df.loc[gap, "A2"] = "garbage"                    # between windows: ignored
    df.to_csv(tmp_path / "t.csv", index=False)
    man = write_manifest(tmp_path, [{"file": "t.csv", "experiment": "E", "direction": "h",
                                     "trial": 1}])
    compare(cfg_path, man)
    row = df.index[df["condition"] == "L1"][1]
    df.loc[row, "A2"] = ""
    df.to_csv(tmp_path / "t.csv", index=False)
    with pytest.raises(DataError, match=rf"t\.csv: A2: condition 'L1', line {row + 2}: "
                                        "expected a finite number"):
        compare(cfg_path, man)
    df.loc[row, "A2"] = "1.0"
    df.loc[row, "Fz"] = "abc"
    df.to_csv(tmp_path / "t.csv", index=False)
    with pytest.raises(DataError, match=r"t\.csv: Fz: condition 'L1', .*got 'abc'"):
        compare(cfg_path, man)


def test_manifest_errors(tmp_path):
    with pytest.raises(ConfigError, match="file not found"):
        load_manifest(tmp_path / "missing.yaml")
    p = tmp_path / "m.yaml"
    p.write_text("baseline: no_load\ntrails: []\n")
    with pytest.raises(ConfigError, match=r"unknown key 'trails'.*did you mean 'trials'"):
        load_manifest(p)
    p.write_text("trials: []\n")
    with pytest.raises(ConfigError, match=r"trials: expected a non-empty list"):
        load_manifest(p)
    p.write_text("trials:\n  - {file: a.csv, experiment: E, trial: 1}\n")
    with pytest.raises(ConfigError, match=r"trials\[0\]\.direction: missing required key"):
        load_manifest(p)
    with pytest.raises(ValueError):
        read_trial(tmp_path / "a.csv", LABELS)       # neither a TrialSpec nor a baseline


# --------------------------------------------------------------------------- figures
def _summary_two_panels():
    rows = []
    for exp, direc, conds, loads in (("I-Act", "horizontal", ("L1", "L2", "L3"),
                                      (11.1, 33.4, 55.6)),
                                     ("II-Pass", "vertical", ("min", "mid", "max"),
                                      (5.0, 11.0, 18.0))):
        for c, load in zip(conds, loads):
            for arm, m in (("rigid", 2.0), ("compliant", 1.0)):
                rows.append((exp, direc, c, arm, m * load / 10, 0.1, 3, load))
    return pd.DataFrame(rows, columns=["experiment", "direction", "condition", "arm",
                                       "mean_rmse_N", "se_rmse_N", "n_trials", "load_N"])


def test_rmse_bars_figure_panels():
    fig = rmse_bars_figure(_summary_two_panels())
    axes = fig.axes
    assert len(axes) == 2
    assert [ax.get_title() for ax in axes] == ["I-Act, horizontal", "II-Pass, vertical"]
    assert all(ax.get_ylabel() == "RMSE [N]" for ax in axes)
    ticks = [t.get_text() for t in axes[0].get_xticklabels()]
    assert ticks == ["L1\n11.1 N", "L2\n33.4 N", "L3\n55.6 N"]
    # 3 conditions x 2 arms = 6 bars per panel, rigid bar of L2 = 2 * 33.4 / 10
    bars = axes[0].patches
    assert len(bars) == 6
    assert max(b.get_height() for b in bars) == pytest.approx(2 * 55.6 / 10)
    legend = fig.legends[0]
    assert [t.get_text() for t in legend.get_texts()] == ["Rigid arm", "Compliant arm"]


def test_heatmap_figure_panels_and_shared_symmetric_scale():
    meas = np.linspace(-2.0, 6.0, 21)
    meas[3] = -0.01
    sim = {"rigid": np.linspace(-1.0, 9.0, 21), "compliant": np.linspace(-3.0, 3.0, 21)}
    fig = heatmap_figure(meas, sim, row_labels=ROWS, n_angles=7, title="E h, trial 1, L1\nFx +1",
                         rmse={"rigid": 2.5, "compliant": 0.75})
    axes = fig.axes
    assert len(axes) == 4                                         # 3 maps + the colour bar
    titles = [ax.get_title() for ax in axes[:3]]
    assert titles[0].startswith("Measured")
    assert titles[1] == "Rigid arm\nRMSE 2.50 N" and titles[2] == "Compliant arm\nRMSE 0.75 N"
    assert axes[3].get_ylabel() == "zeroed load [N]"
    cells = [ax.collections[0] for ax in axes[:3]]                # one quad mesh per map
    clims = {c.get_clim() for c in cells}
    assert clims == {(-9.0, 9.0)}                                 # one scale, centred on 0
    assert all(c.get_cmap().name == "RdBu_r" for c in cells)
    texts = [t.get_text() for t in axes[1].texts]
    assert len(texts) == 21 and texts[0] == "-1.0" and texts[-1] == "9.0"
    assert axes[0].texts[3].get_text() == "0.0"                  # never "-0.0"
    assert [t.get_text() for t in axes[0].get_yticklabels()] == list(ROWS)
    assert [t.get_text() for t in axes[0].get_xticklabels()] == [str(i) for i in range(7)]
    np.testing.assert_array_equal(np.asarray(cells[0].get_array()).reshape(3, 7),
                                  meas.reshape(3, 7))             # the loads, row A first
    assert axes[0].yaxis_inverted()                               # row A on top
    assert fig._suptitle.get_text().startswith("E h, trial 1, L1")


def test_wrench_figure_panels():
    t = np.arange(10) * 0.1
    w = np.outer(np.arange(10), np.ones(6))
    cond = ["no_load"] * 4 + ["", ""] + ["L1"] * 4
    fig = wrench_figure(t, w, cond, title="E h, trial 1")
    ax_f, ax_m = fig.axes
    assert ax_f.get_ylabel() == "force [N]" and ax_m.get_ylabel() == "moment [N·m]"
    assert [ln.get_label() for ln in ax_f.lines] == ["Fx", "Fy", "Fz"]
    assert [ln.get_label() for ln in ax_m.lines] == ["Mx", "My", "Mz"]
    assert [x.get_text() for x in ax_f.texts] == ["no_load", "L1"]


def test_write_compare_writes_every_figure(cfg_path, tmp_path):
    conds = three_conditions()
    entries = []
    for t in (1, 2):
        write_trial(tmp_path / f"t{t}.csv", [(n, w, np.full(21, float(i + t))) for i, (n, w)
                                             in enumerate(conds)])
        entries.append({"file": f"t{t}.csv", "experiment": "I Act", "direction": "h",
                        "trial": t})
    res = compare(cfg_path, write_manifest(tmp_path, entries))
    out = tmp_path / "out"
    write_compare(res, out, dpi=60)
    heat = sorted(p.name for p in (out / "heatmaps").iterdir())
    assert heat == ["I-Act_h_1_L1.png", "I-Act_h_1_L2.png", "I-Act_h_2_L1.png",
                    "I-Act_h_2_L2.png"]
    assert sorted(p.name for p in (out / "wrench").iterdir()) == ["I-Act_h_1.png",
                                                                  "I-Act_h_2.png"]
    # the pressure around the limb where each arm predicts its highest pressure
    assert sorted(p.name for p in (out / "sections").iterdir()) == ["compliant_peak.png",
                                                                    "rigid_peak.png"]
    for name in ("rmse.csv", "summary.csv", "loads.csv", "conditions.csv", "rmse_bars.png",
                 "report.md"):
        assert (out / name).stat().st_size > 0
    report = (out / "report.md").read_text()
    assert summary_markdown(res) in report
    assert "](heatmaps/I-Act_h_2_L2.png)" in report and "](rmse_bars.png)" in report
    assert list(pd.read_csv(out / "rmse.csv").columns[:6]) == ["experiment", "direction",
                                                               "condition", "trial", "arm",
                                                               "rmse_N"]
    # a failure while writing leaves no folder behind
    import phri_spring.reports.compare.figures as figs

    def boom(*a, **k):
        raise RuntimeError("figure failed")

    orig = figs.HeatmapRenderer.fill          # heat maps are drawn by a reused renderer
    figs.HeatmapRenderer.fill = boom
    try:
        with pytest.raises(RuntimeError):
            write_compare(res, tmp_path / "out2")
    finally:
        figs.HeatmapRenderer.fill = orig
    assert not (tmp_path / "out2").exists()
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".out2")]
    with pytest.raises(UsageError, match="contains the input"):
        write_compare(res, tmp_path)


# --------------------------------------------------------------------------- end to end
def test_end_to_end_against_independent_spec_computation(cfg_path, tmp_path):
    exp_dir = tmp_path / "exp"
    manifest = make_experiment(cfg_path, exp_dir, seed=7, trials=3, window_s=0.25,
                               transition_s=0.1,
                               experiments=(("I-Act", "horizontal"), ("II-Pass", "vertical")))
    res = compare(cfg_path, manifest)
    out = tmp_path / "cmp"
    write_compare(res, out, figures=False)
    got_rmse = pd.read_csv(out / "rmse.csv")
    got_sum = pd.read_csv(out / "summary.csv")

    # --- independent computation from the docs/model.md formulas
    man = yaml.safe_load(manifest.read_text())
    models = {arm: spec_model(arm) for arm in ("rigid", "compliant")}
    want = []
    for t in man["trials"]:
        base = t.get("baseline", man.get("baseline", "no_load"))
        df = pd.read_csv(exp_dir / t["file"])
        cond = df["condition"].fillna("").astype(str)
        names = list(dict.fromkeys(c for c in cond if c))
        meas = {c: df.loc[cond == c, list(LABELS)].to_numpy().mean(axis=0) for c in names}
        wlc = {c: df.loc[cond == c, COLS[1:]].to_numpy().mean(axis=0) for c in names}
        for arm, model in models.items():
            sim = {c: spec_forces(model, lc_to_cuff(wlc[c])) for c in names}
            for c in names:
                if c == base:
                    continue
                d = (meas[c] - meas[base]) - (sim[c] - sim[base])
                want.append((t["experiment"], t["direction"], c, t["trial"], arm,
                             math.sqrt(np.sum(d ** 2) / 21)))
    want = pd.DataFrame(want, columns=["experiment", "direction", "condition", "trial", "arm",
                                       "rmse_N"])
    key = ["experiment", "direction", "condition", "trial", "arm"]
    merged = want.merge(got_rmse, on=key, suffixes=("_want", "_got"), how="outer")
    assert len(merged) == len(want) == len(got_rmse) == 2 * 3 * 3 * 2
    np.testing.assert_allclose(merged["rmse_N_got"], merged["rmse_N_want"], atol=1e-5, rtol=0)
    assert set(got_rmse["condition"]) == {"L1", "L2", "L3", "min", "mid", "max"}

    rows = []
    for k, g in want.groupby(["experiment", "direction", "condition", "arm"], sort=False):
        v = g["rmse_N"].to_numpy()
        sd = math.sqrt(np.sum((v - v.mean()) ** 2) / (len(v) - 1))
        rows.append((*k, v.mean(), sd / math.sqrt(len(v)), len(v)))
    want_sum = pd.DataFrame(rows, columns=["experiment", "direction", "condition", "arm",
                                           "mean_rmse_N", "se_rmse_N", "n_trials"])
    m = want_sum.merge(got_sum, on=["experiment", "direction", "condition", "arm"],
                       suffixes=("_want", "_got"), how="outer")
    assert len(m) == len(want_sum) == len(got_sum) == 2 * 3 * 2
    np.testing.assert_allclose(m["mean_rmse_N_got"], m["mean_rmse_N_want"], atol=1e-5, rtol=0)
    np.testing.assert_allclose(m["se_rmse_N_got"], m["se_rmse_N_want"], atol=1e-5, rtol=0)
    assert (m["n_trials_got"] == 3).all()
    # the synthetic truth is compliant: the compliant arm must fit better at the largest load
    s = got_sum.set_index(["condition", "arm"])["mean_rmse_N"]
    assert s["L3", "compliant"] < s["L3", "rigid"]
