"""Every code block of the README and docs/*.md runs as written, or says why it cannot.

What each language tag means, and the ``<!-- not-run: REASON -->`` comment, are in
tests/support/docs_blocks.py. The blocks run in a scratch copy of configs/, examples/ and docs/
(shared by the pages, in page order), each page in a fresh interpreter.
"""

from support.helpers import REPO  # noqa: E402
import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from support import docs_blocks as db

ROOT = REPO
PAGES = db.pages()
ALL = [b for page in PAGES for b in db.blocks(page)]
RUN_PAGES = sorted({b.page for b in ALL if b.runs}, key=[str(p.relative_to(ROOT))
                                                          for p in PAGES].index)


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


def test_every_block_says_what_it_is():
    untagged = [b.where for b in ALL if not b.lang]
    assert untagged == [], f"fenced blocks without a language tag: {untagged}"
    unknown = [f"{b.where} ({b.lang})" for b in ALL
               if b.lang not in db.RUN | db.CHECKED | db.SHOWN and not b.lang.startswith("{")]
    assert unknown == [], f"tags this test does not know: {unknown}"
    misplaced = [b.where for b in ALL if b.not_run and b.lang not in db.RUN]
    assert misplaced == [], f"not-run comments before blocks that never run: {misplaced}"
    dangling = [f"{p.relative_to(ROOT)}:{n}" for p in PAGES for n in db.dangling_markers(p)]
    assert dangling == [], f"not-run comments not right before a block: {dangling}"
    # the count: every block is run, checked, shown or a site directive; none is dropped
    runs = [b for b in ALL if b.runs]
    not_run = [b for b in ALL if b.not_run]
    other = [b for b in ALL if b.lang in db.CHECKED | db.SHOWN or b.lang.startswith("{")]
    assert len(runs) + len(not_run) + len(other) == len(ALL)
    assert len(runs) >= 20 and len(not_run) <= len(runs)


def test_console_steps_parse():
    steps = db.console_steps("$ phri x\nwrote y\n...\n$ ls  # note\n")
    assert steps == [("phri x", ["wrote y", "..."]), ("ls  # note", [])]
    with pytest.raises(ValueError, match="before any"):
        db.console_steps("output\n$ cmd\n")


def test_the_runner_catches_a_wrong_block(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    console = db.Block("x.md", 1, "console", "$ echo 1\n2\n", None)
    assert "did not print" in db.run_block(console, {})
    assert db.run_block(db.Block("x.md", 1, "console", "$ echo 1 2\n1 2\n", None), {}) is None
    assert "exit 3" in db.run_block(db.Block("x.md", 1, "bash", "exit 3\n", None), {})
    assert "NameError" in db.run_block(db.Block("x.md", 1, "python", "nope\n", None), {})


@pytest.mark.parametrize("block", [b for b in ALL if b.lang == "yaml"], ids=lambda b: b.where)
def test_yaml_blocks_parse(block):
    assert isinstance(yaml.safe_load(block.code), dict)


@pytest.mark.parametrize("block", [b for b in ALL if b.not_run], ids=lambda b: b.where)
def test_not_run_blocks_are_reported(block):
    pytest.skip(f"{block.where} not run: {block.not_run}")


@pytest.fixture(scope="module")
def workspace(tmp_path_factory):
    """A scratch copy of what the pages use (they write beside their inputs), shared."""
    work = tmp_path_factory.mktemp("docs_blocks")
    for name in ("configs", "examples", "docs"):
        shutil.copytree(ROOT / name, work / name, ignore=shutil.ignore_patterns("_api"))
    return work


@pytest.mark.parametrize("page", RUN_PAGES)
def test_page_blocks_run(page, workspace):
    env = dict(os.environ, MPLBACKEND="Agg", PYTHONPATH=os.pathsep.join(
        filter(None, [str(ROOT / "tests"), os.environ.get("PYTHONPATH")])))
    # the phri of this interpreter's environment first
    env["PATH"] = os.pathsep.join([str(Path(sys.executable).parent), env.get("PATH", "")])
    res = subprocess.run([sys.executable, str(ROOT / "tests" / "support" / "docs_blocks.py"), page,
                          str(workspace)], capture_output=True, text=True, env=env, timeout=900)
    results = [json.loads(s[len(db.MARK):]) for s in res.stdout.splitlines()
               if s.startswith(db.MARK)]
    expected = [b.where for b in db.blocks(ROOT / page) if b.runs]
    assert res.returncode == 0, res.stderr[-3000:]
    assert [r["where"] for r in results] == expected
    failed = [f"{r['where']}:\n{r['error']}" for r in results if r["error"]]
    assert failed == [], "\n\n".join(failed)
