"""Free element layouts: cuff.patches (docs/model.md section 14)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st

from support.helpers import harmony_dict, one_line, run_phri
from phri_spring.errors import PhriError
from phri_spring.io.config import config_from_dict
from phri_spring.physics.cuff.patches import PatchLayout, check_layout, hoop_shares, mat_layout
from phri_spring.physics.contact.solver import solve
from phri_spring.workflows.common import model_from_config


def grid_as_patches(d: dict) -> dict:
    """The same cuff with its grid written out as one patch per element."""
    g = d["geometry"]
    a = g.pop("angles")
    width = a.get("width", a["step"])
    w = g.pop("row_width")
    rows = g["rows"]
    patches = []
    for i, (r, x) in enumerate(rows.items()):
        wr = w[i] if isinstance(w, list) else w
        for j in range(a["count"]):
            patches.append({"label": f"{r}{j}", "x_m": x,
                            "theta_deg": a["start"] + j * a["step"], "width_deg": width,
                            "length_m": wr})
    if not isinstance(g.get("radius"), list) and "per_row" not in str(g.get("section")):
        g.pop("rows")
    d["cuff"]["patches"] = patches
    return d


def label_mapping(value, labels, n_angles):
    """A per_angle value written as a mapping by label (the forms a free layout accepts)."""
    vals = value["per_angle"]
    return {lab: vals[i % n_angles] for i, lab in enumerate(labels)}


WRENCHES = np.array([[0.0, 0.0, 0.0, 0.0, 0.0, 0.0], [3.0, -20.0, 5.0, 0.4, -0.3, 0.2],
                     [-2.0, 10.0, -30.0, -0.5, 0.6, -0.1], [0.0, 60.0, 10.0, 0.0, 0.0, 1.0]])


@pytest.mark.parametrize("variant", ["circle", "ellipse_taper", "per_row_radius", "handles",
                                     "per_row_sections"])
def test_grid_as_patches_gives_the_grid(variant):
    d = harmony_dict()
    if variant == "ellipse_taper":
        d["geometry"].pop("radius")
        d["geometry"]["section"] = {"ellipse": [0.05, 0.04], "rotation": 20.0}
        d["geometry"]["taper_deg"] = 4.0
    elif variant == "per_row_radius":
        d["geometry"]["radius"] = [0.047, 0.045, 0.042]
    elif variant == "handles":
        d["strap"] = {"tension": 15.0, "model": "handles"}
    elif variant == "per_row_sections":
        d["geometry"].pop("radius")
        d["geometry"]["section"] = {"per_row": [
            {"ellipse": [0.05, 0.042]}, {"ellipse": [0.048, 0.04], "rotation": 10.0},
            {"outline": [[0.045 * math.cos(a) * (1 + 0.05 * math.cos(2 * a)),
                          0.045 * math.sin(a)] for a in np.radians(np.arange(0, 360, 30))]}]}
        d["strap"] = {"tension": 15.0, "model": "handles"}
    grid = config_from_dict(d)
    p = grid_as_patches(harmony_dict() if variant == "circle" else d)
    p["cuff"]["stiffness"] = label_mapping(grid.raw["cuff"]["stiffness"], grid.labels, 7)
    free = config_from_dict(p)
    assert free.labels == grid.labels
    for arm in ("compliant", "rigid"):
        mg, mf = model_from_config(grid, arm), model_from_config(free, arm)
        np.testing.assert_allclose(mf.geometry.points, mg.geometry.points, atol=1e-15)
        np.testing.assert_allclose(mf.geometry.areas, mg.geometry.areas, rtol=1e-12)
        np.testing.assert_allclose(mf.f0, mg.f0, rtol=1e-12, atol=1e-12)
        sg, sf = solve(mg, WRENCHES), solve(mf, WRENCHES)
        np.testing.assert_allclose(sf.forces, sg.forces, rtol=1e-9, atol=1e-9)
        assert sf.converged.all()


def mat_dict(rows=6, columns=6, tension=15.0) -> dict:
    d = harmony_dict()
    g = d["geometry"]
    for k in ("rows", "angles", "row_width"):
        g.pop(k)
    d["cuff"] = {"stiffness": 2.0e5,
                 "patches": {"mat": {"rows": rows, "columns": columns, "pitch_axial_m": 0.01,
                                     "pitch_deg": 360.0 / columns, "x0_m": -0.005 * (rows - 1),
                                     "theta0_deg": 0.0}}}
    d["strap"]["tension"] = tension
    return d


def test_mat_labels_and_hoop_preload_sum():
    cfg = config_from_dict(mat_dict(3, 4))
    assert cfg.labels[:5] == ("R01C01", "R01C02", "R01C03", "R01C04", "R02C01")
    model = model_from_config(cfg)
    # Laplace: a band of tension T around a full turn presses with T * 2 pi in total
    assert math.isclose(model.f0.sum(), 15.0 * 2 * math.pi, rel_tol=1e-12)
    # a closed ring of equal cells: the preload's wrench cancels
    np.testing.assert_allclose(model.W_pre, 0.0, atol=1e-12)


def test_mat_on_a_circle_under_a_radial_push_is_symmetric():
    """A full ring of 8 columns at 0, 45, ... deg pushed along +y: the forces are mirror
    symmetric about the y axis (theta -> -theta) and equal across the mat's rows."""
    cfg = config_from_dict(mat_dict(4, 8))
    sol = solve(model_from_config(cfg), np.array([0.0, 25.0, 0.0, 0.0, 0.0, 0.0]))
    f = np.reshape(sol.forces, (4, 8))
    mirror = (-np.arange(8)) % 8
    np.testing.assert_allclose(f, f[:, mirror], rtol=1e-9, atol=1e-9)
    # rows at x = -0.015, -0.005, 0.005, 0.015 about the origin where the push acts:
    # mirror symmetric in x too
    np.testing.assert_allclose(f[0], f[3], rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(f[1], f[2], rtol=1e-9, atol=1e-9)
    # pushing the cuff toward +y presses its -y side (theta = 180 deg) into the arm
    assert f[:, 4].min() > f[:, 0].max()


@settings(max_examples=15, deadline=None)
@given(st.lists(st.floats(-60.0, 60.0), min_size=6, max_size=6))
def test_balance_of_forces_with_shear(w):
    """Normal plus shear forces on the arm add up to the applied wrench (equilibrium)."""
    cfg = config_from_dict(mat_dict(3, 6))
    model = model_from_config(cfg)
    W = np.array(w) * np.array([1, 1, 1, 0.02, 0.02, 0.02])
    sol = solve(model, W)
    g = model.geometry
    u = np.reshape(sol.u, 6)
    normal = np.reshape(sol.forces, -1)[:, None] * g.normals
    shear = np.reshape(model.shear_forces(u), (-1, 3))
    tot = normal + shear
    F = tot.sum(axis=0)
    M = np.cross(g.points, tot).sum(axis=0)
    np.testing.assert_allclose(np.r_[F, M], W, atol=1e-8 * (1 + np.abs(W).max()))


def test_hoop_shares_closed_form():
    # two staggered bands [0, 2] and [1, 3] plus a separate [5, 6]: union 4
    np.testing.assert_allclose(hoop_shares([1.0, 2.0, 5.5], [2.0, 2.0, 1.0]),
                               [0.5, 0.5, 0.25])


def test_overlap_is_refused_and_touching_allowed():
    touch = PatchLayout(("a", "b"), np.array([0.0, 0.02]), np.radians([0.0, 0.0]),
                        np.radians([30.0, 30.0]), np.array([0.02, 0.02]))
    check_layout(touch)
    over = PatchLayout(("a", "b"), np.array([0.0, 0.01]), np.radians([350.0, 10.0]),
                       np.radians([30.0, 30.0]), np.array([0.02, 0.02]))
    with pytest.raises(ValueError, match="overlap"):
        check_layout(over)
    m = mat_layout(2, 3, 0.01, 20.0, 0.0, 0.0)
    check_layout(m)
    # checked in blocks of rows: an overlap between patches of different blocks is found
    x = np.arange(400) * 0.01
    x[399] = x[3] + 0.001
    far = PatchLayout(tuple(f"p{i}" for i in range(400)), x, np.zeros(400),
                      np.full(400, 0.1), np.full(400, 0.01))
    with pytest.raises(ValueError, match="p3 and p399 overlap"):
        check_layout(far)


# --------------------------------------------------------------------------- commands
def write_config(tmp_path, d, name="cfg.yaml"):
    p = tmp_path / name
    p.write_text(yaml.safe_dump(d, sort_keys=False))
    return p


def free_dict() -> dict:
    """Five FSRs where a lower-limb shell allows: not a grid."""
    d = harmony_dict()
    for k in ("rows", "angles", "row_width"):
        d["geometry"].pop(k)
    d["load_cell"]["position"] = [0.0, 0.0, 0.0]
    d["cuff"] = {"stiffness": {"F1": 2e5, "F2": 2e5, "F3": 1e5, "F4": 3e5, "F5": 2e5},
                 "patches": [
                     {"label": "F1", "x_m": -0.02, "theta_deg": 80.0, "width_deg": 30.0,
                      "length_m": 0.02},
                     {"label": "F2", "x_m": 0.01, "theta_deg": 150.0, "width_deg": 40.0,
                      "length_m": 0.03},
                     {"label": "F3", "x_m": -0.015, "theta_deg": 200.0, "width_deg": 25.0,
                      "length_m": 0.015},
                     {"label": "F4", "x_m": 0.02, "theta_deg": 260.0, "width_deg": 35.0,
                      "length_m": 0.02},
                     {"label": "F5", "x_m": 0.0, "theta_deg": 330.0, "width_deg": 30.0,
                      "length_m": 0.025}]}
    return d


def test_compare_with_a_free_layout(tmp_path):
    """compare reads the measured columns by label and draws the unrolled surface; its RMSE
    is Eq. 1 recomputed here from the model's forces at each condition's mean wrench."""
    cfg_path = write_config(tmp_path, free_dict())
    cfg = config_from_dict(free_dict())
    model = model_from_config(cfg, "compliant")
    W = {"no_load": np.zeros(6), "L1": np.array([0.0, -30.0, 5.0, 0.2, 0.0, 0.1])}
    meas = {"no_load": np.array([1.0, 2.0, 1.5, 2.5, 1.0]),
            "L1": np.array([4.0, 1.0, 1.0, 2.0, 6.0])}
    rows = []
    for t, c in enumerate(["no_load"] * 3 + ["L1"] * 3):
        rows.append([t * 0.1, *W[c], *meas[c], c])
    import pandas as pd

    cols = ["time", "Fx", "Fy", "Fz", "Mx", "My", "Mz", *cfg.labels, "condition"]
    pd.DataFrame(rows, columns=cols).to_csv(tmp_path / "t1.csv", index=False)
    (tmp_path / "m.yaml").write_text(yaml.safe_dump({"baseline": "no_load", "trials": [
        {"file": "t1.csv", "experiment": "E", "direction": "down", "trial": 1}]}))
    r = run_phri("compare", cfg_path, tmp_path / "m.yaml", "-o", tmp_path / "out",
                 "--arms", "rigid,compliant")
    assert r.exit_code == 0, r.output
    rmse = pd.read_csv(tmp_path / "out" / "rmse.csv")
    sim = np.reshape(solve(model, np.stack([W["no_load"], W["L1"]])).forces, (2, 5))
    want = math.sqrt(np.mean(((meas["L1"] - meas["no_load"]) - (sim[1] - sim[0])) ** 2))
    got = rmse.loc[(rmse.arm == "compliant") & (rmse.condition == "L1"), "rmse_N"].item()
    assert math.isclose(got, want, rel_tol=1e-6)
    assert list((tmp_path / "out" / "heatmaps").glob("*.png"))


def test_free_layout_figures_draw_one_rectangle_per_patch():
    from matplotlib.collections import PatchCollection

    from phri_spring.reports.layout_figures import layout_compare_figure, layout_figure

    lay = config_from_dict(free_dict()).patches
    arrays = (lay.x, lay.theta, lay.width, lay.length)
    fig = layout_compare_figure(*arrays, np.arange(5.0), {"rigid": np.ones(5),
                                                          "compliant": -np.ones(5)},
                                labels=lay.labels, rmse={"rigid": 1.0, "compliant": 2.0})
    colls = [c for ax in fig.axes for c in ax.collections if isinstance(c, PatchCollection)]
    assert len(colls) == 3 and all(len(c.get_paths()) == 5 for c in colls)
    assert colls[0].get_clim() == (-4.0, 4.0)     # one symmetric scale for every panel
    np.testing.assert_allclose(colls[0].get_array(), np.arange(5.0))
    # F3 at 200 deg, 25 deg wide, x = -15 mm, 15 mm long: its rectangle in (deg, mm)
    ext = colls[0].get_paths()[2].get_extents(colls[0].get_transforms()[0]
                                               if len(colls[0].get_transforms()) else None)
    assert math.isclose(ext.x0 % 360, 187.5, abs_tol=1e-9)
    assert math.isclose(ext.y0, -22.5, abs_tol=1e-9) and math.isclose(ext.height, 15.0)
    fig1 = layout_figure(*arrays, np.arange(5.0), labels=lay.labels)
    assert any(isinstance(c, PatchCollection) for c in fig1.axes[0].collections)
    assert [t.get_text() for t in fig1.axes[0].texts] == list(lay.labels)


def test_simulate_plot_of_a_free_layout(tmp_path):
    from phri_spring.reports.simulate_figures import simulate_figure
    from phri_spring.workflows.plots.maxpool import MaxPool

    lay = config_from_dict(free_dict()).patches
    pool = MaxPool(5, total=4)
    pool(np.arange(4.0), np.arange(20.0).reshape(4, 5), np.ones(4))
    fig = simulate_figure(pool.result(), labels=lay.labels, pain_threshold_kpa=120.0,
                          layout=(lay.x, lay.theta, lay.width, lay.length))
    from matplotlib.collections import PatchCollection

    colls = [c for ax in fig.axes for c in ax.collections if isinstance(c, PatchCollection)]
    assert len(colls) == 1
    np.testing.assert_allclose(colls[0].get_array(), [15.0, 16.0, 17.0, 18.0, 19.0])


# --------------------------------------------------------------------------- config errors
def _mutated(f):
    d = free_dict()
    f(d)
    return d


BAD = [
    (lambda d: d["cuff"]["patches"][1].update(label="F1"), "cuff.patches", "twice"),
    (lambda d: d["cuff"]["patches"][1].update(theta_deg=90.0, x_m=-0.02), "cuff.patches",
     "overlap"),
    (lambda d: d["cuff"]["patches"][0].update(width_deg=-3), "cuff.patches[0].width_deg",
     "positive"),
    (lambda d: d["cuff"]["patches"][0].pop("length_m"), "cuff.patches[0].length_m", "missing"),
    (lambda d: d["cuff"]["patches"][0].update(lenght_m=0.1), "cuff.patches[0].lenght_m",
     "did you mean"),
    (lambda d: d["cuff"].update(patches=3), "cuff.patches", "expected"),
    (lambda d: d["cuff"].update(patches={"mat": {"rows": 2}}), "cuff.patches.mat.columns",
     "missing"),
    (lambda d: d["cuff"].update(patches={"mat": {"rows": 2, "columns": 40, "pitch_axial_m": 0.01,
                                                 "pitch_deg": 10, "x0_m": 0,
                                                 "theta0_deg": 0}}),
     "cuff.patches.mat.pitch_deg", "360"),
    (lambda d: d["cuff"].update(stiffness={"per_angle": [1e5] * 5}), "cuff.stiffness",
     "rows and angles"),
    (lambda d: d["tissue"].update(stiffness=[[4e3] * 5]), "tissue.stiffness",
     "rows and angles"),
    (lambda d: d["geometry"].update(angles={"start": 0, "step": 30, "count": 3}),
     "geometry.angles", "cuff.patches"),
    (lambda d: d["geometry"].update(row_width=0.02), "geometry.row_width", "cuff.patches"),
    # every patch on one line through the axis: nothing holds the cuff's rotation about it
    (lambda d: d["cuff"].update(stiffness=1e5, patches=[
        {"label": "P", "x_m": -0.02, "theta_deg": 0.0, "width_deg": 0.5, "length_m": 0.01},
        {"label": "Q", "x_m": 0.02, "theta_deg": 0.0, "width_deg": 0.5, "length_m": 0.01}]),
     "cuff.patches", "singular"),
]


@pytest.mark.parametrize("mutate, key, fragment", BAD)
def test_config_errors_are_one_line_naming_the_key(tmp_path, mutate, key, fragment):
    from support.helpers import stderr_of

    p = write_config(tmp_path, _mutated(mutate))
    log = tmp_path / "log.csv"
    log.write_text("time,Fx,Fy,Fz,Mx,My,Mz\n0,1,2,3,0,0,0\n")
    r = run_phri("simulate", p, log, "-o", tmp_path / "out.csv")
    err = stderr_of(r)
    assert r.exit_code == 1, err
    assert one_line(err) and key in err and fragment in err, err
    assert not (tmp_path / "out.csv").exists()


def test_patch_csv_relative_to_the_config(tmp_path):
    d = free_dict()
    rows = ["label,x_m,theta_deg,width_deg,length_m"] + [
        f"{q['label']},{q['x_m']},{q['theta_deg']},{q['width_deg']},{q['length_m']}"
        for q in d["cuff"]["patches"]]
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "fsr.csv").write_text("\n".join(rows) + "\n")
    d["cuff"]["patches"] = "fsr.csv"
    p = write_config(tmp_path / "sub", d)
    from phri_spring.io.config import load_config

    a, b = load_config(p), config_from_dict(free_dict())
    assert a.labels == b.labels
    np.testing.assert_allclose(a.geometry().points, b.geometry().points, atol=1e-15)
    (tmp_path / "sub" / "fsr.csv").write_text("label,x_m,theta_deg,width_deg\nF1,0,0,10\n")
    with pytest.raises(PhriError, match="length_m"):
        load_config(p)


def test_coupled_arm_refuses_a_free_layout(tmp_path):
    from support.helpers import stderr_of

    d = free_dict()
    d["tissue"]["continuum"] = {"thickness": 0.02}
    p = write_config(tmp_path, d)
    log = tmp_path / "log.csv"
    log.write_text("time,Fx,Fy,Fz,Mx,My,Mz\n0,1,2,3,0,0,0\n")
    r = run_phri("simulate", p, log, "-o", tmp_path / "o.csv", "--arm", "coupled")
    assert r.exit_code == 1 and one_line(stderr_of(r)) and "cuff.patches" in stderr_of(r)


@pytest.mark.parametrize("which", ["mat", "grid"])
def test_load_path_split_equals_the_per_element_sum(which):
    """The load split of a mat and of the grid (force_parts, and the summary's fast
    transmitted sums) against the plain sum of every element's normal and shear force
    vectors."""
    from phri_spring.physics.contact.load_path import force_parts
    from phri_spring.physics.contact.solver import normal_forces

    cfg = config_from_dict(mat_dict(4, 8) if which == "mat" else harmony_dict())
    model = model_from_config(cfg)
    W = np.random.default_rng(3).normal(size=(3000, 6)) * [20, 20, 20, 1, 1, 1]
    sol = solve(model, W)
    g, S = model.geometry, sol.contact
    fn = np.where(S, normal_forces(model, sol.u), 0.0)
    s = model.shear_forces(sol.u)                        # (m, n, 3), every element
    want = np.stack([np.einsum("me,ei->mi", fn, g.normals),
                     np.einsum("me,mei->mi", S * 1.0, s),
                     np.einsum("me,mei->mi", (~S) * 1.0, s)], axis=1)
    got = force_parts(model, sol.u, S, normal=sol.forces)
    np.testing.assert_allclose(got, want, atol=1e-9 * np.abs(want).max())
    np.testing.assert_allclose(force_parts(model, sol.u, S), want,
                               atol=1e-9 * np.abs(want).max())
    # the summary's sums of magnitudes, by kind, from the fast rows
    from phri_spring.physics.contact.load_path import shear_rows, transmitted_sums

    mags = np.linalg.norm(s, axis=-1)
    want_sums = np.array([fn.sum(), np.where(S, mags, 0).sum(), np.where(S, 0, mags).sum()])
    got_sums = transmitted_sums(model, sol.u, S, normal=sol.forces, rows=shear_rows(model))
    np.testing.assert_allclose(got_sums, want_sums, rtol=1e-10)


def test_live_and_simulate_write_the_patch_labels(tmp_path):
    """live (single-sample solver) and simulate (batch) on a free layout: the same label
    columns and the same forces."""
    import pandas as pd
    from click.testing import CliRunner

    from phri_cli.main import phri

    p = write_config(tmp_path, free_dict())
    rows = ["time,Fx,Fy,Fz,Mx,My,Mz"] + [
        f"{0.01 * i:.2f},{3 * math.sin(i / 3):.4f},{-20 + i:.4f},{5 * math.cos(i / 4):.4f},"
        f"0.1,-0.05,{0.02 * i:.4f}" for i in range(12)]
    (tmp_path / "log.csv").write_text("\n".join(rows) + "\n")
    r = CliRunner().invoke(phri, ["live", str(p), "--source", "-", "-o",
                                  str(tmp_path / "live.csv")], input="\n".join(rows) + "\n")
    assert r.exit_code == 0, r.output
    r2 = run_phri("simulate", p, tmp_path / "log.csv", "-o", tmp_path / "sim.csv")
    assert r2.exit_code == 0, r2.output
    live, sim = pd.read_csv(tmp_path / "live.csv"), pd.read_csv(tmp_path / "sim.csv")
    labels = ["F1", "F2", "F3", "F4", "F5"]
    assert list(live.columns[1:6]) == labels == list(sim.columns[1:6])
    np.testing.assert_allclose(live[labels].to_numpy(), sim[labels].to_numpy(), atol=1e-5)


def test_patch_between_rows_gets_the_interpolated_outline():
    """Per-row radii 40 and 50 mm at x = -10 and +10 mm: a patch at x = 0 sits at 45 mm, one
    beyond the last row at 50 mm (the nearest row's); arcs and hoop preload follow."""
    d = free_dict()
    d["geometry"]["rows"] = {"P": -0.01, "D": 0.01}
    d["geometry"]["radius"] = [0.04, 0.05]
    d["cuff"] = {"stiffness": 1e5, "patches": [
        {"label": "M", "x_m": 0.0, "theta_deg": 0.0, "width_deg": 60.0, "length_m": 0.01},
        {"label": "E", "x_m": 0.03, "theta_deg": 120.0, "width_deg": 60.0, "length_m": 0.01},
        {"label": "W", "x_m": 0.0, "theta_deg": 240.0, "width_deg": 60.0, "length_m": 0.01}]}
    g = config_from_dict(d).geometry()
    np.testing.assert_allclose(np.hypot(g.points[:, 1], g.points[:, 2]), [0.045, 0.05, 0.045],
                               rtol=1e-12)
    np.testing.assert_allclose(g.areas, 0.01 * np.array([0.045, 0.05, 0.045]) * math.pi / 3,
                               rtol=1e-12)
    # band = union of [-5, 5] mm and [25, 35] mm = 20 mm; each patch 10 mm of it
    model = model_from_config(config_from_dict(d))
    np.testing.assert_allclose(model.f0, 15.0 * (math.pi / 3) * 0.5, rtol=1e-12)
