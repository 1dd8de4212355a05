"""Live wrench sources of ``phri live`` (docs/live.md): standard input, Net F/T, LSL.

Every source has the same small interface (:class:`LiveSource`): :meth:`~LiveSource.open`,
then :meth:`~LiveSource.read` returns one sample ``(time [s], wrench (6,) in the
load cell's units)`` (``(time, wrench, activation)`` from a stream that carries a muscle
activation, :attr:`~LiveSource.has_activation`) or None when none came within the
timeout, until ``ended``; :meth:`~LiveSource.close`. What happens to the stream (a malformed
line or packet skipped, a stall, a reconnection) is counted in ``stats`` and
told in ``events`` (lines for the user, drained by the caller). A source that
goes quiet is waited for: the Net F/T is asked to start again, LSL reconnects
by itself; the silence is recorded as a gap.

:func:`make_source` turns the ``--source`` text into a source: ``-`` (CSV lines
``time,Fx,Fy,Fz,Mx,My,Mz`` on standard input, an optional header line first,
``#`` comment lines skipped; a header may name an ``activation`` column, 0..1, as a
log's), ``netft:HOST[:PORT]`` (ATI Net F/T, RDT over UDP,
:mod:`phri_spring.io.live.netft`) or ``lsl:NAME`` (a Lab Streaming Layer stream
found by name; needs the ``live`` extra, pylsl).
"""

from __future__ import annotations

import collections
import csv
import math
import os
import select
import time
from dataclasses import dataclass, field
from typing import Optional

import numpy as np

from ...errors import DataError, UsageError
from ..logs.columns import ACTIVATION, LOG_COLUMNS, OPTIONAL_LOG_COLUMNS
from ..logs.base import resolve_columns
from .netft import (DEFAULT_COUNTS_PER_FORCE, DEFAULT_COUNTS_PER_TORQUE, RDT_PORT, RdtClient,
                        SequenceTracker, unpack_record)

__all__ = ["LiveSource", "SourceStats", "StdinCsvSource", "NetFtSource", "LslSource",
           "make_source", "import_pylsl", "LIVE_EXTRA_HINT", "quiet_lsl"]

#: how to get pylsl, for the one-line message when it is missing
LIVE_EXTRA_HINT = "pip install 'phri-spring[live]' (or pip install -e '.[live]')"
#: malformed lines or packets told one by one; after that they are only counted
_SHOWN = 5


def import_pylsl(option: str):
    """pylsl, configured to keep liblsl's own log off stderr.

    Raises
    ------
    UsageError
        pylsl (the ``live`` extra) is not installed or its liblsl does not load,
        naming ``option`` and the extra.
    """
    try:
        import pylsl
    except (ImportError, OSError, RuntimeError) as exc:  # liblsl missing: RuntimeError
        why = " ".join(str(exc).split())[:120]
        raise UsageError(f"needs Lab Streaming Layer support, the 'live' extra: {LIVE_EXTRA_HINT}"
                         f" ({why})", key=option) from None
    quiet_lsl(pylsl)
    return pylsl


_LSL_QUIET = []


def quiet_lsl(pylsl) -> None:
    """liblsl logs INFO lines on stderr by default: only its errors, once per process."""
    if not _LSL_QUIET:
        try:
            pylsl.set_config_content("[log]\nlevel = -3\n")
        except Exception:  # noqa: BLE001 - an old liblsl without the call: its log stays
            pass
        _LSL_QUIET.append(True)


@dataclass
class SourceStats:
    """What a source saw: samples delivered, malformed and lost ones, silences."""

    samples: int = 0
    malformed: int = 0
    #: samples the stream's own numbering says never arrived (Net F/T: rdt_sequence gaps)
    lost: int = 0
    #: silences: (time the last sample came [s, monotonic clock], length [s])
    gaps: list = field(default_factory=list)
    reconnects: int = 0


class LiveSource:
    """A live stream of load-cell readings (see the module's description)."""

    #: what the user typed (``-``, ``netft:HOST:PORT``, ``lsl:NAME``)
    name = ""
    #: nominal sample rate [Hz], 0 when unknown or irregular
    nominal_rate = 0.0
    #: True once the stream is known to carry a muscle activation (0..1) with every
    #: sample: :meth:`read` then returns ``(time, wrench, activation)``
    has_activation = False

    def __init__(self, stall_timeout: float = 1.0):
        self.stats = SourceStats()
        self.events: list = []
        self.ended = False
        self.stall_timeout = float(stall_timeout)
        self._last_data = None     # monotonic time of the last sample (or of open)
        self._stalled_since = None

    def open(self) -> None:
        """Connect; raises ``DataError``/``UsageError`` (one line) when it cannot."""
        self._last_data = time.monotonic()

    def read(self, timeout: float):
        """One sample ``(time [s], wrench (6,))`` (and its activation when
        :attr:`has_activation`), or None if none came within ``timeout``."""
        raise NotImplementedError

    def close(self) -> None:
        pass

    def pop_events(self) -> list:
        """The event lines since the last call."""
        out, self.events = self.events, []
        return out

    # shared bookkeeping of the sources
    def _malformed(self, what: str) -> None:
        self.stats.malformed += 1
        if self.stats.malformed <= _SHOWN:
            more = ("; further ones are counted, not shown" if self.stats.malformed == _SHOWN
                    else "")
            self.events.append(f"{self.name}: {what}; skipped{more}")

    def _quiet(self) -> bool:
        """Called when no data came: True once the silence is a stall (told once)."""
        now = time.monotonic()
        if self._stalled_since is None and now - self._last_data >= self.stall_timeout:
            self._stalled_since = self._last_data
            self.events.append(f"{self.name}: no data for {now - self._last_data:.1f} s; "
                               "waiting for the stream to come back")
            return True
        return self._stalled_since is not None

    def _data(self) -> None:
        """Called when a sample came: ends and records a stall."""
        now = time.monotonic()
        if self._stalled_since is not None:
            gap = now - self._stalled_since
            self.stats.gaps.append((self._stalled_since, gap))
            self.stats.reconnects += 1
            self.events.append(f"{self.name}: data again after a gap of {gap:.2f} s "
                               f"(gap {len(self.stats.gaps)} recorded)")
            self._stalled_since = None
        self._last_data = now
        self.stats.samples += 1


# --------------------------------------------------------------------------- standard input
class StdinCsvSource(LiveSource):
    """CSV lines ``time,Fx,Fy,Fz,Mx,My,Mz`` from a binary stream (standard input).

    A header line may come first (any line that is not all numbers, before the
    first data line): its names are mapped like a log's (``load_cell.columns``,
    ``--column``) and may hold other columns too; an ``activation`` column (or the
    one ``--column activation=NAME`` maps) is read with every sample, and a value
    outside 0..1 makes its line malformed. Without one the seven numbers
    come in that order. Lines starting with ``#`` and blank lines are skipped; a
    line that is not seven finite numbers is counted as malformed and skipped.
    The end of the stream ends the source.

    Parameters
    ----------
    stream : binary file object
        Read with ``select`` and ``os.read`` when it has a file descriptor (so a
        quiet pipe never blocks the caller for more than the timeout), else with
        ``read1``/``read``.
    columns : dict, optional
        Spec name -> the header's name.
    """

    name = "-"

    def __init__(self, stream, columns: Optional[dict] = None, stall_timeout: float = 1.0):
        super().__init__(stall_timeout)
        self.stream = stream
        self.columns = dict(columns or {})
        self._fd = None
        self._buf = b""
        self._pending = collections.deque()
        self._line = 0
        self._index = None          # column positions of time, Fx, ..., Mz (after a header)
        self._width = len(LOG_COLUMNS)
        self._eof = False

    def open(self) -> None:
        super().open()
        try:
            self._fd = self.stream.fileno()
            os.fstat(self._fd)
        except (AttributeError, OSError, ValueError):
            self._fd = None

    def _chunk(self, timeout: float) -> Optional[bytes]:
        """Bytes read (b"" at the end of the stream), or None if none came in time."""
        if self._fd is None:
            reader = getattr(self.stream, "read1", None) or self.stream.read
            return reader(65536)
        ready, _, _ = select.select([self._fd], [], [], max(timeout, 0.0))
        if not ready:
            return None
        return os.read(self._fd, 65536)

    def read(self, timeout: float):
        deadline = time.monotonic() + timeout
        while not self._pending and not self._eof:
            data = self._chunk(max(deadline - time.monotonic(), 0.0))
            if data is None:
                self._quiet()
                return None
            if data == b"":
                self._eof = True
                if self._buf:
                    self._parse(self._buf)
                    self._buf = b""
                break
            lines = (self._buf + data).split(b"\n")
            self._buf = lines.pop()
            for raw in lines:
                self._parse(raw)
            if time.monotonic() >= deadline and not self._pending:
                return None
        if self._pending:
            self._data()
            return self._pending.popleft()
        self.ended = True
        return None

    def _parse(self, raw: bytes) -> None:
        self._line += 1
        try:
            text = raw.decode("utf-8")
        except UnicodeDecodeError:
            self._malformed(f"line {self._line}: not UTF-8 text")
            return
        if self._line == 1:
            text = text.lstrip("\ufeff")
        text = text.strip()
        if not text or text.startswith("#"):
            return
        fields = text.split(",")
        if self._index is None and self.stats.samples == 0 and not self._pending:
            try:
                [float(x) for x in fields]
            except ValueError:
                self._header(text)
                return
            if self.columns and any(self.columns.get(c, c) != c
                                    for c in (*LOG_COLUMNS, ACTIVATION) if c in self.columns):
                raise DataError("expected a header line naming the columns "
                                f"({', '.join(self.columns.get(c, c) for c in LOG_COLUMNS)}): "
                                "load_cell.columns or --column map them", file="<stdin>")
            self._index = list(range(len(LOG_COLUMNS)))
        if '"' in text:
            fields = next(csv.reader([text]))
        if len(fields) != self._width:
            self._malformed(f"line {self._line}: expected {self._width} comma-separated "
                            f"values, got {len(fields)}")
            return
        try:
            values = [float(fields[i]) for i in self._index]
        except ValueError:
            self._malformed(f"line {self._line}: expected numbers, got {text[:60]!r}")
            return
        if not all(math.isfinite(v) for v in values):
            self._malformed(f"line {self._line}: expected finite numbers, got {text[:60]!r}")
            return
        wrench = np.array(values[1:7], dtype=float)
        if not self.has_activation:
            self._pending.append((values[0], wrench))
        elif 0.0 <= values[7] <= 1.0:
            self._pending.append((values[0], wrench, values[7]))
        else:
            self._malformed(f"line {self._line}: expected a muscle activation from 0 to 1, "
                            f"got {values[7]:g}")

    def _header(self, text: str) -> None:
        names = [n.strip() for n in next(csv.reader([text]))]
        cols = resolve_columns(names, self.columns, file="<stdin>",
                               wanted=LOG_COLUMNS + OPTIONAL_LOG_COLUMNS)
        self._index = [names.index(c) for c in cols]
        self._width = len(names)
        self.has_activation = len(cols) > len(LOG_COLUMNS)


# --------------------------------------------------------------------------- Net F/T
class NetFtSource(LiveSource):
    """An ATI Net F/T box streaming RDT records over UDP (:mod:`~phri_spring.io.live.netft`).

    The start request is sent on :meth:`open` and again every ``stall_timeout``
    while the box is silent (a box that rebooted or lost its link starts
    again); :meth:`close` sends the stop request. Times are the host's
    monotonic clock at reception [s] (on Linux the clock of LSL's
    ``local_clock``). Readings are counts / counts per force or per torque.
    """

    def __init__(self, host: str, port: int = RDT_PORT, *,
                 counts_per_force: float = DEFAULT_COUNTS_PER_FORCE,
                 counts_per_torque: float = DEFAULT_COUNTS_PER_TORQUE,
                 stall_timeout: float = 1.0):
        super().__init__(stall_timeout)
        self.host, self.port = host, int(port)
        self.name = f"netft:{host}:{self.port}"
        self.cpf, self.cpt = float(counts_per_force), float(counts_per_torque)
        self.client = None
        self.sequence = SequenceTracker()
        self.status_errors = 0
        self._asked = 0.0

    def open(self) -> None:
        import socket

        try:
            self.client = RdtClient(self.host, self.port)
        except socket.gaierror as exc:
            raise UsageError(f"unknown host {self.host!r} ({exc.strerror}); expected "
                             "netft:HOST[:PORT] with the Net F/T's name or address",
                             key="--source") from None
        except OSError as exc:
            raise DataError(f"cannot open a UDP socket to {self.host}:{self.port} "
                            f"({exc.strerror or exc})", key="--source") from None
        super().open()
        self._ask()

    def _ask(self) -> None:
        self._asked = time.monotonic()
        try:
            self.client.start()
        except OSError as exc:   # no route yet: try again later
            self.events.append(f"{self.name}: start request not sent ({exc.strerror or exc})")

    def read(self, timeout: float):
        deadline = time.monotonic() + timeout
        while True:
            packet = self.client.receive(max(deadline - time.monotonic(), 0.0))
            if packet is None:
                if self._quiet() and time.monotonic() - self._asked >= self.stall_timeout:
                    self._ask()
                if time.monotonic() >= deadline:
                    return None
                continue
            t = time.monotonic()
            rec = unpack_record(packet)
            if rec is None:
                self._malformed(f"packet of {len(packet)} bytes; expected a 36-byte RDT record")
            elif rec.status & 0x80000000:
                self.status_errors += 1
                self._malformed(f"record {rec.rdt_sequence}: status 0x{rec.status:08x} (the "
                                "box reports an error; see its status word)")
            else:
                lost = self.sequence.update(rec.rdt_sequence,
                                            after_gap=self._stalled_since is not None)
                if lost >= 0:
                    self.stats.lost += lost
                    self._data()
                    return t, rec.wrench(self.cpf, self.cpt)
            if time.monotonic() >= deadline:
                return None

    def close(self) -> None:
        if self.client is not None:
            self.client.stop()
            self.client.close()
            self.client = None


# --------------------------------------------------------------------------- LSL
class LslSource(LiveSource):
    """A Lab Streaming Layer stream found by name: six channels in the config's units and frame.

    Channel labels (the stream's ``desc/channels/channel/label``) are matched to
    Fx ... Mz like a log's columns (``load_cell.columns``, ``--column``); a stream
    without labels is taken in the order Fx, Fy, Fz, Mx, My, Mz. Times are the
    samples' LSL timestamps mapped to this machine's clock (``proc_clocksync``).
    An inlet recovers a lost stream by itself: the silence is recorded as a gap.
    """

    def __init__(self, stream_name: str, columns: Optional[dict] = None, *,
                 resolve_timeout: float = 5.0, stall_timeout: float = 1.0):
        super().__init__(stall_timeout)
        self.stream_name = stream_name
        self.name = f"lsl:{stream_name}"
        self.columns = dict(columns or {})
        self.resolve_timeout = float(resolve_timeout)
        self.inlet = None
        self._order = None
        self._chunk = collections.deque()

    def open(self) -> None:
        pylsl = import_pylsl("--source")
        found = pylsl.resolve_byprop("name", self.stream_name, timeout=self.resolve_timeout)
        if not found:
            raise DataError(f"no LSL stream named {self.stream_name!r} found within "
                            f"{self.resolve_timeout:g} s; expected a running outlet of that name",
                            key="--source")
        info = found[0]
        if info.channel_count() != 6:
            raise DataError(f"LSL stream {self.stream_name!r} has {info.channel_count()} "
                            "channels; expected 6 (Fx, Fy, Fz, Mx, My, Mz)", key="--source")
        if info.channel_format() in (pylsl.cf_string, pylsl.cf_undefined):
            raise DataError(f"LSL stream {self.stream_name!r} carries text; expected 6 numeric "
                            "channels", key="--source")
        self.nominal_rate = float(info.nominal_srate())
        self.inlet = pylsl.StreamInlet(info, max_buflen=60, recover=True,
                                       processing_flags=pylsl.proc_clocksync)
        self._order = self._channel_order(self.inlet.info(timeout=self.resolve_timeout))
        self.inlet.open_stream(timeout=self.resolve_timeout)
        try:   # the first clock offset takes a few hundred ms: get it before samples flow
            self.inlet.time_correction(timeout=self.resolve_timeout)
        except Exception:  # noqa: BLE001 - pylsl's TimeoutError: the first pull waits instead
            pass
        super().open()

    def _channel_order(self, info) -> list:
        labels = []
        ch = info.desc().child("channels").child("channel")
        while not ch.empty() and len(labels) < 7:
            labels.append(ch.child_value("label"))
            ch = ch.next_sibling()
        if len(labels) != 6 or not all(labels):
            return list(range(6))
        cols = resolve_columns(["time", *labels], self.columns, file=self.name)
        return [labels.index(c) for c in cols[1:]]

    def read(self, timeout: float):
        if not self._chunk:
            samples, stamps = self.inlet.pull_chunk(timeout=0.0, max_samples=4096)
            if not samples:
                sample, stamp = self.inlet.pull_sample(timeout=max(timeout, 0.0))
                if sample is None:
                    self._quiet()
                    return None
                samples, stamps = [sample], [stamp]
            self._chunk.extend(zip(stamps, samples))
        stamp, sample = self._chunk.popleft()
        w = np.asarray(sample, dtype=float)[self._order]
        if not np.isfinite(w).all() or not math.isfinite(stamp):
            self._malformed(f"sample at {stamp:.6f} s: expected 6 finite numbers")
            return None
        self._data()
        return float(stamp), w

    def close(self) -> None:
        if self.inlet is not None:
            try:
                self.inlet.close_stream()
            except Exception:  # noqa: BLE001 - closing a broken inlet: nothing to save
                pass
            self.inlet = None


# --------------------------------------------------------------------------- --source
def make_source(spec: str, *, stdin=None, columns: Optional[dict] = None,
                counts_per_force: float = DEFAULT_COUNTS_PER_FORCE,
                counts_per_torque: float = DEFAULT_COUNTS_PER_TORQUE,
                stall_timeout: float = 1.0, resolve_timeout: float = 5.0) -> LiveSource:
    """The source a ``--source`` text names (not opened yet).

    Parameters
    ----------
    spec : str
        ``-``, ``netft:HOST[:PORT]`` or ``lsl:NAME``.
    stdin : binary file object, optional
        What ``-`` reads (default: the process's standard input).
    columns : dict, optional
        Spec name -> the stream's column or channel name (``-`` and ``lsl:``).
    counts_per_force, counts_per_torque : float
        ``netft:`` only: the box's calibration [counts per unit].
    stall_timeout : float
        Silence [s] after which the stream is said to have stopped (and a Net F/T
        is asked to start again).
    resolve_timeout : float
        ``lsl:`` only: how long to look for the stream [s].

    Raises
    ------
    UsageError
        An unknown kind of source, a bad port, or ``lsl:`` without pylsl.
    """
    spec = str(spec).strip()
    if spec == "-":
        import sys

        stream = stdin if stdin is not None else sys.stdin.buffer
        return StdinCsvSource(stream, columns, stall_timeout=stall_timeout)
    kind, _, rest = spec.partition(":")
    if kind == "netft" and rest:
        host, port = rest, RDT_PORT
        if rest.startswith("["):              # [IPv6]:PORT
            host, _, tail = rest[1:].partition("]")
            if tail.startswith(":"):
                port = _port(tail[1:])
        elif rest.count(":") == 1:
            host, text = rest.split(":")
            port = _port(text)
        if not host:
            raise UsageError(f"expected netft:HOST[:PORT], got {spec!r}", key="--source")
        for value, what in ((counts_per_force, "--counts-per-force"),
                            (counts_per_torque, "--counts-per-torque")):
            if not (math.isfinite(value) and value > 0):
                raise UsageError(f"expected counts > 0, got {value!r}", key=what)
        return NetFtSource(host, port, counts_per_force=counts_per_force,
                           counts_per_torque=counts_per_torque, stall_timeout=stall_timeout)
    if kind == "lsl" and rest:
        import_pylsl("--source")
        return LslSource(rest, columns, resolve_timeout=resolve_timeout,
                         stall_timeout=stall_timeout)
    raise UsageError(f"unknown source {spec!r}; expected - (CSV lines on standard input), "
                     "netft:HOST[:PORT] or lsl:NAME", key="--source")


def _port(text: str) -> int:
    try:
        port = int(text)
    except ValueError:
        port = -1
    if not 0 < port < 65536:
        raise UsageError(f"expected a UDP port 1-65535, got {text!r}", key="--source")
    return port
