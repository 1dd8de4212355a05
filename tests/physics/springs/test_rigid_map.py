"""The one rigid-body map (geometry.rigid_body_map) and its views, against numpy's cross product.

A small rigid motion u = (t, w) moves a point p by t + w x p and turns it by w; the
expected values here are numpy's ``np.cross``, never the package's own skew matrices.
"""

from __future__ import annotations

import types

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from phri_spring.physics.continuum.coupled import rigid_patch_map
from references.rigid_cuff_fe import rigid_cuff_map
from phri_spring.physics.cuff.geometry import element_jacobians, rigid_body_map, skew

_coord = st.floats(-1.0, 1.0, allow_nan=False, allow_infinity=False)
points = st.integers(1, 6).flatmap(lambda n: arrays(float, (n, 3), elements=_coord))
motions = arrays(float, (6,), elements=_coord)


def _moved(p, u):
    """Displacement t + w x p of every point (n, 3), by np.cross."""
    return u[:3] + np.cross(u[3:], p)


@settings(max_examples=60, deadline=None)
@given(p=points, u=motions)
def test_rigid_body_map_moves_a_point_by_t_plus_w_cross_p(p, u):
    d = rigid_body_map(p) @ u
    np.testing.assert_allclose(d, _moved(p, u), rtol=0, atol=1e-14)
    full = rigid_body_map(p, rotations=True) @ u
    np.testing.assert_allclose(full[:, :3], d, rtol=0, atol=0)
    np.testing.assert_array_equal(full[:, 3:], np.broadcast_to(u[3:], (len(p), 3)))


@settings(max_examples=60, deadline=None)
@given(p=points, u=motions)
def test_every_view_of_the_map_is_the_same_map(p, u):
    n = len(p)
    expected = _moved(p, u)
    with_w = np.hstack([expected, np.broadcast_to(u[3:], (n, 3))])
    np.testing.assert_allclose(element_jacobians(p) @ u, expected, rtol=0, atol=1e-14)
    np.testing.assert_allclose((rigid_cuff_map(p, rotations=False) @ u).reshape(n, 3),
                               expected, rtol=0, atol=1e-14)
    np.testing.assert_allclose((rigid_cuff_map(p) @ u).reshape(n, 6), with_w,
                               rtol=0, atol=1e-14)
    geometry = types.SimpleNamespace(n=n, points=p)
    np.testing.assert_allclose((rigid_patch_map(geometry, 3) @ u).reshape(n, 3), expected,
                               rtol=0, atol=1e-14)
    np.testing.assert_allclose((rigid_patch_map(geometry, 6) @ u).reshape(n, 6), with_w,
                               rtol=0, atol=1e-14)


@settings(max_examples=60, deadline=None)
@given(p=arrays(float, (4, 5, 3), elements=_coord), v=arrays(float, (3,), elements=_coord))
def test_skew_is_the_cross_product_for_any_leading_shape(p, v):
    np.testing.assert_allclose(skew(p) @ v, np.cross(p, v), rtol=0, atol=1e-15)
    assert rigid_body_map(p).shape == (4, 5, 3, 6)
