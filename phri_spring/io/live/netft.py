"""ATI Net F/T "raw data transfer" (RDT) over UDP: a small client (docs/live.md).

The protocol, as ATI's Net F/T manual and its sample code describe it
(every field big-endian):

* request, host -> box, 8 bytes to UDP port 49152: ``uint16 header = 0x1234``,
  ``uint16 command`` (0 stop streaming, 2 start real-time streaming),
  ``uint32 sample_count`` (records to send; 0 = until told to stop);
* record, box -> the request's source address, 36 bytes: ``uint32 rdt_sequence``
  (one more for every RDT packet sent), ``uint32 ft_sequence`` (the box's own
  sample counter), ``uint32 status`` (0 = healthy; bit 31 set on an error), then
  ``int32 Fx Fy Fz Tx Ty Tz`` in counts. Force = counts / counts-per-force,
  torque = counts / counts-per-torque, in the units the box is set to (the
  ``load_cell`` units of the config apply after).

Gaps in ``rdt_sequence`` are packets lost on the way: :class:`SequenceTracker`
counts them (modulo 2^32; a jump backwards is a restarted box, not a loss).
"""

from __future__ import annotations

import socket
import struct
from dataclasses import dataclass
from typing import Optional

import numpy as np

__all__ = ["RDT_PORT", "RDT_HEADER", "CMD_STOP", "CMD_START_REALTIME", "INFINITE_SAMPLES",
           "COMMAND_SIZE", "RECORD_SIZE", "pack_command", "unpack_command", "pack_record",
           "unpack_record", "RdtRecord", "SequenceTracker", "RdtClient",
           "DEFAULT_COUNTS_PER_FORCE", "DEFAULT_COUNTS_PER_TORQUE"]

#: the Net F/T's RDT port
RDT_PORT = 49152
RDT_HEADER = 0x1234
CMD_STOP = 0
CMD_START_REALTIME = 2
#: sample count of a start request: stream until a stop request
INFINITE_SAMPLES = 0
COMMAND_SIZE = 8
RECORD_SIZE = 36
#: ATI's common calibration values (the box's web page gives the real ones)
DEFAULT_COUNTS_PER_FORCE = 1_000_000.0
DEFAULT_COUNTS_PER_TORQUE = 1_000_000.0

_COMMAND = struct.Struct(">HHI")
_RECORD = struct.Struct(">III6i")
#: a sequence jump of more than this (forward) is a restarted box, not packets lost
_MAX_GAP = 1 << 31
#: a packet at most this far behind the last is a late one (dropped); further, a restarted box
_LATE = 64


def pack_command(command: int, sample_count: int = INFINITE_SAMPLES) -> bytes:
    """An 8-byte RDT request: header 0x1234, ``command``, ``sample_count`` (0 = infinite)."""
    return _COMMAND.pack(RDT_HEADER, int(command), int(sample_count))


def unpack_command(data: bytes):
    """``(command, sample_count)`` of an RDT request, or None if it is not one."""
    if len(data) != COMMAND_SIZE:
        return None
    header, command, count = _COMMAND.unpack(data)
    if header != RDT_HEADER:
        return None
    return command, count


@dataclass(frozen=True)
class RdtRecord:
    """One RDT record: sequence numbers, status word and the six readings in counts."""

    rdt_sequence: int
    ft_sequence: int
    status: int
    counts: tuple     # (Fx, Fy, Fz, Tx, Ty, Tz) [counts]

    def wrench(self, counts_per_force: float, counts_per_torque: float) -> np.ndarray:
        """(6,) readings: forces = counts / counts_per_force, torques = counts / counts_per_torque."""
        c = np.asarray(self.counts, dtype=float)
        return np.concatenate([c[:3] / counts_per_force, c[3:] / counts_per_torque])


def pack_record(rdt_sequence: int, ft_sequence: int, status: int, counts) -> bytes:
    """A 36-byte RDT record (what a Net F/T sends; for emulators and tests)."""
    return _RECORD.pack(rdt_sequence & 0xFFFFFFFF, ft_sequence & 0xFFFFFFFF,
                        status & 0xFFFFFFFF, *(int(c) for c in counts))


def unpack_record(data: bytes) -> Optional[RdtRecord]:
    """The record in a 36-byte packet, or None for a packet of any other size."""
    if len(data) != RECORD_SIZE:
        return None
    rs, fs, st, *counts = _RECORD.unpack(data)
    return RdtRecord(rs, fs, st, tuple(counts))


class SequenceTracker:
    """Counts RDT packets lost from the gaps in ``rdt_sequence`` (modulo 2^32).

    A packet whose number is not above the last one loses nothing: a duplicate
    or a packet up to 64 behind (late) is dropped; one further behind starts a
    new count (the box restarted). :meth:`update` tells which.
    """

    def __init__(self):
        self.last: Optional[int] = None
        self.lost = 0
        self.restarts = 0

    def update(self, sequence: int, after_gap: bool = False) -> int:
        """Record a packet's number; return the packets lost just before it (0 or more),
        or -1 for a packet to drop (a duplicate or one older than the last).

        ``after_gap``: the first packet after a silence, when any number behind the
        last means a restarted box."""
        if self.last is None:
            self.last = sequence
            return 0
        step = (sequence - self.last) & 0xFFFFFFFF
        if step == 0:
            return -1
        if step >= _MAX_GAP:          # behind the last: a late packet, or the box restarted
            if (1 << 32) - step <= _LATE and not after_gap:
                return -1
            self.restarts += 1
            self.last = sequence
            return 0
        self.last = sequence
        self.lost += step - 1
        return step - 1

    def reset(self) -> None:
        """Forget the last number (a new stream after a start request)."""
        self.last = None


class RdtClient:
    """A UDP client of a Net F/T box's RDT stream.

    Parameters
    ----------
    host : str
        Name or address of the box.
    port : int
        Its RDT port (49152).

    Raises
    ------
    OSError
        ``socket.gaierror`` for a host that does not resolve; any socket error.
    """

    def __init__(self, host: str, port: int = RDT_PORT):
        infos = socket.getaddrinfo(host, port, type=socket.SOCK_DGRAM)
        family, _, _, _, address = infos[0]
        self.address = address
        self.sock = socket.socket(family, socket.SOCK_DGRAM)
        try:
            # a larger receive buffer rides out a slow moment of the reader at 7 kHz
            self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 20)
            self.sock.connect(address)    # only the box's packets are received
        except BaseException:
            self.sock.close()
            raise

    def start(self, sample_count: int = INFINITE_SAMPLES) -> None:
        """Send the start request (real-time streaming)."""
        self.sock.send(pack_command(CMD_START_REALTIME, sample_count))

    def stop(self) -> None:
        """Send the stop request (best effort: the box may be gone)."""
        try:
            self.sock.send(pack_command(CMD_STOP, 0))
        except OSError:
            pass

    def receive(self, timeout: float) -> Optional[bytes]:
        """One packet's bytes, or None if none came within ``timeout`` [s].

        A refused packet (ICMP port unreachable: nothing listens at the box's
        address yet) is reported as None too, like silence.
        """
        self.sock.settimeout(max(timeout, 0.0))
        try:
            return self.sock.recv(2048)
        except (socket.timeout, BlockingIOError, ConnectionRefusedError):
            return None

    def close(self) -> None:
        self.sock.close()
