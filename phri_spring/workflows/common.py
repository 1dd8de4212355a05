"""Config -> physics glue shared by the commands."""

from __future__ import annotations

import numpy as np

from ..errors import ConfigError
from ..io.config import Config
from ..physics.geometry import CuffGeometry, cuff_geometry
from ..physics.loadcell import FORCE_UNITS, MOMENT_UNITS, loadcell_to_cuff
from ..physics.model import SpringModel, build_model, tissue_element_stiffness

__all__ = ["geometry_from_config", "model_from_config", "cuff_wrench", "ARMS"]

#: arm models: the paper's two spring models and the coupled tissue model (docs/model.md)
ARMS = ("compliant", "rigid", "coupled")


def geometry_from_config(cfg: Config) -> CuffGeometry:
    """The element geometry a config describes."""
    return cuff_geometry(cfg.row_x, cfg.radius, cfg.row_width, cfg.angle_start_deg,
                         cfg.angle_step_deg, cfg.angle_count, cfg.angle_width_deg,
                         row_labels=cfg.row_labels)


def model_from_config(cfg: Config, arm: str = "compliant", *, cache_dir=None):
    """Assemble the model of a config for an arm of :data:`ARMS`.

    Parameters
    ----------
    cfg : Config
    arm : {'compliant', 'rigid', 'coupled'}
        The paper's spring network with tissue and cuff springs in series
        (``compliant``) or cuff springs only (``rigid``), or the coupled tissue
        model (``coupled``: needs ``tissue.continuum``; docs/model.md section 10).
    cache_dir : path, optional
        ``coupled`` only: where the built-in FE's surface stiffness is cached.

    Returns
    -------
    SpringModel or CoupledModel

    Raises
    ------
    ConfigError
        If an element would be infinitely stiff (e.g. ``cuff.stiffness: .inf``
        with the rigid arm), the geometry cannot hold the cuff (singular K_s), or
        the coupled model's inputs are missing or out of range.
    UsageError
        ``coupled`` without the ``fe`` extra (and no ``surface_stiffness`` file).
    """
    if arm not in ARMS:
        raise ValueError(f"arm: expected one of {ARMS}, got {arm!r}")
    if arm == "coupled":
        return _coupled_model(cfg, cache_dir)
    geom = geometry_from_config(cfg)
    k_t = tissue_element_stiffness(cfg.tissue_stiffness, geom.areas, cfg.tissue_basis,
                                   cfg.indenter_diameter)
    k_c = cfg.cuff_stiffness
    if arm == "rigid" and np.isinf(k_c).any():
        lab = cfg.labels[int(np.argmax(np.isinf(k_c)))]
        raise ConfigError(f"element {lab} is infinitely stiff in the rigid-arm model "
                          "(k_e = k_c = inf); expected a finite cuff stiffness [N/m]",
                          file=cfg.path, key="cuff.stiffness")
    try:
        return build_model(geom, k_t, k_c, arm=arm, shear_ratio=cfg.shear_ratio,
                           poisson_ratio=cfg.poisson_ratio, strap_tension=cfg.strap_tension,
                           strap_model=cfg.strap_model, handle_angles_deg=cfg.handle_angles_deg,
                           handle_axial_position=cfg.strap_axial_position,
                           pain_threshold_kpa=cfg.pain_threshold_kpa)
    except ValueError as exc:
        key = "geometry.angles" if "K_s" in str(exc) else None
        raise ConfigError(str(exc), file=cfg.path, key=key) from None


def continuum_modulus(cfg: Config, geom: CuffGeometry | None = None) -> np.ndarray:
    """Young's modulus E [Pa] per patch (n,) for the coupled model.

    ``tissue.continuum.young_modulus`` if given; otherwise converted from the
    indenter stiffness in ``tissue.stiffness`` (flat punch of
    ``tissue.indenter_diameter`` on a layer of the continuum's thickness bonded
    to the bone, by the same FE: docs/model.md section 10).
    """
    key = "tissue.continuum"
    n = len(cfg.labels)
    if cfg.continuum_young_modulus is not None:
        return np.full(n, cfg.continuum_young_modulus)
    if cfg.tissue_basis != "indenter":
        raise ConfigError("give tissue.continuum.young_modulus [Pa]: tissue.stiffness is not "
                          "indenter stiffness (tissue.basis: element), so E cannot be derived "
                          "from it", file=cfg.path, key=f"{key}.young_modulus")
    fe = _fe_module(cfg)
    return np.asarray(fe.modulus_from_indenter(cfg.tissue_stiffness, cfg.continuum_thickness,
                                               cfg.poisson_ratio,
                                               radius=cfg.indenter_diameter / 2.0), dtype=float)


def _fe_module(cfg: Config):
    """:mod:`phri_spring.physics.fe_tissue`, after checking that scikit-fem (the ``fe`` extra)
    is installed (a one-line UsageError naming the extra otherwise)."""
    from ..physics import fe_tissue

    fe_tissue._skfem()
    return fe_tissue


def _coupled_model(cfg: Config, cache_dir=None):
    """The coupled tissue model of a config (docs/model.md section 10)."""
    from ..physics.coupled import build_coupled_model

    key = "tissue.continuum"
    if cfg.continuum_thickness is None:
        raise ConfigError("the coupled arm needs tissue.continuum (thickness [m], and "
                          "young_modulus [Pa] unless tissue.stiffness holds indenter values)",
                          file=cfg.path, key=key)
    geom = geometry_from_config(cfg)
    radius = np.unique(geom.radius)
    if len(radius) != 1:
        raise ConfigError("the coupled model needs one cuff radius for every row (a cylindrical "
                          f"arm), got {sorted(radius.tolist())} m", file=cfg.path,
                          key="geometry.radius")
    t = cfg.continuum_thickness
    if not t < radius[0]:
        raise ConfigError(f"expected 0 < thickness < the radius {radius[0]:g} m (the bone's radius "
                          f"is radius - thickness), got {t:g} m", file=cfg.path,
                          key=f"{key}.thickness")
    if not cfg.poisson_ratio < 0.5:
        raise ConfigError(f"the coupled model needs a Poisson ratio below 0.5 (a compressible "
                          f"continuum), got {cfg.poisson_ratio:g}", file=cfg.path,
                          key="tissue.poisson_ratio")
    from ..physics.fe_mesh import MAX_POISSON_RATIO

    # the built-in FE builds K, or turns indenter stiffness into E for a per-patch spread
    builtin_fe = cfg.continuum_surface_stiffness is None or (
        cfg.continuum_young_modulus is None and cfg.continuum_spread == "per_patch")
    if builtin_fe and cfg.poisson_ratio > MAX_POISSON_RATIO:
        raise ConfigError(f"the built-in FE of the coupled arm is converged up to "
                          f"{MAX_POISSON_RATIO} (its elements lock as nu -> 0.5), got "
                          f"{cfg.poisson_ratio:g}; use <= {MAX_POISSON_RATIO}, or give your own "
                          f"FE's tissue.continuum.surface_stiffness and young_modulus",
                          file=cfg.path, key="tissue.poisson_ratio")
    from ..io.surface_stiffness import load_or_build, load_surface_stiffness

    N = None
    if cfg.continuum_surface_stiffness is not None:
        K = load_surface_stiffness(cfg.continuum_surface_stiffness, geom)
        E = None
    else:
        E = continuum_modulus(cfg, geom)
        _fe_module(cfg)
        K, info = load_or_build(geom, t, float(np.mean(E)), cfg.poisson_ratio,
                                cache_dir=cache_dir)
        N = info.get("N")
    if cfg.continuum_spread == "per_patch":
        if E is None:
            E = continuum_modulus(cfg, geom)
        s = E / np.mean(E)
        K = _scale_per_patch(K, s, geom.n)
        if N is not None:  # the output follows the patch's own stiffness
            N = N * np.repeat(np.sqrt(s), N.shape[1] // geom.n)[None, :] * np.sqrt(s)[:, None]
    try:
        return build_coupled_model(geom, K, cfg.cuff_stiffness, poisson_ratio=cfg.poisson_ratio,
                                   shear_ratio=cfg.shear_ratio, strap_tension=cfg.strap_tension,
                                   strap_model=cfg.strap_model,
                                   handle_angles_deg=cfg.handle_angles_deg,
                                   handle_axial_position=cfg.strap_axial_position,
                                   pain_threshold_kpa=cfg.pain_threshold_kpa, normal_output=N)
    except ValueError as exc:
        raise ConfigError(str(exc), file=cfg.continuum_surface_stiffness or cfg.path,
                          key=key) from None


def _scale_per_patch(K: np.ndarray, s: np.ndarray, n: int) -> np.ndarray:
    """D K D with D = diag(sqrt(s_e)) on patch e's dofs: patch e's stiffness scaled by s_e,
    the coupling of patches e and f by sqrt(s_e s_f) (symmetric positive definite kept)."""
    d = np.repeat(np.sqrt(np.asarray(s, dtype=float)), K.shape[0] // n)
    return K * d[:, None] * d[None, :]


def cuff_wrench(cfg: Config, wrench_lc) -> np.ndarray:
    """Load-cell readings (log units) -> wrench on the cuff W (m, 6) [N, N*m] (docs/model.md section 5)."""
    return loadcell_to_cuff(wrench_lc, cfg.loadcell_rotation, cfg.loadcell_position,
                            cfg.loadcell_sign, FORCE_UNITS[cfg.force_unit],
                            MOMENT_UNITS[cfg.moment_unit])
