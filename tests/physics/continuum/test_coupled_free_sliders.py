"""A touching patch whose cone has closed slides freely (docs/model.md 10.2): the samples
where such patches are the only ones sliding are solved in affine blocks, like stuck ones.

Reference: each such sample solved from the same state by the event's semismooth Newton
method (the law written as nonsmooth equations, a different method): the same state and
forces to round-off where Newton finds that state. Coulomb friction's answer need not be
unique (a patch at the edge of contact can leave or stay, each passing every check), so a
few samples may get another answer from Newton; most must agree.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd
import pytest

from phri_spring.io.config import load_config
from phri_spring.physics.friction import path as fp
from phri_spring.physics.friction.events import solve_event_coupled
from phri_spring.physics.friction.form import SLIDING, initial_state, interface_form
from phri_spring.workflows.common import cuff_wrench, model_from_config

from support.helpers import REPO

pytest.importorskip("skfem", reason="the fe extra (scikit-fem) is part of the test extra")

COLS = ["Fx", "Fy", "Fz", "Mx", "My", "Mz"]


@pytest.mark.parametrize("mu", [0.5, 0.9])
def test_free_slider_blocks_are_the_events_answers(mu):
    cfg = dataclasses.replace(load_config(REPO / "configs" / "human_upper_arm.yaml"),
                              friction_coefficient=mu)
    model = model_from_config(cfg, "coupled")
    form = interface_form(model)
    log = pd.read_csv(REPO / "examples" / "wrench_log.csv", comment="#")[COLS].to_numpy()
    r = cuff_wrench(cfg, log[:3000]) + model.W_pre
    state, cache = initial_state(form), {}
    same = other = 0
    for i in range(len(r)):
        before = state
        u, P, cls, solves, conv, state = fp.solve_path(form, r[i:i + 1], before, cache)
        if not (conv[0] and solves[0] == 0 and (cls[0] == SLIDING).any()):
            continue
        # a free block: its patches slide on a closed cone, with no shear
        free = cls[0] == SLIDING
        Pe = P[0].reshape(model.n, model.dofs)
        assert np.all(Pe[free, 1:3] == 0.0)
        scale = np.abs(P[0]).max()
        assert np.all((P[0] @ form.cone_normal.T)[free] <= 1e-9 * scale)
        ue, Pev, new, _, ok = solve_event_coupled(form, r[i], before)
        if ok and np.array_equal(new.cls, cls[0]):
            same += 1
            np.testing.assert_allclose(Pev, P[0], rtol=0, atol=1e-9 * scale)
            np.testing.assert_allclose(ue, u[0], rtol=0, atol=1e-12)
        else:
            other += 1
    assert same > 20 and other <= 0.1 * (same + other)
