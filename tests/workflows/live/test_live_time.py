"""``phri live`` and time at the interface: a stream's muscle activation, the dose on the
dashboard (docs/live.md, docs/tolerance.md, docs/model.md section 15).

The reference for every force and dose is ``phri simulate`` on the same rows written as a
log (its vectorised history solver and chunked dose, not the per-sample ones live uses).
"""

from __future__ import annotations

import io
import json
import math

import numpy as np
import pandas as pd
import yaml
from click.testing import CliRunner

from support.helpers import HARMONY_CONFIG, REPO, harmony_dict
from support.helpers import example_log_lines as log_lines
from phri_cli.main import phri
from phri_spring.io.live.dashboard import LiveDashboard, snapshot_json

LABELS = [f"{r}{j}" for r in "ABC" for j in range(7)]
HEADER = "time,Fx,Fy,Fz,Mx,My,Mz"


def run(*args, stdin: bytes = b""):
    return CliRunner().invoke(phri, [str(a) for a in args], input=stdin)


def activation_log(tmp_path, rows=300, name="EMG (norm)"):
    """The example log's first rows with an activation ramp 0 -> 1 in column ``name``."""
    lines = log_lines(rows)
    act = np.linspace(0.0, 1.0, len(lines))
    text = "\n".join([f"{HEADER},{name}",
                      *(f"{ln},{a:.17g}" for ln, a in zip(lines, act))]) + "\n"
    log = tmp_path / "emg.csv"
    log.write_text(text)
    return log


def stiffening_config(tmp_path):
    raw = harmony_dict()
    raw["tissue"]["activation_factor"] = 3.0
    path = tmp_path / "cfg.yaml"
    path.write_text(yaml.safe_dump(raw))
    return path


def replay_matches_simulate(tmp_path, cfg, log, *options) -> pd.DataFrame:
    """``live`` replaying ``log`` on standard input gives the forces ``simulate`` gives for
    it (same options, 1e-9 N); returns the live output."""
    sim = tmp_path / "sim.parquet"
    res = run("simulate", cfg, log, "-o", sim, *options)
    assert res.exit_code == 0, res.output
    out = tmp_path / "live.parquet"
    res = run("live", cfg, "--source", "-", "-o", out, *options, stdin=log.read_bytes())
    assert res.exit_code == 0, res.output
    live, ref = pd.read_parquet(out), pd.read_parquet(sim)
    np.testing.assert_allclose(live[LABELS].to_numpy(), ref[LABELS].to_numpy(), rtol=0,
                               atol=1e-9)
    return live


def test_a_replayed_activation_column_gives_the_forces_of_simulate(tmp_path):
    cfg, log = stiffening_config(tmp_path), activation_log(tmp_path)
    live = replay_matches_simulate(tmp_path, cfg, log, "--column", "activation=EMG (norm)")
    # and the activation was used: without the column the forces of a = 1 differ
    plain = tmp_path / "plain.parquet"
    lines = log.read_text().splitlines()
    no_act = "\n".join(ln.rsplit(",", 1)[0] for ln in lines) + "\n"
    assert run("live", cfg, "--source", "-", "-o", plain, stdin=no_act.encode()).exit_code == 0
    gap = np.abs(pd.read_parquet(plain)[LABELS].to_numpy() - live[LABELS].to_numpy()).max(axis=1)
    assert gap[0] < 1e-9 and gap[-1] > 1e-3


def test_an_activation_named_activation_needs_no_option(tmp_path):
    # the spec name is read as it is, as simulate reads it
    from phri_spring.io.live.sources import StdinCsvSource

    log = activation_log(tmp_path, rows=5, name="activation")
    src = StdinCsvSource(io.BytesIO(log.read_bytes()))
    src.open()
    first = src.read(1.0)
    assert src.has_activation and len(first) == 3 and first[2] == 0.0


def test_an_activation_outside_0_1_is_a_malformed_line(tmp_path):
    cfg, log = stiffening_config(tmp_path), activation_log(tmp_path, rows=50, name="activation")
    lines = log.read_text().splitlines()
    lines[10] = lines[10].rsplit(",", 1)[0] + ",1.5"
    res = run("live", cfg, "--source", "-", stdin=("\n".join(lines) + "\n").encode())
    assert res.exit_code == 0, res.output
    assert "line 11: expected a muscle activation from 0 to 1, got 1.5; skipped" in res.stderr
    assert "49 samples from -" in res.stderr and "malformed 1" in res.stderr


def test_the_band_strap_refuses_a_streamed_activation_in_one_line(tmp_path):
    # as simulate refuses a log's activation column with the band strap
    log = activation_log(tmp_path, rows=5, name="activation")
    res = run("live", REPO / "examples" / "band_strap.yaml", "--source", "-",
              stdin=log.read_bytes())
    assert res.exit_code == 1, res.output
    err = res.stderr.strip()
    assert "\n" not in err and "tissue.activation_factor" in err and "band" in err


# --------------------------------------------------------------------------- the dose shown
def push_case(tmp_path):
    """A tight strap and a push growing over 50 min, a sample a minute: pressures above the
    floor of Linder-Ganz's curve (9 kPa) and of the knee's discomfort (13.7 kPa)."""
    raw = harmony_dict()
    raw["strap"]["tension"] = 30.0
    cfg = tmp_path / "cfg.yaml"
    cfg.write_text(yaml.safe_dump(raw))
    rows = [f"{60.0 * i:g},2,-3,{1.6 * i:g},0.5,-0.2,0.3" for i in range(51)]
    log = tmp_path / "log.csv"
    log.write_text("\n".join([HEADER, *rows]) + "\n")
    return cfg, log


def test_snapshots_carry_the_dose_of_simulate(tmp_path):
    from phri_spring.io.config import load_config
    from phri_spring.io.live.sources import StdinCsvSource
    from phri_spring.workflows.live import LiveRun

    cfg, log = push_case(tmp_path)
    sim = tmp_path / "sim.parquet"
    res = run("simulate", cfg, log, "-o", sim, "--tolerance", "linder_ganz_2006")
    assert res.exit_code == 0, res.output
    ref = pd.read_parquet(sim)
    source = StdinCsvSource(io.BytesIO(log.read_bytes()))
    live = LiveRun(load_config(cfg), source, tolerance="linder_ganz_2006",
                   dose_alarm=1e-9)
    snaps = []
    live.subscribe(snaps.append)
    live.run(catch_signals=False)
    assert len(snaps) == len(ref) and ref["dose_max"].iloc[-1] > 0.1
    events = [snapshot_json(s) for s in snaps]
    np.testing.assert_allclose([e["dose"]["max"] for e in events], ref["dose_max"], rtol=1e-9,
                               atol=1e-15)
    assert [e["dose"]["element"] for e in events][1:] == list(ref["dose_element"])[1:]
    first = int(np.argmax(ref["dose_max"].to_numpy() >= 1e-9))
    assert [e["dose"]["alarm"] for e in events] == [i >= first for i in range(len(ref))]
    assert all(e["activation"] is None for e in events)        # the stream carries none
    json.dumps(events, allow_nan=False)                        # what the page gets is JSON


def test_without_a_curve_the_snapshot_has_no_dose(tmp_path):
    from phri_spring.io.config import load_config
    from phri_spring.io.live.sources import StdinCsvSource
    from phri_spring.workflows.live import LiveRun

    source = StdinCsvSource(io.BytesIO(("\n".join(log_lines(3)) + "\n").encode()))
    live = LiveRun(load_config(HARMONY_CONFIG), source)
    snaps = []
    live.subscribe(snaps.append)
    live.run(catch_signals=False)
    assert [snapshot_json(s)["dose"] for s in snaps] == [None] * 3


def test_an_infinite_dose_is_json_null_and_flagged(tmp_path):
    from phri_spring.io.config import load_config
    from phri_spring.io.live.sources import StdinCsvSource
    from phri_spring.workflows.live import LiveRun

    # a time-independent curve below the cuff's pressures: infinite once a step is above it
    cfg, log = push_case(tmp_path)
    source = StdinCsvSource(io.BytesIO(log.read_bytes()))
    live = LiveRun(load_config(cfg), source, tolerance="cuff_knee_discomfort_2020")
    snaps = []
    live.subscribe(snaps.append)
    live.run(catch_signals=False)
    p = max(s.peak_pressure_kpa for s in snaps[1:])
    assert p > 13.7, p
    last = snapshot_json(snaps[-1])
    assert last["dose"]["max"] is None and last["dose"]["infinite"] is True
    assert math.isinf(snaps[-1].dose_max)


def test_the_dashboard_state_names_the_curve_and_the_dose_alarm():
    dash = LiveDashboard("127.0.0.1", 0)
    try:
        dash.set_layout(LABELS, ["A", "B", "C"], 7, alarm=0.8, tolerance="linder_ganz_2006",
                        dose_alarm=0.5)
        state = dash.initial()
        assert state["meta"]["tolerance"] == "linder_ganz_2006"
        assert state["meta"]["dose_alarm"] == 0.5 and state["snapshot"] is None
        assert 'id="doseval"' in dash.page()
        dash.set_layout(LABELS, ["A", "B", "C"], 7)
        assert dash.initial()["meta"]["tolerance"] is None
    finally:
        dash.close()


def test_the_coupled_arm_streams_its_relaxing_and_contracting_layer_as_simulate(tmp_path):
    """The coupled arm's relaxing layer with an activation column: the stream's forces are
    those of simulate on the same samples (one state carried through both)."""
    raw = harmony_dict()
    raw["tissue"].update(activation_factor=2.0,
                         relaxation={"fractions": [0.3, 0.2], "times_s": [0.05, 0.8]},
                         continuum={"thickness": 0.02, "young_modulus": 3.0e4})
    cfg = tmp_path / "coupled.yaml"
    cfg.write_text(yaml.safe_dump(raw))
    log = activation_log(tmp_path, rows=150, name="activation")
    replay_matches_simulate(tmp_path, cfg, log, "--arm", "coupled")
