"""Benchmarks and reference models live apart from the package and import without path edits.

- no file under ``benchmarks/`` edits ``sys.path`` (they run as ``python -m benchmarks.NAME``
  from the repository root and share :mod:`benchmarks.common`);
- every ``benchmarks/*.py`` imports (its ``main`` not run), in one fresh process from the
  repository root, as ``python -m`` would;
- the reference FEs of ``references/`` are not in the installed package's list;
- every benchmark command the docs give uses the module form.
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys

import pytest

from support.helpers import REPO

BENCHMARKS = REPO / "benchmarks"
PATH_EDIT = re.compile(r"sys\.path\.(insert|append|extend)|sys\.path\s*(\+=|=)")


def test_no_benchmark_file_edits_sys_path():
    offenders = [f"{p.relative_to(REPO)}:{i}" for p in sorted(BENCHMARKS.rglob("*"))
                 if p.is_file() and p.suffix in (".py", ".md")
                 for i, line in enumerate(p.read_text(encoding="utf-8").splitlines(), 1)
                 if PATH_EDIT.search(line)]
    assert offenders == []


def test_every_benchmark_module_imports():
    names = sorted(p.stem for p in BENCHMARKS.glob("*.py"))
    assert "common" in names and "__init__" in names
    code = (
        "import importlib, json, sys, traceback\n"
        "bad = {}\n"
        f"for name in {names!r}:\n"
        "    mod = 'benchmarks' if name == '__init__' else 'benchmarks.' + name\n"
        "    try:\n"
        "        importlib.import_module(mod)\n"
        "    except BaseException:\n"
        "        bad[name] = traceback.format_exc(limit=1).splitlines()[-1]\n"
        "print(json.dumps(bad))\n")
    # -c puts the working directory first on sys.path, as python -m does; the env var
    # keeps the plotting backend headless
    res = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True,
                         text=True, timeout=300, env={**os.environ, "MPLBACKEND": "Agg"})
    assert res.returncode == 0, res.stderr[-2000:]
    assert json.loads(res.stdout.strip().splitlines()[-1]) == {}


def test_references_are_not_installed():
    tomllib = pytest.importorskip("tomllib")            # Python 3.11+
    setup = tomllib.loads((REPO / "pyproject.toml").read_text(encoding="utf-8"))
    packages = setup["tool"]["setuptools"]["packages"]
    assert not [p for p in packages if p.split(".")[0] in ("references", "benchmarks", "tests")]
    assert (REPO / "references" / "__init__.py").is_file()
    assert not (REPO / "phri_spring" / "physics" / "continuum" / "contact_reference.py").exists()
    assert not (REPO / "phri_spring" / "physics" / "continuum" / "reference.py").exists()


def test_docs_run_benchmarks_as_modules():
    """A command ``python benchmarks/X.py`` would run the script without the repository root
    on ``sys.path`` (``benchmarks.common`` and ``references`` would not import)."""
    docs = [REPO / "README.md", *sorted((REPO / "docs").glob("*.md")),
            *sorted(BENCHMARKS.glob("*.md")), *sorted(BENCHMARKS.glob("*.py"))]
    script = re.compile(r"python3?\s+(?:\S*/)?benchmarks/\w+\.py")
    offenders = [f"{p.relative_to(REPO)}: {m.group(0)}" for p in docs
                 for m in script.finditer(p.read_text(encoding="utf-8"))]
    assert offenders == []
