"""The coupled arm's events solved on the patches in contact only give the full systems'
answers (docs/model.md 12.5).

A released patch's rows in an event's Newton system and in its state's final system say
P_e = 0; the solver eliminates them and solves the smaller block, and takes a Newton step
that solved a state's own system (no patch sliding) as the answer. The reference is the
same path solved with the full systems (``friction_events._REDUCE`` off) and, for the
block elimination itself, a dense solve of the whole matrix.
"""

from __future__ import annotations

import dataclasses
from functools import lru_cache

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from phri_spring.io.config import load_config
from phri_spring.physics.friction import events as friction_events
from phri_spring.physics.friction.form import RELEASED, SLIDING, STUCK, solve_state, interface_form
from phri_spring.physics.contact.solver import solve
from phri_spring.workflows.common import cuff_wrench, model_from_config

from support.helpers import REPO

COLS = ["Fx", "Fy", "Fz", "Mx", "My", "Mz"]


@pytest.mark.parametrize("preset", ["human_upper_arm", "harmony_upper_arm"])
@pytest.mark.parametrize("mu", [None, 0.5])
def test_reduced_events_match_the_full_systems_on_the_example_log(preset, mu, monkeypatch):
    cfg = dataclasses.replace(load_config(REPO / "configs" / f"{preset}.yaml"),
                              friction_coefficient=mu)
    model = model_from_config(cfg, "coupled")
    log = pd.read_csv(REPO / "examples" / "wrench_log.csv", comment="#")[COLS].to_numpy()
    W = cuff_wrench(cfg, log)
    fast = solve(model, W)
    monkeypatch.setattr(friction_events, "_REDUCE", False)
    full = solve(model, W)
    assert (fast.iterations > 1).sum() > 50          # the log has events to compare
    np.testing.assert_array_equal(fast.converged, full.converged)
    ok = full.converged
    peak = np.abs(full.forces[ok]).max()
    assert np.abs(fast.forces[ok] - full.forces[ok]).max() <= 1e-9 * peak
    np.testing.assert_array_equal(fast.contact[ok], full.contact[ok])


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), n=st.integers(2, 8),
       released=st.lists(st.booleans(), min_size=8, max_size=8))
def test_reduced_step_equals_the_dense_solve(seed, n, released):
    """Rows of released patches that are identity rows are eliminated exactly."""
    rng = np.random.default_rng(seed)
    d = 6
    N = n * d
    J = rng.normal(size=(N + 6, N + 6)) + 5 * np.eye(N + 6)
    phi = rng.normal(size=N + 6)
    touch = ~np.array(released[:n])
    slide = rng.random(n) < 0.5
    slide[~touch] = True                 # a released patch with a trial slip
    dof = np.arange(N).reshape(n, d)
    for e in np.flatnonzero(~touch):
        J[dof[e]] = 0.0
        J[dof[e], dof[e]] = 1.0
    keep = friction_events._kept_rows((touch, slide), d)
    assert not keep[dof[~touch].ravel()].any() and keep[dof[touch].ravel()].all()
    dx = friction_events._reduced_step(J[keep], phi, keep)
    np.testing.assert_allclose(dx, np.linalg.solve(J, -phi), rtol=1e-8, atol=1e-10)
    assert np.all(dx[dof[~touch].ravel()] == -phi[dof[~touch].ravel()])


@lru_cache(maxsize=1)
def _harmony_form():
    cfg = load_config(REPO / "configs" / "harmony_upper_arm.yaml")
    return interface_form(model_from_config(cfg, "coupled"))


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**31 - 1))
def test_reduced_state_solve_equals_the_full_one(seed):
    form = _harmony_form()
    rng = np.random.default_rng(seed)
    n, d = form.n, form.d
    cls = rng.choice([RELEASED, STUCK, SLIDING], size=n, p=[0.3, 0.5, 0.2])
    cls[0] = STUCK
    s = rng.normal(size=(n, 2))
    s /= np.linalg.norm(s, axis=1, keepdims=True)
    z = 1e-4 * rng.normal(size=(n, d))
    r = np.concatenate([rng.normal(0, 30, 3), rng.normal(0, 1, 3)])
    full = solve_state(form, r, cls, z, s)
    fast = solve_state(form, r, cls, z, s, reduce=True)
    assert (full is None) == (fast is None)
    if full is not None:
        scale = np.abs(full[1]).max()
        np.testing.assert_allclose(fast[1], full[1], rtol=0, atol=1e-9 * scale)
        assert np.all(fast[1].reshape(n, d)[cls == RELEASED] == 0.0)
        np.testing.assert_allclose(fast[0], full[0], rtol=1e-7, atol=1e-12)
