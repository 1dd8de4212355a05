"""The spring model's outputs at a cuff displacement: compression, forces, energy (docs/model.md
section 4)."""

from __future__ import annotations

import numpy as np
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # annotations only
    from .model import SpringModel

__all__ = ["compression", "forces_from_compression", "normal_forces", "shear_forces", "energy"]


def compression(model: SpringModel, u) -> np.ndarray:
    """Compression g_e = delta0_e + b_e . u of every element [m], shape (..., n).

    docs/model.md section 4: element e is in contact when g_e > 0.
    """
    return model.delta0 + np.asarray(u, dtype=float) @ model.b.T


def forces_from_compression(model: SpringModel, g, out=None) -> np.ndarray:
    """f_e = k_e [g_e]_+ [N] (docs/model.md section 4), shape of g; in place if ``out is g``."""
    f = np.maximum(g, 0.0, out=out)
    f *= model.k
    return f


def normal_forces(model: SpringModel, u) -> np.ndarray:
    """f_e = k_e [delta0_e + b_e . u]_+ [N] (the element law's force for a nonlinear law),
    shape (..., n)."""
    if not model.is_linear:
        return model.element.force(compression(model, u))
    return forces_from_compression(model, compression(model, u))


def shear_forces(model: SpringModel, u) -> np.ndarray:
    """Shear force on the arm s_e = k_s,e (I3 - n_e n_e^T) B_e u [N], shape (..., n, 3)."""
    return model.shear_forces(u)


def energy(model: SpringModel, u, wrench) -> np.ndarray:
    """Pi(u) [J] for displacement(s) u and applied wrench(es) W."""
    u = np.asarray(u, dtype=float)
    g = compression(model, u)
    r = np.asarray(wrench, dtype=float) + model.W_pre
    if model.is_linear:
        gp = np.maximum(g, 0.0)
        elastic = 0.5 * np.sum(model.k * gp * gp, axis=-1)
    else:
        elastic = np.sum(model.element.energy(g), axis=-1)
    return (elastic
            + 0.5 * np.einsum("...i,ij,...j->...", u, model.K_s, u)
            - np.sum(r * u, axis=-1))
