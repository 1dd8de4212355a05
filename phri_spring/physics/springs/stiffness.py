"""Springs of the interface (docs/model.md section 2).

Series chain per element: bone - tissue spring - skin - cuff spring - rigid
robot, plus a bonded tangential (shear) spring. The tissue spring's law is a
plug-in (:mod:`phri_spring.physics.laws`); these are the linear springs.
"""

from __future__ import annotations

import numpy as np

__all__ = ["indenter_to_element", "series_stiffness",
           "shear_ratio_from_poisson", "shear_stiffness_matrix"]


def indenter_to_element(k_indenter, area, indenter_diameter: float = 0.009) -> np.ndarray:
    """Convert an indenter stiffness to the stiffness of an element by area.

    k_t,e = k_ind,e * A_e / (pi d^2 / 4)

    Parameters
    ----------
    k_indenter : array_like
        Stiffness measured with a flat cylindrical indenter [N/m].
    area : array_like
        Element area A_e [m^2].
    indenter_diameter : float
        Indenter diameter d [m].

    Returns
    -------
    ndarray
        Element tissue stiffness [N/m].
    """
    a_ind = np.pi * indenter_diameter ** 2 / 4.0
    return np.asarray(k_indenter, dtype=float) * np.asarray(area, dtype=float) / a_ind


def series_stiffness(k_a, k_b) -> np.ndarray:
    """Two springs in series, 1 / (1/k_a + 1/k_b) [N/m]; an infinite spring drops out."""
    k_a = np.asarray(k_a, dtype=float)
    k_b = np.asarray(k_b, dtype=float)
    with np.errstate(divide="ignore"):
        return 1.0 / (1.0 / k_a + 1.0 / k_b)


def shear_ratio_from_poisson(nu: float) -> float:
    """Default shear ratio eta = k_s,e / k_e = 1 / (2 (1 + nu)) [-] (the paper's model).

    This is G / E of an isotropic tissue: the ratio of a free column of tissue (simple
    shear against compression with its sides free), an assumption of the paper's model,
    not the tangential-to-normal stiffness ratio of a bonded contact. That ratio lies
    between two limits (docs/stiffness.md, "The shear ratio eta: an assumption"):

    * thin bonded layer: shear G / h against confined compression
      E (1 - nu) / ((1 + nu) (1 - 2 nu) h), eta = (1 - 2 nu) / (2 (1 - nu));
    * rigid flat punch bonded to a half-space (Mindlin 1949): tangential 8 G a / (2 - nu)
      against normal 4 G a / (1 - nu), eta = 2 (1 - nu) / (2 - nu).

    At nu = 0.45 they are 0.091 and 0.710, the default 0.345. The default is kept so that
    the paper's results are reproduced; ``interface.shear_ratio`` in a config overrides it.

    Parameters
    ----------
    nu : float
        Poisson ratio of the tissue [-].

    Returns
    -------
    float
        eta [-].
    """
    return 1.0 / (2.0 * (1.0 + float(nu)))


def shear_stiffness_matrix(k_shear, B, normals) -> np.ndarray:
    """K_s = sum_e k_s,e B_e^T (I3 - n_e n_e^T) B_e, shape (6, 6) [N/m, N, N*m].

    Parameters
    ----------
    k_shear : array_like, shape (n,)
        Tangential stiffness of each element [N/m].
    B : ndarray, shape (n, 3, 6)
        Element Jacobians.
    normals : ndarray, shape (n, 3)
        Unit normals.
    """
    P = np.eye(3)[None] - normals[:, :, None] * normals[:, None, :]
    PB = P @ B
    return np.einsum("e,eij,eik->jk", np.asarray(k_shear, dtype=float), B, PB)
