"""The summary's load shares (docs/model.md section 12.4): what the cuff passes to the skin.

The fast per-block computation (``load_path.transmitted`` and ``transmitted_sums``) is
checked against the tangential forces built another way: the spring model's (m, n, 3)
``shear_forces`` (cross products), and the reference model of ``tests/support/reference_model.py``
(an element-by-element loop); friction and the coupled arm against their own solution's
forces and the vector split ``force_parts`` (a sum of magnitudes is at least the magnitude
of the sum). The shares are a property test on random cuffs and loads, the streamed summary
against the in-memory solution of the same log, and the printed line adds up to 100.0 %.
"""

from __future__ import annotations
from support.helpers import REPO  # noqa: E402

import re

import numpy as np
import pandas as pd
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from support.helpers import build_both, physics_cases, run_phri, wrenches
from phri_cli.simulate import percent_parts
from phri_spring.io.config import load_config
from phri_spring.physics.continuum.coupled import build_coupled_model
from phri_spring.physics.cuff.geometry import cuff_geometry, section_geometry
from phri_spring.physics.contact.load_path import (force_parts, load_shares, share_sums, shear_rows,
                                           transmitted, transmitted_sums)
from phri_spring.physics.springs.model import build_model, tissue_element_stiffness
from phri_spring.physics.contact.solution import Solution
from phri_spring.physics.contact.solver import solve
from phri_spring.workflows.common import cuff_wrench, model_from_config
from phri_spring.workflows.simulate import SummaryAccumulator, simulate_file

ROOT = REPO
HARMONY = ROOT / "configs" / "harmony_upper_arm.yaml"


def _harmony(arm="compliant", mu=None):
    g = cuff_geometry([-0.025, 0.0, 0.025], 0.045, 0.025, 75.0, 35.0, 7)
    k_t = tissue_element_stiffness(np.full(g.n, 4242.0), g.areas)
    return build_model(g, k_t, 2e5, arm=arm, strap_tension=15.0, friction_coefficient=mu)


def _tapered_ellipse(arm="compliant"):
    """An elliptic (0.8), turned, tapered (6 deg) limb: shear directions that are not +x."""
    from phri_spring.physics.limb.sections import EllipseSection

    sec = (EllipseSection(0.05, 0.04, np.radians(20.0)),) * 3
    g = section_geometry([-0.025, 0.0, 0.025], sec, 0.025, 75.0, 35.0, 7, taper_deg=6.0)
    k_t = tissue_element_stiffness(np.full(g.n, 4242.0), g.areas)
    return build_model(g, k_t, 2e5, arm=arm, strap_tension=15.0)


def test_shear_rows_follow_a_tapered_limbs_meridian():
    # with a taper the axial shear direction is the skin's meridian, not +x: the fast rows
    # must give the model's own (m, n, 3) shear forces projected on its geometry's axes
    model = _tapered_ellipse()
    W = _loads(300, seed=4)
    sol = solve(model, W)
    assert sol.converged.all()
    s = model.shear_forces(sol.u)                                     # (m, n, 3)
    g = model.geometry
    uR = sol.u @ shear_rows(model)
    scale = np.abs(s).max()
    np.testing.assert_allclose(uR[:, :model.n], np.sum(s * g.meridian, -1), atol=1e-12 * scale)
    np.testing.assert_allclose(uR[:, model.n:], np.sum(s * g.circumferential, -1),
                               atol=1e-12 * scale)
    ref = _by_kind(sol.forces, np.linalg.norm(s, axis=-1), sol.contact)
    got = transmitted(model, sol.u, sol.contact, normal=sol.forces)
    np.testing.assert_allclose(got, ref, rtol=0, atol=1e-12 * ref.sum(1).max())


def _coupled(mu=None):
    """A coupled cuff with a Gaussian-coupled patch compliance (no FE), as in test_friction."""
    g = cuff_geometry([-0.025, 0.0, 0.025], 0.045, 0.025, 75.0, 35.0, 7)
    d2 = np.sum((g.points[:, None, :] - g.points[None, :, :]) ** 2, axis=-1)
    rot = np.diag([1.0, 1.0, 1.0, 1e-3, 1e-3, 1e-3])
    C = 2e-5 * np.kron(np.eye(g.n), rot) + 2e-5 * np.kron(np.exp(-d2 / 0.03**2), rot)
    return build_coupled_model(g, np.linalg.inv(C), 2e5, strap_tension=15.0,
                               friction_coefficient=mu)


def _loads(m, seed=0, force=60.0, moment=2.0):
    rng = np.random.default_rng(seed)
    return rng.normal(size=(m, 6)) * np.array([force / 3] * 3 + [moment / 3] * 3)


def _by_kind(fn, ft, S):
    """Reference (m, 3): normal in contact, tangential magnitude in contact, lifted."""
    return np.stack([np.where(S, fn, 0.0).sum(1), np.where(S, ft, 0.0).sum(1),
                     np.where(S, 0.0, ft).sum(1)], axis=1)


@pytest.mark.parametrize("arm", ["compliant", "rigid"])
def test_bonded_parts_equal_the_cross_product_shear_forces(arm):
    model = _harmony(arm)
    W = _loads(2 * 2048 + 37, seed=1)       # several blocks and a short last one
    sol = solve(model, W)
    assert sol.converged.all() and (~sol.contact).any() and sol.contact.any()
    ft = np.linalg.norm(model.shear_forces(sol.u), axis=-1)            # (m, n, 3) route
    ref = _by_kind(sol.forces, ft, sol.contact)
    scale = ref.sum(axis=1, keepdims=True)
    got = transmitted(model, sol.u, sol.contact, normal=sol.forces)
    np.testing.assert_allclose(got, ref, rtol=0, atol=1e-12 * scale.max())
    # without the solution's forces: recomputed from u
    got_u = transmitted(model, sol.u, sol.contact)
    np.testing.assert_allclose(got_u, ref, rtol=0, atol=1e-12 * scale.max())
    sums = transmitted_sums(model, sol.u, sol.contact, normal=sol.forces,
                            rows=shear_rows(model))
    np.testing.assert_allclose(sums, ref.sum(axis=0), rtol=1e-12)
    # the rows reproduce the model's shear components (axial, circumferential)
    comp = model.shear_components(sol.u[:50])
    n = model.n
    uR = sol.u[:50] @ shear_rows(model)
    np.testing.assert_allclose(uR[:, :n], comp[..., 0], rtol=0, atol=1e-12 * np.abs(comp).max())
    np.testing.assert_allclose(uR[:, n:], comp[..., 1], rtol=0, atol=1e-12 * np.abs(comp).max())


@settings(max_examples=15, deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])
@given(case=physics_cases(max_rows=3, max_count=8),
       loads=st.lists(wrenches(max_force=80.0), min_size=1, max_size=6))
def test_shares_are_fractions_that_add_up_on_random_cuffs(case, loads):
    try:
        model, rmod = build_both(case)
    except ValueError:          # a geometry the cuff is not held by (refused, one line)
        assume(False)
    W = np.array(loads)
    sol = solve(model, W)
    ok = sol.converged
    parts = transmitted(model, sol.u, sol.contact, normal=sol.forces)
    # against the reference model's element-by-element shear springs
    for i in np.flatnonzero(ok):
        ft = np.linalg.norm(rmod.shear(sol.u[i]), axis=1)
        ref = _by_kind(rmod.forces(sol.u[i])[None], ft[None], sol.contact[i][None])[0]
        np.testing.assert_allclose(parts[i], ref, rtol=1e-9, atol=1e-9 * max(ref.sum(), 1e-9))
    shares = load_shares(parts[ok])
    per_sample = load_shares(parts[ok], weighted=False)
    for s in [shares, *per_sample]:
        if np.isfinite(s).all():
            assert np.all(s >= 0) and np.all(s <= 1)
            assert s.sum() == pytest.approx(1.0, abs=1e-12)
        else:
            assert np.isnan(s).all()


@given(parts=st.lists(st.tuples(*[st.one_of(st.floats(0, 1e4), st.just(np.nan))] * 3),
                      min_size=1, max_size=20))
def test_shares_skip_unconverged_samples(parts):
    P = np.array(parts, dtype=float)
    shares = load_shares(P)
    finite = P[np.isfinite(P).all(axis=1)]
    total = finite.sum()
    if total > 0:
        assert np.all((shares >= 0) & (shares <= 1))
        assert shares.sum() == pytest.approx(1.0, abs=1e-12)
        np.testing.assert_allclose(shares, finite.sum(axis=0) / total)
    else:
        assert np.isnan(shares).all()
    np.testing.assert_array_equal(share_sums(P), finite.sum(axis=0))


@pytest.mark.parametrize("make", [lambda: _harmony(mu=0.5), lambda: _coupled(),
                                  lambda: _coupled(mu=0.5)],
                         ids=["friction", "coupled", "coupled-friction"])
def test_friction_and_coupled_parts(make):
    model = make()
    F = np.concatenate([np.linspace(0, 50, 40), np.linspace(50, 0, 40)])
    W = np.zeros((len(F), 6))
    W[:, 2] = F                                     # a push that lifts patches off
    W[:, 1] = 0.3 * F
    sol = solve(model, W)
    assert sol.converged.all() and (~sol.contact).any()
    parts = transmitted(model, sol.u, sol.contact, normal=sol.forces, tangential=sol.tangential)
    if sol.tangential is not None:                  # friction: its own forces, none lifted
        ft = np.linalg.norm(sol.tangential, axis=-1)
        ref = _by_kind(np.abs(sol.forces), ft, sol.contact)
        assert np.all(parts[:, 2] == 0)
    else:                                           # coupled bonded: the program's forces
        P = model.patch_forces(sol.u, sol.contact)
        ref = _by_kind(np.abs(P[..., 0]), np.linalg.norm(P[..., 1:3], axis=-1), sol.contact)
    np.testing.assert_allclose(parts, ref, rtol=1e-12, atol=1e-12 * ref.max())
    sums = transmitted_sums(model, sol.u, sol.contact, normal=sol.forces,
                            tangential=sol.tangential)
    np.testing.assert_allclose(sums, ref.sum(axis=0), rtol=1e-12)
    # a sum of magnitudes is at least the magnitude of the vector sum of each kind
    vec = np.linalg.norm(force_parts(model, sol.u, sol.contact, normal=sol.forces,
                                     tangential=sol.tangential), axis=-1)
    assert np.all(parts >= vec - 1e-9 * ref.max())


def test_summary_skips_unconverged_samples():
    model = _harmony()
    W = _loads(300, seed=3)
    sol = solve(model, W)
    bad = np.zeros(len(W), bool)
    bad[::7] = True
    u, f = sol.u.copy(), sol.forces.copy()
    u[bad], f[bad] = np.nan, np.nan
    flagged = Solution(u, f, sol.iterations, ~bad, np.where(bad[:, None], False, sol.contact))
    acc = SummaryAccumulator(model.labels)
    acc.add_solution(flagged)
    acc.add_load_path(0, model, flagged)
    got = acc.summary("out.csv", None).load_shares
    ref = _by_kind(sol.forces, np.linalg.norm(model.shear_forces(sol.u), axis=-1),
                   sol.contact)[~bad].sum(axis=0)
    np.testing.assert_allclose(got, ref / ref.sum(), rtol=1e-12)
    assert sum(got) == pytest.approx(1.0, abs=1e-12)


def _write_log(path, W_lc):
    df = pd.DataFrame(W_lc, columns=["Fx", "Fy", "Fz", "Mx", "My", "Mz"])
    df.insert(0, "time", np.arange(len(W_lc)) / 100.0)
    df.to_csv(path, index=False, float_format="%.17g")


def test_streamed_summary_equals_the_whole_log_and_the_line_adds_up(tmp_path):
    W_lc = _loads(2500, seed=5, force=40.0, moment=1.5)
    log = tmp_path / "log.csv"
    _write_log(log, W_lc)
    summary = simulate_file(HARMONY, log, tmp_path / "f.csv", chunk_rows=600)
    cfg = load_config(HARMONY)
    model = model_from_config(cfg, "compliant")
    sol = solve(model, cuff_wrench(cfg, W_lc))
    ft = np.linalg.norm(model.shear_forces(sol.u), axis=-1)
    ref = _by_kind(sol.forces, ft, sol.contact).sum(axis=0)
    np.testing.assert_allclose(summary.load_shares, ref / ref.sum(), rtol=1e-9)

    res = run_phri("simulate", HARMONY, log, "-o", tmp_path / "g.csv")
    assert res.exit_code == 0, res.output
    line = re.search(r"force passed to the skin: ([\d.]+)% normal, ([\d.]+)% bonded ties in "
                     r"contact, ([\d.]+)% lifted elements' bonded springs", res.output)
    assert line, res.output
    printed = [float(x) for x in line.groups()]
    assert sum(printed) == pytest.approx(100.0, abs=1e-9)
    np.testing.assert_allclose(printed, 100 * ref / ref.sum(), atol=0.1)


@pytest.mark.parametrize("backlog", [0, 99])
def test_streamed_summary_whichever_thread_adds_the_load_path(tmp_path, monkeypatch, backlog):
    # a writer that is always behind (99) makes the solving thread add every chunk's load
    # path itself, one never behind (0) leaves it to the writer: each chunk counted once
    from phri_spring.io.outputs.forces import ForcesWriter

    monkeypatch.setattr(ForcesWriter, "backlog", property(lambda self: backlog))
    W_lc = _loads(1800, seed=7, force=40.0, moment=1.5)
    log = tmp_path / "log.csv"
    _write_log(log, W_lc)
    summary = simulate_file(HARMONY, log, tmp_path / "f.parquet", chunk_rows=500)
    cfg = load_config(HARMONY)
    model = model_from_config(cfg, "compliant")
    sol = solve(model, cuff_wrench(cfg, W_lc))
    ft = np.linalg.norm(model.shear_forces(sol.u), axis=-1)
    ref = _by_kind(sol.forces, ft, sol.contact).sum(axis=0)
    np.testing.assert_allclose(summary.load_shares, ref / ref.sum(), rtol=1e-9)


@given(shares=st.lists(st.floats(0, 1), min_size=3, max_size=3).filter(lambda s: sum(s) > 0))
def test_printed_percentages_add_up_to_100(shares):
    s = np.array(shares) / sum(shares)
    printed = [float(x) for x in percent_parts(s)]
    assert sum(printed) == pytest.approx(100.0, abs=1e-9)
    assert np.all(np.abs(np.array(printed) - 100 * s) < 0.1 + 1e-9)


class _Wrapped:
    """Another arm's model: not a SpringModel, with the model interface the summary reads."""

    def __init__(self, model):
        self._m = model

    def __getattr__(self, name):
        return getattr(self._m, name)


def test_another_arms_model_gives_its_own_shear_forces():
    model = _harmony()
    sol = solve(model, _loads(200, seed=9))
    fast = transmitted_sums(model, sol.u, sol.contact, normal=sol.forces)
    other = transmitted_sums(_Wrapped(model), sol.u, sol.contact, normal=sol.forces)
    np.testing.assert_allclose(other, fast, rtol=1e-12)
