"""The package stands alone: its wheel, installed outside the checkout, runs the quick start.

The sdist and the wheel are built (the wheel from the sdist, as ``python -m build`` does),
the wheel is installed into a new virtual environment in a temporary folder, and
``phri init`` + ``phri simulate`` run there, in a folder that is not the checkout: the
presets and the example log must come from the installed package.

Building needs the ``build`` package (in the ``test`` extra) and the package registry (for
the build's own setuptools), so this runs where ``CI`` is set (``.ci/run`` sets it) and is
reported as skipped elsewhere. ``.ci/run`` also installs the wheel with its dependencies
from the registry into a clean environment; here, to stay fast, the new environment finds
the dependencies (numpy, pandas, ...) in this one's site-packages, but phri-spring itself
only in the wheel (this environment's editable install is not loaded there).
"""

from __future__ import annotations
from support.helpers import REPO  # noqa: E402

import os
import subprocess
import sys
import sysconfig
import venv
import zipfile
from pathlib import Path

import pytest

ROOT = REPO

pytestmark = pytest.mark.skipif(
    not os.environ.get("CI"),
    reason="builds and installs the wheel: runs where CI is set (CI=1 pytest ...)")


def run(cmd, cwd, env=None, timeout=600):
    res = subprocess.run([str(c) for c in cmd], cwd=cwd, env=env, capture_output=True,
                         text=True, timeout=timeout)
    assert res.returncode == 0, f"{cmd}: exit {res.returncode}\n{res.stdout}\n{res.stderr}"
    return res


def test_wheel_installed_outside_the_checkout_runs_the_quick_start(tmp_path):
    import build  # noqa: F401  (the test extra has it; missing, this fails: no skip)

    dist = tmp_path / "dist"
    run([sys.executable, "-m", "build", "--outdir", dist, ROOT], cwd=tmp_path)
    wheels, sdists = sorted(dist.glob("*.whl")), sorted(dist.glob("*.tar.gz"))
    assert len(wheels) == 1 and len(sdists) == 1, sorted(dist.iterdir())
    # the reference FEs, the benchmarks and the tests stay in the checkout
    top = {n.split("/")[0] for n in zipfile.ZipFile(wheels[0]).namelist()}
    assert not top & {"references", "benchmarks", "tests"}, sorted(top)

    env_dir = tmp_path / "env"
    venv.create(env_dir, with_pip=False, symlinks=os.name != "nt")
    bindir = env_dir / ("Scripts" if os.name == "nt" else "bin")
    python = bindir / ("python.exe" if os.name == "nt" else "python")
    site = Path(run([python, "-c", "import sysconfig; print(sysconfig.get_path('purelib'))"],
                    cwd=tmp_path).stdout.strip())
    # the dependencies from this environment (a path entry: its .pth files, among them the
    # editable install's finder, are not run)
    (site / "zz_dependencies.pth").write_text(sysconfig.get_path("purelib") + "\n")
    run([sys.executable, "-m", "pip", "--python", python, "install", "--quiet", "--no-deps",
         "--no-index", wheels[0]], cwd=tmp_path)

    clean = {k: v for k, v in os.environ.items()
             if k not in ("PYTHONPATH", "VIRTUAL_ENV", "PYTHONHOME")}
    work = tmp_path / "work"
    work.mkdir()
    where = run([python, "-c", "import phri_spring, phri_cli; from importlib import resources; "
                 "print(phri_spring.__file__); print(phri_cli.__file__); "
                 "print(resources.files('phri_spring.presets'))"], cwd=work, env=clean)
    for line in where.stdout.splitlines():
        assert Path(line).resolve().is_relative_to(site.resolve()), where.stdout
    phri = bindir / "phri"
    run([phri, "init", "cuff.yaml", "--example", "."], cwd=work, env=clean)
    run([phri, "init", "--preset", "human_forearm", "forearm.yaml"], cwd=work, env=clean)
    for config in ("cuff.yaml", "forearm.yaml"):
        out = work / f"forces_{config}.csv"
        run([phri, "simulate", config, "wrench_log.csv", "-o", out], cwd=work, env=clean)
        lines = out.read_text().splitlines()
        assert len(lines) == 4601 and lines[0].startswith("time,A0,"), lines[:2]
