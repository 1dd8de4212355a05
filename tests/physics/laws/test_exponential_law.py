"""The exponential (Fung-type) tissue law F(d) = (k0/beta)(exp(beta d) - 1) in the spring model.

References computed independently of the package:

* the law and its energy in closed form, the series element's force for a compression by
  scipy's brentq on d = ln(1 + beta f / k0) / beta + f / k_c;
* a symmetric cuff loaded along its symmetry axis, where the equilibrium reduces to one
  equation in the cuff's displacement, solved backwards: the wrench for a chosen
  displacement, then the model solved for that wrench;
* random configs, where the equilibrium is found by minimising the energy (written here
  from the closed forms) with scipy, to 1e-4 N in the forces.
"""

from __future__ import annotations


import numpy as np
import pandas as pd
import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import brentq, minimize

from phri_spring.physics.cuff.geometry import cuff_geometry
from phri_spring.physics.springs.model import build_model
from phri_spring.physics.contact.solver import solve
from phri_spring.physics.laws import ExponentialLaw, LinearLaw, SeriesElement, make_law

from support.helpers import HARMONY_CONFIG, run_phri, stderr_of, harmony_geometry


def F(d, k0, beta):
    """The law in closed form [N]."""
    x = beta * d
    return k0 * d if x == 0 else k0 * d * np.expm1(x) / x


def psi_closed(d, k0, beta):
    """Stored energy of the law [J]: k0 (expm1(x) - x) / beta^2, x = beta d (its Taylor
    series where x is small, as the difference cancels)."""
    x = beta * d
    if x < 1e-3:
        return k0 * d * d * (0.5 + x / 6 + x * x / 24 + x ** 3 / 120)
    return k0 / beta ** 2 * (np.expm1(x) - x)


def series_force(g, k0, beta, kc):
    """Force of the law in series with a linear spring kc at total compression g (brentq)."""
    if g <= 0:
        return 0.0

    def gap(f):
        y = beta * f / k0
        dt = f / k0 if y == 0 else f / k0 * np.log1p(y) / y
        return dt + (0.0 if np.isinf(kc) else f / kc) - g

    hi = F(g, k0, beta) * (1 + 1e-9) + 1e-12
    return brentq(gap, 0.0, hi, xtol=1e-15, rtol=1e-14)


def series_energy(g, k0, beta, kc):
    f = series_force(g, k0, beta, kc)
    y = beta * f / k0
    dt = f / k0 if y == 0 else f / k0 * np.log1p(y) / y
    return psi_closed(dt, k0, beta) + (0.0 if np.isinf(kc) else 0.5 * f * f / kc)


@settings(max_examples=60, deadline=None)
@given(k0=st.floats(50.0, 1e5), beta=st.one_of(st.just(0.0), st.floats(1e-6, 200.0)),
       d=st.floats(1e-7, 0.03),
       kc=st.sampled_from([2e3, 1e5, np.inf]))
def test_law_and_series_element_against_closed_forms(k0, beta, d, kc):
    law = ExponentialLaw([k0], stiffening=beta)
    x = np.array([d])
    assert law.force(x)[0] == pytest.approx(F(d, k0, beta), rel=1e-10)
    assert law.tangent(x)[0] == pytest.approx(k0 * np.exp(beta * d), rel=1e-12)
    assert law.energy(x)[0] == pytest.approx(psi_closed(d, k0, beta), rel=1e-10)
    assert law.compression_at(law.force(x))[0] == pytest.approx(d, rel=1e-10)
    el = SeriesElement(law, [kc])
    assert el.force(x)[0] == pytest.approx(series_force(d, k0, beta, kc), rel=1e-9)
    assert el.energy(x)[0] == pytest.approx(series_energy(d, k0, beta, kc), rel=1e-8)
    h = 1e-6 * d
    fd = (el.force(x + h) - el.force(x - h))[0] / (2 * h)
    assert el.tangent(x)[0] == pytest.approx(fd, rel=1e-5)
    de = (el.energy(x + h) - el.energy(x - h))[0] / (2 * h)
    assert de == pytest.approx(el.force(x)[0], rel=1e-5)


def test_zero_stiffening_is_the_linear_law_exactly():
    assert isinstance(make_law("exponential", [100.0, 200.0], stiffening=0.0), LinearLaw)
    small = ExponentialLaw([100.0], stiffening=1e-9)
    d = np.array([0.02])
    assert small.force(d)[0] == pytest.approx(2.0, rel=1e-10)
    assert small.energy(d)[0] == pytest.approx(0.02, rel=1e-10)


def _symmetric_cuff(beta, kc, tension=0.0):
    """One row, 6 locations symmetric about -y (each location mirrored by another)."""
    g = cuff_geometry([0.0], 0.045, 0.03, 180.0 - 75.0, 30.0, 6)   # centred on -y (180 deg)
    k0 = 400.0 * np.ones(g.n)
    return build_model(g, k0, kc, strap_tension=tension, law="exponential",
                       law_parameters={"stiffening": beta}), k0


@pytest.mark.parametrize("beta, kc", [(80.0, np.inf), (150.0, 2e4), (0.0, 5e3)])
def test_symmetric_cuff_closed_form(beta, kc):
    """Pushed along -y the cuff moves along -y only: the equilibrium is the single
    equation W_y = sum_e f_e(g_e) (b_e)_y + K_s,yy u_y with g_e = (b_e)_y u_y. Choose u_y,
    compute W from it, solve the model for W: the same u_y and forces."""
    model, k0 = _symmetric_cuff(beta, kc)
    by = model.b[:, 1]
    for uy in (0.002, 0.006, 0.012):
        g = by * uy
        f = np.array([series_force(ge, k0[0], beta, kc) for ge in g])
        assert (f > 0.1).all()                 # every element presses: the law is exercised
        Wy = f @ by + model.K_s[1, 1] * uy
        sol = solve(model, np.array([0.0, Wy, 0.0, 0.0, 0.0, 0.0]))
        assert sol.converged
        assert sol.u[1] == pytest.approx(uy, rel=1e-9)
        np.testing.assert_allclose(sol.u[[0, 2, 3, 4, 5]], 0.0, atol=1e-12)
        np.testing.assert_allclose(sol.forces, f, rtol=0, atol=1e-9 * f.max())


def _reference_solution(model, k0, beta, kc, r):
    """Minimise the energy written from the closed forms (BFGS on scaled variables)."""
    unit = np.array([1e-3] * 3 + [1e-2] * 3)

    def pi(v):
        u = v * unit
        g = model.delta0 + model.b @ u
        psi = sum(series_energy(ge, k0[e], beta[e], kc[e]) for e, ge in enumerate(g))
        return 1e3 * (psi + 0.5 * u @ model.K_s @ u - r @ u)

    res = minimize(pi, np.zeros(6), method="BFGS", options={"gtol": 1e-9, "maxiter": 4000})
    u = res.x * unit
    g = model.delta0 + model.b @ u
    return np.array([series_force(ge, k0[e], beta[e], kc[e]) for e, ge in enumerate(g)])


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_random_cuffs_match_an_independent_minimisation(seed):
    rng = np.random.default_rng(seed)
    rows, count = int(rng.integers(1, 4)), int(rng.integers(4, 9))
    step = 240.0 / count
    g = cuff_geometry(np.linspace(-0.02, 0.02, rows), 0.045, 0.04 / rows, 60.0, step, count)
    k0 = rng.uniform(200.0, 800.0, g.n)
    beta = rng.uniform(0.0, 150.0, g.n)
    kc = np.where(rng.random(g.n) < 0.3, np.inf, rng.uniform(5e3, 5e4, g.n))
    model = build_model(g, k0, kc, strap_tension=float(rng.uniform(0, 20)),
                        law="exponential", law_parameters={"stiffening": beta})
    W = rng.normal(size=(3, 6)) * np.array([25, 25, 25, 0.8, 0.8, 0.8])
    sol = solve(model, W)
    assert sol.converged.all()
    for i in range(len(W)):
        ref = _reference_solution(model, k0, beta, kc, W[i] + model.W_pre)
        np.testing.assert_allclose(sol.forces[i], ref, rtol=0, atol=1e-4)


# --------------------------------------------------------------------------- config and CLI
def _cfg(tmp_path, tissue_edit, name="cfg.yaml"):
    data = yaml.safe_load(HARMONY_CONFIG.read_text())
    tissue_edit(data["tissue"])
    path = tmp_path / name
    path.write_text(yaml.safe_dump(data))
    return path


@pytest.fixture(scope="module")
def log_small(tmp_path_factory):
    path = tmp_path_factory.mktemp("log") / "log.csv"
    pd.read_csv("examples/wrench_log.csv", comment="#").iloc[::40].to_csv(path, index=False)
    return path


def _forces(path, log, tmp_path, *extra):
    out = tmp_path / f"{path.stem}_{len(extra)}.csv"
    res = run_phri("simulate", path, log, "-o", out, "-q", *extra)
    assert res.exit_code == 0, stderr_of(res)
    return pd.read_csv(out)


def test_every_value_form_of_stiffening(tmp_path, log_small):
    """Scalar, per_row, per_angle, nested list, label mapping and a fit-stiffness CSV
    with a stiffening_per_m column all give the same per-element rates."""
    from phri_spring.io.config import load_config
    from phri_spring.workflows.common import model_from_config

    labels = load_config(HARMONY_CONFIG).labels
    per_elem = np.repeat([40.0, 60.0, 80.0], 7)
    csv = tmp_path / "fit.csv"
    pd.DataFrame({"location": labels, "stiffness_N_per_m": 4242.0,
                  "stiffening_per_m": per_elem}).to_csv(csv, index=False)
    forms = {
        "per_row": {"per_row": [40.0, 60.0, 80.0]},
        "nested": [[40.0] * 7, [60.0] * 7, [80.0] * 7],
        "labels": {lab: float(v) for lab, v in zip(labels, per_elem)},
        "csv": str(csv),
    }
    got = {}
    for name, value in forms.items():
        path = _cfg(tmp_path, lambda t, v=value: t.update(stiffening=v), f"{name}.yaml")
        model = model_from_config(load_config(path), "compliant")
        assert model.law.name == "exponential"
        np.testing.assert_array_equal(model.law.params["stiffening"], per_elem)
        got[name] = _forces(path, log_small, tmp_path)
    for name in forms:
        pd.testing.assert_frame_equal(got[name], got["per_row"])
    angle = _cfg(tmp_path, lambda t: t.update(stiffening={"per_angle": [10, 20, 30, 40, 50, 60,
                                                                         70]}), "angle.yaml")
    model = model_from_config(load_config(angle), "compliant")
    np.testing.assert_array_equal(model.law.params["stiffening"], np.tile(np.arange(10, 80, 10),
                                                                          3))
    scalar = _cfg(tmp_path, lambda t: t.update(stiffening=50.0), "scalar.yaml")
    assert (model_from_config(load_config(scalar)).law.params["stiffening"] == 50.0).all()


def test_zero_stiffening_and_rigid_arm_leave_outputs_unchanged(tmp_path, log_small):
    plain = _forces(HARMONY_CONFIG, log_small, tmp_path)
    zero = _cfg(tmp_path, lambda t: t.update(stiffening=0.0), "zero.yaml")
    pd.testing.assert_frame_equal(_forces(zero, log_small, tmp_path), plain)
    stiff = _cfg(tmp_path, lambda t: t.update(stiffening=100.0), "stiff.yaml")
    pd.testing.assert_frame_equal(_forces(stiff, log_small, tmp_path, "--arm", "rigid"),
                                  _forces(HARMONY_CONFIG, log_small, tmp_path, "--arm", "rigid"))
    moved = _forces(stiff, log_small, tmp_path)
    assert moved["converged"].all()
    assert not np.allclose(moved.filter(regex=r"^[ABC]\d$").to_numpy(),
                           plain.filter(regex=r"^[ABC]\d$").to_numpy())


@pytest.mark.parametrize("value, needle", [(-1.0, ">= 0"), (".nan", "tissue.stiffening"),
                                           (".inf", "tissue.stiffening"),
                                           ({"per_row": [1, -2, 3]}, ">= 0")])
def test_bad_stiffening_is_one_line(tmp_path, log_small, value, needle):
    data = yaml.safe_load(HARMONY_CONFIG.read_text())
    data["tissue"]["stiffening"] = value
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(data).replace("'.nan'", ".nan").replace("'.inf'", ".inf"))
    out = tmp_path / "f.csv"
    res = run_phri("simulate", path, log_small, "-o", out)
    err = stderr_of(res).strip()
    assert res.exit_code == 1 and "\n" not in err and "Traceback" not in err, err
    assert "tissue.stiffening" in err and needle in err, err
    assert not out.exists()


def test_bad_stiffening_csv_column(tmp_path, log_small):
    from phri_spring.io.config import load_config

    labels = load_config(HARMONY_CONFIG).labels
    csv = tmp_path / "fit.csv"
    pd.DataFrame({"location": labels, "stiffness_N_per_m": 4242.0}).to_csv(csv, index=False)
    path = _cfg(tmp_path, lambda t: t.update(stiffening=str(csv)))
    res = run_phri("simulate", path, log_small, "-o", tmp_path / "f.csv")
    err = stderr_of(res).strip()
    assert res.exit_code == 1 and "stiffening_per_m" in err and "\n" not in err, err


def test_summary_line_names_the_law(tmp_path, log_small):
    stiff = _cfg(tmp_path, lambda t: t.update(stiffening=100.0), "stiff.yaml")
    res = run_phri("simulate", stiff, log_small, "-o", tmp_path / "f.csv")
    assert res.exit_code == 0 and "compliant arm, exponential tissue law" in stderr_of(res)
    res = run_phri("simulate", HARMONY_CONFIG, log_small, "-o", tmp_path / "g.csv")
    assert res.exit_code == 0 and "tissue law" not in stderr_of(res)


# --------------------------------------------------------------------------- the two iterations
def _harmony_exponential(beta, kc_scale=1.0):
    g = harmony_geometry()
    kc = kc_scale * np.tile([31250, 62500, 125000, 250000, 500000, 1.0e6, 500000], 3)
    return build_model(g, 3000.0 * np.ones(g.n), kc, strap_tension=15.0, law="exponential",
                       law_parameters={"stiffening": beta})


def _random_wrenches(m, scale, seed):
    from phri_spring.synthetic.wrench import smooth_random_log

    return scale * smooth_random_log(m, seed=seed)[1]


@pytest.mark.parametrize("beta, scale", [(150.0, 3.0), (600.0, 8.0)])
def test_fast_and_damped_iterations_reach_the_same_equilibrium(monkeypatch, beta, scale):
    """The mixed (displacement and tissue share) Newton iteration that solves most rows and
    the damped Newton on the energy (docs/model.md 11.2) are different algorithms with the
    same stopping rule: their forces agree to 1e-8 of the peak, and both balance the wrench."""
    from phri_spring.physics.springs import newton as spring_newton

    model = _harmony_exponential(beta)
    W = _random_wrenches(400, scale, 5)
    fast = solve(model, W)
    monkeypatch.setattr(spring_newton, "MIXED_ITERATIONS", 0)    # every row to the damped one
    damped = solve(model, W)
    assert fast.converged.all() and damped.converged.all()
    peak = np.abs(damped.forces).max()
    np.testing.assert_allclose(fast.forces, damped.forces, rtol=0, atol=1e-8 * peak)
    for sol in (fast, damped):
        res = sol.forces @ model.b + sol.u @ model.K_s - (W + model.W_pre)
        assert np.abs(res).max() <= 1e-8 * peak


def test_rows_the_fast_iteration_leaves_are_solved_by_the_damped_one(monkeypatch):
    """Very steep stiffening under large loads: the undamped iteration does not settle on
    some rows within its budget; those rows are handed to the damped Newton, and every row
    converges to the equilibrium found by an independent energy minimisation."""
    from phri_spring.physics.springs import newton as spring_newton

    handed = []
    damped = spring_newton._newton_rows

    def spy(model, r, u, max_steps):
        handed.append(len(r))
        return damped(model, r, u, max_steps)

    monkeypatch.setattr(spring_newton, "_newton_rows", spy)
    monkeypatch.setattr(spring_newton, "MIXED_ITERATIONS", 2)
    beta = 3000.0
    model = _harmony_exponential(beta, kc_scale=0.2)
    W = _random_wrenches(60, 12.0, 8)
    sol = solve(model, W)
    assert sum(handed) > 0
    assert sol.converged.all()
    res = sol.forces @ model.b + sol.u @ model.K_s - (W + model.W_pre)
    assert np.abs(res).max() <= 1e-8 * np.abs(sol.forces).max()
    k0, kc = model.law.k0, model.element.k_cuff
    betas = np.full(model.n, beta)
    for i in (0, 30, 59):
        ref = _reference_solution(model, k0, betas, kc, W[i] + model.W_pre)
        np.testing.assert_allclose(sol.forces[i], ref, rtol=0, atol=1e-4 * max(1.0, ref.max()))


def test_single_sample_solver_matches_the_batch_with_a_stiffening_law():
    from phri_spring.physics.contact.solver import Solver

    model = _harmony_exponential(200.0)
    W = _random_wrenches(50, 4.0, 9)
    batch = solve(model, W)
    one = Solver(model)
    single = np.array([one.forces(w) for w in W])
    np.testing.assert_allclose(single, batch.forces, rtol=0,
                               atol=1e-9 * np.abs(batch.forces).max())


def _stepped_log(m, seed):
    """Plateaus at the paper's load levels in random directions, with sensor noise: lift-off
    at every large step, and steps between neighbours the interpolation cannot follow."""
    rng = np.random.default_rng(seed)
    levels = rng.choice([0.0, 11.1, 33.4, 55.6, 120.0], size=m // 40 + 1)
    dirs = rng.normal(size=(len(levels), 6))
    dirs[:, 3:] *= 0.04
    dirs /= np.linalg.norm(dirs[:, :3], axis=1, keepdims=True)
    W = np.repeat(levels[:, None] * dirs, 40, axis=0)[:m]
    return W + rng.normal(0.0, [0.3, 0.3, 0.3, 0.01, 0.01, 0.01], size=(m, 6))


@pytest.mark.parametrize("m", [31, 33, 1001, 2603])
def test_neighbour_warm_start_reaches_the_cold_starts_equilibrium(m):
    """A log's samples start from their solved neighbours (docs/model.md 11.2): the start
    moves the path, not the answer. Against every sample started from the tangent model
    (warm_start=False), on smooth and stepped logs of lengths that leave a short last
    segment and recurse: forces agree to 1e-8 of the peak, the same contact, equilibrium."""
    model = _harmony_exponential(300.0, kc_scale=0.5)
    for W in (_random_wrenches(m, 4.0, 11), _stepped_log(m, 12)):
        warm = solve(model, W)
        cold = solve(model, W, warm_start=False)
        assert warm.converged.all() and cold.converged.all()
        peak = np.abs(cold.forces).max()
        np.testing.assert_allclose(warm.forces, cold.forces, rtol=0, atol=1e-8 * peak)
        # the same contact set, read where the compression is clear of round-off (two
        # iterations may leave an element at 1e-15 m on either side of zero)
        g = model.delta0 + cold.u @ model.b.T
        clear = np.abs(g) > 1e-9 * np.abs(g).max()
        np.testing.assert_array_equal(warm.contact[clear], cold.contact[clear])
        assert clear.mean() > 0.99
        res = warm.forces @ model.b + warm.u @ model.K_s - (W + model.W_pre)
        assert np.abs(res).max() <= 1e-8 * peak


def test_a_sample_that_does_not_converge_is_no_start_for_its_neighbours():
    """An absurd sample (1e200 N: its forces overflow) on a row solved first is flagged; the
    samples next to it start from the tangent model instead and are solved as without it."""
    model = _harmony_exponential(100.0)
    W = _random_wrenches(400, 3.0, 13)
    bad = W.copy()
    bad[64] = [1e200, 0.0, 0.0, 0.0, 0.0, 0.0]      # a row of the first, strided pass
    sol = solve(model, bad)
    ref = solve(model, W, warm_start=False)
    assert not sol.converged[64] and np.isnan(sol.forces[64]).all()
    others = np.arange(400) != 64
    assert sol.converged[others].all()
    peak = np.abs(ref.forces).max()
    np.testing.assert_allclose(sol.forces[others], ref.forces[others], rtol=0, atol=1e-8 * peak)


@pytest.mark.parametrize("beta", [0.3, 1.0, 40.0, 900.0])
def test_force_and_tangent_together_match_the_law(beta):
    """The solver's inner loop asks the law for force and tangent at once
    (``force_tangent``: exp(x) - 1 for beta >= 1 1/m, expm1 below). Against the closed
    form F = (k0/beta) expm1(beta d) from 0 to 3 cm: the tangent to 1e-13, the force to
    1e-12 of itself plus the rounding of exp(x) - 1, F' * 2.2e-16 / beta (a force far
    below the solver's tolerance)."""
    k0 = np.array([500.0, 3000.0, 9e4])
    law = ExponentialLaw(k0, stiffening=beta)
    d = np.concatenate([[0.0], np.geomspace(1e-12, 0.03, 400)])[:, None] * np.ones(3)
    Fc, Ft = law.force_tangent(d)
    exact = k0 / beta * np.expm1(beta * d)
    np.testing.assert_allclose(Ft, k0 * np.exp(beta * d), rtol=1e-13, atol=0)
    assert np.all(np.abs(Fc - exact) <= 1e-12 * exact + 4 * 2.2e-16 * Ft / beta)
    assert np.all(Fc[0] == 0.0)


def test_rows_resumed_from_another_block_end_where_one_pass_ends():
    """The warm start stops each block after one Newton step and iterates the rows left
    together (docs/model.md 11.1): stopping and resuming must not change a row's path.
    The arithmetic per row is the same; only the blocks the matrix products see differ, so
    the answers agree to round-off and the rows take the same steps."""
    from phri_spring.physics.springs import newton as sn

    model = _harmony_exponential(300.0, kc_scale=0.5)
    W = _stepped_log(300, 21) + model.W_pre
    u_one = np.zeros((len(W), 6))
    u_two = u_one.copy()
    conv1, its1, f1, left1 = sn._mixed_rows(model, W, u_one)
    first = 3        # from rest: some rows settle within three steps, others do not
    conv2, its2, f2, left = sn._mixed_rows(model, W, u_two, steps=first)
    assert left is not None and 0 < len(left[0]) < len(W)
    rows, dt, tol2 = left
    ur = u_two[rows]
    c3, i3, f3, _ = sn._mixed_rows(model, W[rows], ur, dt, steps=sn.MIXED_ITERATIONS - first,
                                   tol2=tol2)
    u_two[rows], conv2[rows], its2[rows] = ur, c3, its2[rows] + i3
    f2[rows[c3]] = f3[c3]
    np.testing.assert_array_equal(conv1, conv2)
    assert np.abs(its1 - its2).max() <= 1
    assert conv1.mean() > 0.9
    peak = np.abs(f1[conv1]).max()
    np.testing.assert_allclose(f2[conv1], f1[conv1], rtol=0, atol=1e-9 * peak)
    np.testing.assert_allclose(u_two[conv1], u_one[conv1], rtol=0,
                               atol=1e-9 * np.abs(u_one[conv1]).max())
