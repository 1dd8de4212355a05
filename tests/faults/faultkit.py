"""Helpers of the fault-injection tests: run a real ``phri`` process and check what it left.

Every case checks the same four things (docs/cli.md, "Errors and exit codes"): the exit status, a single
line on stderr (no traceback, no Python warning, never "internal error"), an
existing output byte-identical after a failure, and no temporary file left.
"""

from __future__ import annotations

import codecs
import os
import re
import resource
import signal
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
CONFIG = ROOT / "configs" / "harmony_upper_arm.yaml"
EXPERIMENT = ROOT / "examples" / "experiment"
INDENTER = ROOT / "examples" / "indenter"

#: the encodings a lab's files come in, and how to write text in each
ENCODINGS = ("utf-8", "utf-8-bom", "utf-16-le-bom", "utf-16-be-bom", "latin-1")


def encode(text: str, encoding: str) -> bytes:
    """``text`` as the bytes a file saved in ``encoding`` holds (BOM included where named)."""
    if encoding == "utf-8":
        return text.encode("utf-8")
    if encoding == "utf-8-bom":
        return codecs.BOM_UTF8 + text.encode("utf-8")
    if encoding == "utf-16-le-bom":
        return codecs.BOM_UTF16_LE + text.encode("utf-16-le")
    if encoding == "utf-16-be-bom":
        return codecs.BOM_UTF16_BE + text.encode("utf-16-be")
    if encoding == "utf-16-le-nobom":
        return text.encode("utf-16-le")
    if encoding == "latin-1":
        return text.encode("latin-1")
    raise ValueError(encoding)


def write_encoded(path: Path, text: str, encoding: str) -> Path:
    path = Path(path)
    path.write_bytes(encode(text, encoding))
    return path


@dataclass
class Run:
    code: int
    stdout: str
    stderr: str


def _preexec(umask=None, fsize=None):
    def pre():
        if umask is not None:
            os.umask(umask)
        if fsize is not None:
            resource.setrlimit(resource.RLIMIT_FSIZE, (fsize, fsize))
    return pre


def command(*args) -> list:
    return [sys.executable, "-m", "phri_cli.main", *map(str, args)]


def cli(*args) -> Run:
    """Run ``phri ARGS`` in this process (the click group, as the entry point calls it).

    Much faster than a process; for the cases that need no process of their own
    (signals and resource limits do).
    """
    from click.testing import CliRunner

    from phri_cli.main import phri as group

    res = CliRunner().invoke(group, [str(a) for a in args], prog_name="phri")
    if res.exception is not None and not isinstance(res.exception, SystemExit):
        raise res.exception
    return Run(res.exit_code, res.stdout, res.stderr)


def phri(*args, cwd=None, umask=None, fsize=None, timeout=120) -> Run:
    """Run ``phri ARGS`` as a real process (the console entry point).

    ``fsize`` sets ``RLIMIT_FSIZE`` [bytes] in the child; SIGXFSZ is left at its
    default there (``subprocess`` restores it), so phri itself must keep a
    too-large write from killing it.
    """
    pre = _preexec(umask, fsize) if (umask is not None or fsize is not None) else None
    res = subprocess.run(command(*args), capture_output=True, text=True, cwd=cwd,
                         timeout=timeout, preexec_fn=pre)
    return Run(res.returncode, res.stdout, res.stderr)


def _signals_at_default() -> None:
    # the signal tests send SIGTERM and SIGHUP on purpose: the child starts with both at their
    # defaults even when the test run itself ignores them (pytest under nohup, say, whose
    # SIG_IGN a child inherits and phri rightly keeps)
    for sig in (signal.SIGTERM, signal.SIGHUP):
        signal.signal(sig, signal.SIG_DFL)


def start_phri(*args, cwd=None, keep_signals: bool = False) -> subprocess.Popen:
    """Start ``phri ARGS`` as a real process, SIGTERM and SIGHUP at their defaults in it.

    ``keep_signals`` leaves them as this process has them (inherited, as a shell would).
    """
    return subprocess.Popen(command(*args), stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, cwd=cwd,
                            preexec_fn=None if keep_signals else _signals_at_default)


def wait_for(predicate, proc: subprocess.Popen, timeout: float = 60.0) -> None:
    """Poll until ``predicate()`` holds (the process must still be running)."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if predicate():
            return
        if proc.poll() is not None:
            raise AssertionError(f"phri ended (status {proc.returncode}) before the awaited "
                                 f"moment: {proc.stderr.read()}")
        time.sleep(0.005)
    proc.kill()
    raise AssertionError("timed out waiting for phri")


def signal_run(proc: subprocess.Popen, sig: int, timeout: float = 60.0) -> Run:
    proc.send_signal(sig)
    out, err = proc.communicate(timeout=timeout)
    return Run(proc.returncode, out, err)


_TEMP = re.compile(r"^\..*\.tmp")


def temporaries(*folders) -> list:
    """Hidden temporary files or folders (``.<name>.<random>.tmp...``) under ``folders``."""
    found = []
    for folder in folders:
        folder = Path(folder)
        if folder.is_dir():
            found += [p for p in folder.rglob(".*") if _TEMP.match(p.name)]
    return found


def snapshot(*paths) -> dict:
    """Bytes and mode of every file at or under ``paths`` (missing paths map to None)."""
    snap = {}
    for path in paths:
        path = Path(path)
        if path.is_dir():
            for p in sorted(path.rglob("*")):
                if p.is_file():
                    snap[str(p)] = (p.read_bytes(), p.stat().st_mode)
        elif path.exists():
            snap[str(path)] = (path.read_bytes(), path.stat().st_mode)
        else:
            snap[str(path)] = None
    return snap


def assert_one_line(run: Run, code: int, *patterns: str) -> str:
    """The exit status is ``code`` and stderr is one line matching every pattern."""
    lines = [ln for ln in run.stderr.splitlines() if ln.strip()]
    assert run.code == code, f"exit {run.code}, expected {code}; stderr: {run.stderr}"
    assert len(lines) == 1, f"expected one stderr line, got: {run.stderr!r}"
    line = lines[0]
    assert "internal error" not in line, line
    assert "Traceback" not in run.stderr and "Warning" not in run.stderr, run.stderr
    for pat in patterns:
        assert re.search(pat, line), f"{pat!r} not in {line!r}"
    return line


def assert_fault(run: Run, code: int, *patterns: str, before: dict | None = None,
                 folders=()) -> str:
    """One-line failure, outputs in ``before`` unchanged, no temporary file in ``folders``."""
    line = assert_one_line(run, code, *patterns)
    if before is not None:
        assert snapshot(*before) == before, "an existing output changed"
    left = temporaries(*folders)
    assert not left, f"temporary files left behind: {left}"
    return line


SIGNALS = {"SIGTERM": signal.SIGTERM, "SIGHUP": signal.SIGHUP, "SIGINT": signal.SIGINT}
