"""The continuum laws of the coupled arm's tissue layer (``tissue.continuum.law``), as a registry.

Each law is declared once, like a tissue law (:mod:`phri_spring.physics.laws`) and an arm
(:mod:`phri_spring.plugins`): its name, one line of description, its parameters with their
units (config keys under ``tissue.continuum.``), whether the coupled arm solves it through
the reduced hyperelastic model (identified on the large-deformation FE) and what it refuses,
with the physical reason. The config accepts exactly the registered names. Plain Python (no
numpy), so that reading a config does not load the FE. How to add one: docs/extending.md.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["ContinuumParameter", "ContinuumLaw", "CONTINUUM_LAW_MODELS",
           "register_continuum_law", "continuum_law_names", "checked_continuum_law"]


@dataclass(frozen=True)
class ContinuumParameter:
    """One parameter of a continuum law: ``tissue.continuum.<key>`` in its SI ``unit``."""

    key: str
    unit: str
    description: str


@dataclass(frozen=True)
class ContinuumLaw:
    """A continuum law of the coupled arm's tissue layer.

    Attributes
    ----------
    name : str
        What a config gives in ``tissue.continuum.law``.
    description : str
        One line for the docs and error messages.
    parameters : tuple of ContinuumParameter
        The keys under ``tissue.continuum.`` it reads beyond the layer's geometry.
    reduced : bool
        Whether the coupled arm solves it through the reduced hyperelastic model (identified
        once on the large-deformation FE; the ``hyper`` extra), not the linear condensed FE.
    refuses : tuple of str
        What it refuses, each with its physical reason (the docs list them; the checks are
        where the model is built).
    """

    name: str
    description: str
    parameters: tuple = ()
    reduced: bool = False
    refuses: tuple = ()


#: name -> continuum law, in registration order (the linear law first)
CONTINUUM_LAW_MODELS: dict = {}


def register_continuum_law(law: ContinuumLaw) -> ContinuumLaw:
    """Make ``law`` available as ``tissue.continuum.law: NAME``."""
    if not isinstance(law, ContinuumLaw) or not law.name or not law.description:
        raise TypeError("register_continuum_law: expected a ContinuumLaw with a name and a "
                        "description")
    for p in law.parameters:
        if not isinstance(p, ContinuumParameter) or not p.unit or not p.description:
            raise TypeError(f"continuum law {law.name!r}: every parameter needs a "
                            "ContinuumParameter with a unit and a description")
    CONTINUUM_LAW_MODELS[law.name] = law
    return law


def continuum_law_names() -> tuple:
    """The registered continuum laws' names, in order."""
    return tuple(CONTINUUM_LAW_MODELS)


def checked_continuum_law(name):
    """``name`` if it is a registered continuum law, else a ValueError listing them (the
    config's validator: one line naming ``tissue.continuum.law``)."""
    if name not in CONTINUUM_LAW_MODELS:
        raise ValueError(f"expected a registered continuum law, one of "
                         f"{', '.join(CONTINUUM_LAW_MODELS)}")
    return name


_E = ContinuumParameter("young_modulus", "Pa", "Young's modulus of the layer (default: from the "
                        "indenter stiffness)")
_RANGE = (ContinuumParameter("max_force", "N", "largest force the reduced model is identified "
                             "for"),
          ContinuumParameter("max_moment", "N*m", "largest moment the reduced model is "
                             "identified for"))
_REDUCED_REFUSES = (
    "a limb that is not a circular cylinder: the reduced model is identified on the FE of "
    "one cylindrical layer",
    "a Monte Carlo that draws the modulus or the strap tension: the reduced model would be "
    "identified again for every draw")

register_continuum_law(ContinuumLaw(
    "linear", "linear elastic layer, condensed by the FE onto the cuff's patches", (_E,)))
register_continuum_law(ContinuumLaw(
    "neo_hookean", "compressible neo-Hookean layer under a rigid bonded cuff (reduced model)",
    (_E,) + _RANGE, reduced=True, refuses=_REDUCED_REFUSES))
register_continuum_law(ContinuumLaw(
    "ogden", "one-term Ogden layer under a rigid bonded cuff (reduced model)",
    (_E, ContinuumParameter("ogden_alpha", "-", "Ogden exponent (default: identified from "
                            "tissue.stiffening by the indenter FE)")) + _RANGE,
    reduced=True, refuses=_REDUCED_REFUSES))
