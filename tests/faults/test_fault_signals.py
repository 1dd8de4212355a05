"""Signals: SIGTERM, SIGHUP (and SIGINT) sent to a real ``phri`` process in the
middle of writing its output: the temporary files are removed, an existing output is left
byte-identical, stderr holds one line and the exit status is 128 + the signal number.

The signal is sent once the process's temporary output exists (it is mid-write), on logs
long enough (two hours, 720,000 samples) that the run is far from its end.
"""

from __future__ import annotations

import time

import pytest

from .faultkit import SIGNALS, assert_fault, signal_run, snapshot, start_phri, temporaries, \
    wait_for


def _interrupt(proc, sig_name: str, folder, settle: float = 0.15):
    wait_for(lambda: temporaries(folder), proc)
    time.sleep(settle)   # well inside the write
    assert proc.poll() is None, "the run ended before the signal; use a longer log"
    return signal_run(proc, SIGNALS[sig_name])


@pytest.mark.parametrize("fmt", ["csv", "parquet"])
@pytest.mark.parametrize("sig_name", ["SIGTERM", "SIGHUP"])
def test_simulate_interrupted_mid_write(inputs, long_logs, out, fmt, sig_name):
    existing = out / f"forces.{fmt}"
    existing.write_bytes(b"the forces of an earlier run\n")
    before = snapshot(existing)
    proc = start_phri("simulate", inputs["cfg"], long_logs[fmt], "-o", existing)
    run = _interrupt(proc, sig_name, out)
    assert_fault(run, 128 + SIGNALS[sig_name], rf"interrupted \({sig_name}\)",
                 before=before, folders=[out])


def test_simulate_ctrl_c_mid_write(inputs, long_logs, out):
    proc = start_phri("simulate", inputs["cfg"], long_logs["csv"], "-o", out / "new.csv")
    run = _interrupt(proc, "SIGINT", out)
    assert_fault(run, 130, r"interrupted \(SIGINT\)", folders=[out])
    assert not (out / "new.csv").exists()


def test_compare_interrupted_while_writing_figures(inputs, out):
    outdir = out / "cmp"
    outdir.mkdir()
    (outdir / "rmse.csv").write_text("an earlier run\n")
    before = snapshot(outdir)
    proc = start_phri("compare", inputs["cfg"], inputs["manifest_one"], "-o", outdir)
    wait_for(lambda: any(p.suffix == ".png" for t in temporaries(out) for p in t.rglob("*")),
             proc)
    run = signal_run(proc, SIGNALS["SIGTERM"])
    assert_fault(run, 143, r"interrupted \(SIGTERM\)", before=before, folders=[out])


def test_fit_stiffness_interrupted_while_writing_plots(inputs, out):
    existing = out / "fit.csv"
    existing.write_text("an earlier fit\n")
    figs = out / "figs"
    before = snapshot(existing, figs)
    proc = start_phri("fit-stiffness", inputs["indenter"], "-o", existing, "--plots", figs)
    run = _interrupt(proc, "SIGHUP", out, settle=0.0)
    assert_fault(run, 129, r"interrupted \(SIGHUP\)", before=before, folders=[out])
    assert not figs.exists()


def test_hangup_ignored_under_nohup(inputs, long_logs, out):
    # a run started with SIGHUP ignored (nohup, a detached job) keeps it ignored: the
    # hang-up of a closed terminal does not stop it, and it writes its output
    import signal
    import subprocess

    from .faultkit import command

    target = out / "forces.csv"
    proc = subprocess.Popen(command("simulate", inputs["cfg"], long_logs["csv"], "-o", target),
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=lambda: signal.signal(signal.SIGHUP, signal.SIG_IGN))
    run = _interrupt(proc, "SIGHUP", out)
    assert run.code == 0, run.stderr
    assert target.is_file() and not temporaries(out)


def test_a_commit_check_stops_every_output(tmp_path, monkeypatch):
    # add_commit_check: what it raises stops the rename (file and folder), and the temporary
    # output is removed as after any failure; the existing output stays as it was
    from phri_spring.io.outputs import atomic

    monkeypatch.setattr(atomic, "_COMMIT_CHECKS", [])
    stop = RuntimeError("stop")
    atomic.add_commit_check(lambda: (_ for _ in ()).throw(stop))
    dest = tmp_path / "f.csv"
    dest.write_text("earlier\n")
    with pytest.raises(RuntimeError):
        with atomic.atomic_file(dest) as tmp:
            tmp.write_text("new\n")
    folder = tmp_path / "d"
    with pytest.raises(RuntimeError):
        with atomic.atomic_directory(folder) as tmp:
            (tmp / "x.txt").write_text("new\n")
    assert dest.read_text() == "earlier\n" and not folder.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["f.csv"]


def test_a_swallowed_interrupt_still_stops_the_run(inputs, out, monkeypatch, capsys):
    # a signal arriving while Python runs a weakref callback (matplotlib's transforms have
    # them): its Interrupted is only "ignored" by Python, yet the run must not replace an
    # output; it ends as interrupted, in one line, status 128 + the signal
    import gc
    import signal as sig
    import sys
    import weakref

    from support.helpers import run_phri, stderr_of
    from phri_cli import _common
    from phri_spring.io.outputs import atomic

    monkeypatch.setattr(_common, "_received", [])
    monkeypatch.setattr(atomic, "_COMMIT_CHECKS", [])
    monkeypatch.setattr(sys, "unraisablehook", sys.unraisablehook)     # restored after
    monkeypatch.setattr(sig, "signal", lambda *a: None)                  # pytest keeps its own
    _common.handle_signals()

    class Node:
        pass

    node = Node()
    ref = weakref.ref(node, lambda _: _common._on_signal(sig.SIGTERM, None))   # noqa: F841
    del node
    gc.collect()                           # the callback runs; Python swallows its exception
    assert "Exception ignored" not in capsys.readouterr().err

    existing = out / "forces.csv"
    existing.write_text("an earlier run\n")
    before = snapshot(existing)
    res = run_phri("simulate", inputs["cfg"], inputs["log_csv"], "-o", existing)
    assert res.exit_code == 128 + sig.SIGTERM
    err = stderr_of(res).strip()
    assert "\n" not in err and "interrupted (SIGTERM)" in err, err
    assert snapshot(existing) == before and not temporaries(out)


@pytest.mark.parametrize("kind", ["file", "directory"])
def test_signal_right_after_the_temporary_is_made_leaves_nothing(tmp_path, monkeypatch, kind):
    """A signal arriving between the temporary path being made and the writer holding its
    name left the path behind with mkstemp/mkdtemp (seen in a loaded test run as a
    fit-stiffness figures folder). The signal is sent once the path exists, before the
    call that made it returns."""
    import os
    import signal
    from pathlib import Path

    from phri_cli._common import Interrupted, _on_signal
    from phri_spring.io.outputs.atomic import atomic_directory, atomic_file

    real = os.mkdir if kind == "directory" else os.open

    def make_then_signal(path, *args, **kwargs):
        made = real(path, *args, **kwargs)     # the path exists; the call has not returned
        if Path(path).name.startswith(".out."):
            os.kill(os.getpid(), signal.SIGTERM)
        return made

    monkeypatch.setattr(os, "mkdir" if kind == "directory" else "open", make_then_signal)
    old = signal.signal(signal.SIGTERM, _on_signal)
    try:
        with pytest.raises(Interrupted):
            writer = atomic_directory if kind == "directory" else atomic_file
            with writer(tmp_path / "out") as tmp:
                time.sleep(0.05)
                raise AssertionError(f"the writer went on with {tmp}")
    finally:
        from phri_cli import _common

        _common._received.clear()      # in-process commands after this one must not see it
        signal.signal(signal.SIGTERM, old)
        for sig in (signal.SIGINT, signal.SIGHUP):
            signal.signal(sig, signal.default_int_handler if sig == signal.SIGINT
                          else signal.SIG_DFL)
    assert list(tmp_path.iterdir()) == []
