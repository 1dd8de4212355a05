"""The compiled friction loop (:mod:`.kernel`), loaded on a thread.

numba's import and the loop's machine code (read from numba's cache, or compiled on the
first run of an install) take about half a second; a model with friction starts loading
them when it is built (:func:`warm_up`), so that the loading overlaps reading the log,
and the first solve waits for it (:func:`kernel`). Where numba is missing or the loading
fails, the friction path is the numpy one: a broken compiler never stops a run.
"""

from __future__ import annotations

import threading

__all__ = ["warm_up", "kernel"]

_MODULE = None
_FAILED = False
_THREAD = None
_LOCK = threading.Lock()


def _load() -> None:
    global _MODULE, _FAILED
    try:
        from . import kernel as module

        if module.NUMBA:
            module.load()
        _MODULE = module
    except Exception:     # numba present but unusable (e.g. a numpy it does not support)
        _FAILED = True


def warm_up() -> None:
    """Start loading the compiled loop on a daemon thread (once per process)."""
    global _THREAD
    with _LOCK:
        if _MODULE is None and _THREAD is None and not _FAILED:
            _THREAD = threading.Thread(target=_load, name="phri-friction-kernel", daemon=True)
            _THREAD.start()


def kernel():
    """The :mod:`.kernel` module once loaded (waiting for :func:`warm_up`'s thread), or None
    where it could not be loaded."""
    thread = _THREAD
    if thread is not None:
        thread.join()
    if _MODULE is None and not _FAILED:
        _load()
    return _MODULE
