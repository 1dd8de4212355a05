"""The spring arms' friction path compiled (phri_spring/physics/friction/kernel.py,
docs/model.md 12.5).

The reference is the numpy path (affine or Newton blocks between events, semismooth Newton
events; ``path._COMPILED = False``), itself checked against closed forms and the bonded
model in test_friction.py and test_friction_laws.py: the compiled loop must give its
answers (every sample converged or flagged alike, forces to 1e-9 of the force scale) and
obey the laws at every sample, on the linear springs and on the exponential law with a
compliant and a rigid cuff; and the loop run as plain Python (no numba) must be the
compiled one.
"""

import dataclasses

import numpy as np
import pytest

from support.helpers import REPO, check_friction_laws
from phri_spring.io.config import load_config
from phri_spring.workflows.common import cuff_wrench, model_from_config
from phri_spring.physics.contact.active_set import FactorCache
from phri_spring.physics.contact.solver import solve
from phri_spring.physics.cuff.geometry import cuff_geometry
from phri_spring.physics.friction import kernel
from phri_spring.physics.friction import path as friction
from phri_spring.physics.springs.model import build_model, tissue_element_stiffness
from phri_spring.synthetic.wrench import smooth_random_log

#: numba installed (the ``fast`` extra, part of the test extra): the loop is compiled
COMPILED = kernel.NUMBA

CASES = {
    "linear": dict(law="linear"),
    "exponential, cuff spring": dict(law="exponential", k_cuff=2e5),
    "exponential, rigid cuff": dict(law="exponential", k_cuff=np.inf),
    # the handles strap compresses nothing: the path starts with every element at g = 0
    # (it holds less: 25 N pushes, all of which have an answer)
    "exponential, handles strap": dict(law="exponential", strap="handles"),
}
LOADS = {"exponential, handles strap": 25.0}


def _model(law="linear", k_cuff=2e5, mu=0.5, tension=15.0, strap="hoop"):
    g = cuff_geometry([-0.025, 0.0, 0.025], 0.045, 0.025, 75.0, 35.0, 7)
    k_t = tissue_element_stiffness(np.full(g.n, 4242.0), g.areas)
    extra = {} if law == "linear" else dict(law="exponential",
                                            law_parameters={"stiffening": 115.0})
    return build_model(g, k_t, k_cuff, strap_tension=tension, strap_model=strap,
                       friction_coefficient=mu, **extra)


def _log(m, seed, load):
    _, W = smooth_random_log(m, seed=seed)
    return W / np.abs(W[:, :3]).max() * load * np.array([0.3, 1, 1, 0.01, 0.02, 0.02])


@pytest.fixture
def loop(monkeypatch):
    """The compiled loop where numba is installed, else the same loop as Python."""
    monkeypatch.setattr(kernel, "NUMBA", True)


@pytest.mark.parametrize("case", sorted(CASES))
def test_the_loop_gives_the_numpy_paths_answers(case, loop, monkeypatch):
    model = _model(**CASES[case])
    assert kernel.supports(friction.interface_form(model))
    W = _log(1500 if COMPILED else 300, 8, LOADS.get(case, 60.0))
    got = solve(model, W)
    monkeypatch.setattr(friction, "_COMPILED", False)
    ref = solve(model, W)
    assert (got.iterations > 0).all()
    np.testing.assert_array_equal(got.converged, ref.converged)
    assert ref.converged.mean() > 0.9 and (~ref.contact[ref.converged]).any()   # lift-off
    scale = np.abs(W).max() + np.abs(model.W_pre).max()
    for a, b in ((got.forces, ref.forces), (got.tangential, ref.tangential)):
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-9 * scale, equal_nan=True)
    check_friction_laws(model, W, got, 0.5)


def test_samples_without_an_answer_are_flagged_as_the_numpy_path_flags_them(loop, monkeypatch):
    """Pushes and twists the friction cannot hold at mu = 0.2 (nine samples in ten): the
    loop runs the numpy path's fallbacks itself (gripping, the Newton method again from
    there, two half increments) and flags what none settles. The two paths flag the
    same samples here; where a fallback settles a sample, the two may take different
    answers (Coulomb friction's need not be unique), so their forces are compared up to
    the first such sample, and the loop's are checked against the laws everywhere."""
    model = _model("exponential", mu=0.2)
    W = _log(400, 3, 60.0) * np.array([3.0, 1, 1, 30, 1, 1])
    got = solve(model, W)
    monkeypatch.setattr(friction, "_COMPILED", False)
    ref = solve(model, W)
    assert 0.5 * len(W) < (~ref.converged).sum() < len(W)
    np.testing.assert_array_equal(got.converged, ref.converged)
    assert np.isnan(got.forces[~got.converged]).all()
    check_friction_laws(model, W, got, 0.2)
    # up to the first sample settled after a flagged one (where a fallback acts)
    after = np.flatnonzero(got.converged[1:] & ~got.converged[:-1])
    upto = after[0] + 1 if after.size else len(W)
    assert upto >= 20
    np.testing.assert_allclose(got.forces[:upto], ref.forces[:upto], rtol=0,
                               atol=1e-9 * np.abs(W).max(), equal_nan=True)


def test_chunks_carry_the_loops_path(loop):
    model = _model("exponential")
    W = _log(600, 5, 50.0)
    one = solve(model, W)
    cache = FactorCache()
    a, b = solve(model, W[:277], cache=cache), solve(model, W[277:], cache=cache)
    np.testing.assert_array_equal(np.concatenate([a.converged, b.converged]), one.converged)
    np.testing.assert_allclose(np.vstack([a.forces, b.forces]), one.forces, rtol=0, atol=1e-9)
    np.testing.assert_allclose(np.vstack([a.tangential, b.tangential]), one.tangential,
                               rtol=0, atol=1e-9)


@pytest.mark.skipif(not COMPILED, reason="compares numba's machine code with Python")
def test_the_interpreted_loop_is_the_compiled_loop(monkeypatch):
    model = _model("exponential")
    W = _log(200, 11, 60.0)
    got = solve(model, W)
    monkeypatch.setattr(kernel, "solve_elements", kernel.solve_elements.py_func)
    ref = solve(model, W)
    np.testing.assert_array_equal(got.converged, ref.converged)
    scale = np.abs(W).max() + np.abs(model.W_pre).max()
    np.testing.assert_allclose(got.forces, ref.forces, rtol=0, atol=1e-12 * scale)


def test_what_the_loop_does_not_cover_takes_the_numpy_path():
    assert not kernel.supports(friction.interface_form(_model(mu=0.0)))      # frictionless
    model = _model("exponential")
    form = friction.interface_form(model)
    assert kernel.supports(form)
    # another registered law (any but the exponential) is the numpy path's
    other = dataclasses.replace(form, normal_response=type("R", (), {"law": object()})())
    assert not kernel.supports(other)


def test_a_loop_that_cannot_load_leaves_the_numpy_path(monkeypatch):
    """numba installed but unusable (its compiler failing): the friction path is the numpy
    one, with the same answers, and nothing is raised."""
    from phri_spring.physics.friction import loader

    def broken():
        raise RuntimeError("numba cannot compile here")

    monkeypatch.setattr(kernel, "NUMBA", True)
    monkeypatch.setattr(kernel, "load", broken)
    for name, value in (("_MODULE", None), ("_FAILED", False)):
        monkeypatch.setattr(loader, name, value)
    model = _model("exponential")
    W = _log(300, 2, 50.0)
    got = solve(model, W)
    assert loader.kernel() is None
    monkeypatch.setattr(friction, "_COMPILED", False)
    ref = solve(model, W)
    np.testing.assert_array_equal(got.converged, ref.converged)
    np.testing.assert_array_equal(got.forces, ref.forces)


def test_a_harsh_log_is_solved_or_flagged_sample_by_sample():
    """The human preset at mu = 0.5 under random forces of 20 N and moments of 2 N*m on
    every axis: a sixth of the samples have no equilibrium, and the Newton iterates of
    some run far enough for the exponential law to overflow (before the fix: LAPACK's SVD
    failing on the overflowed tangent, an internal error, after the compiled loop had
    handed back a sample with its tissue shares spoiled). Each is flagged; the others obey
    the laws."""
    cfg = dataclasses.replace(load_config(REPO / "configs" / "human_upper_arm.yaml"),
                              friction_coefficient=0.5)
    model = model_from_config(cfg, "compliant")
    _, W = smooth_random_log(3000, seed=4)
    W = cuff_wrench(cfg, W / np.abs(W).max(axis=0) * np.array([20.0, 20, 20, 2, 2, 2]))
    sol = solve(model, W)
    assert 0.05 < (~sol.converged).mean() < 0.3
    assert np.isnan(sol.forces[~sol.converged]).all()
    check_friction_laws(model, W, sol, 0.5)


def test_a_newton_step_on_an_overflowed_tangent_is_no_step():
    from phri_spring.physics.friction.events import _newton_step

    K = np.eye(6)
    K[0, 0] = np.inf
    np.testing.assert_array_equal(_newton_step(K, np.ones(6)), np.zeros(6))
    np.testing.assert_array_equal(_newton_step(np.eye(6), np.full(6, np.nan)), np.zeros(6))
