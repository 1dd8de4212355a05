"""Config -> physics glue shared by the commands."""

from __future__ import annotations

import numpy as np

from ..errors import ConfigError
from ..io.config import Config
from ..physics.geometry import CuffGeometry, cuff_geometry
from ..physics.loadcell import FORCE_UNITS, MOMENT_UNITS, loadcell_to_cuff
from ..physics.model import SpringModel, build_model, tissue_element_stiffness

__all__ = ["geometry_from_config", "model_from_config", "cuff_wrench", "ARMS"]

ARMS = ("compliant", "rigid")


def geometry_from_config(cfg: Config) -> CuffGeometry:
    """The element geometry a config describes."""
    return cuff_geometry(cfg.row_x, cfg.radius, cfg.row_width, cfg.angle_start_deg,
                         cfg.angle_step_deg, cfg.angle_count, cfg.angle_width_deg,
                         row_labels=cfg.row_labels)


def model_from_config(cfg: Config, arm: str = "compliant") -> SpringModel:
    """Assemble the spring network of a config for the ``compliant`` or ``rigid`` arm.

    Raises
    ------
    ConfigError
        If an element would be infinitely stiff (e.g. ``cuff.stiffness: .inf``
        with the rigid arm) or the geometry cannot hold the cuff (singular K_s).
    """
    if arm not in ARMS:
        raise ValueError(f"arm: expected one of {ARMS}, got {arm!r}")
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


def cuff_wrench(cfg: Config, wrench_lc) -> np.ndarray:
    """Load-cell readings (log units) -> wrench on the cuff W (m, 6) [N, N*m] (SPEC section 5)."""
    return loadcell_to_cuff(wrench_lc, cfg.loadcell_rotation, cfg.loadcell_position,
                            cfg.loadcell_sign, FORCE_UNITS[cfg.force_unit],
                            MOMENT_UNITS[cfg.moment_unit])
