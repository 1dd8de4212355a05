"""Tissue laws: the normal force of an element's tissue for a compression, as plug-ins.

One module per law (:mod:`.linear`, :mod:`.exponential`), their base class and registry in
:mod:`.base` (how to add one: docs/model.md section 11.2), and the series element of a law
with the cuff spring in :mod:`.series`. Every name is importable from here.
"""

from .base import TISSUE_LAWS, LawParameter, TissueLaw, make_law, register_law
# registration order is the order of TISSUE_LAWS (tables, the composition matrix): the
# paper's linear law first
from .linear import LinearLaw  # isort: skip
from .exponential import ExponentialLaw  # isort: skip
from .series import SeriesElement

__all__ = ["LawParameter", "TissueLaw", "LinearLaw", "ExponentialLaw", "SeriesElement",
           "TISSUE_LAWS", "register_law", "make_law"]
