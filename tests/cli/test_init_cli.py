"""``phri init``: starter configs from the bundled presets, and the bundled example log.

The references are the repository's own files, read here without the package: the presets
are the YAML files of ``configs/`` and the example log is ``examples/wrench_log.csv``.
"""

from __future__ import annotations
from support.helpers import REPO  # noqa: E402

import re
from pathlib import Path

import numpy as np
import pytest
import yaml

from support.helpers import assert_one_line_error, run_phri, stderr_of

ROOT = REPO
CONFIGS = ROOT / "configs"
PRESETS = sorted(p.stem for p in CONFIGS.glob("*.yaml"))
EXAMPLE_LOG = ROOT / "examples" / "wrench_log.csv"


def read_numbers(path: Path, columns=None) -> np.ndarray:
    import pandas as pd

    df = pd.read_csv(path, comment="#")
    return df[columns or list(df.columns)].to_numpy(dtype=float)


def test_the_presets_are_the_files_of_configs_one_copy():
    from phri_spring.io.presets import preset_names, preset_text

    assert preset_names() == PRESETS
    assert "harmony_upper_arm" in PRESETS and len(PRESETS) >= 6
    for name in PRESETS:
        assert preset_text(name) == (CONFIGS / f"{name}.yaml").read_text(encoding="utf-8")


def test_list_names_every_preset_and_its_title():
    res = run_phri("init", "--list")
    assert res.exit_code == 0, res.output
    rows = [ln.split(None, 1) for ln in res.output.splitlines()]
    assert [r[0] for r in rows] == PRESETS
    for name, rest in rows:
        title = yaml.safe_load((CONFIGS / f"{name}.yaml").read_text())["name"]
        assert rest.startswith(title)
        assert rest.endswith("(default)") == (name == "harmony_upper_arm")


@pytest.mark.parametrize("name", PRESETS)
def test_starter_config_is_the_preset_with_a_header(tmp_path, name):
    from phri_spring.io.config import load_config

    out = tmp_path / "sub" / "starter.yaml"
    out.parent.mkdir()
    res = run_phri("init", "--preset", name, out)
    assert res.exit_code == 0, res.output
    text = out.read_text(encoding="utf-8")
    original = (CONFIGS / f"{name}.yaml").read_text(encoding="utf-8")
    assert text.endswith(original)
    header = text[: len(text) - len(original)]
    assert header and all(ln.startswith("#") for ln in header.splitlines())
    assert yaml.safe_load(text) == yaml.safe_load(original)
    a, b = load_config(out), load_config(CONFIGS / f"{name}.yaml")
    np.testing.assert_allclose(a.loadcell_position, b.loadcell_position, rtol=0, atol=0)
    assert a.name == b.name
    # it runs: simulate on the first 300 samples of the example log (its unloaded 3 s)
    log = tmp_path / "short.csv"
    log.write_text("\n".join(EXAMPLE_LOG.read_text().splitlines()[:302]) + "\n")
    res = run_phri("simulate", out, log, "-o", tmp_path / "forces.csv", "-q")
    assert res.exit_code == 0, res.output
    forces = read_numbers(tmp_path / "forces.csv", ["time"])
    assert forces.shape == (300, 1)


@pytest.mark.parametrize("name", PRESETS)
def test_every_value_of_a_preset_is_explained_by_a_comment(name):
    """A key holding a value carries a comment on its line or on the line just above it
    (a section's own key, e.g. ``geometry:``, needs none)."""
    lines = (CONFIGS / f"{name}.yaml").read_text(encoding="utf-8").splitlines()
    bare = []
    for i, line in enumerate(lines):
        m = re.match(r"^\s*[A-Za-z_]\w*:(.*)$", line)
        if not m or not m.group(1).strip() or "#" in line:
            continue
        if i == 0 or not lines[i - 1].lstrip().startswith("#"):
            bare.append(f"{i + 1}: {line.strip()}")
    assert not bare, bare


def test_default_starter_and_example_log_run_simulate(tmp_path):
    """The quick start from scratch: the starter config and the example log give the same
    forces as the repository's config on the repository's log."""
    res = run_phri("init", tmp_path / "cuff.yaml", "--example", tmp_path / "data")
    assert res.exit_code == 0, res.output
    log = tmp_path / "data" / "wrench_log.csv"
    ours, theirs = tmp_path / "ours.csv", tmp_path / "theirs.csv"
    res = run_phri("simulate", tmp_path / "cuff.yaml", log, "-o", ours, "-q")
    assert res.exit_code == 0, res.output
    res = run_phri("simulate", CONFIGS / "harmony_upper_arm.yaml", EXAMPLE_LOG, "-o", theirs,
                   "-q")
    assert res.exit_code == 0, res.output
    cols = ["time"] + [f"{r}{j}" for r in "ABC" for j in range(7)]   # the 21 elements
    a, b = read_numbers(ours, cols), read_numbers(theirs, cols)
    assert a.shape == (4600, 22)
    np.testing.assert_allclose(a, b, rtol=0, atol=1e-9)


def test_example_log_is_the_bundled_one(tmp_path):
    from phri_spring.workflows.starter import write_example_log

    log = write_example_log(tmp_path)
    ours = log.read_text().splitlines()
    theirs = EXAMPLE_LOG.read_text().splitlines()
    assert ours[:2] == theirs[:2]                       # the comment and the column names
    a, b = read_numbers(log), read_numbers(EXAMPLE_LOG)
    assert a.shape == b.shape == (4600, 7)
    np.testing.assert_allclose(a, b, rtol=0, atol=1.5e-4)   # 4 decimals, as stored


def test_existing_file_is_refused_unless_force(tmp_path):
    out = tmp_path / "cuff.yaml"
    out.write_text("mine\n")
    res = run_phri("init", out)
    assert_one_line_error(res, "cuff.yaml", "exists", "--force", code=2)
    assert out.read_text() == "mine\n"
    res = run_phri("init", "--preset", "human_thigh", out, "--force")
    assert res.exit_code == 0, res.output
    assert out.read_text().endswith((CONFIGS / "human_thigh.yaml").read_text())
    assert [p.name for p in tmp_path.iterdir()] == ["cuff.yaml"]   # no temporary file left


def test_existing_example_log_refuses_the_whole_command(tmp_path):
    (tmp_path / "wrench_log.csv").write_text("mine\n")
    res = run_phri("init", tmp_path / "cuff.yaml", "--example", tmp_path)
    assert_one_line_error(res, "--example", "wrench_log.csv", "exists", code=2)
    assert not (tmp_path / "cuff.yaml").exists()                 # nothing written
    assert (tmp_path / "wrench_log.csv").read_text() == "mine\n"


@pytest.mark.parametrize("args, needles", [
    (["--preset", "nope", "x.yaml"], ["--preset", "nope", "harmony_upper_arm"]),
    ([], ["FILE", "--list"]),
    (["--preset", "human_thigh"], ["--preset", "FILE"]),
    (["--list", "x.yaml"], ["--list"]),
    (["missing_folder/x.yaml"], ["FILE", "missing_folder"]),
    (["wrench_log.csv", "--example", "."], ["FILE", "--example", "another name"]),
])
def test_bad_usage_is_one_line_exit_2(tmp_path, monkeypatch, args, needles):
    monkeypatch.chdir(tmp_path)
    res = run_phri("init", *args)
    assert_one_line_error(res, *needles, code=2)
    assert list(tmp_path.iterdir()) == []


def test_a_folder_as_file_and_a_file_as_example_folder_are_refused(tmp_path):
    (tmp_path / "d").mkdir()
    res = run_phri("init", tmp_path / "d")
    assert_one_line_error(res, "is a folder", code=2)
    (tmp_path / "f").write_text("x")
    res = run_phri("init", "--example", tmp_path / "f")
    assert_one_line_error(res, "--example", "is a file", code=2)


def test_quiet_prints_nothing(tmp_path):
    res = run_phri("init", "-q", tmp_path / "c.yaml")
    assert res.exit_code == 0 and stderr_of(res) == "" and res.output == ""


def test_presets_missing_from_a_stale_install_is_one_line(monkeypatch):
    """An editable install made before configs/ was mapped has no phri_spring.presets."""
    from importlib import resources

    def missing(package):
        raise ModuleNotFoundError(package)

    monkeypatch.setattr(resources, "files", missing)
    res = run_phri("init", "--list")
    assert_one_line_error(res, "phri_spring.presets", "pip install -e .", code=2)
