"""The tissue laws ``phri fit-stiffness --law`` can fit, as declared records.

Each fittable law is declared like a tissue law (:mod:`phri_spring.physics.laws`), a
continuum law (:mod:`phri_spring.physics.hyperelastic.laws`) and an arm
(:mod:`phri_spring.plugins`): its name, one line of description, what it fits (the fit
CSV's columns, with their units) and what it refuses, with the reason. Plain Python (no
numpy) so that the command line can list them in ``--help`` without loading the fitting
code. :func:`phri_spring.workflows.fit.stiffness.fit_stiffness` dispatches on these names
(adding a law: docs/extending.md).
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["FitColumn", "FitLaw", "FIT_LAWS", "ELASTIC_PARTS", "law_names"]


@dataclass(frozen=True)
class FitColumn:
    """A value a fit writes per location: the fit CSV's ``column``, in ``unit``."""

    column: str
    unit: str
    description: str


@dataclass(frozen=True)
class FitLaw:
    """A tissue law ``phri fit-stiffness --law NAME`` fits.

    Attributes
    ----------
    name : str
    description : str
        What it fits, one line (shown in ``phri fit-stiffness --help``).
    parameters : tuple of FitColumn
        What it writes per location beside the stiffness.
    refuses : tuple of str
        What it refuses, each with its reason.
    """

    name: str
    description: str
    parameters: tuple = ()
    refuses: tuple = ()


_K = FitColumn("stiffness_N_per_m", "N/m", "the stiffness at small compression")

#: law name -> its record (``phri fit-stiffness --help`` lists them in this order)
FIT_LAWS = {law.name: law for law in (
    FitLaw("linear", "the unloading slope [N/m]", (_K,)),
    FitLaw("exponential", "k0 [N/m] and the stiffening rate beta [1/m] of "
           "F = (k0/beta)(exp(beta (d - d0)) - 1) on the same unloading strokes, "
           "contact point d0 free",
           (_K, FitColumn("stiffening_per_m", "1/m", "the stiffening rate beta"))),
    FitLaw("qlv", "quasi-linear viscoelastic tissue from trials with a hold or several ramp "
           "rates: the elastic part (see --elastic) and a Prony series of --relaxation-terms "
           "terms (fractions [-], times [s]) of the force over time",
           (_K, FitColumn("relaxation_fraction_<i>, relaxation_time_<i>_s", "-, s",
                          "the Prony series' fractions and times"))),
)}

#: elastic (instantaneous) parts of the ``qlv`` law
ELASTIC_PARTS = ("linear", "exponential")


def law_names() -> tuple:
    """The registered law names, in order."""
    return tuple(FIT_LAWS)
