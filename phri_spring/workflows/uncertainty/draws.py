"""The uncertain inputs of a config, their Monte Carlo draws, and what scatters for each arm.

Uncertain inputs (independent Gaussians):

- the tissue stiffness of every location: mean = the config's value, SD from
  the ``std_N_per_m`` column of the ``phri fit-stiffness`` CSV the config's
  ``tissue.stiffness`` names (``from_csv``), or a relative SD of the config's
  values (e.g. 0.06 for the paper's 6 % scatter of the indenter stiffness);
- the stiffening rate beta of the exponential tissue law (``tissue.stiffening``) of every
  location: mean = the config's value, SD from the ``stiffening_std_per_m`` column of the
  ``phri fit-stiffness`` CSV the config's ``tissue.stiffening`` names (``from_csv``, the
  default), or a relative SD of the config's values; otherwise (numbers in the config,
  no SD given) beta is held fixed, and every output says so. Draws below 0 are taken as
  0 (the linear law: beta >= 0). The tissue stiffness SD perturbs k0 only;
- the strap tension: mean = ``strap.tension``, SD in N (set by hand);
- load-cell noise: white Gaussian noise added to every sample and channel of
  the log, SD in N (forces) and N*m (moments), in the log's units.

Each arm takes from the tissue scatter what its model uses (:func:`tissue_route`):

- ``compliant``: every location's tissue stiffness (its tissue spring), and its
  stiffening rate with the exponential law;
- ``rigid``: nothing (cuff springs only; nor the stiffening): its spread comes from the strap
  tension and the load-cell noise alone, and is exactly 0 without them;
- ``coupled`` with ``tissue.continuum.young_modulus``: that one modulus E, drawn
  as one value with the tissue's relative SD (a number: that fraction; ``from_csv``:
  the root mean square of the CSV's SD / stiffness over the locations). The
  condensed FE stiffness is linear in E, so a draw reloads the cached E = 1 matrices
  (``io/surface_stiffness.py``) and scales them: the FE is built once;
- ``coupled`` with E converted from the indenter map: the per-location stiffness
  draws, through E (proportional to the indenter stiffness): their mean (``spread:
  mean``) or each patch's own (``spread: per_patch``);
- ``coupled`` with a user's ``surface_stiffness`` export: nothing (the export has
  no modulus to scatter), unless ``spread: per_patch`` with E from the indenter map.
  The continuum is linear: the stiffening rate does not reach the coupled arm.

The layer's thickness does not scatter: the FE matrices depend on it, so every
draw would rebuild the FE (10-20 s each).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Optional, Union

import numpy as np

from ...errors import DataError, UsageError
from ...io.config import Config
from ...physics.hyperelastic.laws import CONTINUUM_LAW_MODELS
from ...plugins import arm_record

__all__ = ["UncertainInputs", "uncertain_inputs", "parse_sd", "draw_configs", "tissue_route",
           "modulus_sd", "perturbed_inputs", "perturbed_text", "reaches_model",
           "sobol_inputs", "config_at", "check_fe_cache", "PERCENTILES", "stiffening_csv",
           "stiffening_route", "STIFFENING"]

#: the exponential law's stiffening rate: its key under ``tissue.`` and in
#: ``Config.tissue_law_parameters`` [1/m]
STIFFENING = "stiffening"

#: percentiles over the draws that every Monte Carlo reports (simulate, compare bands,
#: a study's best design) [%]
PERCENTILES = (5.0, 50.0, 95.0)


@dataclass(frozen=True)
class UncertainInputs:
    """SDs of the uncertain inputs of one config.

    Attributes
    ----------
    tissue_sd : ndarray, shape (n,)
        SD of each location's tissue stiffness [N/m], in the config's basis.
    tension_sd_N : float
    force_sd_N : float
        Load-cell force noise SD [log force unit].
    moment_sd_Nm : float
        Load-cell moment noise SD [log moment unit].
    stiffening_sd : ndarray, shape (n,), optional
        SD of each location's stiffening rate beta [1/m] (exponential law); None or zeros:
        beta is held fixed.
    """

    tissue_sd: np.ndarray
    tension_sd_N: float = 0.0
    force_sd_N: float = 0.0
    moment_sd_Nm: float = 0.0
    stiffening_sd: Optional[np.ndarray] = None

    @property
    def beta_sd(self) -> np.ndarray:
        """:attr:`stiffening_sd` as an array (zeros when None) [1/m]."""
        sd = self.stiffening_sd
        return np.zeros(len(self.tissue_sd)) if sd is None else np.asarray(sd, dtype=float)

    @property
    def noise_sd(self) -> np.ndarray:
        return np.array([self.force_sd_N] * 3 + [self.moment_sd_Nm] * 3)


def _csv_std(cfg: Config, csv_path=None, column: str = "std_N_per_m") -> Optional[np.ndarray]:
    """Each location's SD from a ``phri fit-stiffness`` CSV's ``column`` (None: no CSV;
    for the stiffening column also None when the CSV lacks it)."""
    import pandas as pd

    path = Path(csv_path) if csv_path is not None else cfg.tissue_stiffness_csv
    if path is None:
        return None
    df = pd.read_csv(path, comment="#")
    if column not in df.columns:
        if column != "std_N_per_m":
            return None      # beta held fixed (the outputs say so)
        raise DataError("missing column 'std_N_per_m'; expected a CSV written by 'phri "
                        "fit-stiffness' (or give the SD as a fraction)", file=path,
                        key="std_N_per_m")
    sd = pd.to_numeric(df[column], errors="coerce").astype(float)
    sd = dict(zip(df["location"].astype(str).str.strip(), sd))
    out = np.array([sd.get(lab, np.nan) for lab in cfg.labels], dtype=float)
    bad = ~np.isfinite(out) | (out < 0)
    return np.where(bad, 0.0, out)   # one trial only: no SD written, no scatter assumed


def stiffening_csv(cfg: Config) -> Optional[Path]:
    """The CSV the config's ``tissue.stiffening`` names (None: numbers, or no stiffening)."""
    tissue = cfg.raw.get("tissue") if isinstance(cfg.raw, dict) else None
    v = tissue.get(STIFFENING) if isinstance(tissue, dict) else None
    if not isinstance(v, str):
        return None
    given = Path(v)
    if given.is_absolute():
        return given
    for f in cfg.stiffness_files:       # resolved against the config's folder when loaded
        parts = Path(f).parts
        if parts[len(parts) - len(given.parts):] == given.parts:
            return Path(f)
    return (cfg.path.parent if cfg.path is not None else Path(".")) / given


def _stiffening_sd(cfg: Config, stiffening_sd, stiffening_csv_path=None) -> np.ndarray:
    """SD [1/m] of each location's stiffening rate (zeros where beta is held fixed)."""
    n = cfg.n_elements
    beta = cfg.tissue_law_parameters.get(STIFFENING)
    if beta is None:
        return np.zeros(n)
    if isinstance(stiffening_sd, str):
        path = stiffening_csv_path or stiffening_csv(cfg)
        from ..fit.stiffness import STIFFENING_COLUMNS

        sd = None if path is None else _csv_std(cfg, path, STIFFENING_COLUMNS[1])
        return np.zeros(n) if sd is None else sd
    if not (math.isfinite(stiffening_sd) and stiffening_sd >= 0):
        raise UsageError(f"expected a relative SD >= 0, got {stiffening_sd!r}",
                         key="stiffening SD")
    return float(stiffening_sd) * np.broadcast_to(np.asarray(beta, dtype=float), (n,))


def uncertain_inputs(cfg: Config, *, tissue_sd: Union[str, float] = "from_csv",
                     tension_sd_N: float = 0.0, force_sd_N: float = 0.0,
                     moment_sd_Nm: float = 0.0, tissue_csv=None,
                     stiffening_sd: Union[str, float] = "from_csv",
                     stiffening_csv_path=None) -> UncertainInputs:
    """The SDs of a config's uncertain inputs.

    Parameters
    ----------
    tissue_sd : 'from_csv' or float
        ``from_csv``: the ``std_N_per_m`` column of the config's stiffness CSV
        (zero when the config gives numbers, or a location has no SD); a float:
        that fraction of each location's stiffness (k0 with a nonlinear law).
    stiffening_sd : 'from_csv' or float
        The exponential law's stiffening rate beta: ``from_csv``: the
        ``stiffening_std_per_m`` column of the CSV ``tissue.stiffening`` names (zero
        when the config gives numbers, the CSV has no such column, or a location has
        no SD: beta held fixed); a float: that fraction of each location's beta.
        Ignored with the linear law.
    """
    for name, v in (("strap tension SD", tension_sd_N), ("load-cell force SD", force_sd_N),
                    ("load-cell moment SD", moment_sd_Nm)):
        if not (math.isfinite(v) and v >= 0):
            raise UsageError(f"expected a finite value >= 0, got {v!r}", key=name)
    if isinstance(tissue_sd, str):
        sd = _csv_std(cfg, tissue_csv)
        sd = np.zeros(cfg.n_elements) if sd is None else sd
    else:
        if not (math.isfinite(tissue_sd) and tissue_sd >= 0):
            raise UsageError(f"expected a relative SD >= 0, got {tissue_sd!r}",
                             key="tissue stiffness SD")
        sd = float(tissue_sd) * np.asarray(cfg.tissue_stiffness, dtype=float)
    return UncertainInputs(sd, float(tension_sd_N), float(force_sd_N), float(moment_sd_Nm),
                           _stiffening_sd(cfg, stiffening_sd, stiffening_csv_path))


def parse_sd(text: Optional[str]) -> dict:
    """Parse ``tissue=from_csv,stiffening=0.1,tension=0.1,force=0.3,moment=0.01`` (any subset).

    ``tissue`` is ``from_csv`` or a fraction of the stiffness (k0); ``stiffening``
    ``from_csv`` (the default) or a fraction of the exponential law's stiffening rate
    (a ``stiffening_sd`` key only when given); ``tension`` [N], ``force`` [log force
    unit] and ``moment`` [log moment unit] are SDs.
    """
    out = {"tissue_sd": "from_csv", "tension_sd_N": 0.0, "force_sd_N": 0.0, "moment_sd_Nm": 0.0}
    names = {"tissue": "tissue_sd", "stiffening": "stiffening_sd", "tension": "tension_sd_N",
             "force": "force_sd_N", "moment": "moment_sd_Nm"}
    if not text:
        return out
    for item in str(text).split(","):
        key, sep, val = item.partition("=")
        key = key.strip()
        if not sep or key not in names:
            raise UsageError(f"expected NAME=SD items with NAME among {', '.join(names)}, "
                             f"got {item.strip()!r}", key="--uncertainty-sd")
        if key in ("tissue", "stiffening") and val.strip() == "from_csv":
            out[names[key]] = "from_csv"
            continue
        try:
            v = float(val)
        except ValueError:
            v = math.nan
        if not (math.isfinite(v) and v >= 0):
            raise UsageError(f"{key}: expected a number >= 0, got {val.strip()!r}",
                             key="--uncertainty-sd")
        out[names[key]] = v
    return out


# --------------------------------------------------------------------------- what each arm uses
def tissue_route(cfg: Config, arm: str) -> str:
    """How the tissue-stiffness scatter reaches an arm's model (see the module docstring).

    ``'stiffness'`` (the per-location stiffness draws), ``'modulus'`` (the continuum's
    one Young's modulus) or ``'none'``.
    """
    route = arm_record(arm).uncertainty.tissue_route
    return "stiffness" if route is None else route(cfg)


def stiffening_route(cfg: Config, arm: str) -> bool:
    """Whether the arm's model runs the config's stiffening rate (its declared
    ``uncertainty.stiffening``: the compliant arm with the exponential law; the rigid arm has
    no tissue, the coupled arm's continuum is linear)."""
    return arm_record(arm).uncertainty.stiffening and STIFFENING in cfg.tissue_law_parameters


def modulus_sd(cfg: Config, inputs: UncertainInputs) -> float:
    """Relative SD [-] of ``tissue.continuum.young_modulus`` (0 when the config has none).

    The tissue's relative SD: exactly the fraction given as a number; for SDs
    from a CSV, the root mean square over the locations of SD / stiffness (the
    typical relative scatter of one location's measurement).
    """
    if cfg.continuum_young_modulus is None:
        return 0.0
    k = np.asarray(cfg.tissue_stiffness, dtype=float)
    sd = np.broadcast_to(np.asarray(inputs.tissue_sd, dtype=float), k.shape)
    if not sd.any():
        return 0.0
    return float(np.sqrt(np.mean((sd / k) ** 2)))


def reaches_model(cfg: Config, inputs: UncertainInputs, arm: str) -> bool:
    """Whether a scattered input changes the arm's model (not counting load-cell noise)."""
    route = tissue_route(cfg, arm)
    return bool(inputs.tension_sd_N > 0
                or (route == "stiffness" and np.any(inputs.tissue_sd))
                or (route == "modulus" and modulus_sd(cfg, inputs) > 0)
                or (stiffening_route(cfg, arm) and np.any(inputs.beta_sd)))


def perturbed_inputs(cfg: Config, inputs: UncertainInputs, arm: str,
                     noise: bool = True) -> list:
    """The inputs that scatter for an arm, one short phrase each (empty: none)."""
    out = []
    route, n = tissue_route(cfg, arm), cfg.n_elements
    m = int(np.count_nonzero(inputs.tissue_sd))
    if route == "stiffness" and m:
        via = arm_record(arm).uncertainty.stiffness_via
        out.append(f"tissue.stiffness ({m} of {n} locations{via})")
    elif route == "modulus" and modulus_sd(cfg, inputs) > 0:
        out.append(f"tissue.continuum.young_modulus (relative SD "
                   f"{modulus_sd(cfg, inputs):.3g})")
    mb = int(np.count_nonzero(inputs.beta_sd))
    if stiffening_route(cfg, arm) and mb:
        out.append(f"tissue.stiffening ({mb} of {n} locations)")
    if inputs.tension_sd_N > 0:
        out.append(f"strap.tension (SD {inputs.tension_sd_N:g} N)")
    if noise and inputs.noise_sd.any():
        out.append(f"load-cell noise (SD {inputs.force_sd_N:g} / {inputs.moment_sd_Nm:g})")
    return out


def perturbed_text(cfg: Config, inputs: UncertainInputs, arm: str, noise: bool = True) -> str:
    """:func:`perturbed_inputs` as one phrase, saying why a given tissue SD does not act."""
    text = ", ".join(perturbed_inputs(cfg, inputs, arm, noise)) or "none"
    if np.any(inputs.tissue_sd) and tissue_route(cfg, arm) == "none":
        why = arm_record(arm).uncertainty.unused_tissue
        text += f" (the tissue stiffness SD is unused: the {arm} arm {why})"
    beta = cfg.tissue_law_parameters.get(STIFFENING)
    if beta is not None and np.any(beta) and stiffening_route(cfg, arm) \
            and not np.any(inputs.beta_sd):
        text += "; tissue.stiffening held fixed (no SD given)"
    elif np.any(inputs.beta_sd) and not stiffening_route(cfg, arm):
        why = arm_record(arm).uncertainty.unused_stiffening
        text += f" (the stiffening SD is unused: {why})"
    return text


# --------------------------------------------------------------------------- draws
def draw_configs(cfg: Config, inputs: UncertainInputs, draws: int, seed: int) -> list:
    """``draws`` configs with the uncertain inputs drawn (the same draws serve every arm).

    Stiffness and tension come from the stream (seed, 0), the continuum's
    Young's modulus (when the config gives one) from (seed, 2), the stiffening
    rates (when they have an SD) from (seed, 3), so adding the modulus or the
    stiffening left the other draws as they were. Every draw keeps the config's
    tissue law (a drawn beta below 0 is 0: the linear law).
    """
    rng = np.random.default_rng([int(seed), 0])
    k = cfg.tissue_stiffness + inputs.tissue_sd * rng.standard_normal((draws, cfg.n_elements))
    t = cfg.strap_tension + inputs.tension_sd_N * rng.standard_normal(draws)
    if np.any(k <= 0):
        raise DataError("a Monte Carlo draw gave a tissue stiffness <= 0; expected SDs well "
                        "below the stiffness (the inputs are Gaussian)", key="tissue.stiffness")
    if np.any(t < 0):
        raise DataError("a Monte Carlo draw gave a strap tension < 0; expected an SD well below "
                        "the tension", key="strap.tension")
    extra = [{} for _ in range(draws)]
    r = modulus_sd(cfg, inputs)
    if r > 0:
        z = np.random.default_rng([int(seed), 2]).standard_normal(draws)
        E = cfg.continuum_young_modulus * (1.0 + r * z)
        if np.any(E <= 0):
            raise DataError(f"a Monte Carlo draw gave a Young's modulus <= 0 (relative SD "
                            f"{r:.3g}); expected a relative SD well below 1",
                            key="tissue.continuum.young_modulus")
        extra = [{"continuum_young_modulus": float(e)} for e in E]
    b_sd = inputs.beta_sd
    if np.any(b_sd) and STIFFENING in cfg.tissue_law_parameters:
        # beta from the stream (seed, 3): the other draws stay as they were without it;
        # a draw below 0 is the linear law (beta >= 0)
        z = np.random.default_rng([int(seed), 3]).standard_normal((draws, cfg.n_elements))
        beta = np.maximum(cfg.tissue_law_parameters[STIFFENING] + b_sd * z, 0.0)
        for d in range(draws):
            extra[d] = {**extra[d], "tissue_law_parameters":
                        {**cfg.tissue_law_parameters, STIFFENING: beta[d]}}
    return [dataclasses.replace(cfg, tissue_stiffness=k[d], strap_tension=float(t[d]),
                                **extra[d]) for d in range(draws)]


def check_fe_cache(cfg: Config, inputs: UncertainInputs, arms) -> None:
    """Refuse (one line) a Monte Carlo whose FE would be rebuilt for every draw (an arm that
    declares ``uncertainty.fe_cache``: the coupled arm).

    Every draw reloads the E = 1 matrices from the disk cache; a cache that
    cannot be written means one FE build (10-20 s) per draw.
    """
    cached = [a for a in arms if arm_record(a).uncertainty.fe_cache]
    if (not cached or cfg.continuum_surface_stiffness is not None
            or cfg.continuum_thickness is None
            or not any(reaches_model(cfg, inputs, a) for a in cached)):
        return
    arm = cached[0]
    if CONTINUUM_LAW_MODELS[cfg.continuum_law].reduced:
        raise UsageError(f"the {arm} arm's Monte Carlo with tissue.continuum.law "
                         f"{cfg.continuum_law} "
                         "would identify the reduced model again for every draw of the "
                         f"modulus or the strap tension (minutes each); run the {arm} arm's "
                         "uncertainty with the linear continuum", key="tissue.continuum.law")
    from ...io.cache.surface_stiffness import load_or_build_operators
    from ..common import geometry_from_config, model_from_config

    try:    # builds the cache entry (K is linear in E: any E keys the same entry)
        info = load_or_build_operators(geometry_from_config(cfg), cfg.continuum_thickness, 1.0,
                                       cfg.poisson_ratio).info
    except ValueError:
        model_from_config(cfg, arm)   # the config's own one-line error
        raise
    if info.get("cache_error"):
        raise UsageError(f"the {arm} arm's Monte Carlo needs the surface-stiffness cache, "
                         f"else the FE is rebuilt for every draw: {info['cache_error']}; set "
                         "it to a writable folder", key="PHRI_SPRING_CACHE")


# --------------------------------------------------------------------------- Sobol inputs
def sobol_inputs(cfg: Config, inputs: UncertainInputs, arm: str) -> list:
    """The scalar inputs of the Sobol indices for an arm: (name, mean, sd, (kind, j)) each.

    Each location's tissue stiffness with a non-zero SD (if it reaches the arm),
    or the continuum's Young's modulus, each location's stiffening rate with a non-zero
    SD (the compliant arm), and the strap tension if its SD is non-zero.
    """
    out = []
    route = tissue_route(cfg, arm)
    if route == "stiffness":
        for j, lab in enumerate(cfg.labels):
            if inputs.tissue_sd[j] > 0:
                out.append((f"tissue.stiffness[{lab}]", float(cfg.tissue_stiffness[j]),
                            float(inputs.tissue_sd[j]), ("k", j)))
    elif route == "modulus" and modulus_sd(cfg, inputs) > 0:
        E = float(cfg.continuum_young_modulus)
        out.append(("tissue.continuum.young_modulus", E, modulus_sd(cfg, inputs) * E,
                    ("E", 0)))
    if stiffening_route(cfg, arm):
        beta = np.broadcast_to(cfg.tissue_law_parameters[STIFFENING], (cfg.n_elements,))
        for j, lab in enumerate(cfg.labels):
            if inputs.beta_sd[j] > 0:
                out.append((f"tissue.stiffening[{lab}]", float(beta[j]),
                            float(inputs.beta_sd[j]), ("b", j)))
    if inputs.tension_sd_N > 0:
        out.append(("strap.tension", float(cfg.strap_tension), inputs.tension_sd_N, ("t", 0)))
    return out


def config_at(cfg: Config, which, x) -> Config:
    """The config with the Sobol inputs ``which`` ((kind, j) of :func:`sobol_inputs`) at ``x``
    (clipped to stay physical: a stiffness or modulus > 0, a tension or stiffening >= 0)."""
    k = np.array(cfg.tissue_stiffness, dtype=float)
    t, E = cfg.strap_tension, cfg.continuum_young_modulus
    params = dict(cfg.tissue_law_parameters)
    if STIFFENING in params:
        params[STIFFENING] = np.array(np.broadcast_to(params[STIFFENING], (cfg.n_elements,)),
                                      dtype=float)
    for (kind, j), v in zip(which, x):
        if kind == "k":
            k[j] = max(v, 1e-9 * k[j])
        elif kind == "E":
            E = max(v, 1e-9 * E)
        elif kind == "b":
            params[STIFFENING][j] = max(v, 0.0)
        else:
            t = max(v, 0.0)
    return dataclasses.replace(cfg, tissue_stiffness=k, strap_tension=float(t),
                               continuum_young_modulus=E, tissue_law_parameters=params)
