"""An ATI Net F/T box on loopback, speaking RDT over UDP, for the tests of ``phri live``.

Written from the protocol's description in ATI's Net F/T manual (every field
big-endian): the host sends 8-byte requests (``uint16 0x1234``, ``uint16
command``: 2 start real-time streaming, 0 stop; ``uint32 sample_count``, 0 =
infinite) to the box's UDP port; the box answers to the request's source
address with 36-byte records (``uint32 rdt_sequence``, ``uint32 ft_sequence``,
``uint32 status``, ``int32 Fx Fy Fz Tx Ty Tz`` counts), ``rdt_sequence`` one
more for every packet sent. Packets are built here with ``struct`` directly,
not with the package's own packer, so that the client is checked against an
independent reading of the protocol.

Faults on demand: ``drop`` (record indices never sent, their sequence numbers
skipped: packets lost on the way), ``garbage`` (indices before which a packet
of the wrong size is sent), ``reboot_after`` (after that many records the box
goes silent, restarts its numbering at 1 and waits for a new start request).
"""

from __future__ import annotations

import socket
import struct
import threading
import time

_REQUEST = struct.Struct(">HHI")
_RECORD = struct.Struct(">III6i")


class NetFtEmulator:
    """Streams ``counts`` (m, 6) integer readings at ``rate_hz`` once asked to start.

    Use as a context manager; ``port`` is the UDP port it listens on (127.0.0.1).
    ``requests`` lists the ``(command, sample_count)`` requests received, in order.
    """

    def __init__(self, counts, *, rate_hz: float = 1000.0, drop=(), garbage=(),
                 reboot_after=None, port: int = 0):
        self.counts = [tuple(int(c) for c in row) for row in counts]
        self.period = 1.0 / rate_hz
        self.drop = set(drop)
        self.garbage = set(garbage)
        self.reboot_after = reboot_after
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", port))
        self.port = self.sock.getsockname()[1]
        self.requests = []
        self.sent = []            # indices of the records sent, in order
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._serve, daemon=True)

    def __enter__(self):
        self._thread.start()
        return self

    def __exit__(self, *exc):
        self._stop.set()
        self._thread.join(5)
        # a request that reached the socket after the serving thread's last read (the
        # client's stop request at the end of its run) is still recorded
        while self._request(0.0) is not None or self._pending():
            pass
        self.sock.close()
        return False

    def _pending(self) -> bool:
        """Whether a datagram (valid or not) is still waiting on the socket."""
        import select
        return bool(select.select([self.sock], [], [], 0)[0])

    def _request(self, timeout):
        """(command, count, address) of the next valid request, or None."""
        self.sock.settimeout(timeout)
        try:
            data, addr = self.sock.recvfrom(64)
        except (socket.timeout, BlockingIOError):
            return None
        if len(data) != 8:
            return None
        header, command, count = _REQUEST.unpack(data)
        if header != 0x1234:
            return None
        self.requests.append((command, count))
        return command, count, addr

    def _serve(self):
        index, sequence, booted = 0, 0, False
        while not self._stop.is_set() and index < len(self.counts):
            req = self._request(0.05)
            if req is None or req[0] != 2:
                continue
            _, count, addr = req
            sent_now = 0
            next_t = time.perf_counter()
            while not self._stop.is_set() and index < len(self.counts):
                if count and sent_now >= count:
                    break
                if (self.reboot_after is not None and not booted
                        and len(self.sent) == self.reboot_after):
                    booted, sequence = True, 0          # rebooted: numbering starts again
                    break                               # silent until the next start request
                if index in self.garbage:
                    self.sock.sendto(b"\x12\x34garbage", addr)
                sequence += 1
                if index not in self.drop:
                    self.sock.sendto(_RECORD.pack(sequence, sequence * 4, 0,
                                                  *self.counts[index]), addr)
                    self.sent.append(index)
                index += 1
                sent_now += 1
                stop = self._poll_stop()
                if stop:
                    break
                next_t += self.period
                delay = next_t - time.perf_counter()
                if delay > 0:
                    time.sleep(delay)
        # after the last record: answer nothing more, but keep reading requests
        while not self._stop.is_set():
            self._request(0.05)

    def _poll_stop(self) -> bool:
        """True if a stop request came meanwhile (non-blocking)."""
        self.sock.setblocking(False)
        try:
            data, _ = self.sock.recvfrom(64)
        except (BlockingIOError, socket.timeout):
            return False
        finally:
            self.sock.setblocking(True)
        if len(data) == 8:
            header, command, count = _REQUEST.unpack(data)
            if header == 0x1234:
                self.requests.append((command, count))
                return command == 0
        return False
