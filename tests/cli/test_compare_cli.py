"""`phri compare` on the command line: outputs, summary on stdout, bad input and usage."""

from __future__ import annotations
from support.helpers import REPO  # noqa: E402

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

from support.helpers import assert_one_line_error, run_phri as run, stderr_of

ROOT = REPO
CONFIG = ROOT / "configs" / "harmony_upper_arm.yaml"
LABELS = [f"{r}{j}" for r in "ABC" for j in range(7)]
WRENCH = ["Fx", "Fy", "Fz", "Mx", "My", "Mz"]


def _trial_frame(conditions, rows=5, gap=2):
    """conditions: list of (name, wrench (6,), loads (21,)); empty condition between windows."""
    recs, t = [], 0.0
    for i, (name, w, f) in enumerate(conditions):
        for _ in range(gap if i else 0):
            recs.append([t, *w, *f, ""])
            t += 0.01
        for _ in range(rows):
            recs.append([t, *w, *f, name])
            t += 0.01
    return pd.DataFrame(recs, columns=["time"] + WRENCH + LABELS + ["condition"])


@pytest.fixture
def experiment(tmp_path):
    """A two-trial I-Act-like experiment in tmp_path/exp; returns the manifest path."""
    exp = tmp_path / "exp"
    exp.mkdir()
    rng = np.random.default_rng(5)
    entries = []
    for t in (1, 2):
        conds = [("no_load", np.zeros(6), rng.uniform(2, 4, 21))]
        for k, load in enumerate((11.1, 33.4), start=1):
            w = np.array([0.0, 0.0, load, 0.07 * load, 0.0, 0.0])     # along load-cell z
            conds.append((f"L{k}", w, conds[0][2] + rng.uniform(-1, 3, 21) * load / 11.1))
        _trial_frame(conds).to_csv(exp / f"h{t}.csv", index=False)
        entries.append({"file": f"h{t}.csv", "experiment": "I-Act", "direction": "horizontal",
                        "trial": t})
    m = exp / "manifest.yaml"
    m.write_text(yaml.safe_dump({"baseline": "no_load", "trials": entries}, sort_keys=False))
    return m


def no_leftovers(folder: Path, name: str = "out"):
    assert not (folder / name).exists()
    assert not [p for p in folder.iterdir() if p.name.startswith(f".{name}.")]


# --------------------------------------------------------------------------- success
def test_compare_writes_outputs_and_prints_summary(experiment, tmp_path):
    out = tmp_path / "out"
    r = run("compare", CONFIG, experiment, "-o", out, "--dpi", 60)
    assert r.exit_code == 0, stderr_of(r)
    for name in ("rmse.csv", "summary.csv", "loads.csv", "conditions.csv", "report.md",
                 "rmse_bars.png"):
        assert (out / name).is_file(), name
    heat = sorted(p.name for p in (out / "heatmaps").glob("*.png"))
    assert heat == ["I-Act_horizontal_1_L1.png", "I-Act_horizontal_1_L2.png",
                    "I-Act_horizontal_2_L1.png", "I-Act_horizontal_2_L2.png"]
    rmse = pd.read_csv(out / "rmse.csv")
    assert list(rmse.columns[:6]) == ["experiment", "direction", "condition", "trial", "arm",
                                      "rmse_N"]
    assert len(rmse) == 2 * 2 * 2 and "no_load" not in set(rmse["condition"])
    summary = pd.read_csv(out / "summary.csv")
    assert list(summary.columns[:7]) == ["experiment", "direction", "condition", "arm",
                                         "mean_rmse_N", "se_rmse_N", "n_trials"]
    assert (summary["n_trials"] == 2).all()
    # stdout holds the same table as report.md
    table = r.stdout.strip()
    assert table.startswith("| experiment | direction | condition | load [N] |")
    assert table in (out / "report.md").read_text()
    assert "| I-Act | horizontal | L2 | 33.4 |" in table
    assert "wrote" in stderr_of(r)


def test_compare_options_arms_no_figures_quiet(experiment, tmp_path):
    out = tmp_path / "out"
    r = run("compare", CONFIG, experiment, "-o", out, "--arms", "compliant", "--no-figures",
            "-q")
    assert r.exit_code == 0, stderr_of(r)
    assert r.stdout == "" and stderr_of(r) == ""
    assert not (out / "rmse_bars.png").exists() and not (out / "heatmaps").exists()
    assert set(pd.read_csv(out / "rmse.csv")["arm"]) == {"compliant"}
    assert "rigid_N" not in pd.read_csv(out / "loads.csv").columns


def test_compare_tissue_stiffness_override(experiment, tmp_path):
    csv = tmp_path / "k.csv"
    rows = [f"{lab},{lab[0]},{lab[1:]},{8000.0},0,3" for lab in LABELS]
    csv.write_text("location,row,angle_index,stiffness_N_per_m,std_N_per_m,n_trials\n"
                   + "\n".join(rows) + "\n")
    a = run("compare", CONFIG, experiment, "-o", tmp_path / "a", "--no-figures", "-q")
    b = run("compare", CONFIG, experiment, "-o", tmp_path / "b", "--no-figures", "-q",
            "--tissue-stiffness", csv)
    assert a.exit_code == 0 and b.exit_code == 0, stderr_of(b)
    ra, rb = (pd.read_csv(tmp_path / x / "rmse.csv") for x in "ab")
    comp = ra["arm"] == "compliant"
    np.testing.assert_allclose(ra.loc[~comp, "rmse_N"], rb.loc[~comp, "rmse_N"])  # rigid: no tissue
    assert np.max(np.abs(ra.loc[comp, "rmse_N"].to_numpy() - rb.loc[comp, "rmse_N"].to_numpy())) \
        > 1e-3
    r = run("compare", CONFIG, experiment, "-o", tmp_path / "c", "--tissue-stiffness",
            tmp_path / "nope.csv")
    assert_one_line_error(r, "nope.csv", "--tissue-stiffness")
    no_leftovers(tmp_path, "c")


def test_help_has_units_and_example():
    r = run("compare", "--help")
    assert r.exit_code == 0
    for s in ("MANIFEST", "[N]", "[s]", "Example:", "phri compare configs/harmony_upper_arm.yaml",
              "--arms", "--no-figures", "--tissue-stiffness"):
        assert s in r.output, s


def test_bundled_example_manifest_is_valid():
    # the bundled example must run with the bundled config (reading only: fast)
    from phri_spring.io.config import load_config
    from phri_spring.io.recordings.experiment import load_manifest, read_trial

    cfg = load_config(CONFIG)
    man = load_manifest(ROOT / "examples" / "experiment" / "manifest.yaml")
    assert len(man.trials) == 12
    seen = {(t.experiment, t.direction) for t in man.trials}
    assert seen == {("I-Act", "horizontal"), ("I-Act", "vertical"), ("II-Pass", "horizontal"),
                    ("II-Pass", "vertical")}
    d = read_trial(man.trials[0], cfg.labels)
    assert d.conditions == ("no_load", "L1", "L2", "L3")
    # horizontal I-Act loads along load-cell z: 11.1, 33.4, 55.6 N above no_load
    np.testing.assert_allclose(d.wrench[1:, 2] - d.wrench[0, 2], [11.1, 33.4, 55.6], atol=0.3)
    p = [t for t in man.trials if t.experiment == "II-Pass"][0]
    assert p.baseline == "start"
    assert read_trial(p, cfg.labels).conditions == ("start", "min", "mid", "max")
    size = sum(f.stat().st_size for f in (ROOT / "examples" / "experiment").iterdir())
    assert size < 3.2e6


# --------------------------------------------------------------------------- bad input: exit 1
def _rewrite(path: Path, fn):
    df = pd.read_csv(path, dtype=str, keep_default_na=False)
    df = fn(df)
    df.to_csv(path, index=False)


def test_missing_manifest(tmp_path):
    r = run("compare", CONFIG, tmp_path / "nope.yaml", "-o", tmp_path / "out")
    assert_one_line_error(r, "nope.yaml", "not found")
    no_leftovers(tmp_path)


def test_missing_trial_file(experiment, tmp_path):
    (experiment.parent / "h2.csv").unlink()
    r = run("compare", CONFIG, experiment, "-o", tmp_path / "out")
    assert_one_line_error(r, "h2.csv", "trial file not found", "trials[1].file")
    no_leftovers(tmp_path)


def test_trial_without_condition_column(experiment, tmp_path):
    _rewrite(experiment.parent / "h1.csv", lambda df: df.drop(columns=["condition"]))
    r = run("compare", CONFIG, experiment, "-o", tmp_path / "out")
    assert_one_line_error(r, "h1.csv: condition:", "missing column 'condition'")
    no_leftovers(tmp_path)


def test_baseline_condition_absent(experiment, tmp_path):
    def rename(df):
        df.loc[df["condition"] == "no_load", "condition"] = "rest"
        return df
    _rewrite(experiment.parent / "h2.csv", rename)
    r = run("compare", CONFIG, experiment, "-o", tmp_path / "out")
    assert_one_line_error(r, "h2.csv: condition:", "baseline condition 'no_load' not found",
                          "rest, L1, L2")
    no_leftovers(tmp_path)


def test_element_column_missing(experiment, tmp_path):
    _rewrite(experiment.parent / "h1.csv", lambda df: df.drop(columns=["C4"]))
    r = run("compare", CONFIG, experiment, "-o", tmp_path / "out")
    assert_one_line_error(r, "h1.csv: C4:", "missing element column")
    no_leftovers(tmp_path)


def test_element_column_extra(experiment, tmp_path):
    _rewrite(experiment.parent / "h1.csv", lambda df: df.assign(D0="1.0"))
    r = run("compare", CONFIG, experiment, "-o", tmp_path / "out")
    assert_one_line_error(r, "h1.csv: D0:", "not in the config's geometry")
    no_leftovers(tmp_path)


@pytest.mark.parametrize("value, shown", [("", "an empty cell"), ("nan", "'nan'"),
                                          ("12,5", "'12,5'"), ("n/a", "'n/a'")])
def test_nan_or_text_in_condition_window(experiment, tmp_path, value, shown):
    def poke(df):
        i = df.index[df["condition"] == "L2"][2]
        df.loc[i, "B5"] = value
        return df
    _rewrite(experiment.parent / "h2.csv", poke)
    r = run("compare", CONFIG, experiment, "-o", tmp_path / "out")
    assert_one_line_error(r, "h2.csv: B5:", "condition 'L2'", "expected a finite number",
                          shown)
    no_leftovers(tmp_path)


def test_unknown_manifest_key_suggests_closest(experiment, tmp_path):
    data = yaml.safe_load(experiment.read_text())
    data["trials"][0]["direktion"] = data["trials"][0].pop("direction")
    experiment.write_text(yaml.safe_dump(data))
    r = run("compare", CONFIG, experiment, "-o", tmp_path / "out")
    assert_one_line_error(r, "manifest.yaml: trials[0].direktion:", "did you mean 'direction'")
    no_leftovers(tmp_path)


# --------------------------------------------------------------------------- bad usage: exit 2
def test_bad_arms_is_usage_error(experiment, tmp_path):
    r = run("compare", CONFIG, experiment, "-o", tmp_path / "out", "--arms", "rigid,soft")
    assert_one_line_error(r, "--arms", "'soft'", code=2)
    no_leftovers(tmp_path)


def test_output_must_not_be_or_contain_an_input(experiment, tmp_path):
    before = sorted(p.name for p in experiment.parent.iterdir())
    r = run("compare", CONFIG, experiment, "-o", experiment.parent)
    assert_one_line_error(r, "-o/--output", "contains the input", code=2)
    r = run("compare", CONFIG, experiment, "-o", experiment)
    assert_one_line_error(r, "-o/--output", code=2)
    assert sorted(p.name for p in experiment.parent.iterdir()) == before


def test_missing_arguments_is_usage_error(tmp_path):
    r = run("compare", CONFIG)
    assert r.exit_code == 2
