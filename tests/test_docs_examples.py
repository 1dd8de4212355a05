"""The Python examples in the docs run as written (from a folder holding the bundled files)."""

import os
import re
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parent.parent


def _python_blocks(doc: Path):
    return re.findall(r"```python\n(.*?)```", doc.read_text(), flags=re.S)


@pytest.mark.parametrize("doc", ["docs/performance.md"])
def test_python_examples_run(doc, tmp_path, monkeypatch):
    for name in ("configs", "examples"):
        os.symlink(ROOT / name, tmp_path / name)
    monkeypatch.chdir(tmp_path)
    blocks = _python_blocks(ROOT / doc)
    assert len(blocks) >= 2
    namespace = {}
    for code in blocks:
        exec(compile(code, doc, "exec"), namespace)  # noqa: S102 - our own docs
    # what the examples promise
    assert namespace["summary"].samples == 4600     # data rows of examples/wrench_log.csv
    assert (tmp_path / "forces.parquet").is_file()
    f = namespace["f"]
    assert f.shape == (21,) and np.all(np.isfinite(f)) and np.all(f >= 0)
