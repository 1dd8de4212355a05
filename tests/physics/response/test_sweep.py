"""Load-controlled sweeps at the load cell (phri_spring/physics/response/sweep.py).

The reference: each branch (an axis, a sign) solved on its own from the preloaded cuff,
a fresh solve of [0; the branch's loads]. With friction the answer depends on the loading
path, so a sweep that ran its branches as one path (each starting where the one before
ended) fails this; without friction both agree.
"""

import numpy as np
import pytest

from phri_spring.physics.contact.solver import solve
from phri_spring.physics.cuff.geometry import cuff_geometry
from phri_spring.physics.cuff.loadcell import loadcell_to_cuff
from phri_spring.physics.response.sweep import axis_loads, sweep_loadcell_axes
from phri_spring.physics.springs.model import build_model, tissue_element_stiffness


def _model(mu):
    g = cuff_geometry([-0.025, 0.0, 0.025], 0.045, 0.025, 75.0, 35.0, 7)
    k_t = tissue_element_stiffness(np.full(g.n, 4242.0), g.areas)
    return build_model(g, k_t, 2e5, strap_tension=15.0, law="exponential",
                       law_parameters={"stiffening": 115.0}, friction_coefficient=mu)


@pytest.mark.parametrize("mu", [None, 0.8])
def test_every_branch_is_loaded_from_the_preloaded_cuff(mu):
    model = _model(mu)
    position = (0.0, -0.07, 0.0)
    sweep = sweep_loadcell_axes(model, None, position, max_force=25.0, max_moment=1.0,
                                points=9)
    loads = axis_loads(25.0, 1.0, 9)
    for i in range(6):
        for b in range(2):
            W = loadcell_to_cuff(loads[i, b][:, None] * np.eye(6)[i], None, position)
            ref = solve(model, np.vstack([np.zeros((1, 6)), W]))
            assert ref.converged.all()
            du = ref.u[1:] - ref.u[0]
            # the load cell's motion along or about axis i (no rotation: the cuff's axes)
            t, w = du[:, :3], du[:, 3:]
            motion = t + np.cross(w, position) if i < 3 else w
            np.testing.assert_allclose(sweep.displacement[i, b], motion[:, i % 3], rtol=0,
                                       atol=1e-9 * np.abs(motion).max())
    assert sweep.converged.all()
