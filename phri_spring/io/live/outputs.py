"""Outputs of ``phri live`` (docs/live.md): the forces table streamed to disk, LSL outlets.

:class:`LiveTable` writes the columns of ``phri simulate`` (through the same
:class:`~phri_spring.io.outputs.forces.ForcesWriter`) batch by batch into a
hidden temporary file beside the output, and renames it onto the output when
the run ends, whichever way it ends once samples were computed (the end of
the stream, ``--duration``, a signal, an error): the output is then a
complete file of what was computed, never a half-written one. A run that
fails before its first sample leaves nothing behind and an existing output
as it was.

:class:`LslOutlet` and :class:`LslMarkers` publish per-sample values and
event markers on Lab Streaming Layer (pylsl, the ``live`` extra).
"""

from __future__ import annotations

import os
import stat
import tempfile
from pathlib import Path
from typing import Optional, Sequence

from ..outputs.atomic import output_error, umask
from ..outputs.forces import ForcesWriter
from .sources import import_pylsl

__all__ = ["LiveTable", "LslOutlet", "LslMarkers"]


def _mode_for(dest: Path) -> int:
    """The replaced output's own mode, else 0666 less the umask (as :mod:`.atomic` does)."""
    try:
        st = os.stat(dest)
        if stat.S_ISREG(st.st_mode):
            return stat.S_IMODE(st.st_mode)
    except OSError:
        pass
    return 0o666 & ~umask()


class LiveTable:
    """The forces table of a live run: batches appended, the file completed atomically.

    Parameters
    ----------
    path : path-like
        The output (CSV or Parquet, ``fmt``); checked by the caller.
    fmt : str
        ``'csv'`` or ``'parquet'``.
    labels : sequence of str
        Element labels (one force column [N] each).
    extra_types : dict
        Extra column -> pyarrow type, as ``phri simulate`` writes them.
    decimals : int or None
        CSV only: decimals kept (None or negative: every digit).
    """

    def __init__(self, path, fmt: str, labels: Sequence[str], extra_types: dict, *,
                 decimals: Optional[int] = 6):
        self.path = Path(path)
        self.fmt = fmt
        self.labels = list(labels)
        self.extra_types = dict(extra_types)
        self.decimals = decimals
        self.rows = 0
        self._tmp: Optional[Path] = None
        self._writer: Optional[ForcesWriter] = None

    def open(self) -> "LiveTable":
        """Create the temporary file and write the header (CSV) or open the writer."""
        parent = self.path.parent if str(self.path.parent) else Path(".")
        try:
            fd, name = tempfile.mkstemp(prefix=f".{self.path.name}.",
                                        suffix=f".tmp{self.path.suffix}", dir=str(parent))
            self._tmp = Path(name)
            try:
                os.fchmod(fd, _mode_for(self.path))
            finally:
                os.close(fd)
            self._writer = ForcesWriter(self._tmp, self.fmt, self.labels, self.extra_types,
                                        threaded=False, decimals=self.decimals)
            self._writer.__enter__()
        except OSError as exc:
            self.discard()
            raise output_error(exc, self.path, self._tmp) from None
        return self

    def write(self, time, forces, extras: dict) -> None:
        """Append rows: time (k,) [s], forces (k, n) [N], extras by column name."""
        try:
            self._writer.write(time, forces, extras)
        except OSError as exc:
            self.discard()
            raise output_error(exc, self.path, self._tmp) from None
        self.rows += len(time)

    def commit(self) -> Path:
        """Close the file and rename it onto the output."""
        try:
            self._writer.__exit__(None, None, None)
            self._writer = None
            os.replace(self._tmp, self.path)
            self._tmp = None
        except OSError as exc:
            self.discard()
            raise output_error(exc, self.path, self._tmp) from None
        return self.path

    def discard(self) -> None:
        """Close and remove the temporary file; the output is left as it was."""
        if self._writer is not None:
            writer, self._writer = self._writer, None
            try:
                writer.__exit__(RuntimeError, RuntimeError("discarded"), None)
            except Exception:  # noqa: BLE001 - the file goes anyway
                pass
        if self._tmp is not None:
            try:
                self._tmp.unlink(missing_ok=True)
            except OSError:  # pragma: no cover - the folder vanished
                pass
            self._tmp = None


class LslOutlet:
    """An LSL outlet of the per-sample results: one channel per element force [N], then
    the peak pressure ratio [-] and the contacts in touch, each sample stamped with
    its input sample's time.

    Parameters
    ----------
    name : str
        The stream's name (``--lsl-out``).
    labels : sequence of str
        Element labels.
    nominal_rate : float
        [Hz], 0 for irregular.
    """

    EXTRA_CHANNELS = (("peak_pressure_to_pain_threshold", "ratio"), ("contacts_in_touch", "count"))

    def __init__(self, name: str, labels: Sequence[str], nominal_rate: float = 0.0):
        pylsl = import_pylsl("--lsl-out")
        channels = [(lab, "N") for lab in labels] + list(self.EXTRA_CHANNELS)
        info = pylsl.StreamInfo(name, "phri-spring", len(channels),
                                nominal_rate if nominal_rate > 0 else pylsl.IRREGULAR_RATE,
                                "double64", f"phri-spring-live-{name}")
        chans = info.desc().append_child("channels")
        for label, unit in channels:
            ch = chans.append_child("channel")
            ch.append_child_value("label", label)
            ch.append_child_value("unit", unit)
            ch.append_child_value("type", "force" if unit == "N" else unit)
        self.name = name
        self.channels = [label for label, _ in channels]
        self.outlet = pylsl.StreamOutlet(info, chunk_size=1, max_buffered=60)

    def push(self, values, timestamp: float) -> None:
        self.outlet.push_sample(values, timestamp)

    def close(self) -> None:
        _drain(self.outlet)
        self.outlet = None


def _drain(outlet, wait_s: float = 0.25) -> None:
    """Give liblsl's sending threads a moment to pass the last samples on to the inlets
    (liblsl sends asynchronously and has no flush; a process that exits at once loses them)."""
    import time

    try:
        if outlet is not None and outlet.have_consumers():
            time.sleep(wait_s)
    except Exception:  # noqa: BLE001 - a broken outlet: nothing more to send
        pass


class LslMarkers:
    """An LSL marker stream (``NAME-markers``, one text channel, irregular rate) for alarms
    and gaps, stamped with the input sample's time."""

    def __init__(self, name: str):
        pylsl = import_pylsl("--lsl-out")
        info = pylsl.StreamInfo(f"{name}-markers", "Markers", 1, pylsl.IRREGULAR_RATE,
                                "string", f"phri-spring-live-{name}-markers")
        self.name = f"{name}-markers"
        self.outlet = pylsl.StreamOutlet(info)

    def push(self, text: str, timestamp: float) -> None:
        self.outlet.push_sample([text], timestamp)

    def close(self) -> None:
        _drain(self.outlet, 0.0 if self.outlet is None else 0.05)
        self.outlet = None
