"""``phri live --dashboard``: a local web page of the pressure map (docs/live.md).

Standard library only: a :class:`http.server.ThreadingHTTPServer` on a daemon
thread serves one self-contained page (``dashboard.html``, package data:
its script and style are inline, nothing comes from elsewhere) and a
server-sent-events stream (``/events``) of the latest sample.

The run's thread only hands each :class:`~phri_spring.workflows.live.LiveSnapshot`
to :meth:`LiveDashboard.observe`, which keeps a reference to it and returns
(no lock, no queue, no JSON). Each client's thread wakes every
:data:`SEND_INTERVAL_S` seconds and sends the latest snapshot if a newer one
came in: at most ~25 events a second per client, whatever the stream's rate,
and a slow client skips samples instead of building a queue.

>>> parse_address("8080"), parse_address("0.0.0.0:8080")
(('127.0.0.1', 8080), ('0.0.0.0', 8080))
"""

from __future__ import annotations

import errno
import json
import math
import socket
import threading
import time
from http import HTTPStatus
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from importlib import resources
from typing import Optional, Sequence

import numpy as np

from ...errors import UsageError

__all__ = ["LiveDashboard", "parse_address", "snapshot_json", "page_text", "SEND_INTERVAL_S"]

#: shortest time between two events sent to a client [s] (25 Hz at most)
SEND_INTERVAL_S = 0.04
#: SSE comment sent to an idle client so that a dead connection is noticed [s]
_KEEPALIVE_S = 10.0
#: longest wait, when the dashboard closes, for clients to get the last sample [s]
_CLOSE_WAIT_S = 2.0
_PAGE = "dashboard.html"
_INIT_MARK = "/*PHRI_INIT*/null"


def parse_address(spec: str) -> tuple:
    """``PORT`` or ``HOST:PORT`` -> (host, port); the host defaults to 127.0.0.1.

    Port 0 asks the system for a free port (the URL is told when the server starts).
    """
    text = str(spec).strip()
    host, sep, port = text.rpartition(":")
    if not sep:
        host = "127.0.0.1"
    host = host.strip("[]") or "127.0.0.1"
    try:
        number = int(port)
    except ValueError:
        number = -1
    if not 0 <= number <= 65535:
        raise UsageError(f"expected [HOST:]PORT with a port 0-65535, got {spec!r}",
                         key="--dashboard")
    return host, number


def _num(x) -> Optional[float]:
    """A float for JSON: NaN and infinities become null (JSON has no NaN)."""
    x = float(x)
    return x if math.isfinite(x) else None


def snapshot_json(snap, *, age_s: float = 0.0) -> dict:
    """A :class:`~phri_spring.workflows.live.LiveSnapshot` as the dict the page gets.

    Forces are the zeroed element forces [N] in the model's label order (row-major,
    A0..A6, B0..); floats keep every digit (``json`` writes their shortest repr).
    ``age_s`` is the time from the sample's processing to this event [s].
    ``dose`` is null without a tolerance curve, else the largest dose over the elements
    so far (``max``, null when infinite, then ``infinite`` is true), its ``element`` and
    whether the dose ``alarm`` was raised; ``activation`` is null when the stream
    carries none.
    """
    h = snap.health
    dose_max = float(getattr(snap, "dose_max", math.nan))
    dose = None if not getattr(snap, "dose_element", "") else {
        "max": _num(dose_max), "infinite": dose_max == math.inf,
        "element": snap.dose_element, "alarm": bool(snap.dose_alarm)}
    return {
        "sample": int(h.samples),
        "time": _num(snap.time),
        "forces": [_num(v) for v in np.asarray(snap.forces, dtype=float)],
        "absolute_forces": [_num(v) for v in np.asarray(snap.absolute_forces, dtype=float)],
        "wrench": [_num(v) for v in np.asarray(snap.wrench, dtype=float)],
        "peak_pressure_kPa": _num(snap.peak_pressure_kpa),
        "peak_element": snap.peak_element,
        "ratio": _num(snap.ratio),
        "contacts_in_touch": int(snap.contacts_in_touch),
        "converged": bool(snap.converged),
        "alarm": bool(snap.alarm),
        "dose": dose,
        "activation": _num(getattr(snap, "activation", math.nan)),
        "health": {"samples": int(h.samples), "lost": int(h.lost),
                   "malformed": int(h.malformed), "gaps": int(h.gaps),
                   "rate_hz": _num(h.rate_hz), "processing_ms": _num(h.processing_s * 1e3),
                   "age_ms": _num(age_s * 1e3)},
    }


def page_text() -> str:
    """The page's HTML, read from the installed package."""
    return resources.files(__package__).joinpath(_PAGE).read_text(encoding="utf-8")


def _script_json(obj) -> str:
    """JSON safe inside a <script> element."""
    return json.dumps(obj, allow_nan=False).replace("</", "<\\/")


class _Server(ThreadingHTTPServer):
    daemon_threads = True
    dashboard: "LiveDashboard"


class _Server6(_Server):
    address_family = socket.AF_INET6


class _Handler(BaseHTTPRequestHandler):
    server: _Server
    protocol_version = "HTTP/1.1"

    def log_message(self, format, *args):      # noqa: A002 - no line per request on stderr
        pass

    def do_GET(self):                           # noqa: N802 - http.server's name
        dash = self.server.dashboard
        path = self.path.split("?", 1)[0]
        if path in ("/", "/index.html"):
            self._send(HTTPStatus.OK, "text/html; charset=utf-8", dash.page().encode())
        elif path == "/snapshot.json":
            self._send(HTTPStatus.OK, "application/json",
                       json.dumps(dash.initial(), allow_nan=False).encode())
        elif path == "/events":
            self._events(dash)
        elif path == "/favicon.ico":
            self._send(HTTPStatus.NO_CONTENT, "image/x-icon", b"")
        else:
            self._send(HTTPStatus.NOT_FOUND, "text/plain; charset=utf-8", b"not found\n")

    def _send(self, status, ctype: str, body: bytes) -> None:
        self.send_response(status)
        self.send_header("Content-Type", ctype)
        self.send_header("Content-Length", str(len(body)))
        self.send_header("Cache-Control", "no-store")
        self.end_headers()
        self.wfile.write(body)

    def _events(self, dash: "LiveDashboard") -> None:
        dash._client_new()
        self.close_connection = True
        sent = None
        last_write = time.monotonic()
        try:
            self.send_response(HTTPStatus.OK)
            self.send_header("Content-Type", "text/event-stream")
            self.send_header("Cache-Control", "no-store")
            self.send_header("Connection", "close")
            self.end_headers()
            self.wfile.write(f"retry: 1000\nevent: meta\ndata: {_script_json(dash.meta)}\n\n"
                             .encode())
            self.wfile.flush()
            while True:
                closing = dash.closed.is_set()
                latest = dash.latest
                if latest is not None and latest[0] is not sent:
                    snap, t_seen = latest
                    data = json.dumps(snapshot_json(snap, age_s=time.monotonic() - t_seen),
                                      allow_nan=False)
                    self.wfile.write(f"data: {data}\n\n".encode())
                    self.wfile.flush()
                    sent, last_write = snap, time.monotonic()
                elif time.monotonic() - last_write > _KEEPALIVE_S:
                    self.wfile.write(b": keep-alive\n\n")
                    self.wfile.flush()
                    last_write = time.monotonic()
                if closing:
                    self.wfile.write(b"event: end\ndata: {}\n\n")
                    self.wfile.flush()
                    return
                dash.closed.wait(SEND_INTERVAL_S)
        except (BrokenPipeError, ConnectionResetError, ConnectionAbortedError, OSError):
            return
        finally:
            dash._client_done()


class LiveDashboard:
    """The dashboard's server: bound at construction, served by :meth:`start`.

    Parameters
    ----------
    host : str
    port : int
        0: a free port (see :attr:`port`).

    Raises
    ------
    UsageError
        The address cannot be bound (a port in use, a host not on this machine).
    """

    def __init__(self, host: str = "127.0.0.1", port: int = 0):
        try:
            server_cls = _Server6 if ":" in host else _Server
            self._server = server_cls((host, int(port)), _Handler, bind_and_activate=True)
        except OSError as exc:
            what = ("is in use" if exc.errno == errno.EADDRINUSE
                    else f"cannot be opened ({exc.strerror or exc})")
            raise UsageError(f"port {port} on {host} {what}", key="--dashboard") from None
        self._server.dashboard = self
        self.host = host
        self.port = int(self._server.server_address[1])
        self.meta: dict = {"labels": [], "row_labels": [], "n_angles": 0, "alarm": None,
                           "title": "phri live", "tolerance": None, "dose_alarm": None}
        #: (snapshot, monotonic time it came in) or None; replaced, never mutated
        self.latest = None
        self.closed = threading.Event()
        self._clients = 0
        self._lock = threading.Lock()
        self._thread: Optional[threading.Thread] = None

    @property
    def url(self) -> str:
        host = "127.0.0.1" if self.host in ("", "0.0.0.0") else self.host
        host = f"[{host}]" if ":" in host else host
        return f"http://{host}:{self.port}/"

    def set_layout(self, labels: Sequence[str], row_labels: Sequence[str], n_angles: int, *,
                   alarm: Optional[float] = None, title: str = "phri live",
                   section: Optional[dict] = None, tolerance: Optional[str] = None,
                   dose_alarm: Optional[float] = None) -> None:
        """The element grid (labels row-major) and what the page's titles say; ``section``:
        the limb's outlines and elements for the page's view of the pressure around the
        limb (:func:`phri_spring.workflows.plots.section.live_section_meta`), None: no view;
        ``tolerance``: the name of the curve the dose is followed against (None: no dose
        shown) and ``dose_alarm`` its alarm level."""
        labels = [str(x) for x in labels]
        rows, n = [str(r) for r in row_labels], int(n_angles)
        if len(rows) * n != len(labels):          # not a rows x angles grid: one row
            rows, n = [""], len(labels)
        self.meta = {"labels": labels, "row_labels": rows, "n_angles": n,
                     "alarm": None if alarm is None else float(alarm), "title": str(title),
                     "tolerance": None if tolerance is None else str(tolerance),
                     "dose_alarm": None if dose_alarm is None else float(dose_alarm)}
        if section is not None:
            self.meta["section"] = section

    def start(self) -> "LiveDashboard":
        """Serve on a daemon thread (the process can end without stopping it)."""
        self._thread = threading.Thread(target=self._server.serve_forever,
                                        kwargs={"poll_interval": 0.1},
                                        name="phri-live-dashboard", daemon=True)
        self._thread.start()
        return self

    def observe(self, snap) -> None:
        """A :meth:`LiveRun.subscribe` observer: keep the latest snapshot, return at once."""
        self.latest = (snap, time.monotonic())

    def initial(self) -> dict:
        """The layout, the latest sample (or None) and the number of event-stream clients."""
        latest = self.latest
        snap = None if latest is None else snapshot_json(latest[0],
                                                         age_s=time.monotonic() - latest[1])
        with self._lock:
            clients = self._clients
        return {"meta": self.meta, "snapshot": snap, "clients": clients}

    def page(self) -> str:
        """The page, with the layout and the latest sample written in (shown before any event)."""
        return page_text().replace(_INIT_MARK, _script_json(self.initial()), 1)

    def _client_done(self) -> None:
        with self._lock:
            self._clients -= 1

    def _client_new(self) -> None:
        with self._lock:
            self._clients += 1

    def close(self) -> None:
        """Send the last sample and an ``end`` event to the clients, then stop serving."""
        if self.closed.is_set():
            return
        self.closed.set()
        end = time.monotonic() + _CLOSE_WAIT_S
        while time.monotonic() < end:
            with self._lock:
                if self._clients <= 0:
                    break
            time.sleep(0.01)
        if self._thread is not None:
            self._server.shutdown()
            self._thread.join(timeout=_CLOSE_WAIT_S)
        self._server.server_close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
        return False

