"""The coupled arm lets go of what lifts off, and every ``--shear`` table balances.

docs/model.md sections 10.2 and 10.6. Without ``interface.friction_coefficient`` the
linear coupled arm releases a patch out of contact (no force, no moment) and keeps a
touching one bonded within a Coulomb cone of :data:`LIFT_OFF_MU`; with the key, within mu.
The checks are the laws themselves, on the presets under one-sided pushes and random
wrenches, and the balance of the per-element forces and moments in the cuff frame
against the applied wrench plus the strap's, summed here from the table's columns.
"""

from __future__ import annotations

import dataclasses
import time

import numpy as np
import pytest

from phri_spring.io.config import load_config
from phri_spring.physics.continuum.coupled import LIFT_OFF_MU, build_coupled_model
from phri_spring.physics.springs.model import build_model, tissue_element_stiffness
from phri_spring.physics.contact.solver import solve
from phri_spring.physics.laws import LinearLaw
from phri_spring.workflows.common import cuff_wrench, model_from_config
from phri_spring.workflows.columns.shear import shear_extras

from support.helpers import REPO, harmony_geometry


def _config(preset, mu):
    cfg = load_config(REPO / "configs" / f"{preset}.yaml")
    # friction takes the linear tissue law (the spring arms'; the coupled arm's continuum
    # is linear either way)
    return dataclasses.replace(cfg, tissue_law="linear", tissue_law_class=LinearLaw,
                               tissue_law_parameters={}, friction_coefficient=mu)


def _pushes(cfg, peak=60.0, steps=6):
    """One-sided pushes of the load cell up to ``peak`` and back, along +-x, +-y, +-z of
    the load cell, read with the moment of their lever (a force at the load cell) and
    without it (the same force through the cuff origin), then seeded random wrenches:
    cuff-frame wrenches (m, 6)."""
    ramp = np.concatenate([np.linspace(0, peak, steps + 1)[1:], np.linspace(peak, 0, steps + 1)[1:]])
    rows = []
    for axis in range(3):
        for sign in (1.0, -1.0):
            W_lc = np.zeros((len(ramp), 6))
            W_lc[:, axis] = sign * ramp
            lever = cuff_wrench(cfg, W_lc)
            through = lever.copy()
            through[:, 3:] = 0.0
            rows += [lever, through]
    rng = np.random.default_rng(11)
    rows.append(rng.normal(size=(40, 6)) * np.array([15.0, 15.0, 15.0, 0.5, 0.5, 0.5]))
    return np.vstack(rows)


def _check(model, W, sol, mu):
    """Released patches carry nothing, touching ones stay in the cone, the columns balance."""
    ok = np.asarray(sol.converged, dtype=bool)
    # a sample without an answer says so: not converged, NaN forces
    assert np.isnan(sol.forces[~ok]).all()
    ex = shear_extras(model, sol)
    L, g = model.labels, model.geometry
    F = np.stack([np.stack([ex[f"{lab}_force_{a}_N"] for a in "xyz"], 1) for lab in L], 1)
    Mp = np.zeros_like(F)
    if f"{L[0]}_moment_x_Nm" in ex:
        Mp = np.stack([np.stack([ex[f"{lab}_moment_{a}_Nm"] for a in "xyz"], 1) for lab in L], 1)
    r = (W + model.W_pre)[ok]
    total = np.concatenate([F[ok].sum(1), (Mp[ok] + np.cross(g.points, F[ok])).sum(1)], 1)
    assert np.all(np.abs(total - r) <= 1e-9 * np.abs(r).max(axis=1, keepdims=True))
    fn = sol.normal[ok] if sol.normal is not None else sol.forces[ok]
    tn = np.linalg.norm(sol.tangential[ok], axis=2)
    scale = np.abs(r).max(axis=1, keepdims=True)
    assert np.all(fn >= -1e-9 * scale)
    off = fn <= 0.0
    assert np.all(tn[off] == 0.0)
    if sol.moments is not None:
        assert np.all(sol.moments[ok][off] == 0.0)
    assert np.all(F[ok][off] == 0.0)
    assert np.all(tn <= mu * np.maximum(fn, 0.0) + 1e-9 * scale)
    assert np.array_equal(sol.contact[ok], ~off)
    # the label column (what the patch's sensor reads, section 10.6) reads 0 N only where
    # the patch is out of contact: a patch that reads nothing carries nothing
    label = sol.forces[ok]
    assert np.all(label >= 0.0)
    quiet = label == 0.0
    assert np.all(tn[quiet] == 0.0) and np.all(F[ok][quiet] == 0.0)
    if sol.moments is not None:
        assert np.all(sol.moments[ok][quiet] == 0.0)
    assert np.all(label[~off] > 0.0)
    if mu != LIFT_OFF_MU:
        # with friction the cone holds on what the sensor reads too (section 10.2: its
        # normal force is the smaller of the force along n_e and the reading's integral)
        assert np.all(tn <= mu * label + 1e-9 * scale)
    return ok


@pytest.mark.parametrize("preset", ["human_upper_arm", "harmony_upper_arm"])
@pytest.mark.parametrize("mu", [None, 0.5])
def test_presets_coupled_release_what_lifts_off(preset, mu):
    cfg = _config(preset, mu)
    model = model_from_config(cfg, "coupled")
    W = _pushes(cfg)
    sol = solve(model, W)
    ok = _check(model, W, sol, LIFT_OFF_MU if mu is None else mu)
    assert (~sol.contact[ok]).any()           # the pushes lift patches off
    if mu is None:
        assert ok[:-40].mean() > 0.9 and ok.mean() > 0.85
    else:   # some pushes need more than mu = 0.5 to be held (docs/model.md 12.3)
        assert ok.mean() > 0.5


@pytest.mark.parametrize("arm", ["compliant", "rigid"])
@pytest.mark.parametrize("mu", [None, 0.5])
def test_spring_arms_shear_columns_balance(arm, mu):
    cfg = _config("harmony_upper_arm", mu)
    model = model_from_config(cfg, arm)
    W = _pushes(cfg)
    sol = solve(model, W)
    ok = np.asarray(sol.converged, dtype=bool)
    ex = shear_extras(model, sol)
    F = np.stack([np.stack([ex[f"{lab}_force_{a}_N"] for a in "xyz"], 1)
                  for lab in model.labels], 1)[ok]
    r = (W + model.W_pre)[ok]
    total = np.concatenate([F.sum(1), np.cross(model.geometry.points, F).sum(1)], 1)
    assert np.all(np.abs(total - r) <= 1e-9 * np.abs(r).max(axis=1, keepdims=True))
    if mu is None:   # the paper's bonded springs: lifted elements still carry shear
        assert sol.tangential is None and ok.all()


def test_a_block_diagonal_coupled_arm_is_the_spring_model_with_the_same_cone():
    """With independent patches the coupled arm's default is the spring model with
    friction at LIFT_OFF_MU (docs/model.md 10.3's reduction, with the interface of 10.2)."""
    g = harmony_geometry()
    k_t = tissue_element_stiffness(np.full(g.n, 4242.0), g.areas)
    eta = 0.4
    K = np.zeros((3 * g.n, 3 * g.n))
    for e in range(g.n):
        nn = np.outer(g.normals[e], g.normals[e])
        K[3 * e:3 * e + 3, 3 * e:3 * e + 3] = k_t[e] * nn + eta * k_t[e] * (np.eye(3) - nn)
    coupled = build_coupled_model(g, K, 2e5, shear_ratio=eta, strap_tension=15.0)
    spring = build_model(g, k_t, 2e5, shear_ratio=eta, strap_tension=15.0,
                         friction_coefficient=LIFT_OFF_MU)
    F = np.concatenate([np.linspace(0, 60, 30), np.linspace(60, 0, 30)])
    W = np.zeros((len(F), 6))
    W[:, 1], W[:, 2], W[:, 3] = -0.7 * F, 0.5 * F, 0.01 * F
    a, b = solve(spring, W), solve(coupled, W)
    # the pull toward the cuff's open side at the peak is beyond what the strap holds:
    # both flag the same samples
    np.testing.assert_array_equal(b.converged, a.converged)
    ok = a.converged
    assert ok.mean() > 0.9 and (~a.contact[ok]).any()
    peak = np.abs(a.forces[ok]).max()
    np.testing.assert_allclose(b.forces[ok], a.forces[ok], rtol=0, atol=1e-9 * peak)
    np.testing.assert_allclose(b.tangential[ok], a.tangential[ok], rtol=0, atol=1e-9 * peak)
    np.testing.assert_array_equal(b.contact, a.contact)


def test_frictionless_coupled_arm_flags_axial_loads_at_once():
    """mu = 0 on a cylinder: normal forces have no axial part and a patch's tied moments
    none at all, so any axial force has no equilibrium; each such sample is flagged after
    one small test, not after a stalled Newton iteration (docs/model.md 12.3)."""
    g = harmony_geometry()
    d2 = np.sum((g.points[:, None, :] - g.points[None, :, :]) ** 2, axis=-1)
    rot = np.diag([1.0, 1.0, 1.0, 1e-3, 1e-3, 1e-3])
    C = 2e-5 * np.kron(np.eye(g.n), rot) + 2e-5 * np.kron(np.exp(-d2 / 0.03**2), rot)
    model = build_coupled_model(g, np.linalg.inv(C), 2e5, strap_tension=15.0,
                                friction_coefficient=0.0)
    rng = np.random.default_rng(3)
    W = rng.normal(size=(300, 6)) * np.array([5.0, 20.0, 20.0, 0.2, 0.2, 0.2])
    t0 = time.perf_counter()
    sol = solve(model, W)
    assert time.perf_counter() - t0 < 5.0
    assert not sol.converged.any() and np.isnan(sol.forces).all()
