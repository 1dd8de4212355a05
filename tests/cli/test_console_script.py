"""The real console entry point (`phri_cli.main:main`), run as a process.

It leaves through os._exit after flushing, so its exit codes and output are
checked here end to end (CliRunner tests call the click group instead).
"""

from support.helpers import REPO  # noqa: E402
import subprocess
import sys
from pathlib import Path

ROOT = REPO
CONFIG = ROOT / "configs" / "harmony_upper_arm.yaml"
LOG = ROOT / "examples" / "wrench_log.csv"


def run(*args):
    return subprocess.run([sys.executable, "-m", "phri_cli.main", *map(str, args)],
                          capture_output=True, text=True, cwd=ROOT, timeout=120)


def test_success_writes_output_and_summary(tmp_path):
    out = tmp_path / "f.csv"
    res = run("simulate", CONFIG, LOG, "-o", out)
    assert res.returncode == 0, res.stderr
    assert out.stat().st_size > 0
    assert "wrote" in res.stderr and "peak pressure" in res.stderr
    lines = out.read_text().splitlines()
    assert len(lines) == 4601 and lines[0].startswith("time,A0,")


def test_exit_codes_and_one_line_errors(tmp_path):
    res = run("simulate", CONFIG, tmp_path / "missing.csv", "-o", tmp_path / "f.csv")
    assert res.returncode == 1
    assert res.stderr.strip().count("\n") == 0 and "missing.csv" in res.stderr
    res = run("simulate", CONFIG, LOG, "-o", tmp_path / "f.csv", "--baseline", "window:5:1")
    assert res.returncode == 2
    assert res.stderr.strip().count("\n") == 0 and "--baseline" in res.stderr
    assert not (tmp_path / "f.csv").exists()
    res = run("--help")
    assert res.returncode == 0 and "simulate" in res.stdout


def test_memory_tuning_turns_transparent_huge_pages_off():
    import pytest

    status = Path("/proc/self/status")
    if not sys.platform.startswith("linux") or "THP_enabled" not in status.read_text():
        pytest.skip("needs Linux >= 5.0 (THP_enabled in /proc/self/status)")
    code = ("from phri_cli.main import _tune_memory; _tune_memory(); "
            "print(open('/proc/self/status').read().split('THP_enabled:')[1].split()[0])")
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         cwd=ROOT, timeout=60)
    assert res.returncode == 0, res.stderr
    assert res.stdout.strip() == "0"
