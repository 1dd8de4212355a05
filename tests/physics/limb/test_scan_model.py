"""geometry.scan in the config and the model, end to end (docs/scans.md).

The scans are made here (tubes of numpy, written as STL) from closed forms; the references
are the same limbs described without a scan: the independent implementation of the
sections (tests/support/reference_sections.py, per-row ellipses and taper_deg) and of the circle
(tests/support/reference_model.py), never the package's output on a scan.
"""

from __future__ import annotations
from support.helpers import REPO  # noqa: E402

import copy
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings, strategies as st

from support import reference_model as ref
from support import reference_sections as rs
from support.helpers import assert_one_line_error, harmony_dict, run_phri, write_yaml
from phri_spring.errors import ConfigError
from phri_spring.io.config import config_from_dict, load_config
from phri_spring.physics.contact.solver import solve
from phri_spring.workflows.common import cuff_wrench, model_from_config

pytest.importorskip("trimesh")

REPO = REPO
RNG = np.random.default_rng(33)


# --------------------------------------------------------------------------- meshes
def tube(n_around, xs, section, mirrored=False):
    """Closed-form tube around x: ``section(x, u) -> (y, z)`` at n_around u per ring. Each
    quad is split on its diagonal from (u_i, x_r) to (u_i+1, x_r+1); ``mirrored``: on the
    other diagonal for u > pi, so that the mesh maps onto itself under u -> -u."""
    u = 2 * np.pi * np.arange(n_around) / n_around
    rings = [np.column_stack([np.full(n_around, x), *section(x, u)]) for x in xs]
    i = np.arange(n_around)
    j = (i + 1) % n_around
    flip = (i >= n_around // 2) if mirrored else np.zeros(n_around, bool)
    faces = []
    for r in range(len(xs) - 1):
        a, b = r * n_around + i, r * n_around + j
        c, d = a + n_around, b + n_around
        faces += [np.where(flip[:, None], np.column_stack([a, b, c]), np.column_stack([a, b, d])),
                  np.where(flip[:, None], np.column_stack([b, d, c]), np.column_stack([a, d, c]))]
    return np.vstack(rings), np.vstack(faces)


def write_binary_stl(path, vertices, faces):
    tri = vertices[faces].astype("<f4")
    rec = np.zeros(len(faces), dtype=[("n", "<f4", 3), ("v", "<f4", (3, 3)), ("a", "<u2")])
    rec["v"] = tri
    with open(path, "wb") as fh:
        fh.write(b"phri-spring test limb".ljust(80) + np.uint32(len(faces)).tobytes()
                 + rec.tobytes())
    return path


def turned_frame():
    """Rotation (columns: cuff axes in the scan frame) and the cuff origin in the scan [mm]."""
    a, b, c = np.radians([25.0, -40.0, 100.0])
    rx = np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])
    ry = np.array([[np.cos(b), 0, np.sin(b)], [0, 1, 0], [-np.sin(b), 0, np.cos(b)]])
    rz = np.array([[np.cos(c), -np.sin(c), 0], [np.sin(c), np.cos(c), 0], [0, 0, 1]])
    return rz @ ry @ rx, np.array([150.0, -60.0, 820.0])


def scan_config(stl, *, unit="mm", frame=None, strap=None, **geometry):
    """The Harmony config on a scan (file relative to the config's folder)."""
    raw = harmony_dict()
    g = raw["geometry"]
    del g["radius"]
    if frame is None:
        frame = (np.eye(3), np.zeros(3))
    rot, origin = frame
    g["scan"] = {"file": Path(stl).name, "unit": unit, "origin": origin.tolist(),
                 "axis": rot[:, 0].tolist(), "y_axis": rot[:, 1].tolist()}
    g.update(geometry)
    if strap:
        raw["strap"].update(strap)
    return raw


def load(raw, folder):
    return config_from_dict(copy.deepcopy(raw), path=Path(folder) / "cfg.yaml", base_dir=folder)


def random_wrenches(m=6, force=60.0, lever=0.05):
    W = RNG.normal(size=(m, 6))
    W[:, :3] *= force / np.linalg.norm(W[:, :3], axis=1, keepdims=True)
    W[:, 3:] *= force * lever / np.linalg.norm(W[:, 3:], axis=1, keepdims=True)
    W *= RNG.uniform(0.2, 1.0, size=(m, 1))
    return np.vstack([np.zeros(6), W])


# --------------------------------------------------------------------------- the acceptance
ALPHA_DEG, A0, B0, ROT_DEG = 4.0, 0.050, 0.041, 20.0
ROWS = {"A": -0.025, "B": 0.0, "C": 0.025}


def ellipse_limb(x, u):
    """Semi-axes a, b shrinking by x tan(alpha) toward +x, turned by ROT_DEG."""
    t = math.tan(math.radians(ALPHA_DEG))
    a, b = A0 - x * t, B0 - x * t
    ph = math.radians(ROT_DEG)
    yp, zp = a * np.cos(u), b * np.sin(u)
    return np.cos(ph) * yp - np.sin(ph) * zp, np.sin(ph) * yp + np.cos(ph) * zp


@pytest.fixture(scope="module")
def ellipse_stl(tmp_path_factory):
    folder = tmp_path_factory.mktemp("ellipse")
    v, f = tube(360, np.linspace(-0.07, 0.07, 29), ellipse_limb)
    rot, origin = turned_frame()
    return write_binary_stl(folder / "limb.stl", v * 1000.0 @ rot.T + origin, f)


@pytest.mark.parametrize("arm", ["compliant", "rigid"])
@pytest.mark.parametrize("strap", ["hoop", "handles"])
def test_tapered_ellipse_scan_gives_its_section_reference(ellipse_stl, arm, strap):
    """The scan of a tapered, turned elliptic limb (binary STL, mm, turned and shifted frame)
    against the same limb as per-row ellipses with taper_deg, solved by the independent
    reference: forces within 2 % of the peak force.

    The reference's taper normal -(sin a, cos a m) is exact for a limb whose outline moves
    inward along its own normal; these semi-axes shrink equally, which moves the ellipse's
    flanks a little less than its ends (by up to (a - b) / a ~ 18 % of x tan alpha), so the
    two limbs' normals differ by well under 0.01 rad: the scan is not expected to reproduce
    the reference to round-off, but to the 2 % the issue asks."""
    strap_cfg = {"model": strap, "axial_position": 0.006} if strap == "handles" else None
    raw = scan_config(ellipse_stl, frame=turned_frame(), strap=strap_cfg, rows=ROWS)
    cfg = load(raw, ellipse_stl.parent)
    model = model_from_config(cfg, arm)
    W = random_wrenches()
    sol = solve(model, W)
    assert sol.converged.all()

    t = math.tan(math.radians(ALPHA_DEG))
    ref_raw = copy.deepcopy(raw)
    g = ref_raw["geometry"]
    del g["scan"]
    g["section"] = {"per_row": [{"ellipse": [A0 - x * t, B0 - x * t], "rotation": ROT_DEG}
                                for x in ROWS.values()]}
    g["taper_deg"] = ALPHA_DEG
    rmod = rs.model_from_config(ref_raw, arm)
    want = np.array([rmod.forces(ref.solve_one(rmod, w)) for w in W])
    peak = np.abs(want).max()
    assert np.abs(sol.forces - want).max() <= 0.02 * peak
    # the geometry itself, much tighter than the forces' budget
    np.testing.assert_allclose(model.geometry.points, rmod.geom.points, rtol=0, atol=2e-5)
    np.testing.assert_allclose(model.geometry.areas, rmod.geom.areas, rtol=2e-3)


@pytest.mark.parametrize("strap", ["hoop", "handles"])
def test_cylinder_scan_gives_the_circle(tmp_path, strap):
    """A scan of a circular cylinder of radius R with N facets around: the inscribed polygon
    is within R (1 - cos(pi/N)) of the circle, its band areas within the same fraction, its
    turnings exact (a regular polygon) and its normals within (pi/N)^2 rad. Forces are
    linear in these through the stiffnesses and lever arms; ten times the largest relative
    geometric error, 10 * (pi/N)^2 / 2 of the peak, bounds their effect with margin."""
    R, N = 0.045, 180
    v, f = tube(N, np.linspace(-0.06, 0.06, 61), lambda x, u: (R * np.cos(u), R * np.sin(u)))
    stl = write_binary_stl(tmp_path / "cyl.stl", v, f)
    strap_cfg = {"model": strap} if strap == "handles" else None
    raw = scan_config(stl, unit="m", strap=strap_cfg)
    W = random_wrenches()
    tol = 10 * (math.pi / N) ** 2 / 2
    circle = harmony_dict()
    if strap_cfg:
        circle["strap"].update(strap_cfg)
    for arm in ("compliant", "rigid"):
        sol = solve(model_from_config(load(raw, tmp_path), arm), W)
        rmod = ref.model_from_config(circle, arm)
        want = np.array([rmod.forces(ref.solve_one(rmod, w)) for w in W])
        assert sol.converged.all()
        assert np.abs(sol.forces - want).max() <= tol * np.abs(want).max()


@pytest.mark.parametrize("strap", ["hoop", "handles"])
def test_a_symmetric_scan_gives_mirrored_forces_to_mirrored_loads(tmp_path, strap):
    """A tapered ellipse meshed symmetrically about the x-y plane (its diagonals mirrored
    too), a cuff symmetric about it (angles -90..90, symmetric stiffness): the mirror
    z -> -z of a load, (Fx, Fy, -Fz, -Mx, -My, Mz), gives the mirrored forces (to the
    float32 rounding of the STL and the solver's tolerance)."""
    v, f = tube(144, np.linspace(-0.06, 0.06, 41),
                lambda x, u: ((0.05 - 0.07 * x) * np.cos(u), (0.04 - 0.07 * x) * np.sin(u)),
                mirrored=True)
    stl = write_binary_stl(tmp_path / "sym.stl", v, f)
    raw = scan_config(stl, unit="m", strap={"model": strap})
    raw["geometry"]["angles"] = {"start": -90.0, "step": 30.0, "count": 7}
    raw["cuff"]["stiffness"] = {"per_angle": [1e5, 2e5, 4e5, 8e5, 4e5, 2e5, 1e5]}
    model = model_from_config(load(raw, tmp_path), "compliant")
    W = random_wrenches()
    f0 = solve(model, W).forces
    fm = solve(model, W * np.array([1, 1, -1, -1, -1, 1])).forces
    mirror = [r * 7 + (6 - j) for r in range(3) for j in range(7)]
    np.testing.assert_allclose(fm[:, mirror], f0, rtol=0, atol=1e-6 * np.abs(f0).max())


# --------------------------------------------------------------------------- bad scans
def _cylinder(path, scale=1.0, drop=None):
    v, f = tube(90, np.linspace(-0.06, 0.06, 13), lambda x, u: (0.045 * np.cos(u),
                                                                0.045 * np.sin(u)))
    if drop is not None:
        f = np.delete(f, drop, axis=0)
    return write_binary_stl(path, v * scale, f)


def test_bad_scans_via_the_cli(tmp_path):
    log = tmp_path / "log.csv"
    np.savetxt(log, np.column_stack([np.arange(3) * 0.01, random_wrenches(2)]),
               delimiter=",", header="time,Fx,Fy,Fz,Mx,My,Mz", comments="")
    out = tmp_path / "out.csv"

    def run(raw, *needles):
        res = run_phri("simulate", write_yaml(tmp_path, raw), log, "-o", out)
        assert_one_line_error(res, *needles, code=1)

    # no mesh: text in a .stl
    (tmp_path / "text.stl").write_text("these are my notes, not a mesh\n")
    run(scan_config(tmp_path / "text.stl", unit="m"), "text.stl")
    # not closed around the axis at row B: the faces crossing x = 0 on one side removed
    # (the quad at u = 0 between x = -0.01 and 0: a vertex on the plane is on its +x side)
    hole = _cylinder(tmp_path / "hole.stl", drop=[5 * 180, 5 * 180 + 90])
    run(scan_config(hole, unit="m"), "hole.stl", "row B", "not closed around the axis")
    # an axis that misses the limb: the origin 10 cm beside it
    cyl = _cylinder(tmp_path / "cyl.stl")
    raw = scan_config(cyl, unit="m")
    raw["geometry"]["scan"]["origin"] = [0.0, 0.1, 0.0]
    run(raw, "cyl.stl", "encloses the axis")
    # the wrong unit: a limb in mm read as m is 120 m long
    mm = _cylinder(tmp_path / "mm.stl", scale=1000.0)
    run(scan_config(mm, unit="m"), "mm.stl", "geometry.scan.unit")
    # the file is missing
    run(scan_config(tmp_path / "none.stl", unit="m"), "geometry.scan.file", "not found")
    # a row's band past the scan's end
    run(scan_config(cyl, unit="m", rows={"A": -0.055, "B": 0.0}), "cyl.stl", "row A")


@pytest.mark.parametrize("key, value", [("radius", 0.045), ("section", "circle"),
                                        ("taper_deg", 0.0)])
def test_shape_keys_are_refused_with_a_scan(tmp_path, key, value):
    cyl = _cylinder(tmp_path / "cyl.stl")
    raw = scan_config(cyl, unit="m")
    raw["geometry"][key] = value
    res = run_phri("stiffness", write_yaml(tmp_path, raw))
    assert_one_line_error(res, f"geometry.{key}", "geometry.scan", code=1)


def test_commands_on_a_scan(tmp_path):
    """stiffness runs; --arm coupled is refused naming geometry.scan; a study varying the
    taper is refused naming it; the scan file is among the config's inputs."""
    cyl = _cylinder(tmp_path / "cyl.stl")
    raw = scan_config(cyl, unit="m")
    raw["tissue"]["continuum"] = {"thickness": 0.02, "young_modulus": 3e4}
    path = write_yaml(tmp_path, raw)
    assert run_phri("stiffness", path).exit_code == 0
    assert_one_line_error(run_phri("stiffness", path, "--arm", "coupled"), "geometry.scan",
                          "not a scanned limb", code=1)
    assert cyl.resolve() in [Path(p).resolve() for p in load_config(path).stiffness_files]
    log = tmp_path / "log.csv"
    np.savetxt(log, np.column_stack([np.arange(5) * 0.01, random_wrenches(4)]),
               delimiter=",", header="time,Fx,Fy,Fz,Mx,My,Mz", comments="")
    study = tmp_path / "study.yaml"
    study.write_text(f"config: {path.name}\nloads: [{log.name}]\narm: compliant\n"
                     "vary:\n  geometry.taper_deg: {values: [0, 2]}\nplan: grid\n"
                     "minimise: [peak_pressure_to_pain_threshold]\n")
    res = run_phri("design", study, "-o", tmp_path / "des")
    assert_one_line_error(res, "vary.geometry.taper_deg", "geometry.scan", code=1)
    # a design whose row misses the scan: one line naming the study, the design and the scan
    study.write_text(study.read_text().replace("geometry.taper_deg: {values: [0, 2]}",
                                               "geometry.rows.A: {values: [-0.025, -0.2]}"))
    res = run_phri("design", study, "-o", tmp_path / "des")
    assert_one_line_error(res, "study.yaml", "design 1", "cyl.stl", "row A", code=1)
    # simulate with a figure, and live from standard input
    res = run_phri("simulate", path, log, "-o", tmp_path / "f.csv", "--plot", tmp_path / "f.png")
    assert res.exit_code == 0, res.output
    assert (tmp_path / "f.png").stat().st_size > 0
    from click.testing import CliRunner

    from phri_cli.main import phri

    res = CliRunner().invoke(phri, ["live", str(path), "--source", "-", "-o",
                                    str(tmp_path / "live.csv")], input=log.read_text())
    assert res.exit_code == 0, res.output
    assert len(pd.read_csv(tmp_path / "live.csv")) == 5


def test_coupled_arm_takes_a_users_fe_on_a_scan(tmp_path):
    """With its own surface stiffness (independent springs of 2e4 N/m per patch direction)
    the coupled arm runs on a scan: at zero load its normal forces are the hoop preload."""
    cyl = _cylinder(tmp_path / "cyl.stl")
    raw = scan_config(cyl, unit="m")
    np.savez(tmp_path / "K.npz", K=np.eye(3 * 21) * 2e4,
             labels=np.array([f"{r}{j}" for r in "ABC" for j in range(7)]))
    raw["tissue"]["continuum"] = {"thickness": 0.02, "young_modulus": 3e4,
                                  "surface_stiffness": "K.npz"}
    path = write_yaml(tmp_path, raw)
    assert run_phri("stiffness", path, "--arm", "coupled").exit_code == 0
    cfg = load(raw, tmp_path)
    sol = solve(model_from_config(cfg, "coupled"), np.zeros((1, 6)))
    # the hoop preload T psi_e w_r / sum w_r with psi_e the 35-degree span
    np.testing.assert_allclose(sol.forces[0], 15.0 * math.radians(35.0) / 3, rtol=1e-4)


def test_handles_strap_outside_the_scan_is_refused(tmp_path):
    cyl = _cylinder(tmp_path / "cyl.stl")
    raw = scan_config(cyl, unit="m", strap={"model": "handles", "axial_position": 0.2})
    res = run_phri("stiffness", write_yaml(tmp_path, raw))
    assert_one_line_error(res, "cyl.stl", "strap.axial_position", "does not cut the scan",
                          code=1)


# --------------------------------------------------------------------------- the example
def test_the_example_config_simulates_the_example_log(tmp_path):
    cfg_path = REPO / "examples" / "scan" / "upper_arm_scan.yaml"
    out = tmp_path / "forces.csv"
    res = run_phri("simulate", cfg_path, REPO / "examples" / "wrench_log.csv", "-o", out,
                   "--shear")
    assert res.exit_code == 0, res.output
    df = pd.read_csv(out)
    assert df["converged"].all()
    cfg = load_config(cfg_path)
    geom = cfg.geometry()
    labels = list(geom.labels)
    fn = df[labels].to_numpy()
    ta = df[[f"{lab}_shear_axial_N" for lab in labels]].to_numpy()
    tc = df[[f"{lab}_shear_circumferential_N" for lab in labels]].to_numpy()
    # the forces on the arm (normal along n_e, shear along a_e and c_e) balance the wrench on
    # the cuff plus the strap's
    n, a, c = geom.normals, geom.meridian, geom.circumferential
    F = fn @ n + ta @ a + tc @ c
    p = geom.points
    M = (np.cross(p, n)[None] * fn[..., None] + np.cross(p, a)[None] * ta[..., None]
         + np.cross(p, c)[None] * tc[..., None]).sum(axis=1)
    log = pd.read_csv(REPO / "examples" / "wrench_log.csv", comment="#")
    W = cuff_wrench(cfg, log[["Fx", "Fy", "Fz", "Mx", "My", "Mz"]].to_numpy())
    W = W + model_from_config(cfg, "compliant").W_pre
    scale = np.abs(W[:, :3]).max()
    np.testing.assert_allclose(F, W[:, :3], rtol=0, atol=1e-6 * scale)
    np.testing.assert_allclose(M, W[:, 3:], rtol=0, atol=1e-6 * scale * 0.1)
    # the scan's limb is no cylinder: the normals carry its 4-degree taper
    assert np.all(np.abs(np.degrees(np.arcsin(geom.normals[:, 0]))) > 2.0)
    with pytest.raises(ConfigError):
        config_from_dict(cfg.raw, path=cfg_path, base_dir=tmp_path)   # file not found there


# --------------------------------------------------------------------------- the outline
@settings(max_examples=40, deadline=None)
@given(n=st.integers(12, 60), bumps=st.floats(0.0, 0.15), seed=st.integers(0, 2 ** 31),
       h=st.floats(0.002, 0.01))
def test_collinear_points_do_not_change_the_tangent(n, bumps, seed, h):
    """A plane's cut through facet diagonals adds points on straight outline pieces: the
    smoothed tangent angle (and so every turning) is that of the outline without them."""
    from phri_spring.physics.limb.scan_sections import tangent_angle

    rng = np.random.default_rng(seed)
    t = np.sort(rng.uniform(0, 2 * np.pi, n))
    r = 0.045 * (1 + bumps * np.cos(3 * t + rng.uniform(0, 6)))
    yz = np.column_stack([r * np.cos(t), r * np.sin(t)])
    # one extra point on every other segment, at a random fraction along it
    nxt = np.roll(yz, -1, axis=0)
    frac = rng.uniform(0.1, 0.9, n)
    rows = []
    for k in range(n):
        rows.append(yz[k])
        if k % 2:
            rows.append(yz[k] + frac[k] * (nxt[k] - yz[k]))
    dense = np.array(rows)
    perimeter = np.linalg.norm(nxt - yz, axis=1).sum()
    pos = rng.uniform(0, perimeter, 9)
    np.testing.assert_allclose(tangent_angle(dense, pos, h), tangent_angle(yz, pos, h),
                               rtol=0, atol=1e-9)
