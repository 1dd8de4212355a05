"""Outputs the system refuses: a file where a folder should be, a virtual file
system that holds no files (/sys), a full device (/dev/full: ENOSPC) and a file-size limit
(RLIMIT_FSIZE in a real child process: EFBIG) hit in the middle of writing a CSV, a Parquet
file or figures. Each ends in one line naming the path and the reason, exit 1, the existing
output untouched and no temporary file left.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import pytest

from .faultkit import assert_fault, cli, phri, snapshot

SYS = Path("/sys")


def _sys_refuses_files() -> bool:
    try:
        fd = os.open(SYS / ".phri_probe", os.O_CREAT | os.O_WRONLY, 0o644)
    except OSError:
        return True
    os.close(fd)  # pragma: no cover - not a real sysfs
    os.unlink(SYS / ".phri_probe")
    return False


needs_sysfs = pytest.mark.skipif(not (SYS.is_dir() and _sys_refuses_files()),
                                 reason="needs a /sys that refuses new files (Linux sysfs)")
needs_dev_full = pytest.mark.skipif(not Path("/dev/full").exists(), reason="needs /dev/full")


def _existing(folder: Path, name: str, data: bytes = b"old output\n") -> Path:
    path = folder / name
    path.write_bytes(data)
    return path


# --------------------------------------------------------------------------- simulate
@pytest.mark.parametrize("ext", ["csv", "parquet"])
def test_simulate_output_under_a_file(inputs, out, ext):
    blocker = _existing(out, "results")          # a file where a folder should be
    before = snapshot(out)
    run = cli("simulate", inputs["cfg"], inputs["log_csv"], "-o", blocker / f"forces.{ext}")
    assert_fault(run, 1, rf"results/forces\.{ext}", "is a file, not a folder",
                 before=before, folders=[out])


@needs_sysfs
def test_simulate_output_in_a_virtual_file_system(inputs):
    run = cli("simulate", inputs["cfg"], inputs["log_csv"], "-o", SYS / "forces.csv")
    assert_fault(run, 1, r"/sys/forces\.csv", "cannot write", "Permission denied")


@pytest.mark.parametrize("ext", ["csv", "parquet"])
def test_simulate_file_size_limit_mid_write(inputs, out, ext):
    """The forces of the 300-sample log take about 60 kB (CSV) and 70 kB (Parquet)."""
    existing = _existing(out, f"forces.{ext}")
    before = snapshot(existing)
    run = phri("simulate", inputs["cfg"], inputs["log_csv"], "-o", existing, fsize=16 << 10)
    assert_fault(run, 1, rf"forces\.{ext}: cannot write \(File too large\)", before=before,
                 folders=[out])


@needs_dev_full
@pytest.mark.parametrize("ext", ["csv", "parquet"])
def test_simulate_full_device(inputs, out, ext):
    link = out / f"forces.{ext}"
    link.symlink_to("/dev/full")
    run = cli("simulate", inputs["cfg"], inputs["log_csv"], "-o", link)
    assert_fault(run, 1, rf"forces\.{ext}: cannot write \(No space left on device\)",
                 folders=[out])
    assert link.is_symlink() and os.readlink(link) == "/dev/full"


# --------------------------------------------------------------------------- fit-stiffness
def test_fit_stiffness_outputs_under_a_file(inputs, out):
    blocker = _existing(out, "results")
    existing = _existing(out, "fit.csv")
    before = snapshot(out)
    run = cli("fit-stiffness", inputs["indenter"], "-o", blocker / "fit.csv")
    assert_fault(run, 1, r"results/fit\.csv", "is a file, not a folder", before=before,
                 folders=[out])
    run = cli("fit-stiffness", inputs["indenter"], "-o", existing, "--plots", blocker / "figs")
    assert_fault(run, 1, r"results/figs", "is a file, not a folder", before=before,
                 folders=[out])
    run = cli("fit-stiffness", inputs["indenter"], "-o", existing, "--trials-csv",
              blocker / "trials.csv")
    assert_fault(run, 1, r"results/trials\.csv", "is a file, not a folder", before=before,
                 folders=[out])


@needs_sysfs
def test_fit_stiffness_output_in_a_virtual_file_system(inputs, out):
    existing = _existing(out, "fit.csv")
    before = snapshot(out)
    run = cli("fit-stiffness", inputs["indenter"], "-o", SYS / "fit.csv")
    assert_fault(run, 1, r"/sys/fit\.csv", "Permission denied")
    run = cli("fit-stiffness", inputs["indenter"], "-o", existing, "--plots", SYS / "figs")
    assert_fault(run, 1, r"/sys/figs", "Permission denied|not permitted", before=before,
                 folders=[out])


def test_fit_stiffness_file_size_limit_on_the_plots(inputs, out):
    existing = _existing(out, "fit.csv")
    figs = out / "figs"
    figs.mkdir()
    _existing(figs, "stiffness_map.png", b"old png")
    before = snapshot(out)
    run = phri("fit-stiffness", inputs["indenter_small"], "-o", existing, "--plots", figs,
               fsize=16 << 10)
    assert_fault(run, 1, r"figs/\w+\.png: cannot write \(File too large\)", before=before,
                 folders=[out])


@needs_dev_full
def test_fit_stiffness_full_device(inputs, out):
    link = out / "fit.csv"
    link.symlink_to("/dev/full")
    run = cli("fit-stiffness", inputs["indenter"], "-o", link)
    assert_fault(run, 1, r"fit\.csv: cannot write \(No space left on device\)", folders=[out])


# --------------------------------------------------------------------------- compare
def test_compare_output_under_a_file(inputs, out):
    blocker = _existing(out, "results")
    before = snapshot(out)
    run = cli("compare", inputs["cfg"], inputs["manifest"], "-o", blocker / "cmp",
              "--no-figures")
    assert_fault(run, 1, r"results/cmp", "is a file, not a folder", before=before,
                 folders=[out])


@needs_sysfs
def test_compare_output_in_a_virtual_file_system(inputs):
    run = cli("compare", inputs["cfg"], inputs["manifest"], "-o", SYS / "cmp", "--no-figures")
    assert_fault(run, 1, r"/sys/cmp", "Permission denied|not permitted")


@pytest.mark.parametrize("limit,where", [(8 << 10, r"cmp/loads\.csv"),
                                         (40 << 10, r"cmp(/[\w/]+\.png)?")])
def test_compare_file_size_limit_on_tables_and_figures(inputs, out, limit, where):
    """8 kB stops the loads table (15 kB); 40 kB lets the tables through, stops a figure.

    (A figure's file is named when the figure writer says which; else the folder.)
    """
    outdir = out / "cmp"
    outdir.mkdir()
    _existing(outdir, "rmse.csv")
    (outdir / "heatmaps").mkdir()
    _existing(outdir / "heatmaps", "keep.png", b"a figure of an earlier run")
    before = snapshot(outdir)
    run = phri("compare", inputs["cfg"], inputs["manifest_one"], "-o", outdir, fsize=limit)
    assert_fault(run, 1, rf"{where}: cannot write \(File too large\)", before=before,
                 folders=[out])


def test_compare_new_output_folder_is_not_created_on_failure(inputs, out):
    outdir = out / "new"
    run = phri("compare", inputs["cfg"], inputs["manifest_one"], "-o", outdir, "--no-figures",
               fsize=8 << 10)
    assert_fault(run, 1, r"new/loads\.csv: cannot write", folders=[out])
    assert not outdir.exists()
    shutil.rmtree(out)
