"""Patch gaps of the built-in tissue FE (``tissue.continuum.patch_gap``, docs/coupled-fe.md).

Tiled patches that move independently impose a displacement jump at their shared edges,
which the FE cannot represent (the L2 projection smears it over the neighbours) and whose
energy grows without bound as the mesh is refined. A strip of free skin between the plates
removes the jump: then every patch motion is imposed exactly on every mesh, so the
condensed stiffness is the energy of one fixed boundary-value problem, approximated from
above by a conforming FE, and converges (benchmarks/fe_patch_gap.py shows it for levels
2-5). The expected values here are written from the geometry by hand, not taken from
the package.
"""

from __future__ import annotations

import copy

import numpy as np
import pytest
import scipy.sparse.linalg as spla
import yaml

from phri_spring.errors import ConfigError, ModelInputError
from phri_spring.io.cache import surface_stiffness as ss
from phri_spring.physics.continuum import tissue as fe
from phri_spring.physics.continuum.assembly import _facet_arrays
from phri_spring.physics.cuff.geometry import cuff_geometry, rigid_body_map

from references import rigid_cuff_fe
from support.helpers import HARMONY_CONFIG, run_phri as run, stderr_of

pytest.importorskip("skfem", reason="the fe extra (scikit-fem) is part of the test extra")

R = 0.045
#: 2 rows 25 mm wide, 25 mm apart, 3 locations 35 deg apart: tiled in both directions
TILED = cuff_geometry([-0.0125, 0.0125], R, 0.025, 55.0, 35.0, 3)


def _facet_extent(tm, facets):
    """(x_min, x_max, theta_min, theta_max) of the vertices of skin facets, and the set
    of their mesh vertices."""
    verts = np.unique(tm.mesh.facets[:, facets])
    p = tm.mesh.p[:, verts]
    th = np.arctan2(p[2], p[1])
    th = np.where(th < 0, th + 2 * np.pi, th)
    return (p[0].min(), p[0].max(), th.min(), th.max()), set(verts.tolist())


@pytest.mark.parametrize("gap", [0.001, 0.004])
def test_the_gap_leaves_a_strip_of_free_skin_of_its_width(gap):
    tm = fe.build_mesh(TILED, 0.01, 1, 1.0, gap)
    ext, verts = zip(*(_facet_extent(tm, f) for f in tm.patch_facets))
    # the cells, by hand: rows [-25, 0] and [0, 25] mm; cells 37.5-72.5, 72.5-107.5 and
    # 107.5-142.5 deg; a shared edge moves back by gap/2 (gap/2R around the arm), an outer
    # edge stays
    d = gap / (2 * R)
    x_cells = {0: (-0.025, -gap / 2), 1: (gap / 2, 0.025)}
    th_cells = {0: (37.5, 72.5), 1: (72.5, 107.5), 2: (107.5, 142.5)}
    for e in range(TILED.n):
        row, loc = divmod(e, 3)
        x0, x1, t0, t1 = ext[e]
        lo, hi = np.radians(th_cells[loc])
        lo += d if loc > 0 else 0.0
        hi -= d if loc < 2 else 0.0
        np.testing.assert_allclose([x0, x1], x_cells[row], atol=1e-12)
        np.testing.assert_allclose([t0, t1], [lo, hi], atol=1e-12)
        # and the plates the FE reports are those of the mesh
        np.testing.assert_allclose([v[e] for v in fe.patch_plates(TILED, gap)],
                                   [x0, x1, t0, t1], atol=1e-12)
    # no patch's facets touch another's
    for a in range(TILED.n):
        for b in range(a + 1, TILED.n):
            assert not verts[a] & verts[b], (TILED.labels[a], TILED.labels[b])
    # inside the cuff's footprint, the skin in no patch is exactly the strips
    on_skin = np.all(np.abs(np.hypot(*tm.mesh.p[1:, tm.mesh.facets]) - R) < 1e-9 * R, axis=0)
    c = tm.mesh.p[:, tm.mesh.facets].mean(axis=1)
    th = np.degrees(np.mod(np.arctan2(c[2], c[1]), 2 * np.pi))
    inside = on_skin & (np.abs(c[0]) < 0.025) & (th > 37.5) & (th < 142.5)
    strip = (np.abs(c[0]) < gap / 2) | (np.abs(th - 72.5) < np.degrees(d)) | (
        np.abs(th - 107.5) < np.degrees(d))
    free = np.ones(tm.mesh.facets.shape[1], bool)
    free[tm.cuff_facets] = False
    assert (inside & strip).any()
    np.testing.assert_array_equal(free[inside], strip[inside])


def test_tiled_patches_touch_without_a_gap():
    """The check above can fail: with no gap neighbouring patches share mesh vertices."""
    tm = fe.build_mesh(TILED, 0.01, 1, 1.0, 0.0)
    verts = [_facet_extent(tm, f)[1] for f in tm.patch_facets]
    assert verts[0] & verts[1] and verts[0] & verts[3]       # A0-A1 and A0-B0 share edges
    assert not verts[0] & verts[5]                           # A0 and B2 do not


def _imposed_field_error(gap):
    """Relative L2 error, over the plates, of the skin field imposed for every single-patch
    rigid motion (the L2 projection A q against the piecewise rigid field it stands for)."""
    t_fe = fe.assemble_tissue_fe(TILED, 0.01, 0.45, 1, 1.0, "fixed", patch_gap=gap)
    s = t_fe.skin
    A = spla.splu(t_fe.M[s][:, s].tocsc()).solve(t_fe.B[s])         # (len(s), 6n)
    full = np.zeros((3 * t_fe.n_nodes, A.shape[1]))
    full[s] = A
    full = full[t_fe.dof_map]                                        # unreduced dofs
    phi, dx, X, edofs = _facet_arrays(t_fe.mesh, t_fe.basis, t_fe.mesh.cuff_facets)
    owner = np.empty(len(t_fe.mesh.cuff_facets), int)
    pos = {f: k for k, f in enumerate(t_fe.mesh.cuff_facets)}
    for e, fs in enumerate(t_fe.mesh.patch_facets):
        owner[[pos[f] for f in fs]] = e
    worst = 0.0
    for col in range(A.shape[1]):
        e, j = divmod(col, 6)
        u = np.einsum("iafq,fiq->afq", phi, full[edofs.T, col][:, :, None]
                      * np.ones(phi.shape[-1]))
        exact = np.zeros_like(u)
        on = owner == e
        rel = np.moveaxis(X[:, on] - TILED.points[e][:, None, None], 0, -1)
        exact[:, on] = np.moveaxis(rigid_body_map(rel)[..., j], -1, 0)
        err = np.sqrt(np.sum((u - exact) ** 2 * dx))
        worst = max(worst, err / np.sqrt(np.sum(exact ** 2 * dx)))
    return worst


def test_gapped_patch_motions_are_imposed_exactly_and_tiled_ones_are_not():
    """Why gaps converge: each plate's rigid motion, its neighbours held, is imposed exactly.

    With a gap the piecewise rigid field lies in the FE space (the strips between plates
    are free), so the projection reproduces it to round-off and refining the mesh only
    refines the approximation of one fixed problem. Tiled, the field jumps at the shared
    edges; the projection spreads the jump over the neighbours' first elements (tens of
    % here) and sharpens it with every refinement, which is what does not converge.
    """
    assert _imposed_field_error(0.002) < 1e-9
    assert _imposed_field_error(0.0) > 0.05


@pytest.mark.parametrize("gap", [0.0, 0.003])
def test_rigid_cuff_on_the_plates_is_the_direct_fe(gap):
    """T^T K T is the direct FE of the cuff bonded to the plates only (tiled: all of them)."""
    ops = fe.condensed_surface_operators(TILED, 0.01, 1.0, 0.45, level=1, patch_gap=gap,
                                         length_factor=1.0)
    Kc, Fn, _ = rigid_cuff_fe.direct_rigid_cuff_response(TILED, 0.01, 0.45, level=1, length_factor=1.0,
                                              patch_gap=gap)
    T = rigid_cuff_fe.rigid_cuff_map(TILED.points)
    np.testing.assert_allclose(T.T @ ops.K @ T, Kc, rtol=0, atol=1e-9 * np.max(np.abs(Kc)))
    np.testing.assert_allclose(ops.N @ T, Fn, rtol=0, atol=1e-9 * np.max(np.abs(Fn)))


def test_gapped_plates_make_a_softer_cuff():
    """Less skin bonded, a softer rigid cuff in every direction (the gap is not ignored)."""
    T = rigid_cuff_fe.rigid_cuff_map(TILED.points)
    diag = [np.diag(T.T @ fe.condensed_surface_operators(
        TILED, 0.01, 1.0, 0.45, level=1, patch_gap=gap, length_factor=1.0).K @ T)
        for gap in (0.0, 0.003)]
    assert np.all(diag[1] < diag[0])


def test_gaps_open_only_where_neighbours_are_closer_than_the_gap():
    """Cells already apart by more than the gap keep their width; closer ones give up half
    of the difference each."""
    g = cuff_geometry([0.0], R, 0.025, 55.0, 35.0, 3, angle_width_deg=30.0)   # 5 deg apart
    apart = R * np.radians(5.0)                                              # 3.93 mm
    _, _, lo, hi = fe.patch_plates(g, apart / 2)
    np.testing.assert_allclose(np.degrees(hi - lo), 30.0, atol=1e-12)
    _, _, lo, hi = fe.patch_plates(g, apart + 0.002)
    np.testing.assert_allclose(np.degrees(hi - lo),
                               30.0 - np.degrees(0.001 / R) * np.array([1, 2, 1]), atol=1e-12)


def test_cache_key_and_builds_distinguish_gaps(tmp_path, monkeypatch):
    g = cuff_geometry([0.0], R, 0.025, 55.0, 35.0, 3)
    keys = {gap: ss.cache_key(g, 0.01, 0.45, level=1, patch_gap=gap)
            for gap in (0.0, 0.001, 0.002)}
    assert len(set(keys.values())) == 3
    assert ss.cache_key(g, 0.01, 0.45, level=1) == ss.cache_key(
        g, 0.01, 0.45, level=1, patch_gap=fe.DEFAULT_PATCH_GAP)
    built = []
    real = fe.condensed_surface_operators
    monkeypatch.setattr(fe, "condensed_surface_operators",
                        lambda *a, **k: built.append(k["patch_gap"]) or real(*a, **k))
    K = {}
    for gap in (0.0, 0.002, 0.0):
        K[gap], info = ss.load_or_build(g, 0.01, 1e4, 0.45, level=1, cache_dir=tmp_path,
                                        patch_gap=gap)
        assert info["patch_gap"] == gap
    assert built == [0.0, 0.002]                  # the second gap 0 came from the cache
    assert info["source"] == "cache"
    assert not np.allclose(K[0.0], K[0.002], rtol=1e-3)
    _, info = ss.load_or_build(g, 0.01, 1e4, 0.45, level=1, cache_dir=tmp_path)
    assert info["patch_gap"] == fe.DEFAULT_PATCH_GAP          # no gap given: the default


@pytest.mark.parametrize("rows, gap, needles", [
    # tiled rows 25 mm wide, the middle one between two neighbours: no plate from 25 mm on
    ((-0.025, 0.0, 0.025), 0.03, ("row at x = 0 mm", "25 mm wide along the arm",
                                  "below 25 mm")),
    # rows 25 mm apart; the cells around the arm are 45 mm * 35 deg = 27.49 mm wide and
    # the middle ones have two neighbours
    ((-0.05, 0.0, 0.05), 0.0276, ("patches at 110 deg", "27.49 mm wide around the arm",
                                  "below 27.49 mm")),
])
def test_a_gap_that_leaves_no_plate_is_one_line(tmp_path, rows, gap, needles):
    g = cuff_geometry(rows, R, 0.025, 75.0, 35.0, 7)
    with pytest.raises(ConfigError) as exc:
        ss.load_or_build(g, 0.02, 1e4, 0.45, level=1, cache_dir=tmp_path, patch_gap=gap)
    msg = str(exc.value)
    assert msg.startswith("tissue.continuum.patch_gap: a gap of ") and "\n" not in msg
    assert "no plate" in msg and all(n in msg for n in needles), msg
    with pytest.raises(ModelInputError, match="^patch_gap: a gap of") as exc:
        fe.condensed_surface_operators(g, 0.02, 1.0, 0.45, level=1, patch_gap=gap)
    assert exc.value.quantity == "patch_gap"
    assert not list(tmp_path.iterdir())


def test_the_command_line_names_the_key(tmp_path):
    data = yaml.safe_load(open(HARMONY_CONFIG))
    data = copy.deepcopy(data)
    data["tissue"]["continuum"]["patch_gap"] = 0.025
    cfg = tmp_path / "cfg.yaml"
    cfg.write_text(yaml.safe_dump(data))
    res = run("stiffness", cfg, "--arm", "coupled")
    err = stderr_of(res).strip()
    assert res.exit_code == 1, err
    assert "\n" not in err and "internal error" not in err and "Traceback" not in err
    assert "tissue.continuum.patch_gap" in err and "no plate" in err


@pytest.mark.parametrize("gap", [0.0, 0.002])
def test_mesh_size_is_that_of_the_built_mesh(gap):
    """fe_mesh.mesh_size (what the memory check can size the FE by) counts the gap's strips."""
    from phri_spring.physics.continuum.mesh import periodic_map, mesh_size

    tm = fe.build_mesh(TILED, 0.01, 2, 1.0, gap)
    _, n_nodes = periodic_map(tm.comp, 0.01)
    assert mesh_size(TILED, 0.01, 2, 1.0, gap) == (tm.mesh.nelements, 3 * n_nodes)
