"""The reduced neo-Hookean model's identification, cached on disk (docs/model.md section 10.8).

Identifying the corrections of :mod:`phri_spring.physics.hyper_reduced` solves the
large-deformation FE at a few hundred cuff poses (minutes); the result is a few arrays,
kept in the surface-stiffness cache folder under a key of everything it depends on.
"""

from __future__ import annotations

import hashlib
import time
from pathlib import Path

import numpy as np

from ..errors import ConfigError, ConvergenceError
from ..physics import hyper_reduced as hr
from .surface_stiffness import _gap, cache_key, default_cache_dir, read_cache_entry, write_cache_entry

__all__ = ["IDENTIFY_LEVEL", "IDENTIFY_RAYS", "REDUCTION_FORMAT_VERSION", "reduction_key",
           "load_or_identify"]

#: bump when the identification or the file layout changes: old entries are then ignored
REDUCTION_FORMAT_VERSION = 2
#: FE mesh level of the identification (its corrections' mesh error: benchmarks/HYPERELASTIC_ROM.md)
IDENTIFY_LEVEL = 2
#: rays of the identification (3 poses each; 84 coefficients per output)
IDENTIFY_RAYS = 96


def reduction_key(geometry, thickness, young_modulus, poisson_ratio, strap, *, max_force,
                  max_moment, level, rays, patch_gap) -> str:
    """SHA-256 (hex) of the inputs the identification depends on: those of the built-in FE's
    surface stiffness (:func:`~phri_spring.io.surface_stiffness.cache_key`: patches,
    thickness, Poisson ratio, mesh level, patch gap), Young's modulus, the strap (its
    settings make the preload), the range, the rays and the format version. Inputs only:
    a computed array (the preload offsets) differs in its last bits between BLAS builds
    and thread counts, and would miss the cache."""
    h = hashlib.sha256()
    h.update(f"phri-spring neo-Hookean reduction v{REDUCTION_FORMAT_VERSION}\n".encode())
    h.update(cache_key(geometry, thickness, poisson_ratio, level=level,
                       patch_gap=patch_gap).encode())
    h.update(repr(tuple(strap)).encode())
    for value in (young_modulus, max_force, max_moment):
        h.update(np.float64(value).tobytes())
    h.update(f"rays={int(rays)}".encode())
    return h.hexdigest()


def load_or_identify(geometry, thickness, young_modulus, poisson_ratio, linear, *,
                     max_force: float, max_moment: float, strap=(), cache_dir=None,
                     level: int = IDENTIFY_LEVEL, rays: int = IDENTIFY_RAYS, patch_gap=None,
                     progress=None):
    """The reduced model's corrections for a config, from the cache or identified now.

    Parameters
    ----------
    geometry : CuffGeometry
    thickness, young_modulus, poisson_ratio : float
        The continuum: t [m], E [Pa], nu [-].
    linear : CoupledModel
        The linear coupled model with a rigid cuff at mesh ``level`` (its preload is the FE's).
    max_force, max_moment : float
        The identified range [N, N*m].
    strap : tuple
        The strap's settings (tension, model, handle angles, axial position): with the
        patches and the material they make the linear model's preload (part of the key).
    cache_dir : path, optional
        Default :func:`~phri_spring.io.surface_stiffness.default_cache_dir`.
    level, rays, patch_gap
        The FE's mesh level, the ray count, the free skin between plates [m] (None: default).
    progress : callable(done, total), optional
        Called after each ray of an identification.

    Returns
    -------
    HyperReduction
        ``info`` gains ``source`` (``cache`` or ``identified``), ``path``, ``seconds`` and
        ``cache_error`` (None, or why the result could not be cached).

    Raises
    ------
    UsageError
        felupe (extra ``hyper``) is missing and the cache has no entry.
    ConfigError
        The FE did not converge at an identification pose (a range too large for the cuff).
    """
    from ..physics import fe_hyper as fh

    t0 = time.perf_counter()
    key = reduction_key(geometry, thickness, young_modulus, poisson_ratio, strap,
                        max_force=max_force, max_moment=max_moment, level=level, rays=rays,
                        patch_gap=patch_gap)
    folder = Path(cache_dir).expanduser() if cache_dir is not None else default_cache_dir()
    path = folder / f"neo-hookean-{key[:32]}.npz"
    K, n = len(hr.EXPONENTS), geometry.n
    hit = read_cache_entry(path, key, dict(scale=(6,), wrench=(K, 6), normal=(K, n),
                                           patch=(K, 6 * n), range_map=(6, 6)))
    red = None if hit is None else hr.HyperReduction(info=hit[1], **hit[0])
    if red is not None:
        red.info.update(source="cache", cache_error=None)
    else:
        cuff = fh.build_hyper_cuff(geometry, thickness, young_modulus, poisson_ratio,
                                   level=level, delta=linear.delta, patch_gap=_gap(patch_gap))
        try:
            red = hr.identify(cuff, hr.linear_bonded(linear), max_force=max_force,
                              max_moment=max_moment, rays=rays, progress=progress)
        except ConvergenceError as exc:
            raise ConfigError(f"the neo-Hookean model's identification failed: {exc}, at a "
                              f"pose the range asks for ({max_force:g} N, {max_moment:g} N*m "
                              f"moves this cuff too far); expected a smaller "
                              f"tissue.continuum.max_force / max_moment",
                              key="tissue.continuum.max_force") from None
        red.info["seconds_identify"] = time.perf_counter() - t0
        error = write_cache_entry(path, key, red.arrays(), red.info)
        red.info.update(source="identified", cache_error=error)
    red.info.update(path=str(path), seconds=time.perf_counter() - t0)
    return red
