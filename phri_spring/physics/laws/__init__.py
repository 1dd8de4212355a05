"""Tissue laws: the normal force of an element's tissue for a compression, as plug-ins.

One module per law (:mod:`.linear`, :mod:`.exponential`), their base class and registry in
:mod:`.base` (how to add one: docs/extending.md), and the series element of a law
with the cuff spring in :mod:`.series`. Every name is importable from here.

>>> import numpy as np
>>> law = make_law("linear", k0=[1000.0, 2000.0])
>>> law.force(np.array([0.002, -0.001]))             # N: 1000 N/m x 2 mm; lifted: 0
array([2., 0.])
>>> {"linear", "exponential"} <= set(TISSUE_LAWS)
True
"""

from .base import TISSUE_LAWS, LawParameter, TissueLaw, register_law
# registration order is the order of TISSUE_LAWS (tables, the composition matrix): the
# paper's linear law first
from .linear import LinearLaw  # isort: skip
from .exponential import ExponentialLaw  # isort: skip
from .series import SeriesElement

__all__ = ["LawParameter", "TissueLaw", "LinearLaw", "ExponentialLaw", "SeriesElement",
           "TISSUE_LAWS", "register_law", "make_law"]


def make_law(name, k0, **params) -> "TissueLaw":
    """The law ``name`` (a registered name, or a :class:`TissueLaw` subclass) with initial
    stiffness ``k0`` (n,) [N/m] and its parameters."""
    if isinstance(name, type) and issubclass(name, TissueLaw):
        cls = name
    else:
        try:
            cls = TISSUE_LAWS[name]
        except KeyError:
            raise ValueError(f"tissue law: expected one of {', '.join(sorted(TISSUE_LAWS))}, "
                             f"got {name!r}") from None
    law = cls(k0, **params)
    # a law that is linear at these parameters is solved as the linear law, exactly
    return LinearLaw(law.k0) if law.linear_here() else law
