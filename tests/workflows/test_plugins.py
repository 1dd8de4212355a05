"""Plug-ins carry their meaning: an arm and a tissue law defined here run everywhere.

The arm ("what if the cuff were twice as stiff") declares its own label, colour, memory
terms and uncertainty routes, and runs through simulate, stiffness, design, compare, live
(stdin) and the memory budget without a line changed elsewhere. Its forces and stiffness
are checked against the compliant arm of a config whose cuff springs were doubled by hand
(an independent route to the same model), its memory terms against the sums worked by
hand. The tissue law (F = s k0 d, solved on the nonlinear path) runs through simulate, checked
against the linear law of a config whose tissue stiffness was scaled by hand, and joins
the composition matrix.
"""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pandas as pd
import pytest
import yaml
from click.testing import CliRunner

from phri_cli.main import phri
from phri_spring.errors import ConfigError
from phri_spring.io.config import load_config
from phri_spring.io.memory import budget as mb
from phri_spring.io.memory.machine import ENV_LIMIT
from phri_spring.physics.laws import TISSUE_LAWS, LawParameter, TissueLaw, register_law
from phri_spring.plugins import ARM_MODELS
from phri_spring.reports.figure_base import ARM_COLORS, ARM_NAMES
from phri_spring.workflows import common
from phri_spring.workflows.common import (ArmMemory, ArmUncertainty, model_from_config,
                                          register_arm)

from support.helpers import HARMONY_CONFIG, REPO, run_phri, stderr_of

ARM = "doubled_cuff_plugin"
LABEL = "Doubled-cuff arm"
COLOUR = "#123456"
#: the plug-in's declared memory: a cache of 4 KiB per element and model, 16 B per value
CACHE_PER_ELEMENT = 4096
PER_VALUE = 16
LAW = "scaled_plugin"


def doubled_cuff(cfg, cache_dir=None):
    """The compliant arm with every cuff spring twice as stiff."""
    return model_from_config(dataclasses.replace(cfg, cuff_stiffness=cfg.cuff_stiffness * 2),
                             "compliant")


def cache_terms(n_elements, n_models):
    return {"plug-in cache": n_models * n_elements * CACHE_PER_ELEMENT}


class ScaledLaw(TissueLaw):
    """F = s k0 d: the linear law scaled by ``tissue.scale``, solved on the nonlinear path
    (not ``is_linear``). The shear springs stay eta k_e of the config's stiffness."""

    name = LAW
    parameters = (LawParameter("scale", "-", "factor on the normal stiffness", default=1.0,
                               minimum=0.1, maximum=10.0),)

    def force(self, d):
        return self.params["scale"] * self.k0 * np.maximum(d, 0.0)

    def tangent(self, d):
        return np.where(np.asarray(d) >= 0.0, self.params["scale"] * self.k0, 0.0)

    def energy(self, d):
        dp = np.maximum(d, 0.0)
        return 0.5 * self.params["scale"] * self.k0 * dp * dp


@pytest.fixture(scope="module", autouse=True)
def plugins():
    """Register the plug-ins for this module, and take them out after it (the composition
    table of the docs lists the package's own)."""
    register_arm(ARM, "the compliant arm with every cuff spring twice as stiff (test)",
                 label=LABEL, colour=COLOUR,
                 memory=ArmMemory(model_terms=cache_terms, bytes_per_value=PER_VALUE,
                                  advice=" (or --arm compliant)"),
                 uncertainty=ArmUncertainty(stiffening=False,
                                            unused_stiffening="the plug-in is linear"))(
        doubled_cuff)
    register_law(ScaledLaw)
    yield
    ARM_MODELS.pop(ARM, None)
    common.ARMS = tuple(ARM_MODELS)
    TISSUE_LAWS.pop(LAW, None)


@pytest.fixture(scope="module")
def small_log(tmp_path_factory):
    path = tmp_path_factory.mktemp("log") / "log.csv"
    pd.read_csv(REPO / "examples" / "wrench_log.csv", comment="#").iloc[::40].to_csv(
        path, index=False)
    return path


def _edited_config(folder, edit):
    data = yaml.safe_load(HARMONY_CONFIG.read_text())
    edit(data)
    path = folder / "edited.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


def _doubled_config(folder):
    cfg = load_config(HARMONY_CONFIG)
    per_angle = (cfg.cuff_stiffness[:cfg.angle_count] * 2).tolist()
    return _edited_config(folder, lambda d: d["cuff"].update(stiffness={"per_angle": per_angle}))


def test_the_arm_plugin_runs_through_every_command(tmp_path, small_log):
    ref_cfg = _doubled_config(tmp_path)
    out, ref = tmp_path / "plugin.csv", tmp_path / "ref.csv"
    res = run_phri("simulate", HARMONY_CONFIG, small_log, "-o", out, "-q", "--arm", ARM)
    assert res.exit_code == 0, stderr_of(res)
    assert run_phri("simulate", ref_cfg, small_log, "-o", ref, "-q").exit_code == 0
    forces = pd.read_csv(out)
    pd.testing.assert_frame_equal(forces, pd.read_csv(ref))

    res = run_phri("stiffness", HARMONY_CONFIG, "--arm", ARM, "--json")
    assert res.exit_code == 0, stderr_of(res)
    K = np.array(json.loads(res.output)["K"])
    K_ref = np.array(json.loads(run_phri("stiffness", ref_cfg, "--json").output)["K"])
    np.testing.assert_allclose(K, K_ref, rtol=1e-12, atol=1e-9 * np.abs(K_ref).max())

    # live, from stdin: the forces of simulate
    live = tmp_path / "live.csv"
    res = CliRunner().invoke(phri, ["live", str(HARMONY_CONFIG), "--source", "-", "--arm", ARM,
                                    "-o", str(live)], input=small_log.read_bytes())
    assert res.exit_code == 0, res.output
    got = pd.read_csv(live)
    labels = [c for c in forces.columns if c[0] in "ABC" and c[1:].isdigit()]
    assert len(got) == len(forces) and labels
    np.testing.assert_allclose(got[labels].to_numpy(), forces[labels].to_numpy(), rtol=0,
                               atol=1e-9)

    study = tmp_path / "study.yaml"
    study.write_text(yaml.safe_dump({
        "config": str(HARMONY_CONFIG), "loads": [str(small_log)], "arm": ARM,
        "vary": {"strap.tension": {"values": [10.0, 20.0]}}, "plan": "grid",
        "minimise": ["peak_pressure_to_pain_threshold"]}))
    res = run_phri("design", study, "-o", tmp_path / "design", "-q", "--no-figures")
    assert res.exit_code == 0, stderr_of(res)
    assert len(pd.read_csv(tmp_path / "design" / "designs.csv")) == 2


def test_the_arm_plugin_is_compared_and_drawn_with_its_label_and_colour(tmp_path):
    res = run_phri("compare", HARMONY_CONFIG, REPO / "examples" / "experiment" / "manifest.yaml",
                   "-o", tmp_path / "cmp", "--arms", f"compliant,{ARM}", "--no-figures", "-q")
    assert res.exit_code == 0, stderr_of(res)
    summary = pd.read_csv(tmp_path / "cmp" / "summary.csv")
    assert set(summary["arm"]) == {"compliant", ARM}
    from matplotlib.colors import to_hex

    from phri_spring.reports.compare.figures import rmse_bars_figure

    assert ARM_NAMES[ARM] == LABEL and ARM_COLORS[ARM] == COLOUR and ARM in ARM_NAMES
    fig = rmse_bars_figure(summary, arms=("compliant", ARM))
    ax = fig.axes[0]
    handles, names = ax.get_legend_handles_labels()
    assert names == ["Compliant arm", LABEL]
    assert to_hex(handles[1].patches[0].get_facecolor()) == COLOUR


def test_the_memory_budget_reads_the_plugins_terms(monkeypatch):
    cfg = load_config(HARMONY_CONFIG)
    n, rows = 21, 100
    plain = mb.estimate(cfg, "compliant", rows)
    est = mb.estimate(cfg, ARM, rows)
    assert est.terms["plug-in cache"] == n * 4096
    assert est.terms["chunk"] - plain.terms["chunk"] == rows * n * 16
    draws = mb.estimate(cfg, ARM, draws=5, distinct_draws=True)
    assert draws.terms["plug-in cache"] == 5 * n * 4096
    # a machine with room for the spring network but not for the plug-in's cache
    monkeypatch.setenv(ENV_LIMIT, "64K")
    assert model_from_config(cfg, "compliant") is not None
    with pytest.raises(ConfigError) as err:
        model_from_config(cfg, ARM)
    msg = str(err.value)
    assert "\n" not in msg and "plug-in cache" in msg and "or --arm compliant" in msg
    assert f"the {ARM} arm's matrices" in msg


def test_the_uncertainty_reads_the_plugins_routes():
    from phri_spring.workflows.uncertainty.draws import stiffening_route, tissue_route

    cfg = load_config(HARMONY_CONFIG)
    stiff = dataclasses.replace(cfg, tissue_law_parameters={"stiffening": np.full(21, 150.0)})
    assert tissue_route(cfg, ARM) == "stiffness"          # the default route: like compliant
    assert stiffening_route(stiff, "compliant") and not stiffening_route(stiff, ARM)


def test_the_tissue_law_plugin_runs_through_simulate(tmp_path, small_log):
    # with a rigid cuff (k_e = k_t), scale 2 at shear ratio eta is the linear law at twice the
    # stiffness and eta / 2: normal springs 2 k_t, shear springs eta k_t in both
    def scaled_law(d):
        d["cuff"]["stiffness"] = float("inf")
        d["tissue"].update(law=LAW, scale=2.0)
        d["interface"]["shear_ratio"] = 0.4

    def by_hand(d):
        d["cuff"]["stiffness"] = float("inf")
        d["tissue"]["stiffness"] = 2 * d["tissue"]["stiffness"]
        d["interface"]["shear_ratio"] = 0.2

    scaled = _edited_config(tmp_path, scaled_law)
    assert load_config(scaled).tissue_law == LAW
    (tmp_path / "hand").mkdir()
    ref_cfg = _edited_config(tmp_path / "hand", by_hand)
    out, ref = tmp_path / "law.csv", tmp_path / "ref.csv"
    res = run_phri("simulate", scaled, small_log, "-o", out, "-q")
    assert res.exit_code == 0, stderr_of(res)
    assert run_phri("simulate", ref_cfg, small_log, "-o", ref, "-q").exit_code == 0
    got, want = pd.read_csv(out), pd.read_csv(ref)
    labels = [c for c in want.columns if c[0] in "ABC" and c[1:].isdigit()]
    np.testing.assert_allclose(got[labels].to_numpy(), want[labels].to_numpy(), rtol=1e-6,
                               atol=1e-6)


def test_the_plugins_join_the_composition_matrix():
    from phri_spring.workflows import composition as cm

    combos = cm.combinations()
    assert any(c.tissue_law == LAW for c in combos)
    assert any(c.arm == ARM and c.tissue_law == LAW for c in combos)
    ours = cm.combinations(package_only=True)
    assert not any(c.tissue_law == LAW or c.arm == ARM for c in ours)
