"""The flat API (``import phri_spring as ps``): lazy, listed, the same objects as the deep
paths, and the README's library example runs as written."""

from __future__ import annotations
from support.helpers import REPO  # noqa: E402

import os
import re
import subprocess
import sys

import numpy as np
import pytest

import phri_spring as ps

ROOT = REPO
FLAT = {
    "load_config": "phri_spring.io.config",
    "simulate": "phri_spring.workflows.simulate",
    "simulate_file": "phri_spring.workflows.simulate",
    "fit_stiffness": "phri_spring.workflows.fit.stiffness",
    "compare": "phri_spring.workflows.compare.run",
    "Solver": "phri_spring.physics.contact.solver",
    "model_from_config": "phri_spring.workflows.common",
    "cuff_wrench": "phri_spring.workflows.common",
    "interface_stiffness": "phri_spring.physics.response.stiffness",
}


@pytest.mark.parametrize("name", sorted(FLAT))
def test_flat_name_is_the_deep_object(name):
    import importlib

    assert getattr(ps, name) is getattr(importlib.import_module(FLAT[name]), name)
    assert name in ps.__all__
    assert name in dir(ps)


def test_unknown_name_is_an_attribute_error():
    with pytest.raises(AttributeError, match="no attribute 'simulat'"):
        ps.simulat  # noqa: B018
    assert not hasattr(ps, "not_a_name")


def test_import_is_lazy():
    # a fresh interpreter: importing the package (or its errors) loads no numpy, no workflow
    code = ("import sys, phri_spring, phri_spring.errors; "
            "print(sorted(m for m in ('numpy', 'pandas', 'matplotlib', 'phri_spring.workflows') "
            "if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout.strip()
    assert out == "[]"


def _readme_library_block() -> str:
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    section = text.split("### As a library", 1)[1].split("\n## ", 1)[0]
    blocks = re.findall(r"```python\n(.*?)```", section, flags=re.S)
    assert len(blocks) == 1
    return blocks[0]


def test_readme_library_example_runs(tmp_path, monkeypatch):
    for name in ("configs", "examples"):
        os.symlink(ROOT / name, tmp_path / name)
    monkeypatch.chdir(tmp_path)
    code = _readme_library_block()
    assert "import phri_spring as ps" in code
    assert "from phri_spring." not in code          # the flat API only
    ns: dict = {}
    exec(compile(code, "README.md", "exec"), ns)  # noqa: S102 - our own README
    assert ns["res"].forces.shape == (1, 21)
    assert ns["summary"].samples == 4600           # data rows of examples/wrench_log.csv
    assert (tmp_path / "forces.csv").is_file()
    f, model = ns["f"], ns["model"]
    assert f.shape == (21,) and np.all(np.isfinite(f)) and np.all(f >= 0)
    # the single-sample solver and the batch path agree (two code paths)
    np.testing.assert_allclose(f, ps.simulate(ns["cfg"], np.array([[0, 0, 20.0, 0, 0, 0]]),
                                              arm="rigid").forces[0], rtol=1e-9, atol=1e-9)
    assert ns["K"].shape == (6, 6)
    np.testing.assert_allclose(ns["K"], ns["K"].T, rtol=1e-9, atol=1e-6)
    assert len(ns["stiffness"].locations) == 21
    assert len(ns["result"].rmse) > 0
    assert model.n == 21
