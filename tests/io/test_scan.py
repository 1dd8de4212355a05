"""3D limb scans as the cuff's surface (io/scan.py, physics/scan_sections.py).

The meshes are made here with numpy (tubes around the x axis) and written with ``struct`` /
text (STL) or trimesh (OBJ, PLY). The references are closed forms of the same surfaces (the
circle; the tapered, turned ellipse with its gradient normal) or quadratures of them, never
the code's own output.
"""

from __future__ import annotations
from support.helpers import REPO  # noqa: E402

import struct
import sys

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from phri_spring.errors import ConfigError, DataError, UsageError
from phri_spring.io.scan import load_scan, read_mesh, scan_elements
from phri_spring.physics.limb.scan_sections import clipped_area, scan_element_geometry

trimesh = pytest.importorskip("trimesh")

# the paper's layout: rows A, B, C and seven angular locations 35 degrees apart, here turned by
# 0.17 degrees so that no ray passes exactly through a mesh vertex
ROWS_X = np.array([-0.025, 0.0, 0.025])
ROW_W = np.full(3, 0.025)
THETA = np.radians(75.17 + 35.0 * np.arange(7))
SPAN = np.full(7, np.radians(35.0))


# ----------------------------------------------------------------------------- meshes
def tube(n_around: int, xs, section):
    """A tube around the x axis: ``section(x, u) -> (y, z)`` at n_around parameters u per ring."""
    u = 2 * np.pi * np.arange(n_around) / n_around
    rings = [np.column_stack([np.full(n_around, x), *section(x, u)]) for x in xs]
    i = np.arange(n_around)
    j = (i + 1) % n_around
    faces = []
    for r in range(len(xs) - 1):
        a, b = r * n_around + i, r * n_around + j
        c, d = a + n_around, b + n_around
        faces += [np.column_stack([a, b, d]), np.column_stack([a, d, c])]
    return np.vstack(rings), np.vstack(faces)


def circle(radius):
    return lambda x, u: (radius * np.cos(u), radius * np.sin(u))


ALPHA = np.radians(5.0)       # taper half-angle
A0, B0, PHI = 0.050, 0.038, np.radians(20.0)


def semi_axes(x):
    """The tapered ellipse's semi-axes (both shrink by x tan alpha) and their x-derivative."""
    return A0 - x * np.tan(ALPHA), B0 - x * np.tan(ALPHA), -np.tan(ALPHA)


def ellipse_section(x, u):
    a, b, _ = semi_axes(x)
    yp, zp = a * np.cos(u), b * np.sin(u)
    return np.cos(PHI) * yp - np.sin(PHI) * zp, np.sin(PHI) * yp + np.cos(PHI) * zp


def write_binary_stl(path, vertices, faces, header=b"phri-spring test mesh"):
    tri = vertices[faces].astype("<f4")
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]).astype("<f4")
    rec = np.zeros(len(faces), dtype=[("n", "<f4", 3), ("v", "<f4", (3, 3)), ("a", "<u2")])
    rec["n"], rec["v"] = normal, tri
    with open(path, "wb") as fh:
        fh.write(header.ljust(80, b" ")[:80] + struct.pack("<I", len(faces)) + rec.tobytes())


def write_ascii_stl(path, vertices, faces):
    # float32 values printed exactly, so that the binary and ASCII files hold the same mesh
    tri = vertices[faces].astype(np.float32)
    lines = ["solid limb"]
    for t in tri:
        lines += ["facet normal 0 0 0", "outer loop"]
        lines += [f"vertex {float(p[0])!r} {float(p[1])!r} {float(p[2])!r}" for p in t]
        lines += ["endloop", "endfacet"]
    lines.append("endsolid limb")
    path.write_text("\n".join(lines) + "\n")


def turned_frame():
    """A rotation (columns: the cuff axes in the scan's frame) and an origin [mm]."""
    a, b, c = np.radians([30.0, -50.0, 110.0])
    rx = np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])
    ry = np.array([[np.cos(b), 0, np.sin(b)], [0, 1, 0], [-np.sin(b), 0, np.cos(b)]])
    rz = np.array([[np.cos(c), -np.sin(c), 0], [np.sin(c), np.cos(c), 0], [0, 0, 1]])
    return rz @ ry @ rx, np.array([120.0, -40.0, 300.0])


def to_scan_mm(vertices_m, rotation, origin_mm):
    return vertices_m * 1000.0 @ rotation.T + origin_mm


def scan_cfg(file, **over):
    cfg = {"file": str(file), "unit": "m", "origin": [0, 0, 0], "axis": [1, 0, 0],
           "y_axis": [0, 1, 0]}
    cfg.update(over)
    return cfg


# ----------------------------------------------------------------------------- references
def ellipse_reference(x, theta, lo, hi, width):
    """Closed forms / quadratures of the tapered turned ellipse at row x, ray theta."""
    a, b, da = semi_axes(x)
    psi = theta - PHI
    rho = 1.0 / np.sqrt(np.cos(psi) ** 2 / a ** 2 + np.sin(psi) ** 2 / b ** 2)
    point = np.array([x, rho * np.cos(theta), rho * np.sin(theta)])
    yp, zp = rho * np.cos(psi), rho * np.sin(psi)
    # gradient of (y'/a)^2 + (z'/b)^2 - 1, outward; inward normal = minus it
    gy, gz = 2 * yp / a ** 2, 2 * zp / b ** 2
    gx = -2 * yp ** 2 * da / a ** 3 - 2 * zp ** 2 * da / b ** 3
    grad = np.array([gx, np.cos(PHI) * gy - np.sin(PHI) * gz, np.sin(PHI) * gy + np.cos(PHI) * gz])
    normal = -grad / np.linalg.norm(grad)

    def u_of(t):       # the ellipse parameter where the ray at t meets it
        return np.arctan2(np.sin(t - PHI) / b, np.cos(t - PHI) / a)

    def tangent_angle(t):
        u = u_of(t)
        return np.arctan2(b * np.cos(u), -a * np.sin(u)) + PHI

    turning = (tangent_angle(hi) - tangent_angle(lo)) % (2 * np.pi)
    ua, ub = u_of(lo), u_of(hi)
    ub = ub if ub > ua else ub + 2 * np.pi
    g, wgt = np.polynomial.legendre.leggauss(40)
    uu = ua + (ub - ua) * (g + 1) / 2
    arc = (ub - ua) / 2 * np.sum(wgt * np.hypot(a * np.sin(uu), b * np.cos(uu)))
    # area of the surface over |x' - x| <= w/2, lo <= theta <= hi, parametrised by (x', theta)
    xs = x + width / 2 * g
    ts = lo + (hi - lo) * (g + 1) / 2
    X, T = np.meshgrid(xs, ts, indexing="ij")
    aa, bb, d = semi_axes(X)
    P = T - PHI
    q = np.cos(P) ** 2 / aa ** 2 + np.sin(P) ** 2 / bb ** 2
    r = q ** -0.5
    r_t = r ** 3 * np.sin(P) * np.cos(P) * (1 / aa ** 2 - 1 / bb ** 2)
    r_x = r ** 3 * (np.cos(P) ** 2 * d / aa ** 3 + np.sin(P) ** 2 * d / bb ** 3)
    dx = np.stack([np.ones_like(X), r_x * np.cos(T), r_x * np.sin(T)], -1)
    dt = np.stack([np.zeros_like(X), r_t * np.cos(T) - r * np.sin(T),
                   r_t * np.sin(T) + r * np.cos(T)], -1)
    dA = np.linalg.norm(np.cross(dx, dt), axis=-1)
    area = width / 2 * (hi - lo) / 2 * np.einsum("i,j,ij->", wgt, wgt, dA)
    return point, normal, area, turning, arc


# ----------------------------------------------------------------------------- geometry
def test_cylinder_gives_the_circle():
    radius, n = 0.045, 720
    v, f = tube(n, np.linspace(-0.06, 0.06, 25), circle(radius))
    g = scan_element_geometry(v, f, ROWS_X, ROW_W, THETA, SPAN)
    th = np.tile(THETA, 3)
    delta = 2 * np.pi / n                          # facet angle
    sag = 1 - np.cos(delta / 2)                    # a facet's chord lies this far inside R
    rho = np.linalg.norm(g.points[:, 1:], axis=1)
    assert np.all(rho <= radius * (1 + 1e-12)) and np.all(rho >= radius * (1 - sag) - 1e-12)
    np.testing.assert_allclose(np.arctan2(g.points[:, 2], g.points[:, 1]) % (2 * np.pi),
                               th % (2 * np.pi), atol=1e-12)
    np.testing.assert_allclose(g.points[:, 0], np.repeat(ROWS_X, 7), atol=1e-15)
    # the facets' normals are radial, at angles up to delta/2 off the ray's; their weighted
    # mean around p_e is off the radial direction only by the kernel's imbalance over the
    # facet grid: second order in the facet angle
    want = -np.column_stack([np.zeros_like(th), np.cos(th), np.sin(th)])
    np.testing.assert_allclose(g.normals, want, atol=delta ** 2)
    # the band of a prism over the 720-gon: arc within a factor [1 - sag, 1 + sag] of R*width
    np.testing.assert_allclose(g.areas, 0.025 * radius * SPAN[0], rtol=2 * sag)
    np.testing.assert_allclose(g.arcs, radius * SPAN[0], rtol=2 * sag)
    # on the regular 720-gon the tangent angle (linear between segment midpoints) grows by
    # delta per side, so the turning is the polygon's arc in sides times delta: width within sag
    np.testing.assert_allclose(g.turning, SPAN[0], rtol=2 * sag)


def test_tapered_turned_ellipse_from_binary_stl_in_mm(tmp_path):
    rotation, origin = turned_frame()
    v, f = tube(360, np.linspace(-0.07, 0.07, 29), ellipse_section)
    write_binary_stl(tmp_path / "limb.stl", to_scan_mm(v, rotation, origin), f)
    cfg = scan_cfg("limb.stl", unit="mm", origin=origin.tolist(),
                   axis=(2.5 * rotation[:, 0]).tolist(),
                   y_axis=(rotation[:, 1] + 0.3 * rotation[:, 0]).tolist())  # not orthogonal
    g = scan_elements(cfg, ROWS_X, ROW_W, THETA, SPAN, tmp_path)
    for e in range(21):
        r, j = divmod(e, 7)
        point, normal, area, turning, arc = ellipse_reference(
            ROWS_X[r], THETA[j], THETA[j] - SPAN[j] / 2, THETA[j] + SPAN[j] / 2, ROW_W[r])
        # 360 facets around leave second-order errors of the facet angle, (2 pi / 360)^2
        # (a / b)^2 ~ 1.3e-4 of a radius or an angle (the float32 STL in mm rounds at 1e-7 of
        # 300 mm, far below); 2e-4 is 25x inside the ~0.5 % geometry budget of the issue's
        # 2 %-of-peak force acceptance. (A plain window average of the tangent angle, without
        # the h^2 correction, misses the turning by 6e-4: this test catches it.)
        tol = 2e-4
        np.testing.assert_allclose(g.points[e], point, atol=tol * A0)
        np.testing.assert_allclose(g.normals[e], normal, atol=tol)
        np.testing.assert_allclose(g.areas[e], area, rtol=tol)
        np.testing.assert_allclose(g.arcs[e], arc, rtol=tol)
        np.testing.assert_allclose(g.turning[e], turning, rtol=tol)
        # section 9's form of the normal: -(sin a, cos a m) with the local taper a (5 degrees
        # where the section's normal is along a semi-axis, a little less between)
        assert 0 < -g.normals[e, 0] <= np.sin(ALPHA) * (1 + 1e-3)
    np.testing.assert_allclose(np.linalg.norm(g.normals, axis=1), 1.0, atol=1e-12)
    # the outline is the section, in the cuff frame
    for r, yz in enumerate(g.outlines):
        a, b, _ = semi_axes(ROWS_X[r])
        c, s = np.cos(PHI), np.sin(PHI)
        yp, zp = c * yz[:, 0] + s * yz[:, 1], -s * yz[:, 0] + c * yz[:, 1]
        np.testing.assert_allclose((yp / a) ** 2 + (zp / b) ** 2, 1.0, atol=5e-4)


def test_ascii_and_binary_stl_obj_ply_agree(tmp_path):
    rotation, origin = turned_frame()
    v, f = tube(120, np.linspace(-0.07, 0.07, 15), ellipse_section)
    vs = to_scan_mm(v, rotation, origin).astype(np.float32).astype(float)
    write_binary_stl(tmp_path / "b.stl", vs, f)
    write_ascii_stl(tmp_path / "a.stl", vs, f)
    trimesh.Trimesh(vs, f, process=False).export(tmp_path / "m.obj")
    trimesh.Trimesh(vs, f, process=False).export(tmp_path / "m.ply")
    frame = dict(unit="mm", origin=origin.tolist(), axis=rotation[:, 0].tolist(),
                 y_axis=rotation[:, 1].tolist())
    ref = scan_elements(scan_cfg("b.stl", **frame), ROWS_X, ROW_W, THETA, SPAN, tmp_path)
    # the same float32 numbers in ASCII STL and binary PLY; OBJ text keeps 8 decimals (of mm)
    for name, tol in (("a.stl", 1e-12), ("m.ply", 1e-12), ("m.obj", 1e-6)):
        got = scan_elements(scan_cfg(name, **frame), ROWS_X, ROW_W, THETA, SPAN, tmp_path)
        for field in ("points", "normals", "areas", "turning", "arcs"):
            np.testing.assert_allclose(getattr(got, field), getattr(ref, field), rtol=tol,
                                       atol=tol * 1e-3, err_msg=f"{name} {field}")


def test_a_noisy_scan_keeps_smooth_normals():
    """Vertices moved by 20 micrometres of noise (0.8 mm facets): the facets' own normals are
    off by about 0.03 rad, the smoothed normal stays within 0.01 of the circle's; the
    turnings stay within 5 % and still close the ring."""
    radius = 0.045
    v, f = tube(360, np.linspace(-0.07, 0.07, 57), circle(radius))
    v = v + np.random.default_rng(7).normal(0.0, 20e-6, v.shape)
    tri = v[f]
    facet = _facet_normals(tri)
    th = np.tile(THETA, 3)
    want = -np.column_stack([np.zeros_like(th), np.cos(th), np.sin(th)])
    g = scan_element_geometry(v, f, ROWS_X, ROW_W, THETA, SPAN)
    # the raw facets near p_e: how noisy a purely local normal would be
    near = np.linalg.norm(tri.mean(axis=1)[:, None, :] - g.points[None, :, :], axis=2) < 1e-3
    raw = np.max([np.abs(facet[near[:, e]] + want[e]).max() for e in range(21)])
    assert raw > 0.02
    assert np.abs(g.normals - want).max() < 0.01
    np.testing.assert_allclose(g.turning, SPAN[0], rtol=0.05)
    ring = scan_element_geometry(v, f, [0.0], [0.025], np.radians(36.0 * np.arange(10)),
                                 np.full(10, np.radians(36.0)))
    assert ring.turning.sum() == pytest.approx(2 * np.pi, abs=1e-9)


def _facet_normals(tri):
    """Outward unit normals of triangles (N, 3, 3) around the x axis."""
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    c = tri.mean(axis=1)
    n *= np.sign(n[:, 1] * c[:, 1] + n[:, 2] * c[:, 2])[:, None]
    return n / np.linalg.norm(n, axis=1, keepdims=True)


def test_winding_of_the_triangles_does_not_matter():
    v, f = tube(180, np.linspace(-0.07, 0.07, 15), ellipse_section)
    ref = scan_element_geometry(v, f, ROWS_X, ROW_W, THETA, SPAN)
    flipped = f.copy()
    flipped[::3] = flipped[::3, ::-1]          # a third of the triangles wound the other way
    got = scan_element_geometry(v, flipped, ROWS_X, ROW_W, THETA, SPAN)
    for field in ("points", "normals", "areas", "turning", "arcs"):
        np.testing.assert_allclose(getattr(got, field), getattr(ref, field), rtol=1e-12,
                                   atol=1e-15)


def test_clipped_area_of_a_unit_square_by_hand():
    # the square [0,1]^2 at z = 0 as two triangles, cut to x >= 0.25 and y <= 0.5: 0.75 * 0.5
    tri = np.array([[[0, 0, 0], [1, 0, 0], [1, 1, 0]], [[0, 0, 0], [1, 1, 0], [0, 1, 0]]], float)
    planes = [((1.0, 0, 0), 0.25), ((0, -1.0, 0), -0.5)]
    assert clipped_area(tri, planes) == pytest.approx(0.375, rel=1e-12)
    assert clipped_area(tri, [((1.0, 0, 0), 2.0)]) == 0.0


@settings(max_examples=12, deadline=None)
@given(start=st.floats(0.0, 2 * np.pi), count=st.integers(3, 9),
       bumps=st.lists(st.floats(-0.08, 0.08), min_size=3, max_size=3))
def test_a_full_ring_turns_once_and_covers_the_band(start, count, bumps):
    """Elements that tile a ring: turnings sum to 2 pi, arcs to the perimeter, areas to the band."""
    def section(x, u):
        rho = 0.04 * (1 + bumps[0] * np.cos(2 * u) + bumps[1] * np.sin(3 * u)
                      + bumps[2] * np.cos(u)) * (1 - 2 * x)
        return rho * np.cos(u), rho * np.sin(u)
    v, f = tube(96, np.linspace(-0.05, 0.05, 11), section)
    theta = start + 2 * np.pi * np.arange(count) / count
    span = np.full(count, 2 * np.pi / count)
    g = scan_element_geometry(v, f, [0.0013], [0.03], theta, span)
    assert g.turning.sum() == pytest.approx(2 * np.pi, abs=1e-9)
    yz = g.outlines[0]
    perimeter = np.linalg.norm(np.roll(yz, -1, axis=0) - yz, axis=1).sum()
    assert g.arcs.sum() == pytest.approx(perimeter, rel=1e-9)
    band = clipped_area(v[f], [((1.0, 0, 0), 0.0013 - 0.015), ((-1.0, 0, 0), -(0.0013 + 0.015))])
    assert g.areas.sum() == pytest.approx(band, rel=1e-9)


# ----------------------------------------------------------------------------- bad scans
def cylinder_stl(path, radius=0.045, n=90, unit_scale=1.0, drop=None):
    """A cylinder of ``radius`` [m] around x in [-0.07, 0.07], written in metres * unit_scale."""
    v, f = tube(n, np.linspace(-0.07, 0.07, 15), circle(radius))
    if drop is not None:
        f = np.delete(f, drop, axis=0)
    write_binary_stl(path, v * unit_scale, f)
    return v, f


def one_line(exc_info, *names):
    text = str(exc_info.value)
    assert "\n" not in text and "Traceback" not in text
    for name in names:
        assert name in text, (name, text)
    return text


def refused(tmp_path, cfg, cls=DataError, rows=ROWS_X):
    with pytest.raises(cls) as info:
        scan_elements(cfg, rows, np.full(len(rows), 0.025), THETA, SPAN, tmp_path)
    # a file's problem is a DataError, not a config one; a key's is a ConfigError (or its
    # ConfigTypeError for a value of the wrong type)
    assert type(info.value) is cls if cls is DataError else isinstance(info.value, cls)
    return info


@pytest.mark.parametrize("content, expected", [
    (b"", "empty file"),
    (b"hello, this is a text file\n" * 20, "not an STL mesh"),
    (b"\x89PNG\r\n\x1a\n" + bytes(range(256)) * 4, "not an STL mesh"),
    (b"solid limb\nthis is no facet\nendsolid limb\n", "limb.stl"),
])
def test_a_file_that_is_no_mesh_is_refused_in_one_line(tmp_path, content, expected):
    (tmp_path / "limb.stl").write_bytes(content)
    info = refused(tmp_path, scan_cfg("limb.stl"))
    one_line(info, "limb.stl", expected)


def test_truncated_binary_stl(tmp_path):
    cylinder_stl(tmp_path / "full.stl")
    data = (tmp_path / "full.stl").read_bytes()
    (tmp_path / "limb.stl").write_bytes(data[: len(data) - 37])
    text = one_line(refused(tmp_path, scan_cfg("limb.stl")), "limb.stl", "truncated")
    assert f"{len(data) - 37:,}" in text


def test_unknown_suffix_and_missing_file(tmp_path):
    (tmp_path / "arm.png").write_bytes(b"\x89PNG\r\n\x1a\n" + bytes(100))
    one_line(refused(tmp_path, scan_cfg("arm.png")), "arm.png", ".stl")
    one_line(refused(tmp_path, scan_cfg("nowhere.stl"), ConfigError), "geometry.scan.file",
             "nowhere.stl")


def test_text_that_parses_to_nothing_as_obj(tmp_path):
    (tmp_path / "limb.obj").write_text("# only a comment\nhello\n")
    one_line(refused(tmp_path, scan_cfg("limb.obj")), "limb.obj", "no triangles")


def test_a_hole_at_a_row_is_refused(tmp_path):
    # the cylinder's faces between x = -0.03 and -0.02 around u = 0 (ring 4 -> 5, the first
    # three quads) removed: row A's plane at x = -0.025 crosses the hole
    n = 90
    drop = np.concatenate([2 * (4 * n + np.arange(3)), 2 * (4 * n + np.arange(3)) + 1])
    cylinder_stl(tmp_path / "limb.stl", n=n, drop=drop)
    one_line(refused(tmp_path, scan_cfg("limb.stl")), "limb.stl", "row 0", "not closed")


def test_an_axis_that_misses_the_limb(tmp_path):
    cylinder_stl(tmp_path / "limb.stl")
    info = refused(tmp_path, scan_cfg("limb.stl", origin=[0.0, 0.1, 0.0]))
    one_line(info, "limb.stl", "encloses the axis")
    # an axis across the limb: the planes x = x_r cut it as lines, not around the axis
    info = refused(tmp_path, scan_cfg("limb.stl", axis=[0, 1, 0], y_axis=[0, 0, 1]))
    one_line(info, "limb.stl")


def test_rows_or_bands_past_the_scan(tmp_path):
    cylinder_stl(tmp_path / "limb.stl")
    one_line(refused(tmp_path, scan_cfg("limb.stl"), rows=np.array([0.0, 0.2])),
             "limb.stl", "does not cut the scan")
    one_line(refused(tmp_path, scan_cfg("limb.stl"), rows=np.array([0.0, 0.065])),
             "limb.stl", "reaches past the scan's end")


@pytest.mark.parametrize("scale, unit, size", [(1000.0, "m", "140 m"), (1.0, "mm", "0.00014 m")])
def test_the_wrong_unit_is_refused_with_the_plausible_range(tmp_path, scale, unit, size):
    # a cylinder 140 mm long written in mm but declared m, or written in m but declared mm
    cylinder_stl(tmp_path / "limb.stl", unit_scale=scale)
    info = refused(tmp_path, scan_cfg("limb.stl", unit=unit), ConfigError)
    one_line(info, "geometry.scan.unit", "limb.stl", size, "0.01 m to 3 m")


@pytest.mark.parametrize("key, value, expected", [
    ("axis", [0, 0, 0], "non-zero"),
    ("y_axis", [0, 0, 0], "non-zero"),
    ("y_axis", [2, 0, 0], "parallel"),
    ("y_axis", [1, 1e-5, 0], "parallel"),
    ("origin", [0, 0], "3 numbers"),
    ("axis", "x", "3 numbers"),
    ("unit", "cm", "mm, m"),
    ("unit", ["mm"], "mm, m"),
    ("max_triangles", 0, "whole number"),
    ("smoothing", -1.0, "length > 0"),
])
def test_bad_keys_name_the_key(tmp_path, key, value, expected):
    cylinder_stl(tmp_path / "limb.stl")
    info = refused(tmp_path, scan_cfg("limb.stl", **{key: value}), ConfigError)
    assert isinstance(info.value, ConfigError)
    one_line(info, f"geometry.scan.{key}", expected)


def test_missing_and_unknown_keys(tmp_path):
    cylinder_stl(tmp_path / "limb.stl")
    cfg = scan_cfg("limb.stl")
    del cfg["y_axis"]
    one_line(refused(tmp_path, cfg, ConfigError), "geometry.scan", "missing key 'y_axis'")
    one_line(refused(tmp_path, scan_cfg("limb.stl", units="mm"), ConfigError), "geometry.scan",
             "unknown key 'units'")
    one_line(refused(tmp_path, {**scan_cfg("limb.stl"), 1: 2, "z": 3}, ConfigError),
             "geometry.scan", "unknown key '1'")


@pytest.mark.parametrize("suffix", [".stl", "_ascii.stl", ".obj", ".ply"])
def test_too_many_triangles_are_refused(tmp_path, suffix):
    v, f = tube(90, np.linspace(-0.07, 0.07, 15), circle(0.045))
    name = "limb" + suffix
    if suffix == ".stl":
        write_binary_stl(tmp_path / name, v, f)
    elif suffix == "_ascii.stl":
        write_ascii_stl(tmp_path / name, v, f)
    else:
        trimesh.Trimesh(v, f, process=False).export(tmp_path / name)
    # 2520 triangles; 10 allowed: binary STL and PLY are refused from their header, the text
    # formats from their size
    info = refused(tmp_path, scan_cfg(name, max_triangles=10))
    one_line(info, name, "geometry.scan.max_triangles")


def test_a_huge_binary_stl_header_is_refused_before_reading(tmp_path, monkeypatch):
    # a binary STL whose size matches 3 million triangles, made sparse: refused from its header
    path = tmp_path / "limb.stl"
    with open(path, "wb") as fh:
        fh.write(b"x" * 80 + struct.pack("<I", 3_000_000))
        fh.truncate(84 + 50 * 3_000_000)
    monkeypatch.setitem(sys.modules, "trimesh", None)     # never reached
    with pytest.raises(DataError) as info:
        read_mesh(path)
    one_line(info, "limb.stl", "3,000,000 triangles", "1,000,000")


def test_missing_trimesh_names_the_extra(tmp_path, monkeypatch):
    cylinder_stl(tmp_path / "limb.stl")
    monkeypatch.setitem(sys.modules, "trimesh", None)
    with pytest.raises(UsageError) as info:
        load_scan(scan_cfg("limb.stl"), tmp_path)
    one_line(info, 'pip install "phri-spring[scan]"')


def test_load_scan_places_the_mesh_in_the_cuff_frame(tmp_path):
    rotation, origin = turned_frame()
    v, f = tube(30, np.linspace(-0.07, 0.07, 5), ellipse_section)
    write_binary_stl(tmp_path / "limb.stl", to_scan_mm(v, rotation, origin), f)
    cfg = scan_cfg("limb.stl", unit="mm", origin=origin.tolist(),
                   axis=(-3 * rotation[:, 0]).tolist(), y_axis=rotation[:, 2].tolist())
    scan = load_scan(cfg, tmp_path)
    # axis reversed and +y along the old +z: the cuff's (x, y, z) are the old (-x, z, y)
    want = np.column_stack([-v[:, 0], v[:, 2], v[:, 1]])
    got = scan.vertices[np.lexsort(scan.vertices.T)]
    np.testing.assert_allclose(got, want[np.lexsort(want.T)], atol=1e-7)
    assert scan.faces.shape == f.shape


def test_the_bundled_example_scan(tmp_path):
    """examples/scan/upper_arm.stl is what examples/make_scan.py writes, small, and usable."""
    import runpy
    root = REPO
    bundled = root / "examples" / "scan" / "upper_arm.stl"
    assert bundled.stat().st_size < 1_000_000
    maker = runpy.run_path(str(root / "examples" / "make_scan.py"))
    maker["write_scan"](tmp_path / "again.stl")
    rec = np.dtype([("n", "<f4", 3), ("v", "<f4", (3, 3)), ("a", "<u2")])
    again, kept = ((tmp_path / "again.stl").read_bytes(), bundled.read_bytes())
    assert again[:84] == kept[:84] and len(again) == len(kept)
    # the same triangles to well below a micrometre (not bytes: libm may round sin differently)
    np.testing.assert_allclose(np.frombuffer(again[84:], rec)["v"],
                               np.frombuffer(kept[84:], rec)["v"], atol=1e-4)
    cfg = scan_cfg(str(bundled), unit="mm", origin=[262.687, -94.627, 973.133],
                   axis=[0.1, 0.2, -1.0], y_axis=[1.0, 0.0, 0.0])
    g = scan_elements(cfg, ROWS_X, ROW_W, np.radians(75 + 35.0 * np.arange(7)), SPAN)
    # the limb tapers by 4 degrees toward +x: every inward normal leans toward -x by about that
    np.testing.assert_allclose(-g.normals[:, 0], np.sin(np.radians(4.0)), rtol=0.05)
    assert g.turning.shape == (21,) and np.all(g.areas > 0)
