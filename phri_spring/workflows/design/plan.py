"""The plan of ``phri design``: the parameter values of every design, and their configs.

:func:`design_values` samples the study's plan (a grid, a Latin hypercube or a
scrambled Sobol sequence); :func:`design_mapping` puts one design's values into
the base config mapping (:mod:`phri_spring.workflows.config_paths`); and
:func:`build_designs` validates every design with the config schema itself,
before anything is computed or written. :func:`config_with` does the same for one
config in a script (``phri_spring.config_with``).
"""

from __future__ import annotations

import copy
import difflib
import itertools
import math
import warnings
from pathlib import Path

import numpy as np

from ...errors import ConfigError, DataError
from ...io.config import Config, config_from_dict
from ...io.config.study import Study
from ..common import ARM_MODELS, model_from_config
from ..config_paths import check_parameter, set_parameter, walk_path

__all__ = ["design_values", "design_mapping", "build_designs", "config_with"]


def design_values(study: Study) -> np.ndarray:
    """The parameter values of every design, shape (designs, parameters).

    ``grid``: every combination (the first parameter varies slowest); a ``range``
    gives ``count`` levels, evenly spaced (in log space with ``log``). ``lhs:N``
    and ``sobol:N``: N points of scipy.stats.qmc's LatinHypercube or scrambled
    Sobol sequence with the study's seed; a ``values``/``scale`` list is
    sampled as a discrete choice among its levels. Factors of ``scale`` are
    reported as such.
    """
    params = study.parameters
    if study.plan == "grid":
        levels = []
        for p in params:
            if p.kind == "range":
                if p.log:
                    lv = np.logspace(math.log10(p.low), math.log10(p.high), p.count)
                else:
                    lv = np.linspace(p.low, p.high, p.count)
                lv[0], lv[-1] = p.low, (p.high if p.count > 1 else p.low)
                levels.append(lv)
            else:
                levels.append(np.array(p.levels))
        return np.array(list(itertools.product(*levels)), dtype=float).reshape(-1, len(params))
    from scipy.stats import qmc

    d = len(params)
    cls = qmc.LatinHypercube if study.plan == "lhs" else qmc.Sobol
    kw = {} if study.plan == "lhs" else {"scramble": True}
    try:
        sampler = cls(d, rng=np.random.default_rng(study.seed), **kw)
    except TypeError:  # scipy < 1.15
        sampler = cls(d, seed=np.random.default_rng(study.seed), **kw)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # Sobol's balance warning for N not a power of 2
        u = sampler.random(study.n_samples)
    out = np.empty_like(u)
    for j, p in enumerate(params):
        if p.kind == "range":
            if p.log:
                a, b = math.log(p.low), math.log(p.high)
                out[:, j] = np.exp(a + u[:, j] * (b - a))
            else:
                out[:, j] = p.low + u[:, j] * (p.high - p.low)
        else:
            lv = np.array(p.levels)
            out[:, j] = lv[np.minimum((u[:, j] * len(lv)).astype(int), len(lv) - 1)]
    return out


def design_mapping(base_raw: dict, study: Study, values) -> dict:
    """The base config mapping with one design's values put at their paths."""
    raw = copy.deepcopy(base_raw)
    for p, v in zip(study.parameters, values):
        set_parameter(raw, p, float(v), study.path)
    return raw


def build_designs(study: Study, base: Config) -> tuple:
    """Validate every design; returns (values (d, p), [Config, ...]).

    Raises
    ------
    ConfigError
        Naming the parameter path (a missing or non-numeric key) or, for a value
        the config schema rejects, the design, its values and the config key.
    """
    if study.arm not in ARM_MODELS:
        close = difflib.get_close_matches(study.arm, ARM_MODELS, n=1, cutoff=0.5)
        hint = f"; did you mean {close[0]!r}?" if close else ""
        raise ConfigError(f"unknown arm model {study.arm!r}{hint} (expected one of "
                          f"{', '.join(ARM_MODELS)})", file=study.path, key="arm")
    for p in study.parameters:
        if base.scan is not None and p.path.split("[")[0].split(".")[:2] in (
                ["geometry", "radius"], ["geometry", "section"], ["geometry", "taper_deg"],
                ["geometry", "scan"]):
            raise ConfigError("the config's limb is a scan (geometry.scan): its shape, size and "
                              "taper come from the scan's surface, so a study cannot vary "
                              f"{p.path}; vary the rows, widths, angles or the cuff instead",
                              file=study.path, key=f"vary.{p.path}")
        check_parameter(base.raw, p, study.path)
    values = design_values(study)
    if len(values) == 0:
        raise ConfigError("the plan gives no design", file=study.path, key="plan")
    cfg_dir = base.path.parent if base.path is not None else Path(".")
    configs = []
    for i, row in enumerate(values):
        raw = design_mapping(base.raw, study, row)
        try:
            cfg = config_from_dict(raw, path=base.path, base_dir=cfg_dir)
            model_from_config(cfg, study.arm)
        except DataError as exc:    # a ConfigError, or a scan the design's rows miss
            what = ", ".join(f"{p.path}={'x' if p.kind == 'scale' else ''}{v:g}"
                             for p, v in zip(study.parameters, row))
            own = isinstance(exc, ConfigError)
            raise type(exc)(f"design {i} ({what}) is not a valid config: "
                            f"{exc.message if own else exc}", file=study.path,
                            key=exc.key if own else None) from None
        configs.append(cfg)
    return values, configs


def config_with(config, values: dict) -> Config:
    """A config with values put at dotted config paths, validated as its YAML file would be.

    Parameters
    ----------
    config : Config or path
        The base config (its YAML mapping is copied; paths in it stay relative to its file).
    values : dict
        Dotted path (``tissue.stiffening``, ``strap.tension``,
        ``cuff.stiffness.per_angle[5]``) -> value (a number, list or mapping, any value
        the config accepts there; a path of a CSV relative to the config's folder).

    Raises
    ------
    ConfigError
        A path that cannot hold a value, or a value the config rejects (one line).

    Examples
    --------
    The exponential tissue law (``tissue.stiffening`` [1/m]) on the bundled config:

    >>> cfg = config_with("configs/harmony_upper_arm.yaml", {"tissue.stiffening": 150.0})
    >>> cfg.tissue_law, float(cfg.tissue_law_parameters["stiffening"][0])
    ('exponential', 150.0)
    """
    from ...io.config import load_config
    from ...io.config.study import parse_path

    base = config if isinstance(config, Config) else load_config(config)
    raw = copy.deepcopy(base.raw)
    for path, value in values.items():
        try:
            node, last = walk_path(raw, parse_path(path), path, base.path, create=True)
        except ConfigError as exc:      # named by the path given, not as a study's vary key
            raise ConfigError(exc.message, file=base.path, key=path) from None
        if isinstance(last, int) and not (isinstance(node, list) and last < len(node)):
            raise ConfigError(f"index [{last}] is out of range", file=base.path, key=path)
        if not isinstance(last, int) and not isinstance(node, dict):
            raise ConfigError(f"the parent of {last!r} is not a mapping", file=base.path,
                              key=path)
        node[last] = copy.deepcopy(value)
    cfg_dir = base.path.parent if base.path is not None else Path(".")
    return config_from_dict(raw, path=base.path, base_dir=cfg_dir)
