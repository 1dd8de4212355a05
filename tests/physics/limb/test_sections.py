"""Limb sections and taper in the spring model (docs/model.md section 13).

Expected values come from closed forms (the ellipse's curvature and perimeter), from
the circular model of section 1, or from ``reference_sections`` (an independent
implementation written from the docs), never from the package's own output.
"""

from __future__ import annotations
from support.helpers import REPO  # noqa: E402

import copy
import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy.special import ellipe

from support import reference_model as ref
from support import reference_sections as rs
from support.helpers import assert_one_line_error, harmony_dict, run_phri, write_yaml
from phri_spring.io.config import config_from_dict
from phri_spring.physics.cuff.geometry import CuffGeometry, section_geometry
from phri_spring.physics.springs.model import build_model
from phri_spring.physics.limb.sections import EllipseSection, OutlineSection
from phri_spring.physics.contact.solver import solve
from phri_spring.workflows.common import model_from_config

SETTINGS = dict(deadline=None, suppress_health_check=[HealthCheck.too_slow])
RNG = np.random.default_rng(20261128)


def random_wrenches(m=12, force=60.0, lever=0.06):
    W = RNG.normal(size=(m, 6))
    W[:, :3] *= force / np.linalg.norm(W[:, :3], axis=1, keepdims=True)
    W[:, 3:] *= force * lever / np.linalg.norm(W[:, 3:], axis=1, keepdims=True)
    W *= RNG.uniform(0.0, 1.0, size=(m, 1))
    return np.vstack([np.zeros(6), W])


def with_section(section, taper=None, strap=None, **geometry):
    c = harmony_dict()
    del c["geometry"]["radius"]
    c["geometry"]["section"] = section
    if taper is not None:
        c["geometry"]["taper_deg"] = taper
    if strap:
        c["strap"].update(strap)
    c["geometry"].update(geometry)
    return c


def forces(raw, arm, W):
    model = model_from_config(config_from_dict(copy.deepcopy(raw)), arm)
    sol = solve(model, W)
    assert sol.converged.all()
    return sol.forces, model


def ellipse_points(a, b, count, phase=0.0):
    t = np.linspace(0.0, 2 * math.pi, count, endpoint=False) + phase
    return np.column_stack([a * np.cos(t), b * np.sin(t)]).tolist()


# --------------------------------------------------------------------------- Laplace's law
def ellipse_curvature(a, b, t):
    """kappa(t) = a b / (a^2 sin^2 t + b^2 cos^2 t)^(3/2) at the point (a cos t, b sin t)."""
    return a * b / (a * a * math.sin(t) ** 2 + b * b * math.cos(t) ** 2) ** 1.5


def ellipse_perimeter(a, b):
    """4 a E(1 - b^2/a^2) for a >= b (complete elliptic integral of the second kind)."""
    a, b = max(a, b), min(a, b)
    return 4.0 * a * ellipe(1.0 - (b / a) ** 2)


def test_turning_over_arc_is_the_curvature_at_small_spans():
    a, b = 0.05, 0.04
    sec = EllipseSection(a, b)
    half = math.radians(0.05)
    for theta in np.radians([0.0, 30.0, 90.0, 135.0, 250.0]):
        psi = float(sec.turning(theta - half, theta + half))
        s = float(sec.arc(theta - half, theta + half))
        # the parameter t of the ray at theta: tan t = (a / b) tan theta
        t = math.atan2(a * math.sin(theta), b * math.cos(theta))
        assert psi / s == pytest.approx(ellipse_curvature(a, b, t), rel=1e-6)


@pytest.mark.parametrize("section", [EllipseSection(0.05, 0.035, math.radians(25.0)),
                                     OutlineSection(ellipse_points(0.05, 0.04, 12, 0.3))])
def test_full_ring_turns_once_and_adds_up(section):
    # the tangent of a closed convex curve turns by 2 pi; arcs and turnings are additive
    edges = np.radians(np.linspace(-40.0, 320.0, 10))
    assert float(np.sum(section.turning(edges[:-1], edges[1:]))) == pytest.approx(2 * math.pi,
                                                                               abs=1e-10)
    assert float(np.sum(section.arc(edges[:-1], edges[1:]))) == pytest.approx(
        section.perimeter(), rel=1e-11)


def test_ellipse_perimeter_closed_form():
    assert EllipseSection(0.05, 0.04).perimeter() == pytest.approx(ellipse_perimeter(0.05, 0.04),
                                                                   rel=1e-11)
    assert EllipseSection(0.03, 0.06, 1.0).perimeter() == pytest.approx(
        ellipse_perimeter(0.03, 0.06), rel=1e-11)


def test_hoop_pressure_against_the_equal_perimeter_circle():
    """Axis ratio 0.8: the hoop pressure T kappa / sum(w) is 1.41x the equal-perimeter
    circle's on the sharp sides (kappa = a / b^2) and 0.72x on the flat ones (b / a^2)."""
    a, b = 0.05, 0.04
    T = 15.0
    g = section_geometry([0.0], EllipseSection(a, b), 0.02, 0.0, 90.0, 4, angle_width_deg=0.2)
    m = build_model(g, 1e5, 1e6, strap_tension=T)
    pressure = m.f0 / m.areas                        # [Pa], rows sum to one width here
    circle = T / 0.02 * 2 * math.pi / ellipse_perimeter(a, b)
    ratio = pressure / circle
    # elements at 0, 90, 180, 270 deg: sharp, flat, sharp, flat
    np.testing.assert_allclose(ratio[[0, 2]], (a / b ** 2) / (2 * math.pi / ellipse_perimeter(a, b)),
                               rtol=1e-5)
    np.testing.assert_allclose(ratio[[1, 3]], (b / a ** 2) / (2 * math.pi / ellipse_perimeter(a, b)),
                               rtol=1e-5)
    assert ratio[0] == pytest.approx(1.41, abs=0.005)
    assert ratio[1] == pytest.approx(0.72, abs=0.005)


def test_hoop_band_bridges_a_concave_stretch():
    """A bean-shaped outline, rho = 0.05 (1 + 0.3 cos 2t): concave around 90 and 270 deg
    (rho^2 + 2 rho'^2 - rho rho'' < 0 there). The band presses nothing there, and u = 0
    is still the equilibrium at zero load: every element carries its f0."""
    t = np.linspace(0.0, 2 * math.pi, 36, endpoint=False)
    r = 0.05 * (1 + 0.3 * np.cos(2 * t))
    sec = OutlineSection(np.column_stack([r * np.cos(t), r * np.sin(t)]))
    g = section_geometry([0.0], sec, 0.02, 0.0, 30.0, 12)
    assert g.turning[3] < 0 and g.turning[9] < 0            # the elements at 90, 270 deg
    assert float(np.sum(g.turning)) == pytest.approx(2 * math.pi, abs=1e-9)
    m = build_model(g, 5e4, 1e6, strap_tension=15.0)
    np.testing.assert_array_equal(m.f0[g.turning < 0], 0.0)
    np.testing.assert_allclose(m.f0[g.turning > 0], 15.0 * g.turning[g.turning > 0],
                               rtol=1e-12)
    sol = solve(m, np.zeros((1, 6)))
    np.testing.assert_allclose(sol.u[0], 0.0, atol=1e-15)
    np.testing.assert_allclose(sol.forces[0], m.f0, rtol=0, atol=1e-12)


# --------------------------------------------------------------------------- the circle limit
@pytest.mark.parametrize("arm", ["compliant", "rigid"])
@pytest.mark.parametrize("strap", ["hoop", "handles"])
def test_round_ellipse_is_the_circle(arm, strap):
    W = random_wrenches()
    circle = harmony_dict()
    circle["strap"]["model"] = strap
    want, _ = forces(circle, arm, W)
    got, _ = forces(with_section({"ellipse": [0.045, 0.045], "rotation": 33.0},
                                 strap={"model": strap}), arm, W)
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-9)


def test_circle_section_keyword_is_today():
    W = random_wrenches(4)
    plain = harmony_dict()
    named = harmony_dict()
    named["geometry"]["section"] = "circle"
    np.testing.assert_array_equal(forces(named, "compliant", W)[0],
                                  forces(plain, "compliant", W)[0])


def test_outline_sampled_from_an_ellipse_gives_its_forces():
    W = random_wrenches()
    for strap in ("hoop", "handles"):
        want, _ = forces(with_section({"ellipse": [0.05, 0.04]}, strap={"model": strap}),
                         "compliant", W)
        got, _ = forces(with_section({"outline": ellipse_points(0.05, 0.04, 36, 0.1)},
                                     strap={"model": strap}), "compliant", W)
        assert np.max(np.abs(got - want)) <= 0.01 * np.max(np.abs(want))


# --------------------------------------------------------------------------- symmetry
@pytest.mark.parametrize("strap", ["hoop", "handles"])
def test_mirror_loads_give_mirror_forces(strap):
    """Ellipse with rotation 0 and a cuff symmetric about the x-y plane (angles -90..90,
    symmetric cuff stiffness): the mirror z -> -z of a load gives the mirrored forces.
    Forces map (Fx, Fy, -Fz); moments, pseudo-vectors, (-Mx, -My, Mz)."""
    raw = with_section({"ellipse": [0.05, 0.038]}, taper=6.0, strap={"model": strap})
    raw["geometry"]["angles"] = {"start": -90.0, "step": 30.0, "count": 7}
    raw["cuff"]["stiffness"] = {"per_angle": [1e5, 2e5, 4e5, 8e5, 4e5, 2e5, 1e5]}
    W = random_wrenches()
    Wm = W * np.array([1, 1, -1, -1, -1, 1])
    f, model = forces(raw, "compliant", W)
    fm, _ = forces(raw, "compliant", Wm)
    mirror = [r * 7 + (6 - j) for r in range(3) for j in range(7)]
    np.testing.assert_allclose(fm[:, mirror], f, rtol=0, atol=1e-9 * max(1.0, np.abs(f).max()))


# --------------------------------------------------------------------------- the reference
def _outlines():
    @st.composite
    def outline(draw):
        n = draw(st.integers(8, 16))
        base = draw(st.floats(0.03, 0.06))
        ratio = draw(st.floats(0.7, 1.0))
        bump = draw(st.floats(0.0, 0.04))
        phase = draw(st.floats(0.0, 2 * math.pi))
        t = np.linspace(0.0, 2 * math.pi, n, endpoint=False) + phase
        r = 1.0 + bump * np.cos(3 * t)
        return {"outline": np.column_stack([base * r * np.cos(t),
                                            base * ratio * r * np.sin(t)]).tolist()}

    ellipse = st.builds(lambda a, q, rot: {"ellipse": [a, a * q], "rotation": rot},
                        st.floats(0.03, 0.06), st.floats(0.7, 1.3), st.floats(-90.0, 90.0))
    return st.one_of(ellipse, outline())


@st.composite
def section_configs(draw):
    n_rows = draw(st.integers(1, 3))
    count = draw(st.integers(3, 7))
    step = draw(st.floats(20.0, 360.0 / count))
    raw = harmony_dict()
    g = raw["geometry"]
    del g["radius"]
    labels = "ABC"[:n_rows]
    g["rows"] = {lab: -0.02 + 0.02 * i for i, lab in enumerate(labels)}
    g["angles"] = {"start": draw(st.floats(-180.0, 180.0)), "step": step, "count": count}
    if draw(st.booleans()):
        g["angles"]["width"] = step * draw(st.floats(0.4, 1.0))
    secs = draw(st.lists(_outlines(), min_size=n_rows, max_size=n_rows))
    g["section"] = {"per_row": secs} if n_rows > 1 and draw(st.booleans()) else secs[0]
    g["taper_deg"] = draw(st.floats(-9.0, 9.0))
    n = n_rows * count
    raw["tissue"]["stiffness"] = draw(st.lists(st.floats(2e3, 2e4), min_size=n, max_size=n))
    raw["tissue"]["stiffness"] = np.reshape(raw["tissue"]["stiffness"], (n_rows, count)).tolist()
    raw["cuff"]["stiffness"] = draw(st.floats(3e4, 1e6))
    strap = draw(st.sampled_from(["hoop", "handles"]))
    raw["strap"] = {"tension": draw(st.floats(0.0, 30.0)), "model": strap}
    if strap == "handles" and draw(st.booleans()):
        raw["strap"]["axial_position"] = draw(st.floats(-0.04, 0.04))
    return raw


@settings(max_examples=25, **SETTINGS)
@given(raw=section_configs(), arm=st.sampled_from(["compliant", "rigid"]),
       seed=st.integers(0, 2 ** 31))
def test_package_agrees_with_the_independent_reference(raw, arm, seed):
    W = np.random.default_rng(seed).normal(size=(3, 6)) * np.array([20, 20, 20, 1, 1, 1])
    W = np.vstack([np.zeros(6), W])
    got, model = forces(raw, arm, W)
    rmod = rs.model_from_config(raw, arm)
    np.testing.assert_allclose(model.geometry.areas, rmod.geom.areas, rtol=1e-9)
    np.testing.assert_allclose(model.W_pre, rmod.W_pre, rtol=0, atol=1e-9)
    want = np.array([rmod.forces(ref.solve_one(rmod, w)) for w in W])
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-9)


# --------------------------------------------------------------------------- frames, scans
def test_shear_directions_are_orthonormal_to_the_tapered_normal():
    raw = with_section({"ellipse": [0.05, 0.04], "rotation": 15.0}, taper=8.0)
    model = model_from_config(config_from_dict(raw), "compliant")
    g = model.geometry
    frame = np.stack([g.normals, g.meridian, g.circumferential], axis=1)
    np.testing.assert_allclose(frame @ frame.transpose(0, 2, 1),
                               np.broadcast_to(np.eye(3), frame.shape), atol=1e-14)
    # the meridian climbs toward +x and, the limb narrowing distally, toward the axis
    assert np.all(g.meridian[:, 0] > 0)
    radial = g.points[:, 1:] / np.linalg.norm(g.points[:, 1:], axis=1, keepdims=True)
    assert np.all(np.sum(g.meridian[:, 1:] * radial, axis=1) < 0)
    u = RNG.normal(size=(5, 6)) * 1e-3
    s = model.shear_forces(u)
    parts = model.shear_components(u)
    np.testing.assert_allclose(np.sum(parts ** 2, axis=-1), np.sum(s ** 2, axis=-1),
                               rtol=1e-12)


def test_a_geometry_from_explicit_arrays_is_the_same_model():
    g = section_geometry([-0.02, 0.0, 0.02],
                         [EllipseSection(0.05, 0.04), EllipseSection(0.048, 0.039),
                          OutlineSection(ellipse_points(0.046, 0.037, 10))],
                         0.02, 75.0, 35.0, 7, taper_deg=3.0)
    h = CuffGeometry.from_elements(g.labels, g.row_labels, g.n_rows, g.n_angles, g.x,
                                   g.row_width, g.theta, g.span, g.points, g.normals, g.areas,
                                   g.turning, strap_section=g.strap_section)
    W = random_wrenches(5)
    for strap in ("hoop", "handles"):
        a = build_model(g, 5e4, 3e5, strap_model=strap)
        b = build_model(h, 5e4, 3e5, strap_model=strap)
        np.testing.assert_allclose(solve(b, W).forces, solve(a, W).forces, rtol=0, atol=1e-12)


# --------------------------------------------------------------------------- config errors
def _cfg(**geometry_changes):
    raw = harmony_dict()
    for k, v in geometry_changes.items():
        if v is None:
            raw["geometry"].pop(k, None)
        else:
            raw["geometry"][k] = v
    return raw


def _star_breaking_outline():
    pts = ellipse_points(0.05, 0.04, 12)
    pts[3], pts[4] = pts[4], pts[3]
    return pts


@pytest.mark.parametrize("changes, key, needle", [
    (dict(section={"ellipse": [0.05, 0.04]}), "geometry.radius", "not both"),
    (dict(radius=None), "geometry.radius", "expected the radius"),
    (dict(radius=None, section={"ellipse": [0.05, -0.04]}), "geometry.section.ellipse",
     "positive"),
    (dict(radius=None, section={"ellipse": [45.0, 40.0]}), "geometry.section.ellipse",
     "between 0.005 and 0.3 m"),
    (dict(radius=None, section={"ellipse": [0.05]}), "geometry.section.ellipse", "two"),
    (dict(radius=None, section={"ellipse": [0.05, 0.04], "rotation": "x"}),
     "geometry.section.rotation", "angle"),
    (dict(radius=None, section={"elipse": [0.05, 0.04]}), "geometry.section.elipse",
     "did you mean 'ellipse'"),
    (dict(radius=None, section="square"), "geometry.section", "circle"),
    (dict(radius=None, section={"outline": ellipse_points(0.05, 0.04, 7)}),
     "geometry.section.outline", "at least 8"),
    (dict(radius=None, section={"outline": (np.array(ellipse_points(0.01, 0.01, 12))
                                            + [0.05, 0.0]).tolist()}),
     "geometry.section.outline", "does not go around"),
    (dict(radius=None, section={"outline": ellipse_points(0.05, 0.04, 12)[::-1]}),
     "geometry.section.outline", "clockwise"),
    (dict(radius=None, section={"outline": _star_breaking_outline()}),
     "geometry.section.outline", "star-shaped"),
    (dict(radius=None, section={"outline": [[1, 2, 3]] * 9}), "geometry.section.outline",
     "[y, z]"),
    (dict(radius=None, section={"per_row": [{"ellipse": [0.05, 0.04]}] * 2}),
     "geometry.section.per_row", "3 sections"),
    (dict(radius=None, section={"per_row": [{"ellipse": [0.05, 0.04]}] * 2
                                + [{"ellipse": [0.05, 0.0]}]}),
     "geometry.section.per_row[2].ellipse", "positive"),
    (dict(radius=None, section={"ellipse": [0.05, 0.04], "outline": [[0.05, 0.0]] * 8}),
     "geometry.section", "not both"),
    (dict(radius=None, section={"per_row": [{"ellipse": [0.05, 0.04]}] * 3, "rotation": 5}),
     "geometry.section.rotation", "per_row takes no other key"),
    (dict(radius=45.0), "geometry.radius", "between 0.005 and 0.3 m"),
    (dict(taper_deg=90.0), "geometry.taper_deg", "between -30 and 30"),
    (dict(taper_deg=45.0), "geometry.taper_deg", "between -30 and 30"),
])
def test_config_errors_are_one_line_naming_the_key(tmp_path, changes, key, needle):
    path = write_yaml(tmp_path, _cfg(**changes))
    res = run_phri("stiffness", path)
    assert_one_line_error(res, key, needle, code=1)


def test_coupled_arm_refuses_a_shape_its_fe_cannot_mesh(tmp_path):
    """The built-in FE meshes sections and tapers; it refuses, in one line naming the key, a
    layer too thick for the limb, a hyperelastic law off the circular cylinder, and a bone
    next to the user's own FE."""
    for changes, cont, key, needle in (
            (dict(taper_deg=4.0), {"thickness": 0.046}, "tissue.continuum.thickness",
             "thinner layer"),
            (dict(radius=None, section={"ellipse": [0.05, 0.04]}),
             {"thickness": 0.02, "law": "neo_hookean"}, "geometry.section", "circular"),
            (dict(bone={"centre": [0.0, 0.0], "radius": 0.02}),
             {"thickness": 0.02, "surface_stiffness": "K.npz"}, "geometry.bone", "own FE")):
        raw = _cfg(**changes)
        raw["tissue"]["continuum"] = {"young_modulus": 30000.0, **cont}
        res = run_phri("stiffness", write_yaml(tmp_path, raw), "--arm", "coupled")
        assert_one_line_error(res, key, needle, code=1)


def test_coupled_arm_takes_a_users_fe_of_any_shape(tmp_path):
    """With its own surface stiffness (here a diagonal one: independent springs of
    2e4 N/m per patch direction) the coupled arm runs on an ellipse: its patch frames are
    the geometry's (n_e, a_e, c_e), so the zero-load normal forces are the hoop preload."""
    raw = with_section({"ellipse": [0.05, 0.04], "rotation": 10.0})
    n = 21
    np.savez(tmp_path / "K.npz", K=np.eye(3 * n) * 2e4,
             labels=np.array([f"{r}{j}" for r in "ABC" for j in range(7)]))
    raw["tissue"]["continuum"] = {"thickness": 0.02, "young_modulus": 3e4,
                                  "surface_stiffness": "K.npz"}
    path = write_yaml(tmp_path, raw)
    assert run_phri("stiffness", path, "--arm", "coupled").exit_code == 0
    cfg = config_from_dict(raw, path=path, base_dir=tmp_path)
    model = model_from_config(cfg, "coupled")
    sol = solve(model, np.zeros((1, 6)))
    spring = model_from_config(cfg, "compliant")
    np.testing.assert_allclose(sol.forces[0], spring.f0, rtol=1e-9, atol=1e-12)


def test_commands_run_on_an_ellipse(tmp_path):
    raw = with_section({"ellipse": [0.05, 0.04], "rotation": 10.0}, taper=4.0)
    cfg = write_yaml(tmp_path, raw)
    log = tmp_path / "log.csv"
    t = np.arange(20) * 0.01
    W = np.column_stack([t, random_wrenches(19)])
    np.savetxt(log, W, delimiter=",", header="time,Fx,Fy,Fz,Mx,My,Mz", comments="")
    for arm in ("compliant", "rigid"):
        res = run_phri("simulate", cfg, log, "-o", tmp_path / f"{arm}.csv", "--arm", arm,
                       "--shear")
        assert res.exit_code == 0, res.output
    raw["interface"]["friction_coefficient"] = 0.5     # Coulomb friction on the cone
    res = run_phri("simulate", write_yaml(tmp_path, raw, "friction.yaml"), log, "-o",
                   tmp_path / "friction.csv", "--shear")
    assert res.exit_code == 0, res.output
    assert run_phri("stiffness", cfg).exit_code == 0


# --------------------------------------------------------------------------- presets
PRESET_SHAPES = {   # circumference [m] the preset's comments cite, axis ratio, taper [deg]
    "human_forearm.yaml": (0.2866, 0.84, 4.7),
    "human_thigh.yaml": (0.5941, 0.85, 4.7),
    "human_shank.yaml": (0.36, 0.92, 4.7),
}


@pytest.mark.parametrize("name", sorted(PRESET_SHAPES))
def test_limb_presets_load_and_simulate(name, tmp_path):

    from phri_spring.io.config import load_config

    path = REPO / "configs" / name
    cfg = load_config(path)
    C, q, taper = PRESET_SHAPES[name]
    (sec,) = set(cfg.sections)
    # the ellipse's perimeter is the cited circumference: 4 a E(1 - q^2)
    assert sec.b / sec.a == pytest.approx(q, abs=5e-3)
    assert ellipse_perimeter(sec.a, sec.b) == pytest.approx(C, rel=2e-3)
    assert cfg.taper_deg == taper
    W = random_wrenches(6)
    for arm in ("compliant", "rigid"):
        model = model_from_config(cfg, arm)
        sol = solve(model, W)
        assert sol.converged.all()
        # equilibrium (docs/model.md section 4): sum_e f_e b_e + K_s u = W + W_pre
        lhs = sol.forces @ model.b + sol.u @ model.K_s.T
        np.testing.assert_allclose(lhs, W + model.W_pre, rtol=0,
                                   atol=1e-9 * (1.0 + np.abs(W).max()))
        assert np.all(sol.forces >= 0)
    # the coupled arm takes the section and taper once the config gives its continuum
    res = run_phri("stiffness", path, "--arm", "coupled")
    assert_one_line_error(res, "tissue.continuum", "needs tissue.continuum", code=1)
