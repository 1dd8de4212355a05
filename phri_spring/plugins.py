"""What a plug-in declares: the records of the arm-model registry (docs/extending.md).

An arm model is registered once (:func:`phri_spring.workflows.common.register_arm`) with
everything the rest of the package asks of it: its label and colour (tables, legends,
figures), its memory terms (:mod:`phri_spring.io.memory.budget`), how the Monte Carlo's
scattered inputs reach it (:mod:`phri_spring.workflows.uncertainty.draws`), what its tissue
is (report texts) and what it refuses. No other module names an arm: they read its record
here. This module imports nothing from the package, so that every layer (io, reports,
workflows) can read the registry.
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass, field
from typing import Callable, Optional

__all__ = ["ArmMemory", "ArmUncertainty", "ArmModel", "ARM_MODELS", "arm_models", "arm_record",
           "FALLBACK_COLOURS"]

#: colours handed, in turn, to arms registered without one (Okabe-Ito, after the built-ins')
FALLBACK_COLOURS = ("#CC79A7", "#D55E00", "#56B4E9", "#F0E442", "#000000")


@dataclass(frozen=True)
class ArmMemory:
    """The memory an arm's model needs beyond the spring network's (the default: nothing).

    Attributes
    ----------
    model_terms : callable (n_elements, n_models) -> {term: bytes}, optional
        Extra terms of the model itself, e.g. dense (6n x 6n) matrices; ``n_models``
        models are held at once (Monte Carlo draws with a model each).
    bytes_per_value : int
        Extra bytes per solved value (sample x element) of a streamed chunk.
    bytes_per_element : int
        Extra bytes per element of every chunk (e.g. gathering dense blocks).
    fe_mesh : callable (cfg, cache_dir) -> (hexahedra, dofs) or None, optional
        The built-in tissue FE's mesh the model will build (None: not built, e.g. cached);
        its terms are then counted (:func:`phri_spring.io.memory.budget.estimate`).
    advice : str
        Appended to "expected fewer elements" when the arm's model cannot fit
        (e.g. ``" (or --arm compliant)"``).
    """

    model_terms: Optional[Callable] = None
    bytes_per_value: int = 0
    bytes_per_element: int = 0
    fe_mesh: Optional[Callable] = None
    advice: str = ""

    @property
    def dense(self) -> bool:
        """Whether the model holds more than the spring network (checked before it is built)."""
        return self.model_terms is not None or self.fe_mesh is not None


@dataclass(frozen=True)
class ArmUncertainty:
    """How the Monte Carlo's scattered inputs (``--uncertainty``) reach an arm's model.

    Attributes
    ----------
    tissue_route : callable (cfg) -> str, optional
        ``'stiffness'`` (the per-location tissue stiffness draws act), ``'modulus'`` (the
        continuum's Young's modulus draws act) or ``'none'``; None: always ``'stiffness'``.
    stiffening : bool
        Whether the model runs the tissue law's stiffening rate (its draws act).
    fe_cache : bool
        Whether every draw reloads the built-in FE from its disk cache (the cache is then
        built before the draws, and a run that cannot write it is refused).
    stiffness_via : str
        How the tissue-stiffness draws reach the model, appended to their phrase (e.g.
        ``", through the continuum's Young's modulus"``).
    unused_tissue : str
        Why the tissue-stiffness SD does not act when the route is ``'none'`` (ends the
        phrase "the tissue stiffness SD is unused: the NAME arm ...").
    unused_stiffening : str
        Why the stiffening SD does not act (when ``stiffening`` is False).
    """

    tissue_route: Optional[Callable] = None
    stiffening: bool = True
    fe_cache: bool = False
    stiffness_via: str = ""
    unused_tissue: str = "does not use the tissue stiffness"
    unused_stiffening: str = "the arm does not run the tissue law's stiffening"


@dataclass(frozen=True)
class ArmModel:
    """An arm model a config can be solved with (``--arm NAME``; docs/extending.md).

    Attributes
    ----------
    name : str
    description : str
        One line for ``--help`` and the docs.
    build : callable (cfg: Config, cache_dir) -> model
        Assembles the model of a config: an object with ``contact_system``, ``W_pre``,
        ``labels``, ``areas`` and ``inv_area_kpa`` (``SpringModel`` and ``CoupledModel``
        are the built-in ones).
    label : str
        How tables, legends and figure titles name it (default: ``"Name arm"``).
    colour : str
        Its colour in figures (a matplotlib colour; default: the next of
        :data:`FALLBACK_COLOURS`).
    memory : ArmMemory
        Its memory terms beyond the spring network's (default: none).
    uncertainty : ArmUncertainty
        How the Monte Carlo's inputs reach it (default: like the compliant arm).
    has_tissue : bool
        Whether it models the tissue at all (report texts list the tissue law of the arms
        that do).
    tissue_text : callable (cfg) -> str, optional
        What its tissue is, for reports (default: the config's tissue law).
    refuse : callable (cfg) -> None, optional
        Config checks with a physical reason, run before the memory check and the build:
        raises a one-line :class:`~phri_spring.errors.ConfigError` naming the key.
    continuum : bool
        Whether it reads ``tissue.continuum`` (the composition matrix crosses it with the
        continuum laws and patch gaps).
    """

    name: str
    description: str
    build: Callable
    label: str = ""
    colour: str = ""
    memory: ArmMemory = field(default_factory=ArmMemory)
    uncertainty: ArmUncertainty = field(default_factory=ArmUncertainty)
    has_tissue: bool = True
    tissue_text: Optional[Callable] = None
    refuse: Optional[Callable] = None
    continuum: bool = False


#: name -> arm model, in registration order (filled by ``register_arm``)
ARM_MODELS: dict = {}

_PLAIN = ArmModel("", "", build=lambda cfg, cache_dir=None: None)


#: the module whose import registers the built-in arms (loaded on the first look-up, so that
#: a layer below it, e.g. the memory budget, reads the same records without importing it)
BUILTIN_ARMS_MODULE = "phri_spring.workflows.common"


def arm_models() -> dict:
    """:data:`ARM_MODELS`, with the built-in arms registered."""
    if not ARM_MODELS:
        importlib.import_module(BUILTIN_ARMS_MODULE)
    return ARM_MODELS


def arm_record(arm) -> ArmModel:
    """The record of an arm (a name or the record itself); a name not registered gets the
    spring network's defaults (no terms beyond it, the compliant arm's routes)."""
    if isinstance(arm, ArmModel):
        return arm
    return arm_models().get(arm, _PLAIN)
