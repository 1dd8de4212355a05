"""The opt-in ``--shear`` columns of ``phri simulate`` (docs/model.md section 10.6).

Per element: its tangential force on the arm in its local axes and, for the coupled arm's
patches, its moment about its centre; then its resultant force on the arm in the cuff
frame and, for patches, its moment about its centre in the cuff frame. Those last add up
(sum of forces; sum of moments plus p_e x force) to the wrench on the cuff plus the
strap's, W + W_pre, about the cuff origin, so a user can check the balance sample by
sample.
"""

from __future__ import annotations

import numpy as np

from ...physics.cuff.geometry import patch_frames

__all__ = ["shear_columns", "has_patch_moments", "element_loads", "shear_extras"]


def shear_columns(labels, moments: bool = False) -> tuple:
    """Names of the opt-in shear columns (``--shear``): two per element [N] and, for patches
    that carry moments (``moments``, the coupled arm), three per patch [N*m] after them;
    then every element's resultant force on the arm in the cuff frame, three each [N], and
    (``moments``) every patch's moment about its centre in the cuff frame, three each [N*m]
    (docs/model.md section 10.6)."""
    names = tuple(f"{lab}_shear_{part}_N" for lab in labels
                  for part in ("axial", "circumferential"))
    if moments:
        names += tuple(f"{lab}_moment_{part}_Nm" for lab in labels
                       for part in ("normal", "axial", "circumferential"))
    names += tuple(f"{lab}_force_{axis}_N" for lab in labels for axis in "xyz")
    if moments:
        names += tuple(f"{lab}_moment_{axis}_Nm" for lab in labels for axis in "xyz")
    return names


def has_patch_moments(model) -> bool:
    """Whether the model's patches carry moments (the coupled arm's 6-dof patches)."""
    return getattr(model, "dofs", 3) == 6


def element_loads(model, sol) -> np.ndarray:
    """Every element's load on the arm in its local axes, (m, n, 3) [N] or, for 6-dof
    patches, (m, n, 6) [N, N*m]: the normal force along n_e the equilibrium uses (for a
    coupled patch not its reported traction integral), the axial and circumferential
    forces, then the moments about the patch centre along n_e, +x, c_e."""
    moments = has_patch_moments(model)
    if sol.tangential is not None:   # friction, or the coupled arm's lift-off: the path's own
        normal = sol.forces if sol.normal is None else sol.normal
        parts = [np.atleast_2d(normal)[..., None], np.atleast_3d(sol.tangential)]
        if moments:
            parts.append(np.array(sol.moments, dtype=float).reshape(len(parts[1]), -1, 3))
        return np.concatenate(parts, axis=2).astype(float)
    if hasattr(model, "patch_forces"):
        return np.array(model.patch_forces(sol.u, sol.contact)[..., :6], dtype=float)
    normal = np.where(np.atleast_2d(sol.contact), np.atleast_2d(sol.forces), 0.0)
    return np.concatenate([normal[..., None], model.shear_components(sol.u, sol.contact)],
                          axis=2)


def shear_extras(model, sol) -> dict:
    """Tangential force on the arm of every element [N] (axial, circumferential) and, for
    6-dof patches, each patch's moment on the skin about its centre [N*m] (local axes:
    normal, axial, circumferential); then each element's resultant force on the arm and
    each patch's moment about its centre in the cuff frame. NaN where the sample did not
    converge."""
    loads = element_loads(model, sol)
    if not np.all(sol.converged):
        loads[~np.asarray(sol.converged, dtype=bool)] = np.nan
    m = len(loads)
    frames = patch_frames(model.geometry)             # rows n_e, a, c_e (cuff frame)
    cols = [loads[..., 1:3].reshape(m, -1)]
    if loads.shape[2] == 6:
        cols.append(loads[..., 3:6].reshape(m, -1))
    cols.append(np.einsum("mek,eki->mei", loads[..., :3], frames).reshape(m, -1))
    if loads.shape[2] == 6:
        cols.append(np.einsum("mek,eki->mei", loads[..., 3:6], frames).reshape(m, -1))
    s = np.concatenate(cols, axis=1)
    return {name: s[:, j] for j, name in
            enumerate(shear_columns(model.labels, moments=loads.shape[2] == 6))}
