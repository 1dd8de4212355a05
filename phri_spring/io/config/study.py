"""The YAML study file of ``phri design``: what to vary, how to sample it, what to minimise.

A study names a base config, a load set (one or more wrench logs), the
parameters to vary by their dotted config paths, a sampling plan and the
objectives. Loading is safe (the config's YAML loader: no code, no duplicate
keys), unknown keys are rejected with the closest valid name, and paths are
resolved against the study file's folder. Errors are :class:`ConfigError`
naming the study file and the key path (``vary.strap.tension.range``).

Objective names are checked against the objectives table,
:data:`phri_spring.objectives.OBJECTIVE_TABLE` (:data:`OBJECTIVES` is its names).
Otherwise this module only checks the study's own shape; whether a parameter
path exists in the config, and whether each design's values are valid there,
is checked by :mod:`phri_spring.workflows.design.plan` against the config
schema itself.
"""

from __future__ import annotations

import difflib
import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional, Union

from pydantic import BaseModel, ConfigDict, Field, ValidationError

from ...errors import ConfigError
from ...objectives import OBJECTIVES
from . import load_yaml
from .schema_errors import config_error_from

__all__ = ["Study", "Parameter", "Constraint", "UncertaintySpec", "load_study", "study_from_dict",
           "OBJECTIVES", "parse_path"]

_PLAN = re.compile(r"^(grid|lhs:(\d+)|sobol:(\d+))$")
_CONSTRAINT = re.compile(r"^\s*(<=|>=|<|>)\s*([-+0-9.eE]+|[-+]?inf)\s*$")
_PATH_TOKEN = re.compile(r"^([A-Za-z_][A-Za-z0-9_]*)((?:\[\d+\])*)$")


# --------------------------------------------------------------------------- schema
class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", strict=False)


class _Vary(_Strict):
    values: Optional[list[float]] = None
    scale: Optional[list[float]] = None
    range: Optional[tuple[float, float]] = None
    log: bool = False
    count: int = Field(default=5, ge=1, le=100000)


class _MergeTolerance(_Strict):
    force_N: float = Field(default=0.0, ge=0, allow_inf_nan=False)
    moment_Nm: float = Field(default=0.0, ge=0, allow_inf_nan=False)


class _Uncertainty(_Strict):
    draws: int = Field(default=200, ge=2, le=10_000_000)
    seed: int = 0
    strap_tension_sd_N: float = Field(default=0.0, ge=0, allow_inf_nan=False)
    tissue_stiffness_sd: Union[float, str] = "from_csv"
    stiffening_sd: Union[float, str] = "from_csv"
    loadcell_force_sd_N: float = Field(default=0.0, ge=0, allow_inf_nan=False)
    loadcell_moment_sd_Nm: float = Field(default=0.0, ge=0, allow_inf_nan=False)
    sobol: int = Field(default=0, ge=0, le=1_000_000)


class _Root(_Strict):
    name: str = ""
    config: str
    loads: Union[str, list[str]]
    arm: str = "compliant"
    vary: dict[str, _Vary]
    plan: str = "grid"
    seed: int = 0
    minimise: list[str] = Field(default_factory=list)
    maximise: list[str] = Field(default_factory=list)
    constraints: dict[str, str] = Field(default_factory=dict)
    best: Optional[str] = None
    batch_size: int = Field(default=0, ge=0, le=1_000_000)
    merge_tolerance: Optional[_MergeTolerance] = None
    uncertainty: Optional[_Uncertainty] = None


def _fields_at(loc) -> list[str]:
    cls = _Root
    for part in loc:
        if part in getattr(cls, "model_fields", {}):
            ann = cls.model_fields[part].annotation
            inner = [a for a in getattr(ann, "__args__", (ann,)) if isinstance(a, type)
                     and issubclass(a, BaseModel)]
            if inner:
                cls = inner[0]
                continue
            if part == "vary":
                cls = _Vary
                continue
            return []
        elif cls is _Vary:
            continue
        else:
            return []
    return list(getattr(cls, "model_fields", {}))


def _error(exc: ValidationError, path) -> ConfigError:
    return config_error_from(exc, path, _fields_at)


# --------------------------------------------------------------------------- result
@dataclass(frozen=True)
class Parameter:
    """One varied config value.

    Attributes
    ----------
    path : str
        Dotted config path, e.g. ``strap.tension`` or ``cuff.stiffness.per_angle[5]``.
    kind : {'values', 'scale', 'range'}
        ``values``: the listed values replace the config's; ``scale``: the
        config's value (a number or every number of a list) is multiplied by the
        listed factors; ``range``: values in [low, high], linear or ``log``.
    levels : tuple of float
        The listed values or factors (``values``, ``scale``).
    low, high : float
        Bounds of a ``range``.
    log : bool
        Sample a ``range`` uniformly in log space.
    count : int
        Levels of a ``range`` in a grid plan.
    """

    path: str
    kind: str
    levels: tuple = ()
    low: float = math.nan
    high: float = math.nan
    log: bool = False
    count: int = 5


@dataclass(frozen=True)
class Constraint:
    """``objective op bound``, e.g. stiffness_translational_N_per_mm >= 2."""

    objective: str
    op: str
    bound: float

    def holds(self, value: float) -> bool:
        if not math.isfinite(value):
            return False
        return {"<=": value <= self.bound, ">=": value >= self.bound,
                "<": value < self.bound, ">": value > self.bound}[self.op]

    def __str__(self):
        return f"{self.objective} {self.op} {self.bound:g}"


@dataclass(frozen=True)
class UncertaintySpec:
    """The ``uncertainty:`` section (Monte Carlo and Sobol indices at the best design)."""

    draws: int = 200
    seed: int = 0
    strap_tension_sd_N: float = 0.0
    tissue_stiffness_sd: Union[float, str] = "from_csv"   # relative SD, or from the CSV
    loadcell_force_sd_N: float = 0.0
    loadcell_moment_sd_Nm: float = 0.0
    sobol: int = 0
    #: the exponential law's stiffening rate: relative SD, or ``from_csv`` (the
    #: ``stiffening_std_per_m`` column of the CSV ``tissue.stiffening`` names; numbers in
    #: the config: beta held fixed)
    stiffening_sd: Union[float, str] = "from_csv"


@dataclass
class Study:
    """A validated study; paths are absolute or relative to the current folder."""

    path: Optional[Path]
    name: str
    config: Path
    loads: tuple
    arm: str
    parameters: tuple
    plan: str                      # 'grid', 'lhs' or 'sobol'
    n_samples: int                 # designs of an lhs/sobol plan (0 for grid)
    seed: int
    objectives: tuple              # names, in the study's order
    senses: tuple                  # +1 minimise, -1 maximise
    constraints: tuple
    best: str
    batch_size: int
    merge_force_N: float = 0.0
    merge_moment_Nm: float = 0.0
    uncertainty: Optional[UncertaintySpec] = None
    raw: dict = field(default_factory=dict, repr=False)


def parse_path(text: str, *, file=None, key=None) -> tuple:
    """Split a dotted config path into keys and list indices.

    ``cuff.stiffness.per_angle[5]`` -> ``('cuff', 'stiffness', 'per_angle', 5)``.
    """
    parts: list = []
    for token in str(text).split("."):
        m = _PATH_TOKEN.match(token)
        if m is None:
            raise ConfigError(f"expected a dotted config path such as strap.tension or "
                              f"cuff.stiffness.per_angle[5], got {text!r}", file=file,
                              key=key or f"vary.{text}")
        parts.append(m.group(1))
        parts.extend(int(i) for i in re.findall(r"\[(\d+)\]", m.group(2)))
    return tuple(parts)


def _objective(name: str, path, key: str) -> str:
    if name not in OBJECTIVES:
        close = difflib.get_close_matches(name, OBJECTIVES, n=1, cutoff=0.5)
        hint = f"; did you mean {close[0]!r}?" if close else ""
        raise ConfigError(f"unknown objective {name!r}{hint} (expected one of "
                          f"{', '.join(OBJECTIVES)})", file=path, key=key)
    return name


def study_from_dict(data, *, path=None, base_dir=None) -> Study:
    """Validate a parsed study mapping into a :class:`Study`.

    Raises
    ------
    ConfigError
        One line naming the study file, the key and what was expected.
    """
    if not isinstance(data, dict):
        raise ConfigError("expected a mapping at the top level (config, loads, vary, plan, "
                          f"minimise, ...), got {type(data).__name__}", file=path)
    try:
        root = _Root.model_validate(data)
    except ValidationError as exc:
        raise _error(exc, path) from None
    base = Path(base_dir) if base_dir is not None else (Path(path).parent if path else Path("."))

    def rel(p: str) -> Path:
        return Path(p) if Path(p).is_absolute() else base / p

    loads = [root.loads] if isinstance(root.loads, str) else list(root.loads)
    if not loads:
        raise ConfigError("expected at least one wrench log (an empty load set has nothing to "
                          "design for)", file=path, key="loads")

    if not root.vary:
        raise ConfigError("expected at least one parameter to vary, e.g. "
                          "{strap.tension: {values: [10, 20]}}", file=path, key="vary")
    params = []
    for p, spec in root.vary.items():
        key = f"vary.{p}"
        parse_path(p, file=path, key=key)
        given = [k for k in ("values", "scale", "range") if getattr(spec, k) is not None]
        if len(given) != 1:
            raise ConfigError("expected exactly one of values, scale or range", file=path,
                              key=key)
        kind = given[0]
        if kind == "range":
            lo, hi = spec.range
            if not (math.isfinite(lo) and math.isfinite(hi) and hi > lo):
                raise ConfigError(f"expected finite [low, high] with low < high, got "
                                  f"{list(spec.range)}", file=path, key=f"{key}.range")
            if spec.log and not lo > 0:
                raise ConfigError(f"a log range needs low > 0, got {lo!r}", file=path,
                                  key=f"{key}.range")
            params.append(Parameter(p, "range", low=float(lo), high=float(hi), log=spec.log,
                                    count=spec.count))
        else:
            levels = getattr(spec, kind)
            if not levels:
                raise ConfigError("expected at least one value", file=path, key=f"{key}.{kind}")
            bad = [v for v in levels if not math.isfinite(v)]
            if bad:
                raise ConfigError(f"expected finite numbers, got {bad[0]!r}", file=path,
                                  key=f"{key}.{kind}")
            params.append(Parameter(p, kind, levels=tuple(float(v) for v in levels)))

    m = _PLAN.match(root.plan.strip())
    if m is None:
        raise ConfigError(f"expected grid, lhs:N or sobol:N, got {root.plan!r}", file=path,
                          key="plan")
    plan = m.group(1).split(":")[0]
    n_samples = int(m.group(2) or m.group(3) or 0)
    if plan != "grid" and n_samples < 1:
        raise ConfigError(f"expected at least one design, got {root.plan!r}", file=path,
                          key="plan")

    objectives, senses = [], []
    for i, name in enumerate(root.minimise):
        sense = 1
        if name.startswith("-"):
            name, sense = name[1:].strip(), -1
        objectives.append(_objective(name, path, f"minimise[{i}]"))
        senses.append(sense)
    for i, name in enumerate(root.maximise):
        objectives.append(_objective(name, path, f"maximise[{i}]"))
        senses.append(-1)
    if not objectives:
        raise ConfigError("expected at least one objective in minimise (or maximise), e.g. "
                          "[peak_pressure_to_pain_threshold, lift_off_fraction]", file=path,
                          key="minimise")
    if len(set(objectives)) != len(objectives):
        dup = next(o for o in objectives if objectives.count(o) > 1)
        raise ConfigError(f"objective {dup!r} is listed twice", file=path, key="minimise")

    constraints = []
    for name, text in root.constraints.items():
        _objective(name, path, f"constraints.{name}")
        cm = _CONSTRAINT.match(str(text))
        if cm is None:
            raise ConfigError(f"expected a bound such as '>= 2' or '< 1.5', got {text!r}",
                              file=path, key=f"constraints.{name}")
        constraints.append(Constraint(name, cm.group(1), float(cm.group(2))))

    best = objectives[0] if root.best is None else root.best
    if best not in objectives:
        raise ConfigError(f"expected one of the study's objectives ({', '.join(objectives)}), "
                          f"got {best!r}", file=path, key="best")

    unc = None
    if root.uncertainty is not None:
        u = root.uncertainty
        for name in ("tissue_stiffness_sd", "stiffening_sd"):
            sd = getattr(u, name)
            if isinstance(sd, str) and sd != "from_csv":
                raise ConfigError(f"expected 'from_csv' or a relative SD such as 0.06, got "
                                  f"{sd!r}", file=path, key=f"uncertainty.{name}")
            if isinstance(sd, float) and not (math.isfinite(sd) and sd >= 0):
                raise ConfigError(f"expected a relative SD >= 0, got {sd!r}", file=path,
                                  key=f"uncertainty.{name}")
        unc = UncertaintySpec(u.draws, u.seed, u.strap_tension_sd_N, u.tissue_stiffness_sd,
                              u.loadcell_force_sd_N, u.loadcell_moment_sd_Nm, u.sobol,
                              u.stiffening_sd)

    mt = root.merge_tolerance
    return Study(path=Path(path) if path else None, name=root.name, config=rel(root.config),
                 loads=tuple(rel(p) for p in loads), arm=root.arm, parameters=tuple(params),
                 plan=plan, n_samples=n_samples, seed=root.seed, objectives=tuple(objectives),
                 senses=tuple(senses), constraints=tuple(constraints), best=best,
                 batch_size=root.batch_size,
                 merge_force_N=0.0 if mt is None else mt.force_N,
                 merge_moment_Nm=0.0 if mt is None else mt.moment_Nm,
                 uncertainty=unc, raw=data)


def load_study(path) -> Study:
    """Load and validate a study YAML file (paths inside are relative to its folder)."""
    path = Path(path)
    data = load_yaml(path)
    return study_from_dict(data, path=path, base_dir=path.parent)
