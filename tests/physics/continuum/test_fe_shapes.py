"""The built-in FE on limb shapes (docs/coupled-fe.md, "Limb shapes"): the circle limit,
mirror symmetry on an ellipse, the taper's cone, the cache key, geometry.bone's errors.

Coarsest mesh level and a one-row cuff of five patches throughout (CI time)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from phri_spring.io.cache.surface_stiffness import cache_key
from phri_spring.physics.continuum import tissue as fe
from phri_spring.physics.continuum.coupled import rigid_patch_map
from phri_spring.physics.continuum.mesh import build_mesh
from phri_spring.physics.continuum.shape import layer_shape
from phri_spring.physics.cuff.geometry import cuff_geometry, section_geometry
from phri_spring.physics.limb.sections import EllipseSection
from support.helpers import assert_one_line_error, harmony_dict, run_phri, write_yaml

pytest.importorskip("skfem", reason="the fe extra (scikit-fem) is part of the test extra")

R, T, NU = 0.05, 0.02, 0.3
ROW = dict(row_x=[0.0], row_width=0.03, angle_step_deg=35.0, angle_count=5)


def _circle(start=110.0, **kw):
    return cuff_geometry(radius=R, angle_start_deg=start, **ROW, **kw)


def _ellipse(a, b, start=110.0, **kw):
    return section_geometry(sections=EllipseSection(a, b), angle_start_deg=start, **ROW, **kw)


def test_circle_limit_is_todays_fe_to_round_off():
    """An ellipse with a = b goes through the mapped mesh (shape.py); the circle through
    the cylindrical one: the same nodes, K and normal-force output to round-off."""
    circle, ellipse = _circle(), _ellipse(R, R)
    assert layer_shape(circle, T) is None and layer_shape(ellipse, T) is not None
    m_c, m_e = build_mesh(circle, T, 1, 6.0), build_mesh(ellipse, T, 1, 6.0)
    np.testing.assert_allclose(m_e.mesh.doflocs, m_c.mesh.doflocs, rtol=0, atol=1e-15)
    a = fe.condensed_surface_operators(circle, T, 1.0, NU, level=1)
    b = fe.condensed_surface_operators(ellipse, T, 1.0, NU, level=1)
    assert np.max(np.abs(b.K - a.K)) <= 1e-12 * np.max(np.abs(a.K))
    assert np.max(np.abs(b.N - a.N)) <= 1e-12 * np.max(np.abs(a.N))


def test_symmetric_ellipse_gives_mirror_forces_under_a_mirror_load():
    """Patches at 0, +-35, +-70 deg on an ellipse (axis ratio 0.8) are symmetric about the
    x-y plane; a rigid cuff moved along y (a load that plane maps onto itself) gives patch
    forces whose mirror images (z -> -z) are the forces of the mirrored patches."""
    g = _ellipse(R, 0.8 * R, start=-70.0)
    K = fe.condensed_surface_operators(g, T, 3e4, NU, level=1).K
    u = np.array([0.0, 1e-3, 0.0, 0.0, 0.0, 0.0])
    P = (K @ (rigid_patch_map(g, 6) @ u)).reshape(g.n, 6)
    mirror = np.diag([1.0, 1.0, -1.0])
    # patch j at -theta is patch 4 - j; a force mirrors as a vector, a moment as a pseudovector
    for j in range(5):
        np.testing.assert_allclose(mirror @ P[j, :3], P[4 - j, :3], rtol=0,
                                   atol=1e-8 * np.abs(P[:, :3]).max())
        np.testing.assert_allclose(-mirror @ P[j, 3:], P[4 - j, 3:], rtol=0,
                                   atol=1e-8 * np.abs(P[:, 3:]).max())
    assert np.abs(P[:, 1]).max() > 0        # the load reaches the patches


def test_tapered_skin_is_the_cone():
    """On a circle with a 5 deg taper the mesh's skin nodes lie on the cone
    r = R - tan(5 deg) (x - x_row) (closed form); the bone nodes on r = R - t."""
    g = _circle(taper_deg=5.0)
    tm = build_mesh(g, T, 1, 6.0)
    x, _, r = tm.comp
    X = tm.mesh.doflocs
    rho = np.hypot(X[1], X[2])
    skin = np.abs(r - R) <= 1e-12
    bone = np.abs(r - (R - T)) <= 1e-12
    cone = R - math.tan(math.radians(5.0)) * x[skin]
    np.testing.assert_allclose(rho[skin], cone, rtol=1e-12)
    np.testing.assert_allclose(rho[bone], R - T, rtol=1e-12)
    assert np.ptp(rho[skin]) > 0.01         # the cone spans centimetres over the layer


def test_cache_key_distinguishes_shapes():
    """Patches at 0 and 180 deg of a circle of radius R and of an ellipse (R, 0.8 R) have the
    same points, normals, radii and spans: the geometry arrays alone would share a cache
    entry; the shape in the key does not. A bone of its own changes the key too."""
    kw = dict(row_x=[0.0], row_width=0.03, angle_start_deg=0.0, angle_step_deg=180.0,
              angle_count=2, angle_width_deg=30.0)
    circle = cuff_geometry(radius=R, **kw)
    ellipse = section_geometry(sections=EllipseSection(R, 0.8 * R), **kw)
    for name in ("points", "normals", "radius", "span", "theta", "x", "row_width"):
        np.testing.assert_allclose(getattr(ellipse, name), getattr(circle, name), atol=1e-15)
    keys = {cache_key(circle, T, NU), cache_key(ellipse, T, NU),
            cache_key(circle, T, NU, bone=(0.0, 0.0, R - T)),
            cache_key(circle, T, NU, bone=(0.002, 0.0, R - T - 0.004))}
    assert len(keys) == 4
    assert cache_key(ellipse, T, NU) == cache_key(ellipse, T, NU)


@pytest.mark.parametrize("bone, key, needle", [
    ([0.0, 0.0], "geometry.bone", "{centre: [y, z], radius}"),
    ({"centre": [0.0, 0.0, 0.0], "radius": 0.02}, "geometry.bone.centre", "two finite"),
    ({"centre": [0.0, 0.0], "radius": -0.02}, "geometry.bone.radius", "> 0"),
    ({"centre": [0.0, "a"], "radius": 0.02}, "geometry.bone", "numbers"),
    ({"centre": [0.0, 0.0], "radius": 0.044}, "geometry.bone", "at least 2 mm"),
    ({"centre": [0.06, 0.0], "radius": 0.01}, "geometry.bone", "outside the skin"),
])
def test_bad_bone_is_one_line_naming_the_key(tmp_path, bone, key, needle):
    raw = harmony_dict()
    raw["geometry"]["bone"] = bone
    assert_one_line_error(run_phri("stiffness", write_yaml(tmp_path, raw)), key, needle, code=1)


def test_a_bone_of_its_own_in_the_fe():
    """geometry.bone: the bone nodes lie on its circle (an off-centre one here), the skin
    nodes on the ellipse; the condensed K is symmetric positive definite."""
    g = _ellipse(R, 0.8 * R)
    bone = (0.003, -0.002, 0.02)
    tm = build_mesh(g, T, 1, 6.0, bone=bone)
    _, th, r = tm.comp
    X = tm.mesh.doflocs
    b = np.abs(r - (R - T)) <= 1e-12
    np.testing.assert_allclose(np.hypot(X[1, b] - bone[0], X[2, b] - bone[1]), bone[2],
                               rtol=1e-12)
    s = np.abs(r - R) <= 1e-12
    np.testing.assert_allclose(np.hypot(X[1, s], X[2, s]),
                               EllipseSection(R, 0.8 * R).rho(th[s]), rtol=1e-12)
    K = fe.condensed_surface_operators(g, T, 3e4, NU, level=1, bone=bone).K
    assert np.linalg.eigvalsh(K).min() > 0


def test_rows_of_different_radii_mesh_between_them():
    """Two rows of radii 45 and 46 mm: the skin nodes between the rows lie on the straight
    line between the two circles (linear in x, closed form), beyond them on each row's."""
    xr, Rr = np.array([-0.025, 0.0]), np.array([0.045, 0.046])
    g = cuff_geometry(xr, Rr, 0.025, 75.0, 35.0, 3)
    tm = build_mesh(g, T, 1, 6.0)
    x, _, r = tm.comp
    skin = np.abs(r - r.max()) <= 1e-12
    rho = np.hypot(*tm.mesh.doflocs[1:, skin])
    np.testing.assert_allclose(rho, np.interp(x[skin], xr, Rr), rtol=1e-12)


def test_a_cached_circle_is_not_read_for_an_ellipse(tmp_path):
    """The disk cache: the circle's entry is written, read back for the circle, and not
    read for the ellipse with the same patch points (built anew, another file)."""
    from phri_spring.io.cache.surface_stiffness import load_or_build_operators

    kw = dict(row_x=[0.0], row_width=0.03, angle_start_deg=0.0, angle_step_deg=180.0,
              angle_count=2, angle_width_deg=30.0)
    circle = cuff_geometry(radius=R, **kw)
    ellipse = section_geometry(sections=EllipseSection(R, 0.8 * R), **kw)
    run = lambda g: load_or_build_operators(g, T, 3e4, NU, cache_dir=tmp_path,  # noqa: E731
                                            level=1).info
    first, again, other = run(circle), run(circle), run(ellipse)
    assert (first["source"], again["source"], other["source"]) == ("built", "cache", "built")
    assert other["path"] != first["path"]
