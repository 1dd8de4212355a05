"""The forces table's columns on samples without an answer (runs with friction).

A run with ``interface.friction_coefficient`` adds three columns after the standard ones
(docs/model.md section 12.7): ``no_equilibrium_reason`` (empty where the sample has an
answer, else one of :data:`~phri_spring.physics.contact.no_equilibrium.REASONS`),
``no_equilibrium_shortfall_N`` [N] and ``no_equilibrium_shortfall_Nm`` [N*m] (the
reason's shortfall in its unit, NaN otherwise). A bonded run (no key) has none of them:
its table is the paper model's. :class:`NoAnswerTally` adds the reasons of a streamed
run up for its summary.
"""

from __future__ import annotations

import math

import numpy as np

from ...physics.contact.no_equilibrium import REASONS, explain

__all__ = ["NO_EQUILIBRIUM_COLUMN_TYPES", "no_equilibrium_extras", "NoAnswerTally"]

#: the columns and their types (as EXTRA_COLUMN_TYPES of :mod:`.simulate`)
NO_EQUILIBRIUM_COLUMN_TYPES = (("no_equilibrium_reason", "label"),
                               ("no_equilibrium_shortfall_N", "float64"),
                               ("no_equilibrium_shortfall_Nm", "float64"))


def no_equilibrium_extras(model, W, sol) -> dict:
    """The three columns for a solved chunk: cuff wrenches W (m, 6) and their solution."""
    code, s_N, s_Nm = explain(model, W, sol.converged)
    return {"no_equilibrium_reason": (code, REASONS),
            "no_equilibrium_shortfall_N": s_N,
            "no_equilibrium_shortfall_Nm": s_Nm}


class NoAnswerTally:
    """Samples without an answer by reason, and the worst one, over a streamed run's chunks
    (chunks may arrive in any order: the worst is the largest shortfall, the first in the
    log among equal ones; a torsion's shortfall counts as the force at ``radius`` [m]
    that makes it, so that the two units compare)."""

    def __init__(self, radius: float):
        self.radius = float(radius)
        self._chunks = {}     # chunk number -> (counts (len(REASONS),), worst tuple or None)

    def add(self, number: int, time, extras: dict) -> None:
        if "no_equilibrium_reason" not in extras:
            return
        code = np.asarray(extras["no_equilibrium_reason"][0])
        counts = np.bincount(code, minlength=len(REASONS))
        worst = None
        s_N = np.asarray(extras["no_equilibrium_shortfall_N"], dtype=float)
        s_Nm = np.asarray(extras["no_equilibrium_shortfall_Nm"], dtype=float)
        for values, unit in ((s_N, "N"), (s_Nm, "N*m")):
            if np.isfinite(values).any():
                j = int(np.nanargmax(values))
                cand = (float(values[j]), unit, REASONS[int(code[j])], float(time[j]))
                if worst is None or self._key(cand) > self._key(worst):
                    worst = cand
        if worst is None and counts[1:].any():      # only "not converged": the first one
            j = int(np.flatnonzero(code > 0)[0])
            worst = (math.nan, "", REASONS[int(code[j])], float(time[j]))
        self._chunks[number] = (counts, worst)

    def result(self):
        """(counts by reason name (nonzero only), worst (reason, time [s], shortfall, unit) or
        None)."""
        counts = np.zeros(len(REASONS), dtype=np.int64)
        worst = None
        for number in sorted(self._chunks):
            c, w = self._chunks[number]
            counts += c
            if w is not None and (worst is None or self._key(w) > self._key(worst)):
                worst = w
        by_reason = {REASONS[k]: int(counts[k]) for k in range(1, len(REASONS)) if counts[k]}
        if worst is None:
            return by_reason, None
        value, unit, reason, t = worst
        return by_reason, (reason, t, value, unit)

    def _key(self, w):
        value, unit = w[0], w[1]
        if not math.isfinite(value):
            return -math.inf
        return value / self.radius if unit == "N*m" else value
