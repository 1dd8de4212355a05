"""Shared fixtures, hypothesis strategies and helpers of the test suite.

Expected values come from ``tests/support/reference_model.py`` (an independent
implementation of docs/model.md sections 1-6), from closed forms derived by hand in the
tests, never from the package's own output.
"""

from __future__ import annotations

import copy
import math
import time
from pathlib import Path

import numpy as np
import pytest
from hypothesis import strategies as st

from support import reference_model as ref

TESTS = Path(__file__).resolve().parent.parent
REPO = TESTS.parent

HARMONY_CONFIG = REPO / "configs" / "harmony_upper_arm.yaml"

#: the example config of docs/model.md section 6, as a mapping
HARMONY_DICT = {
    "name": "Harmony upper-arm cuff on the proxy arm",
    "geometry": {
        "radius": 0.045,
        "rows": {"A": -0.025, "B": 0.0, "C": 0.025},
        "row_width": 0.025,
        "angles": {"start": 75.0, "step": 35.0, "count": 7},
    },
    "load_cell": {"position": [0.0, -0.07, 0.0], "euler_xyz_deg": [0, 0, 0],
                  "convention": "robot_on_cuff"},
    "tissue": {"stiffness": 4242.0, "basis": "indenter", "indenter_diameter": 0.009,
               "poisson_ratio": 0.45},
    "cuff": {"stiffness": {"per_angle": [31250, 62500, 125000, 250000, 500000, 1.0e6, 500000]}},
    "interface": {"pain_threshold_kpa": 120},
    "strap": {"tension": 15.0, "model": "hoop"},
    "solver": {"max_iterations": 100},
}


def harmony_geometry():
    """The Harmony-like test cuff (3 rows 25 mm apart, R = 45 mm, 7 locations from 75 degrees
    35 degrees apart) read from ``configs/harmony_upper_arm.yaml``: the one definition the
    tests and the benchmarks (``benchmarks/common.py``) share."""
    from phri_spring.io.config import load_config
    from phri_spring.workflows.common import geometry_from_config

    return geometry_from_config(load_config(HARMONY_CONFIG))


def harmony_dict() -> dict:
    return copy.deepcopy(HARMONY_DICT)


@pytest.fixture
def harmony() -> dict:
    """A fresh copy of the docs/model.md section 6 example config (mutable)."""
    return harmony_dict()


def small_human_cuff(**continuum) -> dict:
    """The human preset as a mapping, cut to one row of five patches on a rigid cuff (what
    the hyperelastic arm is identified for, small enough to identify in minutes), with
    ``tissue.continuum`` updated by ``continuum``."""
    import yaml

    from phri_spring.io.config.yaml_loader import _StrictSafeLoader

    raw = yaml.load((REPO / "configs" / "human_upper_arm.yaml").read_text(),
                    Loader=_StrictSafeLoader)
    raw["geometry"]["rows"] = {"A": 0.0}
    raw["geometry"]["angles"] = {"start": 110.0, "step": 35.0, "count": 5}
    raw["cuff"]["stiffness"] = float("inf")
    raw["tissue"]["continuum"].update(continuum)
    return raw


def cached_identification_only(mp, cache=None) -> None:
    """The hyperelastic arm from an identification the test already made: identification
    at the tests' mesh level 1, any new identification a failure; with ``cache``, also the
    cache folder the commands use (PHRI_SPRING_CACHE). ``mp``: a pytest MonkeyPatch."""
    import pytest

    from phri_spring.io.cache import hyper_reduction as store

    if cache is not None:
        mp.setenv("PHRI_SPRING_CACHE", str(cache))
    mp.setattr(store, "IDENTIFY_LEVEL", 1)
    mp.setattr("phri_spring.physics.hyperelastic.reduced.identify",
               lambda *a, **k: pytest.fail("identified again"))


def check_friction_laws(model, W, sol, mu):
    """Equilibrium, cone, released-carry-nothing, no penetration, at every converged sample
    of a friction solution (docs/model.md section 12.1); returns (normal forces, the
    released mask, the compressions (spring model; None otherwise), the force scale) of
    those samples for further checks."""
    from phri_spring.physics.friction import path as friction

    form = friction.interface_form(model)
    ok = sol.converged
    fn, ft = sol.forces[ok], sol.tangential[ok]
    m = int(ok.sum())
    P = np.zeros((m, form.n, form.d))
    P[:, :, 0], P[:, :, 1:3] = fn, ft
    if sol.moments is not None:
        P[:, :, 3:] = sol.moments[ok]
    r = W[ok] + model.W_pre
    scale = np.abs(r).max() + 1.0
    np.testing.assert_allclose(P.reshape(m, -1) @ form.T, r, rtol=0, atol=1e-10 * scale)
    tn = np.linalg.norm(ft, axis=2)
    assert np.all(fn >= 0)
    assert np.all(tn <= mu * fn + 1e-9 * scale)
    off = ~sol.contact[ok]
    assert np.all(P[off] == 0.0)
    assert np.all(tn[fn == 0] <= 1e-9 * scale)
    g = None
    if hasattr(model, "delta0"):   # spring model: a released element is not compressed
        g = model.delta0 + sol.u[ok] @ model.bT
        assert np.all(g[off] <= 1e-12 * (np.abs(g).max() + 1e-9))
    return fn, off, g, scale


def write_yaml(folder, raw: dict, name: str = "cfg.yaml") -> Path:
    """``raw`` written as YAML to folder / name; the path."""
    import yaml

    path = Path(folder) / name
    path.write_text(yaml.safe_dump(raw))
    return path


# --------------------------------------------------------------------------- strategies
def _log_uniform(lo, hi):
    return st.floats(math.log(lo), math.log(hi)).map(math.exp)


@st.composite
def geometries(draw, max_rows=4, min_count=2, max_count=12):
    """Keyword arguments of a cuff geometry (docs/model.md section 1)."""
    n_rows = draw(st.integers(1, max_rows))
    count = draw(st.integers(min_count, max_count))
    step = draw(st.floats(8.0, 360.0 / count))
    width = draw(st.one_of(st.none(), st.floats(0.3, 1.0).map(lambda f: f * step)))
    start = draw(st.floats(-180.0, 180.0))
    gaps = draw(st.lists(st.floats(0.01, 0.04), min_size=n_rows - 1, max_size=n_rows - 1))
    x0 = draw(st.floats(-0.05, 0.0))
    xs = [x0]
    for gp in gaps:
        xs.append(xs[-1] + gp)
    per_row_radius = draw(st.booleans())
    radius = (draw(st.lists(st.floats(0.025, 0.07), min_size=n_rows, max_size=n_rows))
              if per_row_radius else draw(st.floats(0.025, 0.07)))
    per_row_width = draw(st.booleans())
    row_width = (draw(st.lists(st.floats(0.01, 0.04), min_size=n_rows, max_size=n_rows))
                 if per_row_width else draw(st.floats(0.01, 0.04)))
    labels = [chr(ord("A") + i) for i in range(n_rows)]
    return dict(rows=dict(zip(labels, xs)), radius=radius, row_width=row_width, start=start,
                step=step, count=count, width=width)


@st.composite
def physics_cases(draw, max_rows=4, max_count=12, allow_inf=True):
    """A geometry, per-element stiffness maps and the model options."""
    geo = draw(geometries(max_rows=max_rows, max_count=max_count))
    n = len(geo["rows"]) * geo["count"]
    kt = draw(st.lists(_log_uniform(2e3, 1e5), min_size=n, max_size=n))   # element basis
    kc_fin = _log_uniform(1e4, 1e7)
    kc_el = st.one_of(kc_fin, st.just(math.inf)) if allow_inf else kc_fin
    kc = draw(st.lists(kc_el, min_size=n, max_size=n))
    arm = draw(st.sampled_from(["compliant", "rigid"]))
    if arm == "rigid" and any(math.isinf(v) for v in kc):
        kc = [1e6 if math.isinf(v) else v for v in kc]
    strap = draw(st.sampled_from(["hoop", "handles"]))
    tension = draw(st.floats(0.0, 30.0).map(lambda v: 0.0 if v < 1e-6 else v))
    eta = draw(st.one_of(st.none(), st.floats(0.05, 1.0)))
    nu = draw(st.floats(0.0, 0.499))
    handle_angles = None
    if strap == "handles" and draw(st.booleans()):
        a = draw(st.floats(-180, 180))
        handle_angles = (a, a + draw(st.floats(30, 330)))
    return dict(geo=geo, kt=np.array(kt), kc=np.array(kc), arm=arm, strap=strap,
                tension=tension, eta=eta, nu=nu, handle_angles=handle_angles)


@st.composite
def wrenches(draw, max_force=500.0, max_lever=0.12):
    """A wrench (6,) with |F| <= max_force [N] and moments of matching size [N*m]."""
    unit = draw(st.lists(st.floats(-1, 1), min_size=6, max_size=6))
    mag = draw(st.one_of(st.floats(0.0, max_force), st.just(max_force),
                         st.floats(0.0, 20.0)))
    lever = draw(st.floats(0.0, max_lever))
    w = np.array(unit, dtype=float)
    nf = np.linalg.norm(w[:3])
    nm = np.linalg.norm(w[3:])
    # (directions from vectors too short to normalise accurately count as zero)
    F = w[:3] / nf * mag if nf > 1e-3 else np.zeros(3)
    M = w[3:] / nm * mag * lever if nm > 1e-3 else np.zeros(3)
    # magnitudes in the subnormal range carry no relative precision: treat as zero
    F[np.abs(F) < 1e-200] = 0.0
    M[np.abs(M) < 1e-200] = 0.0
    return np.concatenate([F, M])


# --------------------------------------------------------------------------- building models
def build_both(case):
    """(package SpringModel, reference RefModel) of one physics case (same inputs)."""
    from phri_spring.physics.cuff.geometry import cuff_geometry
    from phri_spring.physics.springs.model import build_model

    g = case["geo"]
    pg = cuff_geometry(list(g["rows"].values()), g["radius"], g["row_width"], g["start"],
                       g["step"], g["count"], g["width"], row_labels=list(g["rows"]))
    pm = build_model(pg, case["kt"], case["kc"], arm=case["arm"], shear_ratio=case["eta"],
                     poisson_ratio=case["nu"], strap_tension=case["tension"],
                     strap_model=case["strap"], handle_angles_deg=case["handle_angles"])
    rg = ref.make_geometry(g["rows"], g["radius"], g["row_width"], g["start"], g["step"],
                           g["count"], g["width"])
    rmod = ref.build(rg, case["kt"], case["kc"], arm=case["arm"], shear_ratio=case["eta"],
                     poisson_ratio=case["nu"], tension=case["tension"],
                     strap_model=case["strap"], handle_angles=case["handle_angles"])
    return pm, rmod


def reference_of(case):
    g = case["geo"]
    rg = ref.make_geometry(g["rows"], g["radius"], g["row_width"], g["start"], g["step"],
                           g["count"], g["width"])
    return ref.build(rg, case["kt"], case["kc"], arm=case["arm"], shear_ratio=case["eta"],
                     poisson_ratio=case["nu"], tension=case["tension"],
                     strap_model=case["strap"], handle_angles=case["handle_angles"])


def one_line(text: str) -> bool:
    """True when ``text`` is exactly one non-empty line (a trailing newline allowed)."""
    return bool(text.strip()) and "\n" not in text.strip("\n")


def run_phri(*args):
    """``phri ARGS...`` in this process with click's CliRunner (arguments turned to text)."""
    from click.testing import CliRunner

    from phri_cli.main import phri

    return CliRunner().invoke(phri, [str(a) for a in args])


def stderr_of(result) -> str:
    """What a CliRunner result wrote on stderr."""
    try:
        return result.stderr
    except ValueError:  # click < 8.2 mixes the streams unless asked
        return result.output


def assert_one_line_error(result, *needles, code=1):
    """A CliRunner result failed with ``code`` and one stderr line holding every needle."""
    assert result.exit_code == code, result.output
    err = stderr_of(result).strip()
    assert err.count("\n") == 0, err
    assert "Traceback" not in err
    for n in needles:
        assert n in err, err


def example_log_lines(n=None) -> list:
    """The data lines of ``examples/wrench_log.csv`` (no comment, no header), the first n."""
    log = REPO / "examples" / "wrench_log.csv"
    lines = [ln for ln in log.read_text().splitlines() if ln and not ln.startswith("#")]
    return lines[1:] if n is None else lines[1:n + 1]


def wait_for(cond, timeout=30.0, poll=0.05) -> bool:
    """Poll ``cond()`` until it is true (True) or ``timeout`` seconds pass (False)."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if cond():
            return True
        time.sleep(poll)
    return False
