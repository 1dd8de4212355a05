"""Config -> the coupled arm with a hyperelastic layer (``tissue.continuum.law``
``neo_hookean`` or ``ogden``).

docs/model.md section 10.8. The reduced model is identified for a rigid cuff bonded over
its patches, on the built-in FE, for one Young's modulus: a config outside that is told
so in one line naming the key. The Ogden law's exponent is ``tissue.continuum.ogden_alpha``
or, without it, identified from the indenter curve (``tissue.stiffening``) by the punch FE.
The identification (minutes, once per config: cached) reports its progress through
:func:`identification_progress`.
"""

from __future__ import annotations

import contextlib
from contextvars import ContextVar

import numpy as np

from ..errors import ConfigError
from ..io.config import Config

__all__ = ["hyper_coupled_model", "identification_progress", "strap_settings", "ogden_exponent"]

_PROGRESS: ContextVar = ContextVar("phri_identification_progress", default=None)


@contextlib.contextmanager
def identification_progress(callback):
    """Within the block, an identification calls ``callback(done, total)`` after each ray."""
    token = _PROGRESS.set(callback)
    try:
        yield
    finally:
        _PROGRESS.reset(token)


def strap_settings(cfg: Config) -> tuple:
    """What of the config makes the strap's preload (a part of the identification's key)."""
    return (float(cfg.strap_tension), str(cfg.strap_model), cfg.handle_angles_deg,
            cfg.strap_axial_position)


def _check(cfg: Config, E) -> None:
    path = cfg.path
    law = f"tissue.continuum.law {cfg.continuum_law}"
    if cfg.friction_coefficient is not None:
        raise ConfigError(f"{law} is a bonded interface; expected no "
                          "interface.friction_coefficient (friction runs with the linear "
                          "continuum)", file=path, key="interface.friction_coefficient")
    k = np.asarray(cfg.cuff_stiffness, float)
    if not np.all(np.isinf(k)):
        raise ConfigError(f"{law} is identified for a rigid cuff; "
                          "expected cuff.stiffness: inf (a compliant cuff runs with the "
                          "linear continuum)", file=path, key="cuff.stiffness")
    if cfg.continuum_patch_gap is not None and not cfg.continuum_patch_gap > 0:
        # the hyperelastic FE moves each plate's skin nodes as one rigid body: tiled plates
        # share their edge nodes, which two neighbouring plates would move differently
        raise ConfigError(f"{law} needs free skin between the plates (tiled plates share "
                          "edge nodes that two patches would move differently); expected "
                          "tissue.continuum.patch_gap > 0 m or no patch_gap (default 2 mm)",
                          file=path, key="tissue.continuum.patch_gap")
    if cfg.continuum_surface_stiffness is not None:
        raise ConfigError(f"{law} runs the built-in FE; expected no "
                          "tissue.continuum.surface_stiffness", file=path,
                          key="tissue.continuum.surface_stiffness")
    E = np.asarray(E, float)
    if cfg.continuum_spread == "per_patch" and np.ptp(E) > 1e-12 * np.max(E):
        raise ConfigError(f"{law} needs one Young's modulus for the "
                          f"layer, got {E.min():.4g}-{E.max():.4g} Pa over the patches "
                          "(tissue.continuum.spread per_patch)", file=path,
                          key="tissue.continuum.spread")


def ogden_exponent(cfg: Config, young_modulus: float, *, cache_dir=None) -> tuple:
    """(alpha, source) of the Ogden law: ``tissue.continuum.ogden_alpha``, or identified from
    the indenter curve (``tissue.stiffening`` beta, one value) by simulating the indenter
    on the layer (:func:`~phri_spring.io.cache.hyper_reduction.ogden_alpha`), fitted up to the
    force at which the mean pressure under the indenter reaches the pain threshold
    (``interface.pain_threshold_kpa``), as far as an indenter test on a person goes."""
    if cfg.continuum_ogden_alpha is not None:
        return float(cfg.continuum_ogden_alpha), "tissue.continuum.ogden_alpha"
    from ..io.cache import hyper_reduction as store
    beta = np.asarray(cfg.tissue_law_parameters.get("stiffening", 0.0), float)
    if cfg.tissue_law != "exponential" or not np.all(beta > 0):
        raise ConfigError("tissue.continuum.law ogden needs its exponent: give "
                          "tissue.continuum.ogden_alpha, or the indenter curve's "
                          "tissue.stiffening (> 0, from phri fit-stiffness --law exponential) "
                          "to identify it from", file=cfg.path, key="tissue.continuum.ogden_alpha")
    if np.ptp(beta) > 1e-12 * beta.max():
        raise ConfigError("tissue.continuum.law ogden identifies one exponent for the layer; "
                          f"expected one tissue.stiffening, got {beta.min():.4g}-"
                          f"{beta.max():.4g} 1/m over the elements", file=cfg.path,
                          key="tissue.stiffening")
    a = cfg.indenter_diameter / 2.0
    force_max = cfg.pain_threshold_kpa * 1e3 * np.pi * a * a
    try:
        alpha = store.ogden_alpha(float(beta.max()), a, cfg.continuum_thickness,
                                  float(young_modulus), cfg.poisson_ratio, force_max,
                                  cache_dir=cache_dir)
    except ConfigError as exc:
        raise ConfigError(exc.message, file=cfg.path, key=exc.key) from None
    return alpha, "tissue.stiffening"


def hyper_coupled_model(cfg: Config, linear_builder, modulus, *, cache_dir=None, level=None):
    """The reduced hyperelastic coupled model of a config.

    Parameters
    ----------
    cfg : Config
        ``tissue.continuum.law: neo_hookean`` or ``ogden``.
    linear_builder : callable(cfg, level) -> CoupledModel
        Builds the linear coupled model of the config at a mesh level (None: the default).
    modulus : array_like, shape (n,)
        The continuum's Young's modulus per patch [Pa] (``common.continuum_modulus``).
    cache_dir : path, optional
        Where the FE's matrices and the identification are cached.
    level : int, optional
        Mesh level of the linear part (the identification's is ``IDENTIFY_LEVEL``).

    Raises
    ------
    ConfigError
        A config the reduced model is not identified for (one line, naming the key).
    UsageError
        felupe (extra ``hyper``) is needed and not installed.
    """
    from ..io.cache import hyper_reduction as store
    from ..physics.hyperelastic.coupled import HyperCoupledModel
    geom = cfg.geometry()
    E = np.asarray(modulus, float)
    _check(cfg, E)
    law, alpha, source = cfg.continuum_law, None, None
    if law == "ogden":
        alpha, source = ogden_exponent(cfg, float(np.mean(E)), cache_dir=cache_dir)
    linear = linear_builder(cfg, level)
    id_level = store.IDENTIFY_LEVEL
    ident = linear if level == id_level else linear_builder(cfg, id_level)
    try:
        red = store.load_or_identify(
            geom, cfg.continuum_thickness, float(np.mean(E)), cfg.poisson_ratio, ident,
            max_force=cfg.continuum_max_force, max_moment=cfg.continuum_max_moment,
            strap=strap_settings(cfg), cache_dir=cache_dir, level=id_level, rays=store.IDENTIFY_RAYS,
            patch_gap=cfg.continuum_patch_gap, progress=_PROGRESS.get(), law=law,
            ogden_alpha=alpha)
    except ConfigError as exc:
        if exc.file is not None:
            raise
        raise ConfigError(exc.message, file=cfg.path, key=exc.key) from None
    if alpha is not None:
        red.info.update(ogden_alpha=alpha, ogden_alpha_source=source)
    return HyperCoupledModel(linear=linear, reduction=red, continuum_law=law,
                             pain_threshold_kpa=cfg.pain_threshold_kpa)
