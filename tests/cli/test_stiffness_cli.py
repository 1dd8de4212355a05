"""`phri stiffness` on the command line: JSON and table output, the --arm list, bad input."""

from __future__ import annotations
from support.helpers import REPO  # noqa: E402

import copy
import json
import math
import re
from pathlib import Path

import numpy as np
import pytest
import yaml

from support.helpers import assert_one_line_error, run_phri as run, stderr_of
from support.stiffness_reference import CFG, fd_loadcell_map, rotation_xyz, spec_cuff_stiffness

ROOT = REPO
HARMONY = ROOT / "configs" / "harmony_upper_arm.yaml"
HUMAN = ROOT / "configs" / "human_upper_arm.yaml"


def stdout_of(result) -> str:
    try:
        return result.stdout
    except ValueError:  # pragma: no cover - click < 8.2
        return result.output


@pytest.fixture
def cfg_path(tmp_path):
    p = tmp_path / "cuff.yaml"
    p.write_text(yaml.safe_dump(CFG), encoding="utf-8")
    return p


# --------------------------------------------------------------------------- JSON
@pytest.mark.parametrize("arm", ["compliant", "rigid"])
def test_json_is_one_object_with_the_independent_K(cfg_path, arm):
    res = run("stiffness", cfg_path, "--arm", arm, "--json")
    assert res.exit_code == 0, res.output
    out = stdout_of(res)
    assert out.count("\n") == 1                         # one line, one object
    d = json.loads(out)
    K = np.array(d["K"])
    assert K.shape == (6, 6)
    np.testing.assert_allclose(K, K.T, rtol=0, atol=1e-12 * np.abs(K).max())
    Jinv = np.linalg.inv(fd_loadcell_map(rotation_xyz(CFG["load_cell"]["euler_xyz_deg"]),
                                         np.array(CFG["load_cell"]["position"])))
    expected = Jinv @ spec_cuff_stiffness(CFG, arm) @ Jinv.T
    np.testing.assert_allclose(K, expected, rtol=1e-9, atol=1e-9 * np.abs(expected).max())
    assert d["rows"] == ["Fx", "Fy", "Fz", "Mx", "My", "Mz"]
    assert d["columns"] == ["x", "y", "z", "rx", "ry", "rz"]
    assert d["units"][0][0] == "N/m" and d["units"][0][3] == "N/rad"
    assert d["units"][3][0] == "N*m/m" and d["units"][3][3] == "N*m/rad"
    assert d["arm"] == arm and d["name"] == CFG["name"] and d["config"] == str(cfg_path)
    pr = d["principal"]
    np.testing.assert_allclose(pr["translational_N_per_m"], np.linalg.eigvalsh(K[:3, :3]),
                               rtol=1e-10)
    np.testing.assert_allclose(pr["translational_N_per_mm"],
                               np.array(pr["translational_N_per_m"]) / 1000.0, rtol=1e-14)
    np.testing.assert_allclose(pr["rotational_Nm_per_rad"], np.linalg.eigvalsh(K[3:, 3:]),
                               rtol=1e-10)
    np.testing.assert_allclose(pr["rotational_Nm_per_deg"],
                               np.array(pr["rotational_Nm_per_rad"]) * math.pi / 180, rtol=1e-14)


def test_json_K_against_the_solver(cfg_path):
    """A small wrench dW read by the load cell moves the load-cell point by K^-1 dW."""
    from phri_spring.io.config import load_config
    from phri_spring.physics.cuff.loadcell import loadcell_to_cuff
    from phri_spring.physics.contact.solver import solve
    from phri_spring.workflows.common import model_from_config

    K = np.array(json.loads(stdout_of(run("stiffness", cfg_path, "--json")))["K"])
    np.testing.assert_array_equal(K, K.T)
    R = rotation_xyz(CFG["load_cell"]["euler_xyz_deg"])
    p = np.array(CFG["load_cell"]["position"])
    model = model_from_config(load_config(cfg_path), "compliant")
    dW = np.array([0.3, -0.2, 0.4, 0.01, -0.015, 0.005])          # N, N*m at the load cell
    sol = solve(model, np.vstack([np.zeros(6), loadcell_to_cuff(dW, R, p)]))
    assert sol.contact.all()
    du = sol.u[1] - sol.u[0]                                      # cuff frame, about its origin
    moved = np.concatenate([R.T @ (du[:3] + np.cross(du[3:], p)), R.T @ du[3:]])
    np.testing.assert_allclose(moved, np.linalg.solve(K, dW), rtol=1e-7,
                               atol=1e-9 * np.abs(moved).max())


# --------------------------------------------------------------------------- table
def _parse_table(text):
    """The 6x6 block of the printed table -> array (people's units)."""
    rows = {}
    for line in text.splitlines():
        m = re.match(r"^(Fx|Fy|Fz|Mx|My|Mz) \[(N|N\*m)\]\s+(.*)$", line)
        if m:
            rows[m.group(1)] = [float(v) for v in m.group(3).split()]
    return np.array([rows[r] for r in ("Fx", "Fy", "Fz", "Mx", "My", "Mz")])


@pytest.mark.parametrize("config", [HARMONY, HUMAN])
def test_table_shows_K_in_people_units(config):
    res = run("stiffness", config)
    assert res.exit_code == 0, res.output
    text = stdout_of(res)
    shown = _parse_table(text)
    K = np.array(json.loads(stdout_of(run("stiffness", config, "--json")))["K"])
    factor = np.array([1e-3] * 3 + [math.pi / 180] * 3)      # per mm, per degree
    expected = K * factor[None, :]
    big = np.abs(expected).max()
    np.testing.assert_allclose(shown, expected, rtol=6e-4, atol=1e-9 * big)
    header = next(line for line in text.splitlines() if "x [mm]" in line)
    assert header.split() == ["x", "[mm]", "y", "[mm]", "z", "[mm]", "rx", "[deg]", "ry",
                              "[deg]", "rz", "[deg]"]
    assert "principal translational stiffness [N/mm]" in text
    assert "principal rotational stiffness [N*m/deg]" in text
    assert text.rstrip().splitlines()[-1].startswith("summary: compliant arm: translational")
    assert stderr_of(res) == ""


# --------------------------------------------------------------------------- --arm
def test_help_lists_every_arm_of_common(monkeypatch):
    from phri_spring.workflows import common

    res = run("stiffness", "--help")
    assert res.exit_code == 0
    assert "[" + "|".join(common.ARMS) + "]" in res.output
    monkeypatch.setattr(common, "ARMS", tuple(common.ARMS) + ("wooden",))
    res = run("stiffness", "--help")
    assert "|wooden]" in res.output                 # read from ARMS, not a copy of it


def test_unknown_arm_is_usage_error(cfg_path):
    res = run("stiffness", cfg_path, "--arm", "wooden")
    assert_one_line_error(res, "--arm", "wooden", code=2)


# --------------------------------------------------------------------------- bad input
def test_missing_config(tmp_path):
    res = run("stiffness", tmp_path / "nope.yaml")
    assert_one_line_error(res, "nope.yaml", "not found")


def test_bad_config_key(tmp_path):
    data = copy.deepcopy(CFG)
    data["tissue"]["stifness"] = data["tissue"].pop("stiffness")
    p = tmp_path / "bad.yaml"
    p.write_text(yaml.safe_dump(data))
    res = run("stiffness", p, "--json")
    assert_one_line_error(res, "bad.yaml", "tissue.stifness", "did you mean 'stiffness'")
    assert stdout_of(res) == ""


def test_rigid_arm_with_infinite_cuff(tmp_path):
    data = copy.deepcopy(CFG)
    data["cuff"]["stiffness"] = ".inf"
    p = tmp_path / "inf.yaml"
    p.write_text(yaml.safe_dump(data).replace("'.inf'", ".inf"))
    res = run("stiffness", p, "--arm", "rigid")
    assert_one_line_error(res, "inf.yaml", "cuff.stiffness")
    assert run("stiffness", p, "--arm", "compliant").exit_code == 0


def test_not_yaml(tmp_path):
    p = tmp_path / "x.yaml"
    p.write_text("geometry: [unclosed\n")
    res = run("stiffness", p)
    assert_one_line_error(res, "x.yaml")
    assert "internal error" not in stderr_of(res)


def test_listed_in_phri_help():
    res = run("--help")
    assert res.exit_code == 0 and "stiffness" in res.output


# --------------------------------------------------------------------------- docs/stiffness.md
DOC = ROOT / "docs" / "stiffness.md"


def _json_of(config, arm):
    res = run("stiffness", config, "--arm", arm, "--json")
    assert res.exit_code == 0, res.output
    return json.loads(stdout_of(res))


def test_docs_table_matches_the_command():
    """Every number of the comparison table is what `phri stiffness` prints (to its rounding).

    A row without numbers must say it is to be filled (the coupled model's, until it is);
    once filled, its numbers are checked like the others."""
    rows = [line for line in DOC.read_text().splitlines()
            if re.match(r"^\| (harmony|human)_upper_arm\.yaml \| ", line)]
    deg = math.pi / 180
    checked = set()
    for line in rows:
        cells = [c.strip() for c in line.strip("|").split("|")]
        arm = cells[1].split(":")[0].strip()
        if not cells[2]:
            assert "to be filled by the lead" in cells[1], line
            continue
        d = _json_of(ROOT / "configs" / cells[0], arm)
        Kc = np.array(d["K_cuff"])
        expected = [d["principal"]["translational_N_per_mm"],
                    d["principal"]["rotational_Nm_per_deg"],
                    [d["torsion_about_arm_axis_Nm_per_deg"]],
                    sorted([Kc[4, 4] * deg, Kc[5, 5] * deg])]
        for cell, exp in zip(cells[2:], expected):
            shown = [float(v) for v in cell.split(",")]
            np.testing.assert_allclose(shown, exp, rtol=2e-3, err_msg=line)
        checked.add((cells[0], arm))
    assert {(c, a) for c in ("harmony_upper_arm.yaml", "human_upper_arm.yaml")
            for a in ("compliant", "rigid")} <= checked
    assert any("coupled" in line for line in rows)


def test_docs_output_block_is_the_real_output(monkeypatch):
    monkeypatch.chdir(ROOT)
    text = DOC.read_text()
    block = re.search(r"```console\n\$ phri stiffness configs/harmony_upper_arm.yaml\n"
                      r"(interface stiffness of Harmony.*?)```", text, flags=re.S).group(1)
    res = run("stiffness", "configs/harmony_upper_arm.yaml")
    assert res.exit_code == 0
    assert stdout_of(res) == block


def test_docs_python_example_runs(monkeypatch):
    import os
    import sys

    monkeypatch.chdir(ROOT)
    # the `phri` of this interpreter's environment first on PATH
    monkeypatch.setenv("PATH", str(Path(sys.executable).parent) + os.pathsep
                       + os.environ.get("PATH", ""))
    blocks = re.findall(r"```python\n(.*?)```", DOC.read_text(), flags=re.S)
    assert len(blocks) == 1
    ns = {}
    exec(compile(blocks[0], str(DOC), "exec"), ns)  # noqa: S102 - our own docs
    assert ns["K"].shape == (6, 6)
