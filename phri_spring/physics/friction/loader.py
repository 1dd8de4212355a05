"""The compiled friction loop (:mod:`.kernel`), loaded once, on first use.

numba's import and the loop's machine code (read from numba's cache, or compiled on the
first run of an install) take about half a second. Loading them on a thread while the
model was built and the log opened gained nothing measurable (benchmarks/FRICTION.md,
seventh session: the start is Python work that holds the interpreter), so the first solve
loads them. Where numba is missing or the loading fails, the friction path is the numpy
one: a broken compiler never stops a run.
"""

from __future__ import annotations

__all__ = ["kernel"]

_MODULE = None
_FAILED = False


def _load() -> None:
    global _MODULE, _FAILED
    try:
        from . import kernel as module

        if module.NUMBA:
            module.load()
        _MODULE = module
    except Exception:     # numba present but unusable (e.g. a numpy it does not support)
        _FAILED = True


def kernel():
    """The :mod:`.kernel` module once loaded, or None where it could not be loaded."""
    if _MODULE is None and not _FAILED:
        _load()
    return _MODULE
