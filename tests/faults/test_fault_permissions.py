"""Permissions: new outputs honour the umask like any other tool (0644 files and
0755 folders under umask 022), and a replaced output keeps its own mode.
"""

from __future__ import annotations

import os
import stat
from contextlib import contextmanager

import pytest

from .faultkit import cli, phri


@contextmanager
def umask(mask: int):
    old = os.umask(mask)
    try:
        yield
    finally:
        os.umask(old)


def mode(path) -> int:
    return stat.S_IMODE(os.stat(path).st_mode)


@pytest.mark.parametrize("mask,file_mode", [(0o022, 0o644), (0o027, 0o640), (0o002, 0o664)])
def test_simulate_new_output_honours_the_umask(inputs, out, mask, file_mode):
    """In a real process, the umask set in the child (as a shell's `umask` would)."""
    run = phri("simulate", inputs["cfg"], inputs["log_csv"], "-o", out / "f.csv", "-q",
               umask=mask)
    assert run.code == 0, run.stderr
    assert mode(out / "f.csv") == file_mode


@pytest.mark.parametrize("ext", ["csv", "parquet"])
def test_simulate_replaced_output_keeps_its_mode(inputs, out, ext):
    target = out / f"f.{ext}"
    target.write_bytes(b"old")
    os.chmod(target, 0o604)
    with umask(0o077):
        run = cli("simulate", inputs["cfg"], inputs["log_csv"], "-o", target, "-q")
    assert run.code == 0, run.stderr
    assert mode(target) == 0o604 and target.read_bytes() != b"old"


def test_fit_stiffness_outputs_honour_the_umask_and_keep_modes(inputs, out):
    fit, trials, figs = out / "fit.csv", out / "trials.csv", out / "figs"
    trials.write_text("old\n")
    os.chmod(trials, 0o660)
    with umask(0o022):
        run = cli("fit-stiffness", inputs["indenter_small"], "-o", fit, "--plots", figs,
                  "--trials-csv", trials, "-q")
    assert run.code == 0, run.stderr
    assert mode(fit) == 0o644 and mode(trials) == 0o660
    assert mode(figs) == 0o755
    assert {p.name: mode(p) for p in figs.iterdir()} == {
        "force_displacement.png": 0o644, "stiffness_map.png": 0o644}


def test_compare_folders_and_files_honour_the_umask(inputs, out):
    outdir = out / "cmp"
    with umask(0o022):
        run = cli("compare", inputs["cfg"], inputs["manifest_one"], "-o", outdir, "-q",
                  "--dpi", "50")
    assert run.code == 0, run.stderr
    modes = {p.relative_to(outdir).as_posix(): mode(p) for p in [outdir, *outdir.rglob("*")]}
    assert modes["."] == 0o755 and modes["heatmaps"] == 0o755 and modes["wrench"] == 0o755
    files = {k: v for k, v in modes.items() if k.endswith((".csv", ".png", ".md"))}
    assert len(files) > 8 and set(files.values()) == {0o644}, files
    # a second run into the same folder: a file someone made group-writable keeps its mode
    os.chmod(outdir / "rmse.csv", 0o664)
    with umask(0o077):
        run = cli("compare", inputs["cfg"], inputs["manifest_one"], "-o", outdir, "-q",
                  "--no-figures")
    assert run.code == 0, run.stderr
    assert mode(outdir / "rmse.csv") == 0o664 and mode(outdir) == 0o755
