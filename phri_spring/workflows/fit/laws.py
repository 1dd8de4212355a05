"""The tissue laws ``phri fit-stiffness --law`` can fit: names and one-line descriptions.

Plain Python (no numpy) so that the command line can list them in ``--help`` without
loading the fitting code. :func:`phri_spring.workflows.fit.stiffness.fit_stiffness`
dispatches on these names.
"""

from __future__ import annotations

__all__ = ["FIT_LAWS", "ELASTIC_PARTS", "law_names"]

#: law name -> what it fits (shown in ``phri fit-stiffness --help``)
FIT_LAWS = {
    "linear": "the unloading slope [N/m]",
    "exponential": "k0 [N/m] and the stiffening rate beta [1/m] of "
                   "F = (k0/beta)(exp(beta (d - d0)) - 1) on the same unloading strokes, "
                   "contact point d0 free",
    "qlv": "quasi-linear viscoelastic tissue from trials with a hold or several ramp rates: "
           "the elastic part (see --elastic) and a Prony series of --relaxation-terms terms "
           "(fractions [-], times [s]) of the force over time",
}

#: elastic (instantaneous) parts of the ``qlv`` law
ELASTIC_PARTS = ("linear", "exponential")


def law_names() -> tuple:
    """The registered law names, in order."""
    return tuple(FIT_LAWS)
