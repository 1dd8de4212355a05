"""``phri live --dashboard`` (docs/live.md): the page, its event stream, a real browser.

The reference for every force is ``phri simulate`` on the same rows written as
a log. The event stream is read with urllib on a thread; the browser test runs
Debian's ``chromium`` headless against a replay and reads the heat map's values
from the DOM (each cell carries its value in ``data-value``). Waits are bounded
polls of a condition, never a fixed duration.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import socket
import subprocess
import sys
import threading
import time
import urllib.error
import urllib.request
from importlib import resources
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from click.testing import CliRunner

from support.helpers import HARMONY_CONFIG, REPO, one_line, wait_for
from support.helpers import example_log_lines as log_lines
from phri_cli.main import phri
from phri_spring.io.live.dashboard import LiveDashboard, page_text, parse_address

LOG = REPO / "examples" / "wrench_log.csv"
LABELS = [f"{r}{j}" for r in "ABC" for j in range(7)]
ROWS = 200
#: where the browser test keeps its screenshot besides its temporary folder: set
#: PHRI_SCREENSHOT_DIR=docs/img to refresh the README's picture (a test never writes into
#: the repository by itself)
SCREENSHOT_DIR = os.environ.get("PHRI_SCREENSHOT_DIR")


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """simulate's forces on the first ROWS rows of the example log, and those rows."""
    folder = tmp_path_factory.mktemp("dash")
    lines = log_lines(ROWS)
    log = folder / "log.csv"
    log.write_text("\n".join(["time,Fx,Fy,Fz,Mx,My,Mz", *lines]) + "\n")
    out = folder / "sim.parquet"
    res = CliRunner().invoke(phri, ["simulate", str(HARMONY_CONFIG), str(log), "-o", str(out)])
    assert res.exit_code == 0, res.output
    return pd.read_parquet(out), lines


class _Live:
    """``phri live --source - --dashboard 0`` as a subprocess; its URL from its first line."""

    def __init__(self, *args):
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "phri_cli.main", "live", str(HARMONY_CONFIG), "--source", "-",
             "--dashboard", "0", *map(str, args)],
            stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
        first = self.proc.stderr.readline().decode()
        m = re.search(r"dashboard on (http://127\.0\.0\.1:\d+/)", first)
        assert m, first
        self.url = m.group(1)

    def feed(self, lines):
        self.proc.stdin.write(("\n".join(lines) + "\n").encode())
        self.proc.stdin.flush()

    def state(self) -> dict:
        with urllib.request.urlopen(self.url + "snapshot.json", timeout=5) as r:
            return json.load(r)

    def finish(self):
        self.proc.stdin.close()
        self.proc.wait(timeout=60)
        return self.proc.returncode, self.proc.stderr.read().decode()

    def kill(self):
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait()


def _read_events(url: str, events: list, connected: threading.Event):
    """Collect the SSE events (name, data) of ``url`` until the 'end' event."""
    with urllib.request.urlopen(url, timeout=60) as r:
        name, data = "message", []
        for raw in r:
            line = raw.decode().rstrip("\n")
            if not line:
                if data:
                    events.append((name, json.loads("\n".join(data))))
                    if name == "meta":
                        connected.set()
                    if name == "end":
                        return
                name, data = "message", []
            elif line.startswith("event:"):
                name = line[6:].strip()
            elif line.startswith("data:"):
                data.append(line[5:].strip())


def assert_forces_of_the_model(snapshot_forces, sample: int, ref: pd.DataFrame):
    assert 1 <= sample <= len(ref)
    np.testing.assert_allclose(np.asarray(snapshot_forces, dtype=float),
                               ref[LABELS].to_numpy()[sample - 1], rtol=0, atol=1e-9)


# --------------------------------------------------------------------------- the event stream
def test_events_carry_the_forces_of_simulate(reference):
    ref, lines = reference
    live = _Live("--max-samples", ROWS)
    try:
        events, connected = [], threading.Event()
        reader = threading.Thread(target=_read_events, args=(live.url + "events", events,
                                                             connected), daemon=True)
        reader.start()
        assert connected.wait(30)
        live.feed(lines)
        code, err = live.finish()
        reader.join(30)
    finally:
        live.kill()
    assert code == 0, err
    assert "sample count reached" in err
    names = [n for n, _ in events]
    assert names[0] == "meta" and names[-1] == "end"
    meta = events[0][1]
    assert meta["labels"] == LABELS and meta["row_labels"] == ["A", "B", "C"]
    assert meta["n_angles"] == 7
    samples = [d for n, d in events if n == "message"]
    # throttled: the latest sample at most every 40 ms, never a queue of every sample
    assert 1 <= len(samples) <= ROWS
    assert [s["sample"] for s in samples] == sorted({s["sample"] for s in samples})
    assert samples[-1]["sample"] == ROWS           # the last one is sent when the run ends
    for s in samples:
        assert_forces_of_the_model(s["forces"], s["sample"], ref)
        assert s["time"] == float(lines[s["sample"] - 1].split(",")[0])
        assert s["wrench"] == [float(x) for x in lines[s["sample"] - 1].split(",")[1:]]
        row = ref.iloc[s["sample"] - 1]
        assert s["ratio"] == pytest.approx(row["peak_pressure_to_pain_threshold"], abs=1e-12)
        assert s["peak_element"] == row["peak_pressure_element"]
        assert s["health"]["samples"] == s["sample"] and s["health"]["lost"] == 0
        assert s["alarm"] is False


# --------------------------------------------------------------------------- the page
def test_the_page_comes_from_the_installed_package_and_loads_nothing_from_elsewhere():
    path = resources.files("phri_spring.io.live").joinpath("dashboard.html")
    html = path.read_text(encoding="utf-8")
    assert html == page_text()
    with LiveDashboard("127.0.0.1", 0) as dash:
        dash.set_layout(LABELS, "ABC", 7, alarm=0.8, title="t")
        dash.start()
        with urllib.request.urlopen(dash.url, timeout=10) as r:
            assert r.headers["Content-Type"].startswith("text/html")
            served = r.read().decode()
        with urllib.request.urlopen(dash.url + "snapshot.json", timeout=10) as r:
            state = json.load(r)
        with urllib.request.urlopen(dash.url + "favicon.ico", timeout=10) as r:
            assert r.status == 204
        with pytest.raises(urllib.error.HTTPError) as exc:
            urllib.request.urlopen(dash.url + "app.js", timeout=10)
        assert exc.value.code == 404
    assert state == {"meta": {"labels": LABELS, "row_labels": ["A", "B", "C"], "n_angles": 7,
                              "alarm": 0.8, "title": "t", "tolerance": None,
                              "dose_alarm": None}, "snapshot": None, "clients": 0}
    for text in (html, served):
        assert "http://" not in text and "https://" not in text
        # no script, style, image or frame from a URL, no CSS import: everything is inline
        assert not re.search(r"<(script|link|img|iframe)[^>]*(src|href)=", text)
        assert "url(" not in text and "@import" not in text
    assert '"labels": ["A0"' in served                       # the layout is written in


@pytest.mark.parametrize("spec, host, port", [("8080", "127.0.0.1", 8080),
                                              ("0.0.0.0:0", "0.0.0.0", 0),
                                              ("[::1]:9000", "::1", 9000)])
def test_address(spec, host, port):
    assert parse_address(spec) == (host, port)


def test_a_port_in_use_is_one_line_and_leaves_nothing(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        port = busy.getsockname()[1]
        res = CliRunner().invoke(phri, ["live", str(HARMONY_CONFIG), "--source", "-", "-o",
                                        "out.csv", "--dashboard", str(port)],
                                 input=LOG.read_bytes())
    assert res.exit_code == 2, res.output
    assert one_line(res.stderr) and f"port {port}" in res.stderr and "in use" in res.stderr
    assert list(tmp_path.iterdir()) == []
    res = CliRunner().invoke(phri, ["live", str(HARMONY_CONFIG), "--source", "-",
                                    "--dashboard", "host:port"], input=b"")
    assert res.exit_code == 2 and one_line(res.stderr) and "--dashboard" in res.stderr


# --------------------------------------------------------------------------- a real browser
CHROMIUM = shutil.which("chromium")


@pytest.mark.skipif(CHROMIUM is None,
                    reason="Debian's chromium is not installed (apt-get install -y chromium)")
def test_a_browser_shows_the_heat_map_of_the_model(reference, tmp_path):
    ref, lines = reference
    # standard input open: the run goes on until it is closed (no stall while pages load)
    live = _Live("--alarm", 0.05, "--stall-timeout", 60)
    shot = tmp_path / "live_dashboard.png"
    common = [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars",
              "--no-first-run", "--window-size=1280,860", "--virtual-time-budget=20000",
              f"--user-data-dir={tmp_path / 'profile'}"]
    browsers = []
    try:
        # both pages load before the samples come: they follow the run through its events
        browsers.append(subprocess.Popen([*common, "--dump-dom", live.url],
                                         stdout=subprocess.PIPE, stderr=subprocess.DEVNULL))
        browsers.append(subprocess.Popen([*common[:-1], f"--user-data-dir={tmp_path / 'p2'}",
                                          f"--screenshot={shot}", live.url],
                                         stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        assert wait_for(lambda: live.state()["clients"] == 2, 60, poll=0.02), \
            "the pages did not connect"
        for i in range(0, ROWS, 10):           # about a second of the log, paced
            live.feed(lines[i:i + 10])
            time.sleep(0.03)
        assert wait_for(lambda: (live.state()["snapshot"] or {}).get("sample") == ROWS,
                        poll=0.02)
        code, err = live.finish()              # the end event lets the pages settle
        dom = browsers[0].communicate(timeout=60)[0].decode()
        browsers[1].wait(timeout=60)
    finally:
        live.kill()
        for b in browsers:
            if b.poll() is None:
                b.kill()
                b.wait()
    assert code == 0, err
    table = re.search(r'<table id="values" data-sample="(\d+)"[^>]*>(.*?)</table>', dom, re.S)
    assert table, dom[:2000]
    sample = int(table.group(1))
    values = dict(re.findall(r'<tr data-label="(\w+)" data-value="([^"]+)"', table.group(2)))
    assert list(values) == LABELS
    assert_forces_of_the_model([float(values[k]) for k in LABELS], sample, ref)
    cells = dict(re.findall(r'<rect class="cell"[^>]*data-label="(\w+)"[^>]*data-value="([^"]+)"',
                            dom))
    assert cells == values                     # the heat map's cells carry the same values
    assert sample == ROWS and "the run has ended" in dom
    assert shot.stat().st_size > 10_000
    if SCREENSHOT_DIR:
        keep = Path(SCREENSHOT_DIR)
        keep.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(shot, keep / shot.name)
