"""What the machine can still give a run: the memory figure :mod:`.memory_budget` checks against.

The smallest of ``MemAvailable`` (``/proc/meminfo``; physical memory less this
process's resident set where there is none), the room left under the cgroup's
memory limit (containers: ``memory.max``, or v1's ``memory.limit_in_bytes``) and
the address space left under ``RLIMIT_AS`` (``ulimit -v``: the soft limit less
what the process has mapped). ``PHRI_SPRING_MEMORY_LIMIT`` (bytes, or with a K,
M, G or T suffix, powers of 1024) replaces the first two: a test, or a user who
knows better, sets the memory a run may take; ``ulimit -v`` still holds.
"""

from __future__ import annotations

import os
import re
import resource
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

from ...errors import UsageError

__all__ = ["ENV_LIMIT", "MemoryBudget", "available_memory"]

#: environment variable replacing the machine's memory figure [bytes, or 512M, 2G, ...]
ENV_LIMIT = "PHRI_SPRING_MEMORY_LIMIT"
#: the machine figure is read again after this long [s]: one run reads it once, a library
#: user's long session sees the memory others have taken since
_BUDGET_TTL = 2.0


@dataclass(frozen=True)
class MemoryBudget:
    """What the machine can still give this process.

    Attributes
    ----------
    memory : int
        Bytes the run may still take [B].
    source : str
        Where ``memory`` comes from (``MemAvailable``, ``cgroup memory.max``,
        ``PHRI_SPRING_MEMORY_LIMIT``, ...).
    address_space : int or None
        Bytes of address space left under ``RLIMIT_AS`` (None: no limit).
    """

    memory: int
    source: str
    address_space: Optional[int] = None


_cache: dict = {}


def _parse_limit(text: str) -> int:
    m = re.fullmatch(r"\s*(\d+)\s*([kKmMgGtT]?)(?:i?[bB])?\s*", text)
    if not m:
        raise UsageError(f"expected a number of bytes, optionally with K, M, G or T "
                         f"(e.g. 2G), got {text!r}", key=ENV_LIMIT)
    power = " KMGT".index(m.group(2).upper() or " ")
    return int(m.group(1)) * (1024 ** power)


def _meminfo() -> dict:
    out = {}
    try:
        with open("/proc/meminfo", encoding="ascii") as fh:
            for line in fh:
                name, _, rest = line.partition(":")
                parts = rest.split()
                if parts and parts[0].isdigit():
                    out[name] = int(parts[0]) * 1024
    except OSError:
        pass
    return out


def _self_status() -> dict:
    out = {}
    try:
        with open("/proc/self/status", encoding="ascii", errors="replace") as fh:
            for line in fh:
                name, _, rest = line.partition(":")
                if name in ("VmSize", "VmRSS"):
                    out[name] = int(rest.split()[0]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return out


def _read_int(path: Path) -> Optional[int]:
    try:
        text = path.read_text(encoding="ascii").strip()
    except OSError:
        return None
    return int(text) if text.isdigit() else None


def _cgroup_room() -> Optional[int]:
    """Bytes left under this process's cgroup memory limit (v2, else v1), or None."""
    try:
        lines = Path("/proc/self/cgroup").read_text(encoding="ascii").splitlines()
    except OSError:
        return None
    for line in lines:
        hier, _, rest = line.partition(":")
        ctrl, _, rel = rest.partition(":")
        base = Path("/sys/fs/cgroup")
        if hier == "0" and ctrl == "":                       # cgroup v2
            folder = base / rel.lstrip("/")
            limit, used = _read_int(folder / "memory.max"), _read_int(folder / "memory.current")
        elif "memory" in ctrl.split(","):                    # cgroup v1
            folder = base / "memory" / rel.lstrip("/")
            limit = _read_int(folder / "memory.limit_in_bytes")
            used = _read_int(folder / "memory.usage_in_bytes")
        else:
            continue
        if limit is not None and limit < (1 << 60):         # v1 says "no limit" with ~2^63
            return max(0, limit - (used or 0))
    return None


def _machine() -> tuple:
    """(bytes, source) of the memory figure: the override, else RAM, MemAvailable, cgroup."""
    env = os.environ.get(ENV_LIMIT, "").strip()
    hit = _cache.get(env)
    if hit is not None and time.monotonic() - hit[0] < _BUDGET_TTL:
        return hit[1]
    if env:
        memory, source = _parse_limit(env), f"{ENV_LIMIT}={env}"
    else:
        try:
            phys = os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
        except (ValueError, OSError, AttributeError):  # pragma: no cover - not POSIX
            phys = 1 << 62
        memory = max(0, phys - _self_status().get("VmRSS", 0))
        source = "physical memory"
        available = _meminfo().get("MemAvailable")      # free + reclaimable, Linux 3.14+
        if available is not None and available < memory:
            memory, source = available, "MemAvailable"
        room = _cgroup_room()
        if room is not None and room < memory:
            memory, source = room, "the cgroup's memory.max"
    _cache.clear()
    _cache[env] = (time.monotonic(), (int(memory), source))
    return int(memory), source


_unwinder = []


def _preload_unwinder() -> None:
    """Load libgcc_s now, while memory is plentiful.

    glibc loads it on the first C++ exception or thread cancellation; under an address-space
    limit that load can fail, and the process then aborts ("libgcc_s.so.1 must be installed
    for unwinding to work") instead of pyarrow's allocation failure becoming a MemoryError.
    """
    if _unwinder:
        return
    _unwinder.append(None)
    try:
        import ctypes

        _unwinder[0] = ctypes.CDLL("libgcc_s.so.1")
    except (OSError, ImportError):  # not glibc, or linked statically: nothing to load
        pass


def available_memory() -> MemoryBudget:
    """What this machine can still give the run (see the module docstring).

    The memory figure is read at most every two seconds; the address space left is read
    at every call (it shrinks as libraries load and threads start).

    Raises
    ------
    UsageError
        ``PHRI_SPRING_MEMORY_LIMIT`` is not a number of bytes.
    """
    _preload_unwinder()
    memory, source = _machine()
    address_space = None
    try:
        soft, _ = resource.getrlimit(resource.RLIMIT_AS)
    except (ValueError, OSError, AttributeError):  # pragma: no cover
        soft = resource.RLIM_INFINITY
    if soft != resource.RLIM_INFINITY and soft > 0:
        address_space = max(0, int(soft) - _self_status().get("VmSize", 0))
        if address_space < memory:
            memory, source = address_space, "the address-space limit (ulimit -v)"
    return MemoryBudget(int(memory), source, address_space)
