"""Which tissue law an arm ran, as the short text every summary line and report shows.

The compliant arm runs the config's tissue law (``tissue.law``, e.g. the exponential law
selected by ``tissue.stiffening``); the rigid arm has no tissue; the coupled arm's tissue
is a linear continuum, which does not use the law's parameters: a config that gives them
is told so, in one phrase, rather than silently run linear.

>>> from phri_spring.io.config import config_from_dict
>>> raw = {"geometry": {"radius": 0.045, "rows": {"A": 0.0}, "row_width": 0.025,
...                     "angles": {"start": 0.0, "step": 60.0, "count": 6}},
...        "load_cell": {"position": [0, 0, 0], "euler_xyz_deg": [0, 0, 0]},
...        "tissue": {"stiffness": 4000.0, "stiffening": 150}, "cuff": {"stiffness": 1e5}}
>>> cfg = config_from_dict(raw)
>>> arm_law_text(cfg, "compliant")
'exponential tissue law (beta 150 1/m)'
>>> arm_law_text(cfg, "coupled")
'linear continuum (tissue.stiffening is used by the compliant arm only)'
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from ..plugins import arm_record

__all__ = ["effective_law", "is_nonlinear", "law_text", "arm_law_text", "arms_law_text",
           "values_text", "designs_law_text", "LAW_SYMBOLS"]

#: how a law parameter is named in the text (its config key otherwise)
LAW_SYMBOLS = {"stiffening": "beta"}


def effective_law(cfg) -> tuple:
    """(name, {parameter key: (n,) values}) of the law the compliant arm runs.

    A law that is linear at its parameters (the exponential law with every beta 0) is
    solved as the linear law exactly, and named so.
    """
    from ..physics.laws import TISSUE_LAWS

    cls = getattr(cfg, "tissue_law_class", None) or TISSUE_LAWS.get(cfg.tissue_law)
    if cls is None:
        return str(cfg.tissue_law), dict(cfg.tissue_law_parameters)
    if cls.is_linear:
        return "linear", {}
    try:
        law = cls(np.ones(cfg.n_elements), **cfg.tissue_law_parameters)
    except Exception:         # the model build reports a bad parameter itself
        return cls.name or str(cfg.tissue_law), dict(cfg.tissue_law_parameters)
    if law.linear_here():
        return "linear", {}
    return cls.name or str(cfg.tissue_law), dict(law.params)


def is_nonlinear(cfg) -> bool:
    """Whether the config's tissue law is not the linear one (at its parameters)."""
    return effective_law(cfg)[0] != "linear"


def values_text(values, unit: str) -> str:
    """``150 1/m`` for one value, ``100-200 1/m over the elements, mean 150`` for a spread."""
    v = np.asarray(values, dtype=float).ravel()
    if v.size == 0:
        return f"- {unit}"
    lo, hi = float(np.min(v)), float(np.max(v))
    if lo == hi:
        return f"{lo:.4g} {unit}"
    return f"{lo:.4g}-{hi:.4g} {unit} over the elements, mean {float(np.mean(v)):.4g}"


def law_text(cfg) -> str:
    """``exponential tissue law (beta 150 1/m)`` (the parameters with their units), or
    ``linear tissue law``."""
    from ..physics.laws import TISSUE_LAWS

    name, params = effective_law(cfg)
    units = {p.key: p.unit for p in getattr(TISSUE_LAWS.get(name), "parameters", ())}
    values = [f"{LAW_SYMBOLS.get(k, k)} {values_text(v, units.get(k, ''))}".rstrip()
              for k, v in params.items()]
    return f"{name} tissue law" + (f" ({'; '.join(values)})" if values else "")


def _law_keys(cfg) -> list:
    """The config keys that make the law nonlinear (``tissue.stiffening``), or ``tissue.law``."""
    keys = [f"tissue.{k}" for k in cfg.tissue_law_parameters]
    return keys or ["tissue.law"]


def arm_law_text(cfg, arm: str) -> str:
    """What the tissue of an arm is: its registered ``tissue_text``
    (:class:`~phri_spring.plugins.ArmModel`; ``no tissue (cuff springs only)`` for the rigid
    arm, :func:`continuum_law_text` for the coupled arm), else the config's law
    (:func:`law_text`)."""
    text = arm_record(arm).tissue_text
    return law_text(cfg) if text is None else text(cfg)


def continuum_law_text(cfg) -> str:
    """``linear continuum`` (or ``neo-Hookean continuum``, ``Ogden continuum``:
    ``tissue.continuum.law``), with the note that the tissue law's parameters are not used by
    it, when the config gives a nonlinear law: the coupled arm's tissue."""
    notes = []
    law = getattr(cfg, "continuum_law", "linear")
    alpha = getattr(cfg, "continuum_ogden_alpha", None)
    stiffening_used = law == "ogden" and alpha is None     # alpha from the indenter curve
    if law == "neo_hookean":
        name = "neo-Hookean continuum"
        notes.append("reduced model, rigid bonded cuff")
    elif law == "ogden":
        name = "Ogden continuum"
        notes.append(f"alpha {alpha:g}" if alpha is not None else
                     "alpha identified from tissue.stiffening by the indenter FE")
        notes.append("reduced model, rigid bonded cuff")
    else:
        name = "linear continuum"
    if is_nonlinear(cfg) and not stiffening_used:
        keys = _law_keys(cfg)
        verb = "is" if len(keys) == 1 else "are"
        notes.append(f"{' and '.join(keys)} {verb} used by the compliant arm only")
    return name + (f" ({'; '.join(notes)})" if notes else "")


def arms_law_text(cfg, arms: Sequence[str]) -> str:
    """``compliant arm: exponential tissue law (beta 150 1/m); coupled arm: linear continuum
    (...)`` for the arms that have tissue (the rigid arm's text when it is the only one)."""
    shown = [a for a in arms if arm_record(a).has_tissue] or list(arms)
    return "; ".join(f"{a} arm: {arm_law_text(cfg, a)}" for a in shown)


def designs_law_text(configs, arm: str) -> str:
    """:func:`arm_law_text` of a study's designs: the one text when every design has it, else
    the laws and the range of each law parameter over the designs (a study that varies
    ``tissue.stiffening``: ``linear/exponential tissue law, varied by the study (beta
    0-400 1/m over the designs)``)."""
    from ..physics.laws import TISSUE_LAWS

    configs = list(configs)
    texts = list(dict.fromkeys(arm_law_text(c, arm) for c in configs))
    if len(texts) <= 1:
        return texts[0] if texts else ""
    if arm_record(arm).tissue_text is not None:
        # the arm's own tissue (the coupled continuum): the note wins, some design gives a
        # law that tissue ignores
        return next((t for t in texts if "(" in t), texts[0])
    names = list(dict.fromkeys(effective_law(c)[0] for c in configs))
    units = {p.key: p.unit for c in configs for p in
             getattr(c.tissue_law_class or TISSUE_LAWS.get(c.tissue_law), "parameters", ())}
    spans = []
    for key in dict.fromkeys(k for c in configs for k in c.tissue_law_parameters):
        v = np.concatenate([np.ravel(c.tissue_law_parameters[key]) for c in configs
                            if key in c.tissue_law_parameters])
        lo, hi = float(v.min()), float(v.max())
        span = f"{lo:.4g}" if lo == hi else f"{lo:.4g}-{hi:.4g}"
        spans.append(f"{LAW_SYMBOLS.get(key, key)} {span} {units.get(key, '')}".rstrip())
    return (f"{'/'.join(names)} tissue law, varied by the study"
            + (f" ({'; '.join(spans)} over the designs)" if spans else ""))
