"""`phri stiffness --curves`: load-controlled force-displacement curves at the load cell.

Expected values are computed here, independently of the code under test: the
cuff-frame stiffness written out from the formulas of docs/model.md (as in
tests/physics/response/test_stiffness.py), the load-cell map J = dW_cuff / dW_lc by finite
differences, the compliance C = J^T K_cuff^-1 J of the load-cell point under load
control, and, where contacts lift off, the equilibrium of tests/support/reference_model.py
(another solver, written from docs/model.md).
"""

from __future__ import annotations

import copy
import math

import numpy as np
import pandas as pd
import pytest
import yaml

from support import reference_model as ref
from support.helpers import assert_one_line_error, run_phri as run
from support.stiffness_reference import (CFG, cfg_of, fd_loadcell_map, loadcell_point_displacement,
                            rotation_xyz, spec_cuff_stiffness)
from phri_spring.errors import UsageError
from phri_spring.physics.response.sweep import axis_loads, loadcell_motion
from phri_spring.reports.stiffness_curves_figure import stiffness_curves_figure
from phri_spring.workflows.stiffness.matrix import interface_stiffness_report
from phri_spring.workflows.stiffness.curves import (CSV_COLUMNS, CSV_NAME, FIGURE_NAME,
                                                    human_reference_bands, stiffness_curves)

#: the test cuff with its load cell aligned with the cuff, 70 mm below the arm's axis
#: (as in the bundled configs): +y pushes the cuff into the arm, -y pulls it off
ALIGNED = copy.deepcopy(CFG)
ALIGNED["load_cell"] = {"position": [0.0, -0.07, 0.0], "euler_xyz_deg": [0.0, 0.0, 0.0]}
PEOPLE = np.array([1e3] * 3 + [180.0 / math.pi] * 3)     # mm per m, deg per rad


def independent_compliance(data, arm="compliant"):
    """C (6, 6) [m/N, ...]: load-cell point motion per load-cell wrench, every contact closed."""
    K_cuff = spec_cuff_stiffness(data, arm)
    R = rotation_xyz(data["load_cell"]["euler_xyz_deg"])
    J = fd_loadcell_map(R, np.array(data["load_cell"]["position"], dtype=float))
    # u = K_cuff^-1 J W_lc and u_lc = J^T u (work conjugacy)
    return J.T @ np.linalg.solve(K_cuff, J)


def reference_model_of(data):
    """The spring model of tests/support/reference_model.py for a config mapping shaped as CFG."""
    g = data["geometry"]
    a = g["angles"]
    geom = ref.make_geometry(g["rows"], g["radius"], g["row_width"], a["start"], a["step"],
                             a["count"])
    n_rows, n_ang = len(g["rows"]), a["count"]
    k_ind = np.repeat(data["tissue"]["stiffness"]["per_row"], n_ang)
    k_t = ref.indenter_to_element(k_ind, geom.areas, data["tissue"]["indenter_diameter"])
    k_c = np.tile(data["cuff"]["stiffness"]["per_angle"], n_rows)
    return ref.build(geom, k_t, k_c, poisson_ratio=data["tissue"]["poisson_ratio"],
                     tension=data["strap"]["tension"], strap_model=data["strap"]["model"])


# --------------------------------------------------------------------------- the physics
def test_slope_at_zero_is_the_inverse_compliance_diagonal_of_the_report():
    """Under load control the slope at 0 is 1 / (K^-1)_ii of `phri stiffness`'s K, not K_ii."""
    cfg = cfg_of()
    K = interface_stiffness_report(cfg).K
    c = stiffness_curves(cfg, max_force=0.5, max_moment=0.02, points=3)
    assert (c.contacts[:, :, 1] == 21).all()                       # small load: no lift-off
    slope = c.load[:, :, 1] / c.displacement[:, :, 1]              # (6, 2)
    expected = 1.0 / np.diag(np.linalg.inv(K))
    np.testing.assert_allclose(slope, np.c_[expected, expected], rtol=1e-6)
    np.testing.assert_allclose(c.slope_at_zero, expected, rtol=1e-12)
    # and the independent compliance gives the same; K_ii would not (the load cell's offset
    # couples every axis here)
    C = independent_compliance(CFG)
    np.testing.assert_allclose(slope[:, 0], 1.0 / np.diag(C), rtol=1e-6)
    assert np.all(np.abs(slope[:, 0] / np.diag(K) - 1.0) > 1e-3)


def test_linear_law_without_lift_off_is_a_straight_line():
    """Every sample on u = C_ii s (closed form) when no element lifts off."""
    data = copy.deepcopy(CFG)
    data["strap"]["tension"] = 300.0            # a preload no load of the sweep undoes
    c = stiffness_curves(cfg_of(data), max_force=20.0, max_moment=1.0, points=9)
    assert c.converged.all() and (c.contacts == 21).all()
    C = independent_compliance(data)
    expected = np.diag(C)[:, None, None] * c.load
    np.testing.assert_allclose(c.displacement, expected, rtol=1e-9,
                               atol=1e-12 * np.abs(expected).max())
    assert np.all(c.displacement[:, :, 0] == 0.0)


def test_lift_off_bends_the_pull_curve_as_the_reference_solver_does():
    """Pulling the cuff off the arm (-y) lifts elements off: softer, and on the reference."""
    c = stiffness_curves(cfg_of(ALIGNED))
    push, pull = c.displacement[1, 0], c.displacement[1, 1]
    assert (c.contacts[1, 0] == 21).all() and c.contacts[1, 1, -1] < 21
    secant_pull = c.load[1, 1, -1] / pull[-1]
    assert secant_pull < 0.9 * c.slope_at_zero[1]
    np.testing.assert_allclose(c.load[1, 0, -1] / push[-1], c.slope_at_zero[1], rtol=1e-9)
    model = reference_model_of(ALIGNED)
    R = rotation_xyz(ALIGNED["load_cell"]["euler_xyz_deg"])
    p = np.array(ALIGNED["load_cell"]["position"])
    J = fd_loadcell_map(R, p)
    u0 = ref.solve_one(model, np.zeros(6))
    for k in (10, 20, 30):
        W_lc = np.zeros(6)
        W_lc[1] = c.load[1, 1, k]
        u = ref.solve_one(model, J @ W_lc)
        expected = loadcell_point_displacement(u - u0, R, p)[1]
        assert c.displacement[1, 1, k] == pytest.approx(expected, rel=1e-8)


def test_stiffening_tissue_stiffens_the_push_curve():
    """tissue.stiffening > 0: the push slope grows with load; beta = 0: it stays constant."""
    data = copy.deepcopy(ALIGNED)
    data["tissue"]["stiffness"] = 400.0
    slopes = {}
    for beta in (0.0, 1000.0):
        data["tissue"]["stiffening"] = beta
        c = stiffness_curves(cfg_of(data))
        assert c.converged.all() and (c.contacts[1, 0] == 21).all()
        slopes[beta] = np.diff(c.load[1, 0]) / np.diff(c.displacement[1, 0])
    np.testing.assert_allclose(slopes[0.0], slopes[0.0][0], rtol=1e-9)
    s = slopes[1000.0]
    assert np.all(np.diff(s) > 0)
    assert s[-1] > 1.3 * s[0]


def test_samples_that_do_not_converge_are_nan():
    data = copy.deepcopy(CFG)
    data["solver"] = {"max_iterations": 1}
    c = stiffness_curves(cfg_of(data))
    assert 0 < c.failed < c.converged.size
    np.testing.assert_array_equal(np.isnan(c.displacement), ~c.converged)
    assert (c.contacts[~c.converged] == 0).all()
    table = c.table()
    assert table["displacement"].isna().sum() == c.failed


def test_loadcell_motion_is_the_rigid_body_map():
    """t + w x p, then into the load-cell axes, for random motions and poses."""
    rng = np.random.default_rng(7)
    for _ in range(5):
        R = rotation_xyz(rng.uniform(-90, 90, 3))
        p = rng.normal(size=3) * 0.05
        u = rng.normal(size=(4, 6)) * 1e-3
        expected = np.array([loadcell_point_displacement(v, R, p) for v in u])
        np.testing.assert_allclose(loadcell_motion(u, R, p), expected, rtol=1e-12, atol=1e-18)


def test_axis_loads_layout():
    s = axis_loads(60.0, 3.0, 5)
    assert s.shape == (6, 2, 5)
    np.testing.assert_array_equal(s[2, 0], [0, 15, 30, 45, 60])
    np.testing.assert_array_equal(s[4, 1], [0, -0.75, -1.5, -2.25, -3])


@pytest.mark.parametrize("value", [0.0, -1.0, math.inf, math.nan])
def test_bad_maximum_is_a_usage_error(value):
    with pytest.raises(UsageError, match="--max-force"):
        stiffness_curves(cfg_of(), max_force=value)


# --------------------------------------------------------------------------- human data
def test_reference_bands_follow_the_load_cell_axes():
    d, r = human_reference_bands()
    assert d == ("along the arm", "across the arm", "across the arm") * 2
    assert [(b.low, b.high) for b in r] == [(2.1, 2.4), (2.8, 4.5), (2.8, 4.5), (0.03, 0.04),
                                             (0.18, 0.22), (0.18, 0.22)]
    # load-cell x along the cuff's y, load-cell y along the cuff's -x (rotation about z)
    d, r = human_reference_bands(rotation_xyz([0.0, 0.0, 90.0]))
    assert d[:2] == ("across the arm", "along the arm") and r[4].low == 0.03
    # 45 degrees off: no band
    d, r = human_reference_bands(rotation_xyz([0.0, 0.0, 45.0]))
    assert r[0] is None and r[1] is None and r[2] is not None and "45 deg" in d[0]


def test_figure_has_six_panels_and_the_bands():
    c = stiffness_curves(cfg_of(ALIGNED), points=5)
    fig = stiffness_curves_figure(c)
    axes = fig.axes
    assert len(axes) == 6
    assert [a.get_ylabel() for a in axes] == ["Fx [N]", "Fy [N]", "Fz [N]", "Mx [N*m]",
                                              "My [N*m]", "Mz [N*m]"]
    assert axes[0].get_xlabel().endswith("[mm]") and axes[3].get_xlabel().endswith("[deg]")
    assert all(len(a.collections) == 1 for a in axes)          # the human band of each axis
    tilted = stiffness_curves(cfg_of(), points=3)               # load cell 20 deg off the arm
    assert sum(len(a.collections) for a in stiffness_curves_figure(tilted).axes) < 6


# --------------------------------------------------------------------------- the command
@pytest.fixture
def aligned_path(tmp_path):
    p = tmp_path / "cuff.yaml"
    p.write_text(yaml.safe_dump(ALIGNED), encoding="utf-8")
    return p


def test_cli_writes_the_table_and_the_figure(aligned_path, tmp_path):
    out = tmp_path / "curves"
    res = run("stiffness", aligned_path, "--curves", out, "--max-force", "30")
    assert res.exit_code == 0, res.output
    assert sorted(f.name for f in out.iterdir()) == sorted([CSV_NAME, FIGURE_NAME])
    assert (out / FIGURE_NAME).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    t = pd.read_csv(out / CSV_NAME)
    assert tuple(t.columns) == CSV_COLUMNS and len(t) == 6 * 2 * 31
    blocks = list(dict.fromkeys(zip(t["axis"], t["sign"])))
    assert blocks == [(a, s) for a in ("x", "y", "z", "rx", "ry", "rz") for s in (1, -1)]
    y = t[(t["axis"] == "y") & (t["sign"] == 1)]
    assert y["force"].iloc[-1] == 30.0 and y["force_unit"].iloc[0] == "N"
    assert set(t.loc[t["axis"] == "rz", "displacement_unit"]) == {"deg"}
    # slope at 0 [N/mm] against the independent compliance
    C = independent_compliance(ALIGNED)
    slope = y["force"].iloc[1] / y["displacement"].iloc[1]
    assert slope == pytest.approx(1.0 / C[1, 1] * 1e-3, rel=1e-6)


def test_json_is_unchanged_by_curves(aligned_path, tmp_path):
    plain = run("stiffness", aligned_path, "--json")
    both = run("stiffness", aligned_path, "--json", "--curves", tmp_path / "c")
    assert plain.exit_code == both.exit_code == 0
    assert both.stdout == plain.stdout


@pytest.mark.parametrize("where, code", [("file", 2), ("file/sub", 1)])
def test_bad_curves_path_is_one_line_and_writes_nothing(aligned_path, tmp_path, where, code):
    (tmp_path / "file").write_text("not a folder")
    before = sorted(p.name for p in tmp_path.iterdir())
    res = run("stiffness", aligned_path, "--curves", tmp_path / where)
    assert_one_line_error(res, "file", code=code)
    assert res.stdout == ""
    assert sorted(p.name for p in tmp_path.iterdir()) == before
    assert (tmp_path / "file").read_text() == "not a folder"


@pytest.mark.parametrize("args", [["--max-force", "10"], ["--max-moment", "1"]])
def test_maximum_without_curves_is_a_usage_error(aligned_path, args):
    assert_one_line_error(run("stiffness", aligned_path, *args), args[0], "--curves", code=2)


def test_cli_bad_maximum_writes_nothing(aligned_path, tmp_path):
    res = run("stiffness", aligned_path, "--curves", tmp_path / "c", "--max-moment", "inf")
    assert_one_line_error(res, "--max-moment", code=2)
    assert not (tmp_path / "c").exists()


def test_docs_table_is_what_the_command_computes():
    """docs/stiffness.md's table of the human preset: slopes at 0 and secants at +-max."""
    import re

    from support.helpers import REPO
    from phri_spring.io.config import load_config

    text = (REPO / "docs" / "stiffness.md").read_text(encoding="utf-8")
    rows = re.findall(r"^\| (x|y|z|rx|ry|rz), [^|]*\| [^|]*\|(.*)\|$", text, flags=re.M)
    assert [r[0] for r in rows] == ["x", "y", "z", "rx", "ry", "rz"]
    cfg = load_config(REPO / "configs" / "human_upper_arm.yaml")
    for k, arm in enumerate(("compliant", "coupled")):
        c = stiffness_curves(cfg, arm)
        d = c.displacement_people()
        for i, (_, cells) in enumerate(rows):
            cells = [x.strip() for x in cells.split("|")]
            slope = float(cells[2 * k])
            # "-": the sweep's last sample has no answer (flagged, NaN in the curves)
            secants = [float("nan") if v.strip() == "-" else float(v)
                       for v in cells[2 * k + 1].split("/")]
            assert slope == pytest.approx(c.slope_at_zero_people[i], rel=5e-3)
            np.testing.assert_allclose(secants, c.load[i, :, -1] / d[i, :, -1], rtol=5e-3,
                                       equal_nan=True)
