"""Data at the edges: values no double can hold ("1e999" parses to inf), missing
values spelled otherwise than an empty cell, absurd but finite wrenches (no Python warning
line), and an indenter not at rest in its zero window (the message blames the right thing).
"""

from __future__ import annotations

import shutil

import numpy as np
import pytest

from .faultkit import assert_fault, assert_one_line, cli, phri, snapshot

TRIAL = "iact_horizontal_1.csv"


def _replace_cell(text: str, line_no: int, column: str, value: str) -> str:
    """CSV text with the cell of ``column`` on line ``line_no`` (1 = header) set to ``value``."""
    lines = text.splitlines()
    header = lines[0].split(",")
    cells = lines[line_no - 1].split(",")
    cells[header.index(column)] = value
    lines[line_no - 1] = ",".join(cells)
    return "\n".join(lines) + "\n"


# --------------------------------------------------------------------------- beyond a double
def test_simulate_refuses_a_log_value_beyond_a_double(inputs, out):
    log = out / "log.csv"
    log.write_text(_replace_cell(inputs["log_csv"].read_text(), 42, "Fz", "1e999"))
    existing = out / "forces.csv"
    existing.write_bytes(b"old\n")
    before = snapshot(existing)
    run = cli("simulate", inputs["cfg"], log, "-o", existing)
    assert_fault(run, 1, r"log\.csv: Fz:", "line 42", "beyond the range of a double",
                 before=before, folders=[out])


def test_compare_refuses_a_trial_value_beyond_a_double(inputs, tmp_path):
    exp = tmp_path / "exp"
    shutil.copytree(inputs["exp"], exp)
    trial = exp / TRIAL
    trial.write_text(_replace_cell(trial.read_text(), 10, "B3", "-1e999"))
    run = cli("compare", inputs["cfg"], exp / "manifest.yaml", "-o", tmp_path / "cmp",
              "--no-figures")
    assert_fault(run, 1, rf"{TRIAL}: B3:", "line 10", "finite", folders=[tmp_path])
    assert not (tmp_path / "cmp").exists()


def test_fit_stiffness_refuses_an_indenter_value_beyond_a_double(inputs, tmp_path, out):
    folder = tmp_path / "trials"
    shutil.copytree(inputs["indenter"], folder)
    trial = folder / "A1_2.csv"
    trial.write_text(_replace_cell(trial.read_text(), 7, "force", "1e999"))
    existing = out / "fit.csv"
    existing.write_text("old\n")
    before = snapshot(existing)
    run = cli("fit-stiffness", folder, "-o", existing)
    assert_fault(run, 1, r"A1_2\.csv: force:", "line 7", "inf", before=before, folders=[out])


@pytest.mark.parametrize("basis", ["tissue", "cuff"])
def test_stiffness_csv_value_beyond_a_double(inputs, tmp_path, basis):
    exp = tmp_path / "exp"
    shutil.copytree(inputs["exp"], exp)
    k = exp / "stiffness.csv"
    k.write_text(k.read_text().replace("A0,A,0,4639.5", "A0,A,0,1e999"))
    cfg = tmp_path / "cfg.yaml"
    text = inputs["cfg"].read_text()
    if basis == "cuff":
        text = text.replace("stiffness: {per_angle: [31250, 62500, 125000, 250000, 500000, "
                            "1.0e6, 500000]}", f"stiffness: {k}")
    else:
        text = text.replace("stiffness: 4242.0", f"stiffness: {k}")
    cfg.write_text(text)
    run = cli("simulate", cfg, inputs["log_csv"], "-o", tmp_path / "f.csv")
    assert_fault(run, 1, r"stiffness\.csv: stiffness_N_per_m", "A0", "1e999",
                 folders=[tmp_path])


def test_absurd_finite_wrench_prints_no_python_warning(inputs, out):
    """Finite but absurd loads (1e306 .. 1e308): whatever the solver makes of them, the
    user sees no Python warning line and no "internal error"."""
    text = inputs["log_csv"].read_text()
    for line, col, value in ((5, "Fx", "1e308"), (6, "Fz", "-1e308"), (7, "Mx", "1e306")):
        text = _replace_cell(text, line, col, value)
    log = out / "huge.csv"
    log.write_text(text)
    run = phri("simulate", inputs["cfg"], log, "-o", out / "f.csv")
    assert run.code == 0, run.stderr
    assert "Warning" not in run.stderr and "internal error" not in run.stderr, run.stderr
    assert "Traceback" not in run.stderr
    # the three absurd samples are not converged, with NaN forces, and counted
    import pandas as pd

    table = pd.read_csv(out / "f.csv")
    bad = table.index.isin([3, 4, 5])             # file lines 5-7 are data rows 3-5
    assert not table.loc[bad, "converged"].any()
    assert table.loc[bad, "A0":"C6"].isna().all().all()
    assert table.loc[~bad, "converged"].all()
    assert np.isfinite(table.loc[~bad, "peak_pressure_kPa"]).all()
    assert "did not converge for 3 of" in run.stderr, run.stderr


# --------------------------------------------------------------------------- missing values
@pytest.mark.parametrize("spelling", ["NaN", "NA", "null", "<NA>", "None", "n/a", "#N/A"])
def test_compare_condition_missing_in_any_spelling(inputs, tmp_path, spelling):
    """Rows between windows with a condition spelled as missing are not a condition."""
    exp = tmp_path / "exp"
    shutil.copytree(inputs["exp"], exp)
    for name in (TRIAL, "iipass_horizontal_1.csv"):
        lines = (exp / name).read_text().splitlines()
        lines = [ln + spelling if ln.endswith(",") else ln for ln in lines]
        assert sum(ln.endswith("," + spelling) for ln in lines) > 100
        (exp / name).write_text("\n".join(lines) + "\n")
    run = cli("compare", inputs["cfg"], exp / "manifest.yaml", "-o", tmp_path / "cmp",
              "--no-figures", "-q", "--tissue-stiffness", exp / "stiffness.csv")
    assert run.code == 0, run.stderr
    for name, data in inputs["ref_cmp"].items():
        assert (tmp_path / "cmp" / name).read_bytes() == data, name


def test_compare_condition_pandas_na_in_parquet(inputs, tmp_path):
    """A Parquet trial written after ``convert_dtypes()`` holds <NA> between windows."""
    import pandas as pd

    exp = tmp_path / "exp"
    shutil.copytree(inputs["exp"], exp)
    man = exp / "manifest.yaml"
    text = man.read_text()
    for name in (TRIAL, "iipass_horizontal_1.csv"):
        df = pd.read_csv(exp / name).convert_dtypes()
        assert df["condition"].isna().sum() > 100 and str(df["condition"].dtype) == "string"
        df.to_parquet(exp / name.replace(".csv", ".parquet"))
        text = text.replace(name, name.replace(".csv", ".parquet"))
    man.write_text(text)
    run = cli("compare", inputs["cfg"], man, "-o", tmp_path / "cmp", "--no-figures", "-q",
              "--tissue-stiffness", exp / "stiffness.csv")
    assert run.code == 0, run.stderr
    cond = pd.read_csv(tmp_path / "cmp" / "conditions.csv")
    ref = pd.read_csv(inputs["base"] / "reference" / "cmp" / "conditions.csv")
    assert sorted(cond["condition"].unique()) == sorted(ref["condition"].unique())
    rmse = pd.read_csv(tmp_path / "cmp" / "rmse.csv")
    ref_rmse = pd.read_csv(inputs["base"] / "reference" / "cmp" / "rmse.csv")
    assert len(rmse) == len(ref_rmse)
    num = ref_rmse.select_dtypes("number").columns
    np.testing.assert_allclose(rmse[num].to_numpy(float), ref_rmse[num].to_numpy(float),
                               rtol=1e-12)


@pytest.mark.parametrize("spelling", ["NA", "null"])
def test_missing_numbers_are_named_in_logs_and_indenter_files(inputs, tmp_path, spelling):
    log = tmp_path / "log.csv"
    log.write_text(_replace_cell(inputs["log_csv"].read_text(), 12, "My", spelling))
    run = cli("simulate", inputs["cfg"], log, "-o", tmp_path / "f.csv")
    assert_fault(run, 1, r"log\.csv: My:", "line 12", folders=[tmp_path])
    folder = tmp_path / "trials"
    shutil.copytree(inputs["indenter"], folder)
    trial = folder / "B2_1.csv"
    trial.write_text(_replace_cell(trial.read_text(), 30, "displacement", spelling))
    run = cli("fit-stiffness", folder, "-o", tmp_path / "fit.csv")
    assert_fault(run, 1, r"B2_1\.csv: displacement:", "line 30", "missing",
                 folders=[tmp_path])


# --------------------------------------------------------------------------- indenter at rest
def test_indenter_pushing_in_the_zero_window_is_named_as_such(tmp_path):
    """A trial whose push starts 1 s into a 3 s zero window: 'not at rest', not 'no indentation'."""
    from phri_spring.synthetic.indenter import synth_trial, write_trials

    trial = synth_trial(4000.0, seed=11, location="B3", trial=1, rest=1.0)
    folder = tmp_path / "trials"
    write_trials([trial], folder)
    run = cli("fit-stiffness", folder, "-o", tmp_path / "fit.csv")
    line = assert_fault(run, 1, r"B3_1\.csv", "not at rest inside the zero window of 3 s",
                        r"--zero-window", folders=[tmp_path])
    assert "no indentation" not in line
    # with a 0.5 s window, the rest period is long enough: the same trial fits
    run = cli("fit-stiffness", folder, "-o", tmp_path / "fit.csv", "--zero-window", "0.5", "-q")
    assert run.code == 0, run.stderr
    # whatever onset threshold is given, the message is the same
    run = cli("fit-stiffness", folder, "-o", tmp_path / "fit.csv", "--onset-threshold", "100")
    assert_one_line(run, 1, "not at rest inside the zero window")
