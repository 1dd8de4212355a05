"""The coupled arm's friction events by active sets (docs/model.md 12.3): a sample where
patches slip, stick, lift off or come back is solved on the sliding patches' forces alone,
the state found as a return mapping finds it.

Reference: each event sample solved again from the same state by the semismooth Newton
method on all patch forces (Alart and Curnier's nonsmooth equations, a different method,
``phri_spring.physics.friction.events``). Where Newton ends in the same state (the same
patches stuck, sliding on an open cone, sliding freely, released) the forces must agree to
round-off. Coulomb friction with a cone on the reading need not have one answer (a patch at
the edge of its cone or of contact can take either side, each passing every check), so a
few samples may get another state from Newton; almost all must agree. Every answer is
checked against the law itself (equilibrium, compression, the cone, slip along the force).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd
import pytest

from phri_spring.io.config import load_config
from phri_spring.physics.friction import active
from phri_spring.physics.friction import path as fp
from phri_spring.physics.friction.events import solve_event_coupled
from phri_spring.physics.friction.form import (SLIDING, STATE_RTOL, initial_state,
                                               interface_form, relative, scales)
from phri_spring.workflows.common import cuff_wrench, model_from_config

from support.helpers import REPO

pytest.importorskip("skfem", reason="the fe extra (scikit-fem) is part of the test extra")

COLS = ["Fx", "Fy", "Fz", "Mx", "My", "Mz"]


def _preset_path(preset, mu, rows):
    cfg = dataclasses.replace(load_config(REPO / "configs" / f"{preset}.yaml"),
                              friction_coefficient=mu)
    model = model_from_config(cfg, "coupled")
    form = interface_form(model)
    log = pd.read_csv(REPO / "examples" / "wrench_log.csv", comment="#")[COLS].to_numpy()
    return model, form, cuff_wrench(cfg, log[:rows]) + model.W_pre


def _open(state):
    return (state.cls == SLIDING) & np.any(state.s != 0.0, axis=1)


def _check_law(form, r, before, after, P, u):
    """The Coulomb law at one answer: the cuff's balance, compression, the cone on
    min(P_n, f), released patches free, a sliding patch's slip along its force."""
    n, d, mu = form.n, form.d, form.mu
    scale = np.abs(r).max() + np.abs(form.W_pre).max()
    np.testing.assert_allclose(form.T.T @ P, r, rtol=0, atol=1e-10 * scale)
    Pe = P.reshape(n, d)
    touch = after.cls != 0
    assert np.all(Pe[touch, 0] >= -1e-9 * scale)
    assert np.all(Pe[~touch] == 0.0)
    tn = np.hypot(Pe[:, 1], Pe[:, 2])
    assert np.all(tn <= mu * np.maximum(form.cone_force(P), 0.0) + 1e-9 * scale)
    # the slip of an open slider since the last sample (rel - its tie then) is along its
    # force: not against it beyond the solver's tolerance, and where it is larger than
    # that, in the force's direction to round-off
    op = _open(after)
    slip = relative(form, u, P).reshape(n, d)[op, 1:3] - before.z[op, 1:3]
    F = Pe[op, 1:3]
    x_tol = STATE_RTOL * scales(form, r)[1]
    ns, nf = np.linalg.norm(slip, axis=1), np.linalg.norm(F, axis=1)
    along = np.einsum("ek,ek->e", slip, F) / nf
    assert np.all(along >= -x_tol)
    big = ns > 1e3 * x_tol
    assert np.all(along[big] >= (1.0 - 1e-9) * ns[big])


@pytest.mark.parametrize("preset", ["human_upper_arm", "harmony_upper_arm"])
def test_active_set_events_are_the_semismooth_newtons_answers(preset):
    model, form, r = _preset_path(preset, 0.5, 3000)
    state, cache = initial_state(form), {}
    same = other = 0
    agree = []
    for i in range(len(r)):
        before = state
        u, P, cls, solves, conv, state = fp.solve_path(form, r[i:i + 1], before, cache)
        if solves[0] == 0:          # a block row, not an event
            continue
        assert conv[0]
        _check_law(form, r[i], before, state, P[0], u[0])
        ue, Pe, new, _, ok = solve_event_coupled(form, r[i], before)
        if ok and np.array_equal(new.cls, cls[0]) and np.array_equal(_open(new), _open(state)):
            same += 1
            agree.append(np.abs(Pe - P[0]).max() <= 1e-9 * np.abs(P[0]).max())
        else:
            other += 1
    assert same > 100 and other <= 0.05 * (same + other)
    assert np.mean(agree) >= 0.98


def test_the_scalar_iterations_are_the_array_iteration(monkeypatch):
    """One and a few sliding patches are iterated in Python scalars (cheaper at that size);
    each call along a path is repeated with the array iteration: the same forces, slip
    directions and outcome."""
    model, form, r = _preset_path("human_upper_arm", 0.5, 3000)
    seen = {1: 0, 2: 0}

    def checked(fast):
        def run(sm, base, F, mu, tol):
            out = fast(sm, base.copy(), F.copy(), mu, tol)
            ref = active._newton(sm, base.copy(), F.copy(), mu, tol)
            seen[min(sm.K, 2)] += 1
            if isinstance(ref, tuple):
                assert isinstance(out, tuple)
                scale = np.abs(ref[0]).max()
                np.testing.assert_allclose(out[0], ref[0], rtol=0, atol=1e-9 * scale)
                np.testing.assert_allclose(out[2], ref[2], rtol=0, atol=1e-9)
            elif ref is None:
                assert out is None
            else:
                np.testing.assert_array_equal(out, ref)
            return out
        return run

    monkeypatch.setattr(active, "_newton_one", checked(active._newton_one))
    monkeypatch.setattr(active, "_newton_few", checked(active._newton_few))
    u, P, cls, solves, conv, _ = fp.solve_path(form, r, initial_state(form), {})
    assert conv.all() and seen[1] > 100 and seen[2] > 10


def test_a_patch_toggling_at_the_edge_of_contact_comes_back_sliding_freely(monkeypatch):
    """Harmony's preset at mu = 0.5: a released patch that its neighbours press back into
    the cuff pulls once tied where it lands, and released again is pressed back. The
    answer (the semismooth Newton's too) is the patch touching with its cone closed,
    sliding freely; the active sets take it when the states start to repeat, instead of
    handing the sample to the semismooth Newton (on these 4,600 samples 7 did, 2 do)."""
    model, form, r = _preset_path("harmony_upper_arm", 0.5, 4600)
    found = {"none": 0, "free_back": 0}
    step = active.active_step

    def spy(form, cache, state, r, f_tol, x_tol):
        out = step(form, cache, state, r, f_tol, x_tol)
        if out is None:
            found["none"] += 1
        else:
            back = (state.cls == 0) & (out[2].cls == SLIDING) & ~np.any(out[2].s != 0.0, axis=1)
            if back.any():
                found["free_back"] += 1
                _check_law(form, r, state, out[2], out[1], out[0])
        return out

    monkeypatch.setattr(fp, "active_step", spy)
    u, P, cls, solves, conv, _ = fp.solve_path(form, r, initial_state(form), {})
    assert conv.all()
    assert found["free_back"] >= 5 and found["none"] <= 4
