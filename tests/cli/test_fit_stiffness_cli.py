"""``phri fit-stiffness`` end to end: recovery on unseen data, bad inputs, plots, config use.

The truth is the generator's stiffness map (phri_spring.synthetic.indenter), drawn
with seeds other than the bundled example's; the recovered values are compared
with it, never with the command's own earlier output.
"""

from __future__ import annotations
from support.helpers import REPO  # noqa: E402

import importlib
import re
import shutil
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from click.testing import CliRunner

from phri_spring.synthetic.indenter import synth_dataset, synth_trial, truth_map, write_trials

try:
    from phri_cli.main import phri
except ModuleNotFoundError:  # not installed: the cli/ folder is the phri_cli package
    sys.path.insert(0, str(REPO))
    sys.modules["phri_cli"] = importlib.import_module("cli")
    from phri_cli.main import phri

REPO = REPO
EXAMPLE = REPO / "examples" / "indenter"
EXAMPLE_TRUTH = REPO / "examples" / "indenter_truth.csv"
HARMONY = REPO / "configs" / "harmony_upper_arm.yaml"
LABELS = [f"{r}{j}" for r in "ABC" for j in range(7)]
SPEC_COLUMNS = ["location", "row", "angle_index", "stiffness_N_per_m", "std_N_per_m",
                "n_trials"]


def run(*args):
    return CliRunner().invoke(phri, ["fit-stiffness", *map(str, args)])


def one_line(text: str) -> bool:
    return bool(text.strip()) and "\n" not in text.strip("\n")


@pytest.fixture(scope="module")
def unseen(tmp_path_factory):
    """21 locations x 2 trials, 100-500 Hz, seeds unlike the bundled example's."""
    truth = truth_map(seed=31)
    trials = synth_dataset(truth, seed=555, rates=(100.0, 173.0, 250.0, 333.0, 500.0))
    base = tmp_path_factory.mktemp("unseen")
    write_trials(trials, base / "folder", layout="folder")
    write_trials(trials, base / "long.csv", layout="long")
    write_trials(trials, base / "long_m.csv", layout="long", displacement_unit="m")
    write_trials(trials[:8], base / "folder_m", layout="folder", displacement_unit="m")
    return truth, base, trials


def assert_recovered(csv_path, truth, n_trials=2):
    table = pd.read_csv(csv_path)
    assert list(table.columns[:6]) == SPEC_COLUMNS
    assert list(table["location"]) == list(truth)
    rel = table["stiffness_N_per_m"].to_numpy() / np.array(list(truth.values())) - 1
    assert np.abs(rel).max() < 0.01, dict(zip(table["location"], rel))
    assert (table["n_trials"] == n_trials).all()
    np.testing.assert_array_equal(table["row"], [lab[0] for lab in truth])
    np.testing.assert_array_equal(table["angle_index"], [int(lab[1:]) for lab in truth])
    return table


# --------------------------------------------------------------------------- recovery


@pytest.mark.parametrize("layout,args", [("folder", []), ("long.csv", []),
                                         ("long_m.csv", ["--displacement-unit", "m"])])
def test_recovers_unseen_stiffness_within_one_percent(unseen, tmp_path, layout, args):
    truth, base, _ = unseen
    out = tmp_path / "k.csv"
    res = run(base / layout, "-o", out, *args)
    assert res.exit_code == 0, res.output
    table = assert_recovered(out, truth)
    # the summary line is the mean and sample SD over the locations
    k = table["stiffness_N_per_m"].to_numpy()
    m = re.search(r"stiffness over 21 locations: (\d+) \+- ([\d.]+) N/m \(mean \+- SD\)",
                  res.stdout)
    assert m, res.stdout
    assert float(m.group(1)) == pytest.approx(k.mean(), abs=0.5)
    assert float(m.group(2)) == pytest.approx(k.std(ddof=1), abs=0.05)
    # the truth map's own mean: 4242 N/m
    assert k.mean() == pytest.approx(4242.0, rel=0.01)
    # std over the two trials is a sample SD: |k1 - k2| / sqrt(2), finite
    assert np.isfinite(table["std_N_per_m"]).all()


def test_folder_in_metres(unseen, tmp_path):
    truth, base, _ = unseen
    out = tmp_path / "k.csv"
    res = run(base / "folder_m", "-o", out, "--displacement-unit", "m")
    assert res.exit_code == 0, res.output
    assert_recovered(out, dict(list(truth.items())[:4]))


def test_bundled_example_recovers_its_truth(tmp_path):
    truth = pd.read_csv(EXAMPLE_TRUTH)
    assert (EXAMPLE / "TRUTH.md").exists()        # ignored by the reader (not *.csv)
    assert len(list(EXAMPLE.glob("*.csv"))) == 42
    res = run(EXAMPLE, "-o", tmp_path / "k.csv")
    assert res.exit_code == 0, res.output
    assert_recovered(tmp_path / "k.csv",
                     dict(zip(truth["location"], truth["true_stiffness_N_per_m"])))
    assert "stiffness over 21 locations: 42" in res.stdout


def test_single_trial_file_and_parquet(unseen, tmp_path):
    truth, base, trials = unseen
    out = tmp_path / "k.csv"
    res = run(base / "folder" / "B4_2.csv", "-o", out)
    assert res.exit_code == 0, res.output
    table = pd.read_csv(out)
    assert list(table["location"]) == ["B4"] and table["n_trials"].tolist() == [1]
    k_true = next(t.stiffness for t in trials if (t.location, t.trial) == ("B4", 2))
    assert table["stiffness_N_per_m"][0] == pytest.approx(k_true, rel=0.01)
    pq = tmp_path / "long.parquet"
    pd.read_csv(base / "long.csv").to_parquet(pq)
    res = run(pq, "-o", out)
    assert res.exit_code == 0, res.output
    assert_recovered(out, truth)


def test_mat_files(tmp_path):
    savemat = pytest.importorskip("scipy.io").savemat
    pytest.importorskip("pymatreader")
    folder = tmp_path / "mat"
    folder.mkdir()
    truth = {"B2": 3900.0, "C5": 4600.0}
    for lab, k in truth.items():
        for trial in (1, 2):
            tr = synth_trial(k, rate=250.0, seed=trial * 100 + int(lab[1]))
            savemat(folder / f"{lab}_{trial}.mat",
                    {"time": tr.time, "displacement": tr.displacement * 1e3, "force": tr.force})
    out = tmp_path / "k.csv"
    res = run(folder, "-o", out)
    assert res.exit_code == 0, res.output
    assert_recovered(out, truth)


def test_mat_without_pymatreader_is_a_clear_error(tmp_path, monkeypatch):
    savemat = pytest.importorskip("scipy.io").savemat
    tr = synth_trial(4000.0, rate=100.0, seed=1)
    folder = tmp_path / "mat"
    folder.mkdir()
    savemat(folder / "A0_1.mat", {"time": tr.time, "displacement": tr.displacement * 1e3,
                                  "force": tr.force})
    monkeypatch.setitem(sys.modules, "pymatreader", None)
    res = run(folder, "-o", tmp_path / "k.csv")
    assert res.exit_code == 1
    assert one_line(res.stderr)
    assert "pymatreader" in res.stderr and "A0_1.mat" in res.stderr


# --------------------------------------------------------------------------- bad inputs


def small_set(folder: Path) -> None:
    truth = {"A0": 4000.0, "A1": 4500.0}
    write_trials(synth_dataset(truth, seed=8, rates=(100.0,)), folder, layout="folder")


def _edit(path: Path, fn) -> None:
    df = pd.read_csv(path, dtype=str, keep_default_na=False)
    new = fn(df)
    (df if new is None else new).to_csv(path, index=False)


def _set(col, row, value):
    def fn(df):
        df.loc[row, col] = value
    return fn


def _case(name, tmp_path):
    folder = tmp_path / "in"
    folder.mkdir()
    small_set(folder)
    bad = folder / "A1_2.csv"
    if name == "missing_folder":
        return tmp_path / "nope", "nope", None
    if name == "empty_folder":
        for p in folder.glob("*.csv"):
            p.unlink()
        (folder / "README.md").write_text("not a trial\n")
        return folder, "in", None
    if name == "bad_name":
        bad.rename(folder / "A1-2.csv")
        return folder, "A1-2.csv", None
    if name == "missing_column":
        _edit(bad, lambda df: df.drop(columns=["force"]))
        return folder, "A1_2.csv", "force"
    if name == "text":
        _edit(bad, _set("force", 20, "abc"))
        return folder, "A1_2.csv", "force"
    if name == "nan":
        _edit(bad, _set("displacement", 30, ""))
        return folder, "A1_2.csv", "displacement"
    if name == "short":
        _edit(bad, lambda df: df.iloc[:200])   # 2 s at 100 Hz
        return folder, "A1_2.csv", "time"
    if name == "no_indentation":
        _edit(bad, lambda df: df.__setitem__("force", "0.5"))
        return folder, "A1_2.csv", "force"
    if name == "time_not_increasing":
        _edit(bad, _set("time", 40, "0.1"))
        return folder, "A1_2.csv", "time"
    long = tmp_path / "long.csv"
    write_trials(synth_dataset({"A0": 4000.0}, seed=9, rates=(100.0,)), long, layout="long")
    if name == "long_missing_column":
        _edit(long, lambda df: df.drop(columns=["trial"]))
        return long, "long.csv", "trial"
    if name == "long_text":
        _edit(long, _set("time", 700, "1O.2"))
        return long, "long.csv", "time"
    if name == "long_bad_location":
        _edit(long, _set("location", 5, "3B"))
        return long, "long.csv", "location"
    raise AssertionError(name)


BAD = ["missing_folder", "empty_folder", "bad_name", "missing_column", "text", "nan", "short",
       "no_indentation", "time_not_increasing", "long_missing_column", "long_text",
       "long_bad_location"]


@pytest.mark.parametrize("name", BAD)
def test_bad_input_is_one_line_exit_1_no_output(tmp_path, name):
    inp, fname, column = _case(name, tmp_path)
    out_dir = tmp_path / "out"
    out_dir.mkdir()
    res = run(inp, "-o", out_dir / "k.csv", "--plots", out_dir / "figs")
    assert res.exit_code == 1, res.output
    assert one_line(res.stderr), res.stderr
    assert "Traceback" not in res.output
    assert fname in res.stderr
    if column:
        assert f": {column}: " in res.stderr
    assert list(out_dir.iterdir()) == []          # nothing left behind, not even temp files


def test_error_names_the_line_of_the_text(tmp_path):
    inp, _, _ = _case("text", tmp_path)
    res = run(inp, "-o", tmp_path / "k.csv")
    # row index 20 is line 22 of the file (header on line 1)
    assert "line 22" in res.stderr and "'abc'" in res.stderr


@pytest.mark.parametrize("name", ["text", "short", "no_indentation", "bad_name"])
def test_skip_bad_trials_shows_in_n_trials(tmp_path, name):
    inp, fname, _ = _case(name, tmp_path)
    out = tmp_path / "k.csv"
    res = run(inp, "-o", out, "--skip-bad-trials")
    assert res.exit_code == 0, res.output
    assert "warning: skipped" in res.stderr and fname in res.stderr
    table = pd.read_csv(out).set_index("location")
    assert table.loc["A0", "n_trials"] == 2
    assert table.loc["A1", "n_trials"] == 1
    assert np.isnan(table.loc["A1", "std_N_per_m"])
    assert table.loc["A1", "n_trials_skipped"] == (0 if name == "bad_name" else 1)
    assert "single_trial" in table.loc["A1", "flags"]
    assert table.loc["A1", "stiffness_N_per_m"] == pytest.approx(4500.0, rel=0.03)


def test_all_trials_bad_is_an_error_even_when_skipping(tmp_path):
    folder = tmp_path / "in"
    folder.mkdir()
    pd.DataFrame({"time": [0, 1, 2], "displacement": [0, 0, 0], "force": [0, 0, 0]}).to_csv(
        folder / "A0_1.csv", index=False)
    res = run(folder, "-o", tmp_path / "k.csv", "--skip-bad-trials")
    assert res.exit_code == 1
    assert "no usable trials" in res.stderr
    assert not (tmp_path / "k.csv").exists()


def test_output_may_not_be_or_sit_in_the_input(unseen, tmp_path):
    _, base, _ = unseen
    long = tmp_path / "long.csv"
    shutil.copy(base / "long.csv", long)
    before = long.read_bytes()
    res = run(long, "-o", long)
    assert res.exit_code == 2 and one_line(res.stderr)
    assert long.read_bytes() == before
    folder = tmp_path / "f"
    small_set(folder)
    res = run(folder, "-o", folder / "stiffness.csv")
    assert res.exit_code == 2 and "inside the input folder" in res.stderr
    assert not (folder / "stiffness.csv").exists()


@pytest.mark.parametrize("args", [["--zero-window", "0"], ["--displacement-unit", "cm"],
                                  ["--onset-threshold", "-1"], None])
def test_bad_usage_is_exit_2(tmp_path, args):
    folder = tmp_path / "f"
    small_set(folder)
    # None: -o missing
    cmd = [folder] if args is None else [folder, *args, "-o", tmp_path / "k.csv"]
    res = run(*cmd)
    assert res.exit_code == 2
    assert one_line(res.stderr)
    assert not (tmp_path / "k.csv").exists()


def test_help_shows_units_and_an_example():
    res = CliRunner().invoke(phri, ["fit-stiffness", "--help"])
    assert res.exit_code == 0
    for text in ("[s]", "[N]", "mm", "N/m", "Example", "phri fit-stiffness examples/indenter",
                 "--skip-bad-trials", "--plots"):
        assert text in res.output, text


# --------------------------------------------------------------------------- plots and figures


def test_plots_written_to_dir(unseen, tmp_path):
    _, base, _ = unseen
    out, figs, trials = tmp_path / "k.csv", tmp_path / "figs", tmp_path / "trials.csv"
    res = run(base / "folder", "-o", out, "--plots", figs, "--trials-csv", trials, "-q")
    assert res.exit_code == 0, res.output
    assert res.stdout == ""
    for name in ("force_displacement.png", "stiffness_map.png"):
        png = figs / name
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 10_000
    tt = pd.read_csv(trials)
    assert len(tt) == 42 and {"location", "trial", "stiffness_N_per_m", "r2_min",
                              "onset_time_s", "zero_level_N"} <= set(tt.columns)


def test_failure_while_plotting_leaves_nothing(unseen, tmp_path, monkeypatch):
    import phri_spring.workflows.fit.stiffness as wf

    _, base, _ = unseen

    def boom(*args, **kwargs):
        raise RuntimeError("disk full")

    monkeypatch.setattr(wf, "_save_plots", boom)
    out_dir = tmp_path / "out"
    out_dir.mkdir()
    res = run(base / "folder", "-o", out_dir / "k.csv", "--plots", out_dir / "figs",
              "--trials-csv", out_dir / "t.csv")
    assert res.exit_code == 1 and one_line(res.stderr)
    assert list(out_dir.iterdir()) == []


def test_failure_while_writing_the_csv_leaves_nothing(unseen, tmp_path, monkeypatch):
    import phri_spring.workflows.fit.stiffness as wf

    _, base, _ = unseen

    def half_written(table, path, **kwargs):
        Path(path).write_text("location,row\nA0,")
        raise OSError("disk full")

    monkeypatch.setattr(wf, "write_stiffness_csv", half_written)
    out_dir = tmp_path / "out"
    out_dir.mkdir()
    res = run(base / "folder", "-o", out_dir / "k.csv", "--plots", out_dir / "figs")
    assert res.exit_code == 1 and one_line(res.stderr)
    assert list(out_dir.iterdir()) == []


def test_figures_are_figure_objects(unseen):
    from matplotlib.figure import Figure

    from phri_spring.reports.indenter_figures import (force_displacement_grid,
                                                      indentation_response, stiffness_map)
    from phri_spring.workflows.fit.stiffness import fit_stiffness

    truth, base, _ = unseen
    result = fit_stiffness(base / "folder")
    grid = force_displacement_grid(result.locations)
    assert isinstance(grid, Figure) and len(grid.axes) == 3 * 7
    first = grid.axes[0]
    assert first.get_title().startswith("A0:")
    # each panel: 2 trial curves + one dashed line per unloading stroke
    loc0 = result.locations[0]
    assert len(first.lines) == 2 + loc0.n_strokes
    assert "[mm]" in grid.axes[-1].get_xlabel() and "[N]" in first.get_ylabel()
    assert grid.legends and "unloading fit" in [t.get_text() for t in grid.legends[0].texts]

    smap = stiffness_map(result.locations)
    assert isinstance(smap, Figure) and len(smap.axes) == 2
    img = smap.axes[0].images[0].get_array()
    expected = np.array(list(truth.values())).reshape(3, 7)
    np.testing.assert_allclose(np.asarray(img), expected, rtol=0.01)
    texts = [t.get_text() for t in smap.axes[0].texts]
    assert f"{result.locations[0].stiffness:.0f}" in texts
    assert smap.axes[1].get_ylabel() == "indenter stiffness [N/m]"

    one = indentation_response(result.locations[3])
    assert isinstance(one, Figure) and len(one.axes) == 1
    assert one.axes[0].get_xlabel() == "depth from onset [mm]"


def test_grid_with_missing_locations_keeps_the_layout(tmp_path):
    from phri_spring.reports.indenter_figures import force_displacement_grid, stiffness_map
    from phri_spring.workflows.fit.stiffness import fit_stiffness

    folder = tmp_path / "f"
    small_set(folder)
    result = fit_stiffness(folder)
    fig = force_displacement_grid(result.locations, rows=["A", "B", "C"], n_angles=7)
    assert len(fig.axes) == 21
    smap = stiffness_map(result.locations, rows=["A", "B", "C"], n_angles=7)
    img = np.ma.masked_invalid(smap.axes[0].images[0].get_array())
    assert img.count() == 2


# --------------------------------------------------------------------------- config


def test_output_is_a_valid_tissue_stiffness(tmp_path):
    config = pytest.importorskip("phri_spring.io.config")
    yaml = pytest.importorskip("yaml")
    out = tmp_path / "fit" / "stiffness.csv"
    out.parent.mkdir()
    res = run(EXAMPLE, "-o", out)
    assert res.exit_code == 0, res.output
    data = yaml.safe_load(HARMONY.read_text())
    data["tissue"]["stiffness"] = "fit/stiffness.csv"      # relative to the config file
    cfg_path = tmp_path / "config.yaml"
    cfg_path.write_text(yaml.safe_dump(data))
    cfg = config.load_config(cfg_path)
    table = pd.read_csv(out).set_index("location")
    expected = table.loc[LABELS, "stiffness_N_per_m"].to_numpy()
    k = np.asarray(cfg.tissue_stiffness)
    assert k.shape == (21,)
    np.testing.assert_allclose(k, expected, rtol=1e-12)
