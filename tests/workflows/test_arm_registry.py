"""Arm models plug in: one registry that every command, its help and the docs read.

A toy arm registered here ("what if the cuff were half as stiff") runs through simulate,
stiffness, compare and a design study; its forces are checked against the compliant arm
of a config whose cuff springs were halved by hand, an independent route to the same
model. The first example of docs/extending.md (adding an arm model) is executed as written.
"""

from __future__ import annotations

import dataclasses
import re

import numpy as np
import pandas as pd
import pytest
import yaml

from phri_spring.io.config import load_config
from phri_spring.physics.contact.solver import solve
from phri_spring.workflows import common
from phri_spring.workflows.common import (ARM_MODELS, cuff_wrench, model_from_config,
                                          register_arm)

from support.helpers import HARMONY_CONFIG, REPO, run_phri, stderr_of


@register_arm("toy_half_cuff", "the compliant arm with every cuff spring half as stiff (test)")
def toy_half_cuff(cfg, cache_dir=None):
    return model_from_config(dataclasses.replace(cfg, cuff_stiffness=cfg.cuff_stiffness / 2),
                             "compliant")


@pytest.fixture(scope="module")
def small_log(tmp_path_factory):
    path = tmp_path_factory.mktemp("log") / "log.csv"
    pd.read_csv(REPO / "examples" / "wrench_log.csv", comment="#").iloc[::25].to_csv(
        path, index=False)
    return path


def _halved_config(tmp_path):
    data = yaml.safe_load(HARMONY_CONFIG.read_text())
    cfg = load_config(HARMONY_CONFIG)
    per_angle = (cfg.cuff_stiffness[:cfg.angle_count] / 2).tolist()
    data["cuff"]["stiffness"] = {"per_angle": per_angle}
    path = tmp_path / "halved.yaml"
    path.write_text(yaml.safe_dump(data))
    assert np.allclose(load_config(path).cuff_stiffness, cfg.cuff_stiffness / 2)
    return path


def test_every_command_lists_the_registered_arms():
    assert set(common.ARMS) == set(ARM_MODELS) >= {"compliant", "rigid", "coupled",
                                                   "toy_half_cuff"}
    for cmd in ("simulate", "stiffness"):
        res = run_phri(cmd, "--help")
        assert res.exit_code == 0
        assert "toy_half_cuff" in res.output and "coupled" in res.output, res.output
    # the docs list every built-in arm
    docs = (REPO / "docs" / "model.md").read_text()
    table = docs[docs.index("### 11.4 Arm models"):docs.index("### 11.5")]
    for name in ARM_MODELS:
        if not name.startswith(("toy_", "half_stiff")):
            assert f"| `{name}` |" in table, name


def test_toy_arm_through_simulate_stiffness_compare_and_design(tmp_path, small_log):
    out = tmp_path / "toy.csv"
    res = run_phri("simulate", HARMONY_CONFIG, small_log, "-o", out, "-q", "--arm",
                   "toy_half_cuff")
    assert res.exit_code == 0, stderr_of(res)
    ref = tmp_path / "ref.csv"
    res = run_phri("simulate", _halved_config(tmp_path), small_log, "-o", ref, "-q")
    assert res.exit_code == 0, stderr_of(res)
    pd.testing.assert_frame_equal(pd.read_csv(out), pd.read_csv(ref))
    # a softer cuff moves more under the same load than the bundled one
    cfg = load_config(HARMONY_CONFIG)
    W = cuff_wrench(cfg, np.array([[0.0, 0.0, 33.4, 0.0, 0.0, 0.0]]))
    assert (np.abs(solve(model_from_config(cfg, "toy_half_cuff"), W).u).max()
            > np.abs(solve(model_from_config(cfg, "compliant"), W).u).max())

    import json

    res = run_phri("stiffness", HARMONY_CONFIG, "--arm", "toy_half_cuff", "--json")
    assert res.exit_code == 0, stderr_of(res)
    K_toy = np.array(json.loads(res.output)["K"])
    K_ref = np.array(json.loads(run_phri("stiffness", _halved_config(tmp_path), "--json")
                                .output)["K"])
    np.testing.assert_allclose(K_toy, K_ref, rtol=1e-12, atol=1e-9 * np.abs(K_ref).max())

    res = run_phri("compare", HARMONY_CONFIG, REPO / "examples" / "experiment" / "manifest.yaml",
                   "-o", tmp_path / "cmp", "--arms", "compliant,toy_half_cuff", "--no-figures",
                   "-q")
    assert res.exit_code == 0, stderr_of(res)
    assert set(pd.read_csv(tmp_path / "cmp" / "rmse.csv")["arm"]) == {"compliant",
                                                                       "toy_half_cuff"}

    study = tmp_path / "study.yaml"
    study.write_text(yaml.safe_dump({
        "config": str(HARMONY_CONFIG), "loads": [str(small_log)], "arm": "toy_half_cuff",
        "vary": {"strap.tension": {"values": [10.0, 20.0]}}, "plan": "grid",
        "minimise": ["peak_pressure_to_pain_threshold"]}))
    res = run_phri("design", study, "-o", tmp_path / "design", "-q", "--no-figures")
    assert res.exit_code == 0, stderr_of(res)
    assert len(pd.read_csv(tmp_path / "design" / "designs.csv")) == 2


def test_unknown_arm_is_one_line(tmp_path, small_log):
    res = run_phri("simulate", HARMONY_CONFIG, small_log, "-o", tmp_path / "f.csv", "--arm",
                   "wooden")
    assert res.exit_code == 2 and "wooden" in stderr_of(res)


def test_the_docs_example_arm_runs(tmp_path, small_log):
    text = (REPO / "docs" / "extending.md").read_text()
    section = text[text.index("## Adding an arm model"):]
    code = re.findall(r"```python\n(.*?)```", section, flags=re.S)[0]
    try:
        exec(compile(code, "docs/extending.md", "exec"), {})  # noqa: S102 - our own docs
        a, b = tmp_path / "a.csv", tmp_path / "b.csv"
        for arm, out in (("half_stiff_cuff", a), ("toy_half_cuff", b)):
            res = run_phri("simulate", HARMONY_CONFIG, small_log, "-o", out, "-q", "--arm", arm)
            assert res.exit_code == 0, stderr_of(res)
        pd.testing.assert_frame_equal(pd.read_csv(a), pd.read_csv(b))
    finally:
        ARM_MODELS.pop("half_stiff_cuff", None)
        common.ARMS = tuple(ARM_MODELS)
