"""``phri live`` (docs/live.md): sources, the per-sample loop, outputs, faults.

The reference for every force is ``phri simulate`` run on the same samples
written as a log (its vectorised solver, not the single-sample one live uses);
the Net F/T stream comes from an emulator written from the RDT protocol's
description (``tests/support/netft_emulator.py``); alarm crossings are counted from
simulate's ratio column. Nothing here asserts a duration: waits are bounded
polls of a condition.
"""

from __future__ import annotations

import io
import signal
import subprocess
import sys
import time
import uuid
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml
from click.testing import CliRunner

from support.helpers import HARMONY_CONFIG, REPO, harmony_dict, one_line, wait_for
from support.helpers import example_log_lines as log_lines
from support.netft_emulator import NetFtEmulator
from phri_cli.main import phri

LOG = REPO / "examples" / "wrench_log.csv"
LABELS = [f"{r}{j}" for r in "ABC" for j in range(7)]
WRENCH = ["Fx", "Fy", "Fz", "Mx", "My", "Mz"]
SAME_COLUMNS = ["contacts_in_touch", "peak_pressure_element", "converged"]


# --------------------------------------------------------------------------- helpers
def run(*args, stdin: bytes = b""):
    return CliRunner().invoke(phri, [str(a) for a in args], input=stdin)


def simulate(tmp_path: Path, log: Path, config=HARMONY_CONFIG, *args) -> pd.DataFrame:
    out = tmp_path / f"sim-{uuid.uuid4().hex[:6]}.parquet"
    res = run("simulate", config, log, "-o", out, *args)
    assert res.exit_code == 0, res.output
    return pd.read_parquet(out)


def read(path: Path) -> pd.DataFrame:
    return pd.read_parquet(path) if path.suffix == ".parquet" else pd.read_csv(path)


def write_log(path: Path, lines, header="time,Fx,Fy,Fz,Mx,My,Mz") -> Path:
    path.write_text("\n".join([header, *lines]) + "\n")
    return path


def assert_same_forces(live: pd.DataFrame, ref: pd.DataFrame, tol=1e-9, time=True):
    assert list(live.columns) == list(ref.columns)
    assert len(live) == len(ref)
    np.testing.assert_allclose(live[LABELS].to_numpy(), ref[LABELS].to_numpy(), rtol=0, atol=tol)
    np.testing.assert_allclose(live["peak_pressure_to_pain_threshold"],
                               ref["peak_pressure_to_pain_threshold"], rtol=0, atol=tol)
    for col in SAME_COLUMNS:
        assert (live[col].astype(str).to_numpy() == ref[col].astype(str).to_numpy()).all(), col
    if time:
        np.testing.assert_array_equal(live["time"].to_numpy(), ref["time"].to_numpy())


def leftovers(folder: Path) -> list:
    return sorted(p.name for p in folder.iterdir() if p.name.startswith("."))


# --------------------------------------------------------------------------- replay = simulate
@pytest.mark.parametrize("arm, baseline, rows", [("compliant", "none", None),
                                                 ("rigid", "first:5", None),
                                                 ("compliant", "window:10:12", 1600),
                                                 ("coupled", "zero", 900)])
def test_replay_through_stdin_gives_the_forces_of_simulate(tmp_path, arm, baseline, rows):
    lines = log_lines(rows)
    log = write_log(tmp_path / "log.csv", lines)
    ref = simulate(tmp_path, log, HARMONY_CONFIG, "--arm", arm, "--baseline", baseline)
    out = tmp_path / "live.parquet"
    # the example log as it is on disk: a comment line, then the header
    text = LOG.read_bytes() if rows is None else log.read_bytes()
    res = run("live", HARMONY_CONFIG, "--source", "-", "--arm", arm, "--baseline", baseline,
              "-o", out, stdin=text)
    assert res.exit_code == 0, res.output
    assert f"{len(lines):,} samples from -" in res.stderr
    assert_same_forces(read(out), ref)
    assert leftovers(tmp_path) == []


def test_config_units_and_column_names_apply_as_in_simulate(tmp_path):
    cfg = harmony_dict()
    cfg["load_cell"].update(force_unit="lbf", moment_unit="N*mm",
                            euler_xyz_deg=[10, -20, 30], convention="cuff_on_robot",
                            columns={"time": "t (s)", "Fx": "Fx (lbf)", "Mz": "Mz (N*mm)"})
    config = tmp_path / "cfg.yaml"
    config.write_text(yaml.safe_dump(cfg))
    rng = np.random.default_rng(3)
    w = rng.normal(0, [3, 3, 5, 200, 200, 200], size=(300, 6))
    df = pd.DataFrame(np.column_stack([np.arange(300) * 0.01, w]),
                      columns=["t (s)", "Fx (lbf)", "Fy", "Fz", "Mx", "My", "Mz (N*mm)"])
    df.insert(2, "other", 7.0)              # a column live does not need
    log = tmp_path / "log.csv"
    df.to_csv(log, index=False, float_format="%.17g")
    ref = simulate(tmp_path, log, config)
    out = tmp_path / "live.parquet"
    res = run("live", config, "--source", "-", "-o", out, stdin=log.read_bytes())
    assert res.exit_code == 0, res.output
    assert_same_forces(read(out), ref)


def test_csv_output_has_the_columns_and_digits_of_simulate(tmp_path):
    log = write_log(tmp_path / "log.csv", log_lines(500))
    sim = tmp_path / "sim.csv"
    assert run("simulate", HARMONY_CONFIG, log, "-o", sim).exit_code == 0
    out = tmp_path / "live.csv"
    # no header this time: the seven numbers in order
    res = run("live", HARMONY_CONFIG, "--source", "-", "-o", out,
              stdin=("\n".join(log_lines(500)) + "\n").encode())
    assert res.exit_code == 0, res.output
    assert out.read_text().splitlines()[0] == sim.read_text().splitlines()[0]
    assert_same_forces(read(out), read(sim), tol=1.5e-6)


def test_malformed_lines_are_counted_reported_and_skipped(tmp_path):
    lines = log_lines(400)
    ref = simulate(tmp_path, write_log(tmp_path / "log.csv", lines))
    bad = list(lines)
    bad.insert(10, "1.0,2.0,oops,4,5,6,7")
    bad.insert(50, "1,2,3")
    bad.insert(90, "# a comment is not malformed")
    bad.insert(91, "")
    bad.insert(200, "3.0,1,2,3,4,5,nan")
    out = tmp_path / "live.parquet"
    res = run("live", HARMONY_CONFIG, "--source", "-", "-o", out,
              stdin=("time,Fx,Fy,Fz,Mx,My,Mz\n" + "\n".join(bad) + "\n").encode())
    assert res.exit_code == 0, res.output
    assert "malformed 3," in res.stderr
    assert res.stderr.count("skipped") == 3
    assert "line 12: expected numbers" in res.stderr      # header is line 1
    assert_same_forces(read(out), ref)


# --------------------------------------------------------------------------- alarm, observers
def crossings(ratio: np.ndarray, thr: float, clear=None, hold=0.0, times=None):
    """(raises, clears, times of the raises, times of the clears) of an alarm raised at
    ``thr``, cleared below ``clear`` (default ``thr``) after ``hold`` seconds raised."""
    clear = thr if clear is None else clear
    times = np.arange(len(ratio)) if times is None else times
    on, since, ups, downs = False, 0.0, [], []
    for t, r in zip(times, ratio):
        if not on and r >= thr:
            on, since = True, t
            ups.append(t)
        elif on and r < clear and t - since >= hold:
            on = False
            downs.append(t)
    return len(ups), len(downs), ups, downs


def test_alarm_lines_follow_the_peak_ratio_of_simulate(tmp_path):
    ref = simulate(tmp_path, LOG)
    ratio = ref["peak_pressure_to_pain_threshold"].to_numpy()
    thr = float(np.quantile(ratio, 0.8))
    ups, downs, _, _ = crossings(ratio, thr)
    assert ups >= 2
    # clear level = raise level, no hold: no hysteresis, every crossing
    res = run("live", HARMONY_CONFIG, "--source", "-", "--alarm", f"{thr!r}",
              "--alarm-clear", f"{thr!r}", "--alarm-hold", "0", stdin=LOG.read_bytes())
    assert res.exit_code == 0, res.output
    assert res.stderr.count("ALARM: peak pressure ratio") == ups
    assert res.stderr.count("alarm cleared") == downs
    assert f"alarms {ups};" in res.stderr
    first = np.flatnonzero(ratio >= thr)[0]
    assert f"at t = {ref['time'][first]:.3f} s" in res.stderr


def test_observers_get_every_sample(tmp_path):
    from phri_spring.io.config import load_config
    from phri_spring.io.live.sources import StdinCsvSource
    from phri_spring.workflows.live import LiveRun

    lines = log_lines(300)
    ref = simulate(tmp_path, write_log(tmp_path / "log.csv", lines))
    thr = float(np.median(ref["peak_pressure_to_pain_threshold"]))
    source = StdinCsvSource(io.BytesIO(("\n".join(lines) + "\n").encode()))
    live = LiveRun(load_config(HARMONY_CONFIG), source, alarm=thr, alarm_clear=thr, alarm_hold=0)
    snaps = []
    live.subscribe(snaps.append)
    summary = live.run(catch_signals=False)
    assert summary.samples == len(snaps) == 300
    assert summary.output is None
    np.testing.assert_allclose([s.forces for s in snaps], ref[LABELS].to_numpy(), atol=1e-9,
                               rtol=0)
    alarm = np.array([s.alarm for s in snaps])
    np.testing.assert_array_equal(alarm, ref["peak_pressure_to_pain_threshold"] >= thr)
    assert snaps[-1].health.samples == 300 and snaps[-1].health.malformed == 0
    assert snaps[0].labels == tuple(LABELS)


def _hovering_log(tmp_path, seed=32):
    """A log at 1 kHz: a push whose peak ratio dithers around one level for 1 s (load-cell
    noise), then released for 1 s; with simulate's ratio of every sample."""
    rng = np.random.default_rng(seed)
    t = np.arange(2000) / 1000.0
    w = np.zeros((len(t), 6))
    w[:1000, 1] = -40.0 + rng.normal(0.0, 0.4, 1000)       # Fy [N], 1 % noise
    lines = [",".join(f"{v:.6g}" for v in (ti, *wi)) for ti, wi in zip(t, w)]
    log = write_log(tmp_path / "hover.csv", lines)
    return log, t, simulate(tmp_path, log)["peak_pressure_to_pain_threshold"].to_numpy()


def test_a_ratio_hovering_at_the_threshold_raises_the_alarm_once(tmp_path):
    log, t, ratio = _hovering_log(tmp_path)
    thr = float(np.median(ratio[:1000]))
    chatter, _, _, _ = crossings(ratio, thr, times=t)
    assert chatter > 20                       # without hysteresis it would chatter
    # the defaults: clear at 0.9 of the raise level, raised at least 0.5 s
    ups, downs, t_up, t_down = crossings(ratio, thr, clear=0.9 * thr, hold=0.5, times=t)
    assert (ups, downs) == (1, 1) and t_down[0] >= 1.0    # cleared by the release only
    res = run("live", HARMONY_CONFIG, "--source", "-", "--alarm", f"{thr!r}",
              stdin=log.read_bytes())
    assert res.exit_code == 0, res.output
    assert res.stderr.count("ALARM: peak pressure ratio") == 1
    assert res.stderr.count("alarm cleared") == 1
    assert f"ALARM: peak pressure ratio {ratio[t == t_up[0]][0]:.3f}" in res.stderr
    assert f"< {0.9 * thr:g} at t = {t_down[0]:.3f} s" in res.stderr
    assert "alarms 1;" in res.stderr


@pytest.mark.parametrize("clear_frac, hold", [(1.0, 0.05), (0.97, 0.0), (0.99, 0.01)])
def test_the_clear_level_and_the_hold_time_are_options(tmp_path, clear_frac, hold):
    log, t, ratio = _hovering_log(tmp_path)
    thr = float(np.median(ratio[:1000]))
    clear = clear_frac * thr
    ups, downs, _, t_down = crossings(ratio, thr, clear=clear, hold=hold, times=t)
    res = run("live", HARMONY_CONFIG, "--source", "-", "--alarm", f"{thr!r}",
              "--alarm-clear", f"{clear!r}", "--alarm-hold", hold, stdin=log.read_bytes())
    assert res.exit_code == 0, res.output
    assert res.stderr.count("ALARM: peak pressure ratio") == ups
    assert res.stderr.count("alarm cleared") == downs
    assert f"at t = {t_down[-1]:.3f} s" in res.stderr


# --------------------------------------------------------------------------- Net F/T
def emulated(tmp_path, n, cpf=1e6, cpt=1e6):
    """Counts of the first n samples of the example log, and their wrenches as a log."""
    w = np.array([[float(x) for x in ln.split(",")[1:]] for ln in log_lines(n)])
    counts = np.column_stack([np.round(w[:, :3] * cpf), np.round(w[:, 3:] * cpt)])
    return counts.astype(np.int64)


def counts_log(tmp_path, counts, keep, cpf=1e6, cpt=1e6) -> Path:
    c = counts[keep].astype(float)
    w = np.column_stack([c[:, :3] / cpf, c[:, 3:] / cpt])
    df = pd.DataFrame(np.column_stack([np.arange(len(w)) * 0.001, w]),
                      columns=["time", *WRENCH])
    path = tmp_path / "netft_log.csv"
    df.to_csv(path, index=False, float_format="%.17g")
    return path


def test_netft_stream_gives_the_model_forces_and_counts_lost_packets(tmp_path):
    cpf, cpt = 1e6, 2.5e5
    counts = emulated(tmp_path, 600, cpf, cpt)
    drop, garbage = {5, 6, 7, 300}, {100, 101}
    with NetFtEmulator(counts, drop=drop, garbage=garbage) as emu:
        out = tmp_path / "nf.parquet"
        res = run("live", HARMONY_CONFIG, "--source", f"netft:127.0.0.1:{emu.port}",
                  "-o", out, "--max-samples", 600 - len(drop), "--counts-per-force", cpf,
                  "--counts-per-torque", cpt)
    assert res.exit_code == 0, res.output
    assert "lost 4," in res.stderr and "malformed 2," in res.stderr
    assert emu.requests[0] == (2, 0)          # start real-time streaming, infinite
    assert emu.requests[-1] == (0, 0)         # and stop at the end
    keep = [i for i in range(600) if i not in drop]
    ref = simulate(tmp_path, counts_log(tmp_path, counts, keep, cpf, cpt))
    live = read(out)
    assert np.all(np.diff(live["time"]) >= 0)
    assert_same_forces(live, ref, time=False)


def test_netft_box_that_goes_away_is_asked_again_and_the_gap_recorded(tmp_path):
    counts = emulated(tmp_path, 300)
    with NetFtEmulator(counts, reboot_after=120) as emu:
        out = tmp_path / "nf.parquet"
        res = run("live", HARMONY_CONFIG, "--source", f"netft:127.0.0.1:{emu.port}", "-o", out,
                  "--max-samples", 300, "--stall-timeout", 0.2)
    assert res.exit_code == 0, res.output
    assert "no data for" in res.stderr and "gap 1 recorded" in res.stderr
    assert "gaps 1" in res.stderr and "lost 0," in res.stderr
    assert [r for r in emu.requests if r[0] == 2][:2] == [(2, 0), (2, 0)]
    ref = simulate(tmp_path, counts_log(tmp_path, counts, list(range(300))))
    assert_same_forces(read(out), ref, time=False)


def test_rdt_sequence_gaps_wrap_and_restarts():
    from phri_spring.io.live.netft import SequenceTracker, pack_command, unpack_record

    assert pack_command(2) == bytes.fromhex("1234000200000000")
    assert pack_command(0) == bytes.fromhex("1234000000000000")
    assert unpack_record(b"\0" * 35) is None
    seq = SequenceTracker()
    assert [seq.update(s) for s in (0xFFFFFFFE, 0xFFFFFFFF, 2, 2, 1, 5)] == [0, 0, 2, -1, -1, 2]
    assert seq.lost == 4
    assert seq.update(1, after_gap=True) == 0 and seq.restarts == 1  # after a silence: restarted
    assert seq.update(3) == 1
    assert seq.update(500) == 496 and seq.update(2) == 0 and seq.restarts == 2  # far behind
    assert seq.lost == 4 + 1 + 496


# --------------------------------------------------------------------------- faults and usage
@pytest.mark.parametrize("args, code, text", [
    (["--source", "serial:/dev/ttyUSB0"], 2, "unknown source"),
    (["--source", "netft:127.0.0.1:99999"], 2, "UDP port"),
    (["--source", "-", "--dashboard", "80800"], 2, "--dashboard"),
    (["--source", "-", "--alarm", "0"], 2, "--alarm"),
    (["--source", "-", "--alarm", "0.8", "--alarm-clear", "0.9"], 2, "--alarm-clear"),
    (["--source", "-", "--alarm-clear", "0.7"], 2, "--alarm-clear"),
    (["--source", "-", "--alarm", "0.8", "--alarm-hold", "-1"], 2, "--alarm-hold"),
    (["--source", "-", "-o", "out.txt2"], 2, "--out"),
])
def test_bad_usage_is_one_line(tmp_path, monkeypatch, args, code, text):
    monkeypatch.chdir(tmp_path)
    res = run("live", HARMONY_CONFIG, *args, stdin=b"0,0,0,0,0,0,0\n")
    assert res.exit_code == code, res.output
    assert one_line(res.stderr) and text in res.stderr
    assert list(tmp_path.iterdir()) == []


def test_failure_before_the_first_sample_leaves_the_output_as_it_was(tmp_path):
    out = tmp_path / "live.csv"
    out.write_text("old\n")
    res = run("live", HARMONY_CONFIG, "--source", "-", "-o", out,
              stdin=b"time,Fx,Fy,Fx2,Mx,My,Mz\n0,1,2,3,4,5,6\n")
    assert res.exit_code == 1, res.output
    assert one_line(res.stderr) and "missing column 'Fz'" in res.stderr
    assert out.read_text() == "old\n"
    assert leftovers(tmp_path) == []


def test_without_pylsl_lsl_options_name_the_extra(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "pylsl", None)        # import pylsl -> ImportError
    out = tmp_path / "live.csv"
    for args in (["--source", "lsl:Force"], ["--source", "-", "--lsl-out", "cuff", "-o", out]):
        res = run("live", HARMONY_CONFIG, *args, stdin=LOG.read_bytes())
        assert res.exit_code == 2, res.output
        assert one_line(res.stderr) and "'live' extra" in res.stderr
    assert list(tmp_path.iterdir()) == []


# --------------------------------------------------------------------------- signals, duration
def _phri(*args, **kw):
    return subprocess.Popen([sys.executable, "-m", "phri_cli.main", *map(str, args)],
                            stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, **kw)


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_a_signal_ends_the_run_with_a_complete_output(tmp_path, sig):
    lines = log_lines(1500)
    out = tmp_path / "live.csv"
    proc = _phri("live", HARMONY_CONFIG, "--source", "-", "-o", out, "--decimals", -1)
    try:
        proc.stdin.write(("\n".join(lines) + "\n").encode())
        proc.stdin.flush()
        # the rows stream into a hidden file beside the output while the run goes on
        grown = wait_for(lambda: any(p.stat().st_size > 200_000 for p in tmp_path.iterdir()
                                      if p.name.startswith(".live.csv.")))
        assert grown
        proc.send_signal(sig)
        _, err = proc.communicate(timeout=30)      # standard input still open: no EOF
    finally:
        proc.kill()
    assert proc.returncode == 128 + sig, err
    err = err.decode()
    assert f"interrupted ({signal.Signals(sig).name}); wrote {out}" in err
    assert leftovers(tmp_path) == []
    live = read(out)
    assert 0 < len(live) <= 1500
    ref = simulate(tmp_path, write_log(tmp_path / "log.csv", lines[:len(live)]))
    assert_same_forces(live, ref)


def test_duration_ends_the_run_cleanly(tmp_path):
    lines = log_lines(200)
    out = tmp_path / "live.parquet"
    proc = _phri("live", HARMONY_CONFIG, "--source", "-", "-o", out, "--duration", 1.5)
    try:
        proc.stdin.write(("\n".join(lines) + "\n").encode())
        proc.stdin.flush()
        proc.wait(timeout=60)                     # standard input stays open: no EOF
        err = proc.stderr.read().decode()
    finally:
        proc.kill()
    assert proc.returncode == 0, err
    assert "duration reached" in err
    ref = simulate(tmp_path, write_log(tmp_path / "log.csv", lines))
    assert_same_forces(read(out), ref)


# --------------------------------------------------------------------------- LSL
def _pylsl():
    try:
        import pylsl as mod
        mod.local_clock()
    except Exception as exc:  # noqa: BLE001 - no pylsl or no liblsl: the live extra is absent
        pytest.skip(f"pylsl unavailable: {exc}")
    from phri_spring.io.live.sources import quiet_lsl

    quiet_lsl(mod)
    return mod


def _outlet(lsl, name, channels=6, labels=WRENCH, rate=1000.0):
    info = lsl.StreamInfo(name, "Force", channels, rate, "double64", name)
    chans = info.desc().append_child("channels")
    for lab in labels[:channels]:
        chans.append_child("channel").append_child_value("label", lab)
    return lsl.StreamOutlet(info)


def test_lsl_round_trip_gives_the_model_forces_with_the_input_times(tmp_path):
    lsl = _pylsl()
    tag = uuid.uuid4().hex[:8]
    n = 400
    lines = log_lines(n)
    w = np.array([[float(x) for x in ln.split(",")[1:]] for ln in lines])
    # channels in another order than Fx..Mz: the labels say which is which
    order = [3, 0, 4, 1, 5, 2]
    outlet = _outlet(lsl, f"in-{tag}", labels=[WRENCH[i] for i in order])
    out = tmp_path / "live.parquet"
    proc = _phri("live", HARMONY_CONFIG, "--source", f"lsl:in-{tag}", "--lsl-out", f"out-{tag}",
                 "-o", out, "--max-samples", n)
    try:
        found = lsl.resolve_byprop("name", f"out-{tag}", timeout=30)
        assert found, proc.stderr.read1().decode() if proc.poll() is not None else "no outlet"
        inlet = lsl.StreamInlet(found[0])
        inlet.open_stream(timeout=10)
        assert wait_for(outlet.have_consumers)
        t0 = lsl.local_clock()
        stamps = t0 + np.arange(n) * 1e-3
        for i in range(n):
            outlet.push_sample(w[i, order].tolist(), stamps[i])
        got, times = [], []
        end = time.monotonic() + 30
        while len(got) < n and time.monotonic() < end:
            chunk, ts = inlet.pull_chunk(timeout=0.5)
            got += chunk
            times += ts
        _, err = proc.communicate(timeout=30)
    finally:
        proc.kill()
    assert proc.returncode == 0, err
    info = inlet.info()
    assert info.channel_count() == 23
    ref = simulate(tmp_path, write_log(tmp_path / "log.csv", lines))
    got = np.array(got)
    assert got.shape == (n, 23)
    np.testing.assert_allclose(got[:, :21], ref[LABELS].to_numpy(), atol=1e-9, rtol=0)
    np.testing.assert_allclose(got[:, 21], ref["peak_pressure_to_pain_threshold"], atol=1e-9)
    np.testing.assert_array_equal(got[:, 22], ref["contacts_in_touch"])
    np.testing.assert_allclose(times, stamps, atol=1e-3, rtol=0)   # same clock, one machine
    assert_same_forces(read(out), ref, time=False)


def test_lsl_stream_with_the_wrong_channel_count_is_one_line(tmp_path):
    lsl = _pylsl()
    tag = uuid.uuid4().hex[:8]
    outlet = _outlet(lsl, f"five-{tag}", channels=5)      # alive while the run looks for it
    res = run("live", HARMONY_CONFIG, "--source", f"lsl:five-{tag}", "-o", tmp_path / "x.csv")
    assert res.exit_code == 1, res.output
    assert one_line(res.stderr) and "has 5 channels; expected 6" in res.stderr
    assert list(tmp_path.iterdir()) == []
    del outlet
