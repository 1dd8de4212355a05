"""The hyperelastic reference FE (phri_spring.physics.hyperelastic.fe, felupe).

Expected values come from the project's linear FE on the same mesh
(references.rigid_cuff_fe.direct_rigid_cuff_response, scikit-fem), from statics (the patch forces add
up to the cuff's resultant) and from a property of the neo-Hookean law (a pushed layer
stiffens, a pulled one softens). The human preset's cuff on a coarse mesh (level 1,
1.5 thicknesses of tissue beyond each cuff edge) keeps the file fast.
"""

from __future__ import annotations

import builtins

import numpy as np
import pytest

pytest.importorskip("felupe", reason="the hyper extra (felupe) is not installed")
pytest.importorskip("skfem", reason="the fe extra (scikit-fem) is part of the test extra")

from phri_spring.errors import UsageError  # noqa: E402
from phri_spring.physics.hyperelastic import fe as fh  # noqa: E402
from phri_spring.physics.continuum.coupled import patch_frames  # noqa: E402
from references.rigid_cuff_fe import direct_rigid_cuff_response  # noqa: E402
from support.helpers import harmony_geometry  # noqa: E402

GEOM = harmony_geometry()   # the human preset's cuff is the Harmony's
T, E, NU, LF = 0.025, 3.0e4, 0.45, 1.5


@pytest.fixture(scope="module")
def linear_fe():
    Kc, Fn, _ = direct_rigid_cuff_response(GEOM, T, NU, level=1, length_factor=LF)
    return E * Kc, E * Fn


@pytest.fixture(scope="module")
def neo():
    return fh.build_hyper_cuff(GEOM, T, E, NU, level=1, length_factor=LF)


@pytest.fixture(scope="module")
def lin():
    return fh.build_hyper_cuff(GEOM, T, E, NU, level=1, length_factor=LF, law="linear")


def test_linear_law_is_the_linear_fe(lin, linear_fe):
    # same mesh, element and quadrature as the scikit-fem FE: equal to round-off
    Kc, Fn = linear_fe
    lin.restore({})
    for u in (np.array([0, 1e-3, 0, 0, 0, 0]), np.array([2e-4, 0, -5e-4, 0.01, 0, 0.02])):
        s = fh.patch_forces(lin, u, preload=False)
        np.testing.assert_allclose(s.wrench, Kc @ u, rtol=0, atol=1e-9 * np.abs(Kc @ u).max())
        np.testing.assert_allclose(s.normal_forces, Fn @ u, rtol=0,
                                   atol=1e-9 * np.abs(Fn @ u).max())


def test_small_strain_limit(neo, linear_fe):
    # 0.1 N / 0.01 N*m move the skin ~10 um (strain ~ 4e-4): the neo-Hookean answer is the
    # linear one up to terms of that order; 0.2 % of the peak patch force leaves room for
    # them while any error of the model (kinematics, output, a factor in mu or K) is larger
    Kc, Fn = linear_fe
    neo.restore({})
    for W in np.diag([0.1, 0.1, 0.1, 0.01, 0.01, 0.01])[[0, 1, 2, 4, 5]]:
        s = fh.solve_wrench(neo, W, preload=False)
        u = np.linalg.solve(Kc, W)
        f = Fn @ u
        assert np.abs(s.normal_forces - f).max() <= 2e-3 * np.abs(f).max()
        np.testing.assert_allclose(s.u, u, rtol=0, atol=2e-3 * np.abs(u).max())
        np.testing.assert_allclose(s.wrench, W, rtol=0, atol=1e-8)


def test_zero_displacement_zero_force(neo):
    neo.restore({})
    s = fh.patch_forces(neo, np.zeros(6), preload=False)
    assert np.abs(s.normal_forces).max() == 0 and np.abs(s.patch_forces).max() == 0
    assert np.abs(s.wrench).max() == 0


def test_force_balance_with_preload_and_finite_rotation(neo):
    # every plate pressed 1 mm in and turned 0.02 rad about its axial axis; the cuff moved
    # 1 mm and turned 0.06 rad: the patches' forces and moments add up to the resultant
    delta = np.zeros((GEOM.n, 6))
    delta[:, 0], delta[:, 4] = 1e-3, 0.02
    neo.set_preload(delta)
    try:
        u = np.array([0.0, 1e-3, 5e-4, 0.06, 0.0, 0.01])
        s = fh.patch_forces(neo, u, steps=2)
        R = fh.rotation_matrix(u[3:])
        F = np.einsum("eji,ej->ei", patch_frames(GEOM), s.patch_forces[:, :3])
        M = np.einsum("eji,ej->ei", patch_frames(GEOM), s.patch_forces[:, 3:])
        frames = patch_frames(GEOM)
        centres = GEOM.points + np.einsum("eji,ej->ei", frames, delta[:, :3])
        arm = centres @ R.T                      # moved centre - moved cuff origin
        np.testing.assert_allclose(F.sum(0), s.wrench[:3], atol=1e-9)
        np.testing.assert_allclose((np.cross(arm, F) + M).sum(0), s.wrench[3:], atol=1e-9)
        # load control back to that resultant finds the same pose
        neo.restore({})
        s2 = fh.solve_wrench(neo, s.wrench, steps=1)
        np.testing.assert_allclose(s2.u, u, rtol=0, atol=1e-7)
        np.testing.assert_allclose(s2.normal_forces, s.normal_forces, rtol=0,
                                   atol=1e-6 * np.abs(s.normal_forces).max())
    finally:
        neo.set_preload(np.zeros(6 * GEOM.n))


def test_push_stiffens_pull_softens(neo, lin):
    # the patches sit round theta = 180 deg (-y): +y presses them in, -y pulls them out
    out = {}
    for name, m in (("neo", neo), ("lin", lin)):
        for sign in (1, -1):
            m.restore({})
            s = fh.patch_forces(m, [0, sign * 0.01, 0, 0, 0, 0], preload=False, steps=1)
            out[name, sign] = sign * s.wrench[1]
    assert out["lin", 1] == pytest.approx(out["lin", -1], rel=1e-9)
    assert out["neo", 1] > 1.1 * out["lin", 1]
    assert out["neo", -1] < 0.95 * out["lin", -1]


def test_missing_felupe_is_a_usage_error(monkeypatch):
    real = builtins.__import__

    def fake(name, *args, **kwargs):
        if name == "felupe" or name.startswith("felupe."):
            raise ImportError(name)
        return real(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", fake)
    with pytest.raises(UsageError, match=r"pip install -e \.\[hyper\]"):
        fh.build_hyper_cuff(GEOM, T, E, NU, level=1)
