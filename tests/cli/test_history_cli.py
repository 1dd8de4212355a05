"""Relaxation and muscle activation from the command line (docs/model.md section 15).

Bad inputs give exit 1 (data) with one line naming the file and key or column; a log's
activation column at 0 changes nothing; a relaxing tissue's outputs differ from the
elastic ones only after the first sample's rest.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
import yaml
from click.testing import CliRunner

from support.helpers import harmony_dict, one_line
from phri_cli.main import phri


def _run(*args):
    return CliRunner().invoke(phri, [*map(str, args)], catch_exceptions=False)


def _line(result) -> str:
    """The run's error output, asserted to be one line."""
    text = result.stderr if hasattr(result, "stderr") else result.output
    assert one_line(text), text
    return text.strip()


def _write_log(path, W, activation=None, name="activation"):
    """The wrenches W (m, 6) as a 100 Hz CSV log, with an activation column if given."""
    df = pd.DataFrame(W, columns=["Fx", "Fy", "Fz", "Mx", "My", "Mz"])
    df.insert(0, "time", 0.01 * np.arange(len(W)))
    if activation is not None:
        df[name] = activation
    df.to_csv(path, index=False)
    return path


def _step_log(path, m: int, fy: float):
    """A log of m samples: no load, then Fy = ``fy`` [N] held from sample 50."""
    W = np.zeros((m, 6))
    W[50:, 1] = fy
    return _write_log(path, W)


def _log(path, m=120, activation=None, name="activation", seed=0):
    rng = np.random.default_rng(seed)
    W = np.cumsum(rng.normal(size=(m, 6)), axis=0) * [2, 2, 2, 0.05, 0.05, 0.05]
    return _write_log(path, W, activation, name)


def _config(tmp_path, **tissue):
    raw = harmony_dict()
    raw["tissue"].update(tissue)
    path = tmp_path / "cfg.yaml"
    path.write_text(yaml.safe_dump(raw))
    return path


def test_activation_at_zero_changes_nothing(tmp_path):
    cfg = _config(tmp_path)
    plain = _log(tmp_path / "plain.csv")
    zero = _log(tmp_path / "zero.csv", activation=np.zeros(120))
    assert _run("simulate", cfg, plain, "-o", tmp_path / "a.csv").exit_code == 0
    r = _run("simulate", cfg, zero, "-o", tmp_path / "b.csv")
    assert r.exit_code == 0, r.output
    a, b = pd.read_csv(tmp_path / "a.csv"), pd.read_csv(tmp_path / "b.csv")
    labels = [c for c in a.columns if c[0] in "ABC" and c[1:].isdigit()]
    np.testing.assert_allclose(b[labels], a[labels], atol=2e-6)   # 6 decimals written


def test_activation_stiffens_the_tissue_and_is_mapped_by_column(tmp_path):
    cfg = _config(tmp_path, activation_factor=3.0)
    act = np.linspace(0.0, 1.0, 120)
    log = _log(tmp_path / "emg.csv", activation=act, name="EMG (norm)")
    r = _run("simulate", cfg, log, "-o", tmp_path / "out.csv", "--column", "activation=EMG (norm)")
    assert r.exit_code == 0, r.output
    plain = _log(tmp_path / "plain.csv")
    _run("simulate", cfg, plain, "-o", tmp_path / "plain_out.csv")
    a, b = pd.read_csv(tmp_path / "out.csv"), pd.read_csv(tmp_path / "plain_out.csv")
    labels = [c for c in a.columns if c[0] in "ABC" and c[1:].isdigit()]
    d = np.abs(a[labels].to_numpy() - b[labels].to_numpy()).max(axis=1)
    assert d[0] < 2e-6 and d[-1] > 1e-3       # a = 0 at the start, a = 1 at the end


@pytest.mark.parametrize("bad", [1.5, -0.2])
def test_activation_outside_0_1_is_one_line_naming_column_and_row(tmp_path, bad):
    cfg = _config(tmp_path)
    act = np.full(120, 0.5)
    act[37] = bad
    log = _log(tmp_path / "bad.csv", activation=act)
    before = log.read_bytes()
    r = _run("simulate", cfg, log, "-o", tmp_path / "out.csv")
    assert r.exit_code == 1
    line = _line(r)
    assert "activation" in line and "38" in line and "bad.csv" in line
    assert not (tmp_path / "out.csv").exists() and log.read_bytes() == before
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]


@pytest.mark.parametrize("relaxation, needle", [
    ({"fractions": [0.6, 0.5], "times_s": [1.0, 2.0]}, "sum < 1"),
    ({"fractions": [0.2], "times_s": [0.0]}, "times_s"),
    ({"fractions": [0.2, 0.1], "times_s": [1.0]}, "as many"),
    ({"fractions": [-0.2], "times_s": [1.0]}, "fractions: expected finite numbers >= 0"),
])
def test_bad_relaxation_is_one_line_naming_the_key(tmp_path, relaxation, needle):
    cfg = _config(tmp_path, relaxation=relaxation)
    r = _run("simulate", cfg, _log(tmp_path / "l.csv"), "-o", tmp_path / "o.csv")
    assert r.exit_code == 1
    line = _line(r)
    assert "tissue.relaxation" in line and needle in line


def test_the_coupled_arm_relaxes_and_its_hyperelastic_layers_refuse(tmp_path):
    """The linear layer relaxes (docs/model.md section 15.1): held, the load settles on the
    softer relaxed layer, so the forces move after a step where the elastic arm's stay; a
    hyperelastic layer is refused in one line before any identification."""
    _step_log(tmp_path / "step.csv", 300, -20.0)
    layer = {"thickness": 0.02, "young_modulus": 3.0e4}
    out = {}
    for name, extra in (("elastic", {}), ("relax", {"relaxation": {"fractions": [0.4],
                                                                   "times_s": [0.5]}})):
        (tmp_path / name).mkdir()
        cfg = _config(tmp_path / name, continuum=layer, **extra)
        r = _run("simulate", cfg, tmp_path / "step.csv", "-o", tmp_path / f"{name}.csv",
                 "--arm", "coupled")
        assert r.exit_code == 0, r.output
        out[name] = pd.read_csv(tmp_path / f"{name}.csv")
    labels = [c for c in out["elastic"].columns if c[0] in "ABC" and c[1:].isdigit()]
    e, q = out["elastic"][labels].to_numpy(), out["relax"][labels].to_numpy()
    assert np.abs(e[60] - e[-1]).max() < 1e-5          # elastic: the held load stays put
    assert np.abs(q[60] - q[-1]).max() > 1e-3          # relaxing: it keeps moving
    bad = _config(tmp_path, relaxation={"fractions": [0.3], "times_s": [1.0]},
                  continuum={**layer, "law": "neo_hookean"})
    r = _run("simulate", bad, _log(tmp_path / "l.csv"), "-o", tmp_path / "o.csv",
             "--arm", "coupled")
    assert r.exit_code == 1
    assert "tissue.relaxation" in _line(r)


def test_relaxation_shows_after_a_load_step(tmp_path):
    """A step of load held: the elastic forces stay, the relaxing ones move (creep)."""
    _step_log(tmp_path / "step.csv", 400, -30.0)
    elastic = _config(tmp_path)
    r = _run("simulate", elastic, tmp_path / "step.csv", "-o", tmp_path / "e.csv")
    assert r.exit_code == 0
    relax = tmp_path / "relax.yaml"
    raw = yaml.safe_load(elastic.read_text())
    raw["tissue"]["relaxation"] = {"fractions": [0.4], "times_s": [0.5]}
    relax.write_text(yaml.safe_dump(raw))
    r = _run("simulate", relax, tmp_path / "step.csv", "-o", tmp_path / "r.csv")
    assert r.exit_code == 0, r.output
    e, q = pd.read_csv(tmp_path / "e.csv"), pd.read_csv(tmp_path / "r.csv")
    labels = [c for c in e.columns if c[0] in "ABC" and c[1:].isdigit()]
    E, Q = e[labels].to_numpy(), q[labels].to_numpy()
    assert np.abs(np.diff(E[60:], axis=0)).max() < 1e-9     # elastic: constant after the step
    assert np.abs(Q[60] - Q[-1]).max() > 1e-2               # relaxing: still moving
    # the total force along the load balances the same wrench in both (equilibrium)
    assert np.isfinite(Q).all()


@pytest.mark.parametrize("case", ["coupled", "friction", "friction, stiffening"])
def test_activation_along_a_path_is_a_stiffer_tissue(tmp_path, case):
    """A held activation a is the tissue with its stiffness times s = 1 + (c - 1) a: on the
    coupled arm the layer's Young's modulus (a linear layer's every stiffness scales with
    it), on the spring arm with friction the tissue stiffness (the exponential law's k0,
    its rate kept); a = 0 is the arm without the column (docs/model.md section 15.2). The
    handles strap's preload is a wrench, the same for both configs (a hoop's is an offset
    set on the resting tissue, which a config of stiffer tissue would set on that)."""
    E, k, c, a = 3.0e4, 414.0, 2.0, 0.4
    s = 1 + (c - 1) * a
    raw = harmony_dict()
    raw["tissue"]["activation_factor"] = c
    raw["strap"] = {"tension": 15.0, "model": "handles"}
    if case == "coupled":
        raw["tissue"]["continuum"] = {"thickness": 0.02, "young_modulus": E}
        arm = "coupled"
    else:
        raw["tissue"].update(stiffness=k, basis="indenter", indenter_diameter=0.009)
        raw.setdefault("interface", {})["friction_coefficient"] = 0.5
        if case.endswith("stiffening"):
            raw["tissue"].update(law="exponential", stiffening=115.0)
        arm = "compliant"
    act = tmp_path / "act.yaml"
    act.write_text(yaml.safe_dump(raw))
    if case == "coupled":
        raw["tissue"]["continuum"]["young_modulus"] = E * s
    else:
        raw["tissue"]["stiffness"] = k * s
    stiff = tmp_path / "stiff.yaml"
    stiff.write_text(yaml.safe_dump(raw))
    common = ("--arm", arm, "--shear")
    outs = {}
    for name, cfg, column in [("act", act, np.full(200, a)), ("stiff", stiff, None),
                              ("zero", act, np.zeros(200)), ("plain", act, None)]:
        log = _log(tmp_path / f"{name}.csv", m=200, activation=column)
        r = _run("simulate", cfg, log, "-o", tmp_path / f"o_{name}.csv", *common)
        assert r.exit_code == 0, r.output
        outs[name] = pd.read_csv(tmp_path / f"o_{name}.csv")
    labels = [c for c in outs["stiff"].columns if c[0] in "ABC" and c[1:].isdigit()]
    cols = labels + [c for c in outs["stiff"].columns if c.endswith("_N") and c[0] in "ABC"]
    assert len(cols) == 21 * 6                       # normal, 2 shear, 3 resultant
    peak = np.nanmax(np.abs(outs["stiff"][cols].to_numpy()))
    ok = outs["stiff"]["converged"].to_numpy(dtype=bool)
    assert ok.mean() > 0.6         # (the handles strap holds less than the hoop)
    np.testing.assert_array_equal(outs["act"]["converged"].to_numpy(dtype=bool), ok)
    # the two tissues' stiffnesses agree to round-off; the contact path can carry that on,
    # never beyond a tiny share of the peak
    np.testing.assert_allclose(outs["act"][cols][ok], outs["stiff"][cols][ok], rtol=0,
                               atol=1e-4 * peak)
    np.testing.assert_allclose(outs["zero"][cols], outs["plain"][cols], rtol=0, atol=2e-6)
