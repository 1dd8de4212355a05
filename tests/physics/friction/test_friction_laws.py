"""Coulomb friction on the spring arms with a nonlinear tissue law (docs/model.md 12.6).

References are independent of the solver:

- three elements on six decoupled dofs (a synthetic interface form) under a normal load
  each and a shared axial load: every normal compression is the series element's closed
  form (the exponential law's inverse plus the cuff spring's f / k_c), the shared axial
  load splits by the ties' stiffness until one element reaches mu f_n, then that element
  carries mu f_n and the other the rest (worked by hand below);
- the laws at every sample of random loading paths (hypothesis): the forces balance the
  wrench, every tangential force is within mu times its normal force, a released element
  carries nothing and is not compressed; and two chunks give the answer of one call;
- mu -> large with no element lifting off: the bonded model with the same law.
"""

from support.helpers import REPO  # noqa: E402
import dataclasses

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from support.helpers import check_friction_laws
from phri_spring.physics.friction import path as friction
from phri_spring.physics.contact.active_set import FactorCache
from phri_spring.physics.friction.form import InterfaceForm
from phri_spring.physics.friction.normal import NormalResponse
from phri_spring.physics.cuff.geometry import cuff_geometry
from phri_spring.physics.springs.model import build_model, tissue_element_stiffness
from phri_spring.physics.contact.solver import solve
from phri_spring.physics.laws import SeriesElement, make_law
from phri_spring.synthetic.wrench import smooth_random_log

BETA = 115.0          # 1/m, the human preset's stiffening


def _harmony_exp(mu, tension=15.0, beta=BETA, k_cuff=2e5):
    g = cuff_geometry([-0.025, 0.0, 0.025], 0.045, 0.025, 75.0, 35.0, 7)
    k_t = tissue_element_stiffness(np.full(g.n, 4242.0), g.areas)
    return build_model(g, k_t, k_cuff, strap_tension=tension, law="exponential",
                       law_parameters={"stiffening": beta}, friction_coefficient=mu)


def _check_laws(model, W, sol, mu):
    """The laws of every friction solution, and the series element's force where pressing."""
    fn, off, g, scale = check_friction_laws(model, W, sol, mu)
    # a pressing element carries its series element's force at its compression
    on = ~off
    np.testing.assert_allclose(fn[on], model.element.force(g)[on], rtol=1e-9,
                               atol=1e-9 * scale)


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 10_000), mu=st.floats(0.1, 1.5), tension=st.floats(5.0, 40.0),
       load=st.floats(5.0, 60.0), beta=st.floats(20.0, 200.0))
def test_laws_and_chunks_on_random_paths_with_the_exponential_law(seed, mu, tension, load,
                                                                  beta):
    model = _harmony_exp(mu, tension, beta)
    _, W = smooth_random_log(240, seed=seed)
    W = W / np.abs(W[:, :3]).max() * load * np.array([0.3, 1, 1, 0.01, 0.02, 0.02])
    one = solve(model, W)
    if one.converged.any():
        _check_laws(model, W, one, mu)
    assert np.isnan(one.forces[~one.converged]).all()
    cache = FactorCache()
    cut = int(seed % 200) + 20
    a, b = solve(model, W[:cut], cache=cache), solve(model, W[cut:], cache=cache)
    np.testing.assert_array_equal(np.concatenate([a.converged, b.converged]), one.converged)
    np.testing.assert_allclose(np.vstack([a.forces, b.forces]), one.forces, rtol=0, atol=1e-9)
    np.testing.assert_allclose(np.vstack([a.tangential, b.tangential]), one.tangential,
                               rtol=0, atol=1e-9)


def test_lift_off_and_recontact_with_the_exponential_law():
    model = _harmony_exp(0.5)
    F = np.concatenate([np.linspace(0, 45, 120), np.linspace(45, 0, 120)])
    W = np.zeros((len(F), 6))
    W[:, 1] = -F
    sol = solve(model, W)
    assert sol.converged.all()
    _check_laws(model, W, sol, 0.5)
    assert (~sol.contact[119]).any() and sol.contact[0].all() and sol.contact[-1].all()


def _compression(f, k0, beta, k_cuff):
    """The series element's compression at force f: ln(1 + beta f / k0) / beta + f / k_c."""
    return np.log1p(beta * f / k0) / beta + f / k_cuff


def _three_elements(mu, k0, beta, k_cuff, kt, f0=1.0):
    """Three elements on six dofs: element 1 (normal u0, tangential u1, u2), element 2
    (u3; u1, u4), element 3 (u5; u4, u2), each pressed by f0 [N] at u = 0."""
    rows = [0, 1, 2, 3, 1, 4, 5, 4, 2]
    T = np.eye(6)[rows]
    C = np.diag(np.ravel([[1.0 / k0[e], 1.0 / kt[e], 1.0 / kt[e]] for e in range(3)]))
    element = SeriesElement(make_law("exponential", k0, stiffening=beta), k_cuff)
    delta = np.zeros((3, 3))
    delta[:, 0] = _compression(f0, k0, beta, k_cuff)
    return InterfaceForm(n=3, d=3, C=C, C_skin=None, T=T, delta=delta.ravel(),
                         W_pre=np.zeros(6), mu=mu, diagonal=True,
                         normal_response=NormalResponse(element))


def test_three_elements_by_hand_exponential_law_and_sliding():
    mu, beta = 0.4, 80.0
    k0 = np.array([3000.0, 5000.0, 4000.0])
    k_cuff = np.array([2e4, 5e4, 1e5])
    kt = np.array([900.0, 300.0, 600.0])
    form = _three_elements(mu, k0, beta, k_cuff, kt)
    N = np.array([10.0, 30.0, 20.0])
    # a ramp of the normal loads, then a shared axial load Ta on u1 (elements 1 and 2)
    Ta = np.linspace(0.0, 14.0, 57)
    r = np.zeros((20 + len(Ta), 6))
    r[:20, [0, 3, 5]] = 1.0 + np.linspace(0, 1, 20)[:, None] * (N - 1.0)
    r[20:, [0, 3, 5]] = N
    r[20:, 1] = Ta
    u, P, cls, solves, conv, _ = friction.solve_path(form, r)
    assert conv.all()
    P = P.reshape(len(r), 3, 3)
    # normal: the exponential law's inverse plus the cuff spring, d = ln(1 + beta f/k0)/beta + f/k_c
    f = r[:, [0, 3, 5]]
    d = _compression(f, k0, beta, k_cuff) - _compression(1.0, k0, beta, k_cuff)
    np.testing.assert_allclose(u[:, [0, 3, 5]], d, rtol=1e-10, atol=1e-15)
    np.testing.assert_allclose(P[:, :, 0], f, rtol=1e-10, atol=1e-12)
    # the shared axial load: stuck, t_e = kt_e u1 with u1 = Ta / (kt1 + kt2), until element 1
    # reaches mu N1 = 4 N (at Ta = 4 (kt1 + kt2) / kt1 = 5.33 N); then t1 = 4 N, t2 = Ta - 4
    t1 = np.where(kt[0] * Ta / (kt[0] + kt[1]) <= mu * N[0], kt[0] * Ta / (kt[0] + kt[1]),
                  mu * N[0])
    t2 = Ta - t1
    np.testing.assert_allclose(P[20:, 0, 1], t1, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(P[20:, 1, 1], t2, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(u[20:, 1], t2 / kt[1], rtol=1e-10, atol=1e-15)
    slides = kt[0] * Ta / (kt[0] + kt[1]) > mu * N[0] * (1 + 1e-9)
    assert slides.any() and (~slides).any()
    assert np.all(cls[20:][slides, 0] == friction.SLIDING)
    assert np.all(cls[20:][~slides] == friction.STUCK)


def test_three_elements_beyond_the_cone_has_no_equilibrium():
    form = _three_elements(0.4, np.full(3, 3000.0), 80.0, np.full(3, 2e4), np.full(3, 500.0))
    r = np.zeros((3, 6))
    r[:, [0, 3, 5]] = 10.0
    r[1, 1] = 7.9          # within mu (N1 + N2) = 8 N
    r[2, 1] = 8.1          # beyond it: nothing holds u1
    _, P, _, _, conv, _ = friction.solve_path(form, r)
    assert conv[:2].all() and not conv[2]
    assert np.isnan(P[2]).all()


@pytest.mark.parametrize("arm_cuff", [2e5, np.inf])
def test_large_mu_without_lift_off_is_the_bonded_nonlinear_model(arm_cuff):
    fric = _harmony_exp(1e6, tension=30.0, k_cuff=arm_cuff)
    bonded = _harmony_exp(None, tension=30.0, k_cuff=arm_cuff)
    _, W = smooth_random_log(300, seed=11)
    W = W / np.abs(W[:, :3]).max() * 8.0 * np.array([0.3, 1, 1, 0.01, 0.02, 0.02])
    a, b = solve(fric, W), solve(bonded, W)
    assert a.converged.all() and b.converged.all() and a.contact.all() and b.contact.all()
    np.testing.assert_allclose(a.forces, b.forces, rtol=0, atol=1e-8 * np.abs(b.forces).max())
    np.testing.assert_allclose(a.u, b.u, rtol=0, atol=1e-9 * np.abs(b.u).max())
    np.testing.assert_allclose(a.tangential, bonded.shear_components(b.u), rtol=0,
                               atol=1e-8 * np.abs(b.forces).max())


def test_blocks_and_events_agree_with_the_exponential_law(monkeypatch):
    monkeypatch.setattr(friction, "_COMPILED", False)   # the numpy path's blocks and events
    model = _harmony_exp(0.5)
    _, W = smooth_random_log(600, seed=8)
    W = W / np.abs(W[:, :3]).max() * 50.0 * np.array([0.3, 1, 1, 0.01, 0.02, 0.02])
    form = friction.interface_form(model)
    r = W + model.W_pre
    u, P, cls, solves, conv, _ = friction.solve_path(form, r)
    assert conv.all() and (solves == 0).any() and (solves > 0).any()
    # elements that slid gripping again at the next sample, solved in a block (12.3)
    assert np.any((cls[:-1] == friction.SLIDING).any(axis=1) & (solves[1:] == 0))
    state = friction.initial_state(form)
    for i in range(len(r)):
        _, Pi, state, _, ok = friction.solve_event_elements(form, r[i], state)
        assert ok
        np.testing.assert_allclose(Pi, P[i], rtol=0, atol=1e-9 * np.abs(r[i]).max())
        assert np.array_equal(state.cls, cls[i]), i


def test_simulate_in_memory_with_friction_gives_the_reasons_in_its_frame():
    import yaml
    from pathlib import Path

    from phri_spring.io.config import load_config
    from phri_spring.workflows.simulate import simulate

    root = REPO
    raw = yaml.safe_load((root / "configs" / "human_upper_arm.yaml").read_text())
    raw["interface"]["friction_coefficient"] = 0.5
    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "mu.yaml"
        path.write_text(yaml.safe_dump(raw, sort_keys=False))
        cfg = load_config(path)
        W = np.zeros((3, 6))
        W[1, 2] = 30.0          # at the load cell, 7 cm off the arm's axis: 2.1 N*m of torsion
        frame = simulate(cfg, W).to_frame()
        from phri_spring.workflows.common import cuff_wrench, model_from_config

        model = model_from_config(cfg, "compliant")
        bonded = model_from_config(dataclasses.replace(cfg, friction_coefficient=None),
                                   "compliant")
        r = cuff_wrench(cfg, W)[1] + model.W_pre
        f_sum = solve(bonded, cuff_wrench(cfg, W)[1:2]).forces.sum()
    assert list(frame["converged"]) == [True, False, True]
    assert list(frame["no_equilibrium_reason"]) == ["", "torsion beyond friction capacity", ""]
    # the shortfall: the torsion less what friction holds beside the axial force
    cap = 0.5 * f_sum
    expected = abs(r[3]) - 0.045 * np.sqrt(max(cap ** 2 - r[0] ** 2, 0.0))
    assert expected > 0
    np.testing.assert_allclose(frame["no_equilibrium_shortfall_Nm"][1], expected, rtol=1e-6)
    assert np.isnan(frame["no_equilibrium_shortfall_N"]).all()


def test_the_regrip_probe_only_decides_which_solver_runs(monkeypatch):
    """After a sample where elements slid, a block tries them gripping again unless the
    first row's linearised step takes one clearly past its cone (normal.block_nonlinear's
    probe). Whether that call is right or wrong, the sample is solved: skipping every such
    block (the event solver then takes each sample) or none gives the same answers."""
    from phri_spring.physics.friction import normal as friction_normal

    monkeypatch.setattr(friction, "_COMPILED", False)    # the numpy path's blocks
    model = _harmony_exp(0.5)
    _, W = smooth_random_log(600, seed=8)
    W = W / np.abs(W[:, :3]).max() * 50.0 * np.array([0.3, 1, 1, 0.01, 0.02, 0.02])
    form = friction.interface_form(model)
    runs, regrips = [], []
    for margin in (-1.0, 1e9):     # every doubtful block skipped, none skipped
        monkeypatch.setattr(friction_normal, "_PROBE_MARGIN", margin)
        runs.append(solve(model, W))
        _, _, cls, solves, _, _ = friction.solve_path(form, W + model.W_pre)
        # samples right after a sliding one solved in a block: the regrips
        regrips.append(int(np.sum((cls[:-1] == friction.SLIDING).any(axis=1)
                                  & (solves[1:] == 0))))
    assert regrips[0] == 0 and regrips[1] > 10
    a, b = runs
    np.testing.assert_array_equal(a.converged, b.converged)
    assert a.converged.all()
    scale = np.abs(W).max() + np.abs(model.W_pre).max()
    np.testing.assert_allclose(a.forces, b.forces, rtol=0, atol=1e-8 * scale)
    np.testing.assert_allclose(a.tangential, b.tangential, rtol=0, atol=1e-8 * scale)
