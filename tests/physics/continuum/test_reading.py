"""What a coupled patch reads: the compressive part of its normal traction (docs/model.md 10.6).

References: the sum of positive parts written out as loops (the definition), the built-in
FE's condensed output map N (the traction integral the parts must add up to), the
spring model's hoop preload f0 (section 3) that the patches read at zero wrench.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from phri_spring.io.cache import surface_stiffness as ss
from phri_spring.io.config import load_config
from phri_spring.physics.continuum.reading import PatchReading, node_parts, parts_sum
from phri_spring.physics.continuum.spread import scale_parts
from phri_spring.physics.cuff.geometry import cuff_geometry
from phri_spring.physics.cuff.preload import strap_preload
from phri_spring.workflows.common import model_from_config

from support.helpers import REPO

pytest.importorskip("skfem", reason="the fe extra (scikit-fem) is part of the test extra")


@settings(max_examples=40, deadline=None)
@given(st.integers(1, 5), st.integers(1, 4), st.integers(0, 2**31 - 1))
def test_the_reading_is_the_sum_of_positive_parts(n, per, seed):
    rng = np.random.default_rng(seed)
    d = 3
    owner = np.sort(np.concatenate([np.arange(n), rng.integers(0, n, size=per * n)]))
    rows = rng.normal(size=(len(owner), n * d))
    C_t = rng.normal(size=(n * d, n * d))
    P = rng.normal(size=(7, n * d))
    reading = PatchReading.build(rows, owner, C_t, n)(P)
    q = P @ C_t.T
    expected = np.zeros((len(P), n))
    for i in range(len(P)):
        for k, e in enumerate(owner):
            expected[i, e] += max(float(rows[k] @ q[i]), 0.0)
    np.testing.assert_allclose(reading, expected, rtol=1e-12, atol=1e-12)
    # never below the clipped traction integral, equal to it where every part presses
    N = parts_sum(rows, owner, n)
    assert np.all(reading >= np.maximum(q @ N.T, 0.0) - 1e-12)
    parts = q @ rows.T
    for e in range(n):
        all_press = np.all(parts[:, owner == e] >= 0, axis=1)
        np.testing.assert_allclose(reading[all_press, e], (q @ N.T)[all_press, e], rtol=1e-12,
                                   atol=1e-12)
        nothing = np.all(parts[:, owner == e] <= 0, axis=1)
        assert np.all(reading[nothing, e] == 0.0)


@pytest.mark.parametrize("pinned", [True, False])
def test_a_long_reading_is_the_same_split_over_two_threads(monkeypatch, pinned):
    """Where BLAS is held to one thread, a long reading's second half goes to a second
    thread, split at a multiple of the row blocks: every row comes out bit for bit as the
    one-thread reading's (reference: the rows read 1,024 at a time in this thread)."""
    from phri_spring.physics.continuum import reading as rd

    for v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        monkeypatch.delenv(v, raising=False)
    if pinned:
        monkeypatch.setenv("OPENBLAS_NUM_THREADS", "1")
    rng = np.random.default_rng(7)
    n, d = 4, 6
    owner = np.repeat(np.arange(n), 5)
    reading = PatchReading(G=rng.normal(size=(len(owner), n * d)), owner=owner)
    P = rng.normal(size=(2 * rd._SPLIT_AT + 3 * rd._CHUNK + 17, n * d))
    expected = np.empty((len(P), n))
    for a in range(0, len(P), rd._CHUNK):
        Pc = P[a:a + rd._CHUNK]
        expected[a:a + len(Pc)] = np.add.reduceat(np.maximum(Pc @ reading.G.T, 0.0),
                                                  reading.starts, axis=1)
    np.testing.assert_array_equal(reading(P), expected)


def test_rows_must_name_every_patch_in_order():
    with pytest.raises(ValueError, match="every patch"):
        PatchReading.build(np.ones((2, 6)), [0, 0], np.eye(6), 2)
    with pytest.raises(ValueError, match="grouped by patch"):
        PatchReading.build(np.ones((3, 6)), [1, 0, 1], np.eye(6), 2)


def test_scaled_parts_follow_the_scaled_output_map():
    rng = np.random.default_rng(3)
    n, d = 3, 6
    owner = np.array([0, 0, 1, 2, 2, 2])
    rows = rng.normal(size=(6, n * d))
    s = np.array([0.5, 1.0, 3.0])
    r = np.sqrt(s)
    expected = parts_sum(rows, owner, n) * r[:, None] * np.repeat(r, d)[None, :]
    np.testing.assert_allclose(parts_sum(scale_parts(rows, owner, s, d), owner, n), expected,
                               rtol=1e-14)


def test_the_fe_node_parts_add_up_to_its_traction_integral(tmp_path):
    # one row of four 40-degree patches on a 40 mm arm (a quick level-1 FE)
    g = cuff_geometry(row_x=[0.0], radius=0.04, row_width=0.02, angle_start_deg=0.0,
                      angle_step_deg=40.0, angle_count=4)
    ops = ss.load_or_build_operators(g, 0.015, 2.0e4, 0.4, cache_dir=tmp_path, level=1)
    assert ops.parts is not None and ops.parts.shape[1] == 6 * g.n
    np.testing.assert_array_equal(ops.part_patch, np.sort(ops.part_patch))
    np.testing.assert_allclose(parts_sum(ops.parts, ops.part_patch, g.n), ops.N,
                               rtol=0, atol=1e-12 * np.abs(ops.N).max())
    # a level-1 plate is one quadratic facet: 3 x 3 skin nodes, a part each
    assert np.array_equal(np.bincount(ops.part_patch), np.full(g.n, 9))
    again = ss.load_or_build_operators(g, 0.015, 2.0e4, 0.4, cache_dir=tmp_path, level=1)
    assert again.info["source"] == "cache"
    np.testing.assert_array_equal(again.part_patch, ops.part_patch)
    np.testing.assert_allclose(again.parts, ops.parts, rtol=1e-15, atol=0)


def test_node_parts_group_each_nodes_components():
    # two nodes (dofs 0-2 and 3-5), two patches; node 1 shares both
    C = np.array([[1.0, 0], [0, 0], [0, 0], [0.5, 0.25], [0, 0.5], [0, 0]])
    lam = np.arange(12.0).reshape(6, 2)
    rows, owner = node_parts(C, lam, np.arange(6))
    np.testing.assert_array_equal(owner, [0, 0, 1])
    np.testing.assert_allclose(rows, [C[:3, 0] @ lam[:3], C[3:, 0] @ lam[3:],
                                      C[3:, 1] @ lam[3:]])


@pytest.mark.parametrize("preset", ["human_upper_arm", "harmony_upper_arm"])
def test_at_zero_wrench_the_patches_read_the_hoop_preload(preset):
    cfg = load_config(REPO / "configs" / f"{preset}.yaml")
    model = model_from_config(cfg, "coupled")
    assert model.reading is not None
    f0, _ = strap_preload(model.geometry, cfg.strap_tension, "hoop")
    from phri_spring.physics.contact.solver import solve

    sol = solve(model, np.zeros((1, 6)))
    np.testing.assert_allclose(sol.forces[0], f0, rtol=1e-9)
