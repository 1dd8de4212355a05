"""Tissue laws as plug-ins: a toy law registered here runs through the library and the commands.

The toy law F(d) = k0 d (1 + c d) (``tissue.law: toy_quadratic``, ``tissue.toy_rate: c``
[1/m]) is written in this file only, as a user would add one. It is not linear as far as
the solver knows (``is_linear`` False), so with c = 0 the damped Newton path must give the
exact active-set answer of the linear model; with c > 0 its answer must be the minimiser of
the energy written out here independently and minimised by scipy.
"""

from __future__ import annotations

import copy

import numpy as np
import pandas as pd
import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import minimize

from phri_spring.physics.springs.model import build_model, tissue_element_stiffness
from phri_spring.physics.contact.solver import Solver, solve, solve_per_sample
from phri_spring.physics.laws import (TISSUE_LAWS, LawParameter, SeriesElement, TissueLaw,
                                             make_law, register_law)

from support.helpers import HARMONY_CONFIG, run_phri, stderr_of, harmony_geometry


class ToyQuadratic(TissueLaw):
    name = "toy_quadratic"
    parameters = (LawParameter("toy_rate", "1/m", "stiffening of the toy law", 0.0),)

    def force(self, d):
        dp = np.maximum(d, 0.0)
        return self.k0 * dp * (1.0 + self.params["toy_rate"] * dp)

    def tangent(self, d):
        d = np.asarray(d, dtype=float)
        return np.where(d >= 0, self.k0 * (1.0 + 2.0 * self.params["toy_rate"] * np.maximum(d, 0)),
                        0.0)

    def energy(self, d):
        dp = np.maximum(d, 0.0)
        return self.k0 * (0.5 * dp ** 2 + self.params["toy_rate"] * dp ** 3 / 3.0)


@pytest.fixture(autouse=True, scope="module")
def toy_registered():
    register_law(ToyQuadratic)
    yield
    TISSUE_LAWS.pop("toy_quadratic", None)


def _geometry():
    return harmony_geometry()


def _model(rate, strap="hoop", k_c=None, seed=0):
    g = _geometry()
    rng = np.random.default_rng(seed)
    k_t = tissue_element_stiffness(rng.uniform(3000, 5000, g.n), g.areas)
    k_c = rng.uniform(3e4, 1e6, g.n) if k_c is None else k_c
    return build_model(g, k_t, k_c, strap_model=strap, strap_tension=15.0,
                       law="toy_quadratic", law_parameters={"toy_rate": rate})


def _log(m, seed):
    rng = np.random.default_rng(seed)
    return rng.normal(size=(m, 6)) * np.array([30, 30, 30, 1.5, 1.5, 1.5])


@settings(max_examples=40, deadline=None)
@given(k0=st.floats(100.0, 1e5), kc=st.sampled_from([1e3, 1e5, np.inf]),
       c=st.floats(0.0, 500.0), d=st.floats(1e-6, 0.03))
def test_series_element_force_tangent_energy_agree(k0, kc, c, d):
    """f = dpsi/dd and k = df/dd by central differences; d = d_t + f / k_c; the inverse."""
    el = SeriesElement(make_law("toy_quadratic", [k0], toy_rate=c), [kc])
    h = 1e-7 * d
    f, k = el.force(np.array([d]))[0], el.tangent(np.array([d]))[0]
    dpsi = (el.energy(np.array([d + h])) - el.energy(np.array([d - h])))[0] / (2 * h)
    df = (el.force(np.array([d + h])) - el.force(np.array([d - h])))[0] / (2 * h)
    assert dpsi == pytest.approx(f, rel=1e-5)
    assert df == pytest.approx(k, rel=1e-5)
    dt = el.tissue_compression(np.array([d]))[0]
    assert dt + f / kc == pytest.approx(d, rel=1e-12)
    assert el.compression_at(np.array([f]))[0] == pytest.approx(d, rel=1e-9)
    assert el.force(np.array([-d]))[0] == 0.0 and el.energy(np.array([-d]))[0] == 0.0


@pytest.mark.parametrize("strap", ["hoop", "handles"])
def test_zero_rate_through_newton_is_the_linear_model(strap):
    """c = 0: the toy law is k0 d, solved by the Newton path; the linear law by the exact
    active-set path. Same forces to 1e-9 of the peak, same contact sets away from 0 N."""
    toy = _model(0.0, strap)
    g = toy.geometry
    lin = build_model(g, toy.law.k0, toy.element.k_cuff, strap_model=strap, strap_tension=15.0)
    assert not toy.is_linear and lin.is_linear
    W = _log(600, 1)
    a, b = solve(toy, W), solve(lin, W)
    assert a.converged.all() and b.converged.all()
    peak = np.abs(b.forces).max()
    np.testing.assert_allclose(a.forces, b.forces, rtol=0, atol=1e-9 * peak)
    clear = np.abs(b.forces) > 1e-6 * peak
    np.testing.assert_array_equal(a.contact[clear], b.contact[clear])


def _energy(u, model, r, rate):
    """Pi(u) of the toy law in series with the cuff springs, written out independently."""
    g = model.delta0 + model.b @ u
    k0, kc = model.law.k0, model.element.k_cuff
    psi = 0.0
    for e in np.flatnonzero(g > 0):
        # tissue share d_t: d_t + k0 d_t (1 + c d_t) / k_c = g, a quadratic in d_t
        a, b, c = k0[e] * rate / kc[e], 1.0 + k0[e] / kc[e], -g[e]
        dt = (-b + np.sqrt(b * b - 4 * a * c)) / (2 * a) if a > 0 else -c / b
        f = k0[e] * dt * (1 + rate * dt)
        psi += k0[e] * (0.5 * dt ** 2 + rate * dt ** 3 / 3) + 0.5 * f * f / kc[e]
    return psi + 0.5 * u @ model.K_s @ u - r @ u


def test_stiffening_answer_is_the_energy_minimum_and_in_equilibrium():
    rate = 300.0
    model = _model(rate)
    W = _log(40, 2)
    sol = solve(model, W)
    assert sol.converged.all()
    # equilibrium of the reported forces: sum f_e b_e + K_s u = W + W_pre
    res = sol.forces @ model.b + sol.u @ model.K_s - (W + model.W_pre)
    assert np.abs(res).max() <= 1e-8 * np.abs(sol.forces).max()
    # the minimiser of the independently written energy
    unit = np.array([1e-4] * 3 + [1e-3] * 3)            # m and rad: a well-scaled search

    def scaled(v, r):
        return 1e3 * _energy(v * unit, model, r, rate)

    for i in range(0, 40, 8):
        r = W[i] + model.W_pre
        ref = minimize(scaled, np.zeros(6), args=(r,), method="BFGS",
                       options={"gtol": 1e-10, "maxiter": 5000})
        np.testing.assert_allclose(sol.u[i] / unit, ref.x, rtol=0,
                                   atol=1e-5 * np.abs(sol.u[i] / unit).max())
    # stiffer than the linear model: the same load compresses it less
    lin = build_model(model.geometry, model.law.k0, model.element.k_cuff, strap_tension=15.0)
    assert np.abs(solve(lin, W).u[:, :3]).sum() > np.abs(sol.u[:, :3]).sum()
    # the single-sample solver and the per-sample path give the same answer
    one = Solver(model)
    np.testing.assert_allclose([one.forces(w) for w in W], sol.forces, rtol=0,
                               atol=1e-9 * np.abs(sol.forces).max())
    np.testing.assert_allclose(solve_per_sample(model, W).forces, sol.forces, rtol=0,
                               atol=1e-9 * np.abs(sol.forces).max())


def test_preload_is_carried_at_zero_wrench():
    model = _model(300.0)
    sol = solve(model, np.zeros(6))
    np.testing.assert_allclose(sol.forces, model.f0, rtol=1e-9)
    np.testing.assert_allclose(sol.u, 0.0, atol=1e-12)


# --------------------------------------------------------------------------- the commands
@pytest.fixture
def toy_config(tmp_path):
    data = yaml.safe_load(HARMONY_CONFIG.read_text())
    data["tissue"]["law"] = "toy_quadratic"
    data["tissue"]["toy_rate"] = {"per_row": [200.0, 300.0, 400.0]}
    path = tmp_path / "toy.yaml"
    path.write_text(yaml.safe_dump(data))
    return path, data


def test_toy_law_runs_through_simulate_stiffness_and_design(tmp_path, toy_config):
    from phri_spring.io.config import load_config
    from phri_spring.workflows.common import cuff_wrench, model_from_config

    path, data = toy_config
    out = tmp_path / "f.csv"
    res = run_phri("simulate", path, "examples/wrench_log.csv", "-o", out, "-q")
    assert res.exit_code == 0, stderr_of(res)
    df = pd.read_csv(out)
    assert df["converged"].all()
    cfg = load_config(path)
    model = model_from_config(cfg, "compliant")
    assert model.law.name == "toy_quadratic"
    np.testing.assert_allclose(model.law.params["toy_rate"], np.repeat([200, 300, 400], 7))
    from phri_spring.io.logs import read_wrench_log

    t, w = read_wrench_log("examples/wrench_log.csv")
    ref = solve(model, cuff_wrench(cfg, w))
    np.testing.assert_allclose(df[list(cfg.labels)].to_numpy(), ref.forces, rtol=0, atol=2e-6)

    # interface stiffness: the tangent at the preload, stiffer than the linear law's
    res = run_phri("stiffness", path, "--json")
    assert res.exit_code == 0, stderr_of(res)
    lin = copy.deepcopy(data)
    lin["tissue"].pop("law"), lin["tissue"].pop("toy_rate")
    lin_path = tmp_path / "lin.yaml"
    lin_path.write_text(yaml.safe_dump(lin))
    import json

    K_toy = np.array(json.loads(res.output)["K"])
    K_lin = np.array(json.loads(run_phri("stiffness", lin_path, "--json").output)["K"])
    assert (np.diag(K_toy) >= np.diag(K_lin) - 1e-9 * np.abs(K_lin).max()).all()
    assert np.diag(K_toy)[2] > np.diag(K_lin)[2]

    # a design study over the toy law's parameter
    log = tmp_path / "log.csv"
    pd.read_csv("examples/wrench_log.csv", comment="#").iloc[::20].to_csv(log, index=False)
    study = tmp_path / "study.yaml"
    study.write_text(yaml.safe_dump({
        "config": str(path), "loads": [str(log)], "arm": "compliant",
        "vary": {"tissue.toy_rate.per_row[1]": {"values": [0.0, 600.0]}},
        "plan": "grid", "minimise": ["peak_pressure_to_pain_threshold"]}))
    res = run_phri("design", study, "-o", tmp_path / "design", "-q", "--no-figures")
    assert res.exit_code == 0, stderr_of(res)
    designs = pd.read_csv(tmp_path / "design" / "designs.csv")
    assert len(designs) == 2 and designs["peak_pressure_to_pain_threshold"].notna().all()


@pytest.mark.parametrize("edit, needles", [
    (lambda t: t.update(law="toy_quadratc"), ["tissue.law", "did you mean 'toy_quadratic'"]),
    (lambda t: t.update(toy_rte=1.0), ["tissue.toy_rte", "did you mean 'toy_rate'"]),
    (lambda t: t.update(toy_rate=-1.0), ["tissue.toy_rate", ">= 0"]),
    (lambda t: t.update(toy_rate=".nan"), ["tissue.toy_rate"]),
    (lambda t: t.update(law="linear"), ["tissue.toy_rate", "unknown key"]),
])
def test_bad_law_config_is_one_line(tmp_path, toy_config, edit, needles):
    _, data = toy_config
    data = copy.deepcopy(data)
    edit(data["tissue"])
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(data).replace("'.nan'", ".nan"))
    out = tmp_path / "f.csv"
    res = run_phri("simulate", path, "examples/wrench_log.csv", "-o", out)
    err = stderr_of(res).strip()
    assert res.exit_code == 1 and "\n" not in err and "Traceback" not in err, err
    for n in needles:
        assert n in err, err
    assert not out.exists()


def test_a_law_must_declare_units():
    class NoUnit(TissueLaw):
        name = "no_unit"
        parameters = (LawParameter("x", "", "something"),)

    with pytest.raises(TypeError, match="unit"):
        register_law(NoUnit)


def test_the_docs_example_law_runs(tmp_path):
    """docs/extending.md's example law (adding a tissue law), executed as written, runs
    through simulate with the docs' config keys and equals the toy law of this file with the same rate."""
    import re

    from support.helpers import REPO

    text = (REPO / "docs" / "extending.md").read_text()
    section = text[text.index("## Adding a tissue law"):]
    code = re.findall(r"```python\n(.*?)```", section, flags=re.S)[0]
    keys = yaml.safe_load(re.findall(r"```yaml\n(.*?)```", section, flags=re.S)[0])["tissue"]
    try:
        exec(compile(code, "docs/extending.md", "exec"), {})  # noqa: S102 - our own docs
        data = yaml.safe_load(HARMONY_CONFIG.read_text())
        data["tissue"].update({k: v for k, v in keys.items() if k != "stiffness"})
        path = tmp_path / "docs_law.yaml"
        path.write_text(yaml.safe_dump(data))
        out = tmp_path / "f.csv"
        res = run_phri("simulate", path, "examples/wrench_log.csv", "-o", out, "-q")
        assert res.exit_code == 0, stderr_of(res)
        data["tissue"]["law"] = "toy_quadratic"
        data["tissue"]["toy_rate"] = data["tissue"].pop("quadratic_rate")
        path.write_text(yaml.safe_dump(data))
        res = run_phri("simulate", path, "examples/wrench_log.csv", "-o", tmp_path / "g.csv", "-q")
        assert res.exit_code == 0, stderr_of(res)
        a, b = pd.read_csv(out), pd.read_csv(tmp_path / "g.csv")
        pd.testing.assert_frame_equal(a, b)
    finally:
        TISSUE_LAWS.pop("quadratic", None)
