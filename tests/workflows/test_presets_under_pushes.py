"""The presets as shipped (the human preset's stiffening included), every arm, bonded and
with friction, under one-sided pushes and random wrenches, through ``simulate --shear``:
the written outputs obey the laws (issue 32's acceptance, docs/model.md sections 10.2,
10.6 and 12): a flagged sample has NaN forces, normal forces are >= 0, with friction every
shear force is within mu times the label column and the force along the element's normal,
an element or patch that reads 0 N carries no shear and no moment where contact releases,
and the resultant columns balance the load plus the strap's, forces and moments.

The checks are :func:`phri_spring.workflows.composition.check_outputs`, whose own tests
(tests/workflows/test_composition.py) feed it broken outputs written by hand.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from phri_spring.io.config import load_config
from phri_spring.workflows import composition as cm
from phri_spring.workflows.simulate import simulate_file

from support.helpers import REPO

pytest.importorskip("skfem", reason="the fe extra (scikit-fem) is part of the test extra")


def _log(seed=5):
    """Load-cell wrenches (m, 6): ramps to 50 N and back in seeded random directions of the
    cuff's plane with a little axial force, then random wrenches of +-20 N, +-1 N*m."""
    rng = np.random.default_rng(seed)
    up = np.linspace(0.0, 50.0, 25)
    ramp = np.concatenate([up, up[::-1]])
    rows = []
    for _ in range(6):
        a = rng.uniform(0.0, 2.0 * np.pi)
        w = np.zeros((len(ramp), 6))
        w[:, 0] = rng.normal(0.0, 2.0, len(ramp))
        w[:, 1], w[:, 2] = ramp * np.cos(a), ramp * np.sin(a)
        rows.append(w)
    rows.append(rng.uniform(-1.0, 1.0, (150, 6)) * np.array([20, 20, 20, 1, 1, 1]))
    return np.vstack(rows)


@pytest.mark.parametrize("preset", ["human_upper_arm", "harmony_upper_arm"])
@pytest.mark.parametrize("arm", ["compliant", "rigid", "coupled"])
@pytest.mark.parametrize("mu", [None, 0.5])
def test_presets_obey_the_laws_under_pushes(tmp_path, preset, arm, mu):
    cfg = load_config(REPO / "configs" / f"{preset}.yaml")
    cfg = dataclasses.replace(cfg, friction_coefficient=mu)
    W = _log()
    log = tmp_path / "log.csv"
    np.savetxt(log, np.column_stack([0.01 * np.arange(len(W)), W]), delimiter=",",
               header="time,Fx,Fy,Fz,Mx,My,Mz", comments="", fmt="%.9g")
    out = tmp_path / "out.csv"
    summary = simulate_file(cfg, log, out, arm=arm, shear=True, decimals=None)
    comb = cm.Combination(arm=arm, tissue_law=cfg.tissue_law,
                          interface="bonded" if mu is None else "mu 0.5", cuff="compliant",
                          continuum_law="linear" if arm == "coupled" else None)
    assert cm.check_outputs(cfg, comb, out, log=W) is None
    # most of the log has an answer (some random wrenches are beyond mu = 0.5)
    assert summary.not_converged <= 0.35 * summary.samples
