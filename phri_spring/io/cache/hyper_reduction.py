"""The reduced hyperelastic model's identification, cached on disk (docs/model.md section 10.8).

Identifying the corrections of :mod:`phri_spring.physics.hyperelastic.reduced` solves the
large-deformation FE at a few hundred cuff poses (minutes); the result is a few arrays,
kept in the surface-stiffness cache folder under a key of everything it depends on. The
Ogden law's exponent, when the config leaves it to the indenter curve, is identified by
the punch FE (:func:`ogden_alpha`, a minute or two) and cached the same way.
"""

from __future__ import annotations

import hashlib
import time
from pathlib import Path

import numpy as np

from ...errors import ConfigError, ConvergenceError
from ...physics.hyperelastic import reduced as hr
from .surface_stiffness import patch_gap_value, cache_key, default_cache_dir, read_cache_entry, write_cache_entry

__all__ = ["IDENTIFY_LEVEL", "IDENTIFY_RAYS", "HELD_OUT_LIMIT_PCT", "REDUCTION_FORMAT_VERSION",
           "reduction_key",
           "load_or_identify", "ogden_alpha"]

#: bump when the identification or the file layout changes: old entries are then ignored
REDUCTION_FORMAT_VERSION = 2
#: FE mesh level of the identification (its corrections' mesh error: benchmarks/HYPERELASTIC_ROM.md)
IDENTIFY_LEVEL = 2
#: rays of the identification (3 poses each; 84 coefficients per output)
IDENTIFY_RAYS = 96
#: largest held-out error of the patch normal forces [% of the peak] a reduction may have
HELD_OUT_LIMIT_PCT = 5.0


def reduction_key(geometry, thickness, young_modulus, poisson_ratio, strap, *, max_force,
                  max_moment, level, rays, patch_gap, law="neo_hookean",
                  ogden_alpha=None) -> str:
    """SHA-256 (hex) of the inputs the identification depends on: those of the built-in FE's
    surface stiffness (:func:`~phri_spring.io.cache.surface_stiffness.cache_key`: patches,
    thickness, Poisson ratio, mesh level, patch gap), Young's modulus, the strap (its
    settings make the preload), the range, the rays, the law (and its exponent) and the
    format version (a neo-Hookean key is the one it was before the Ogden law). Inputs only:
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
    if law != "neo_hookean":
        h.update(f"law={law}".encode())
        h.update(np.float64(ogden_alpha).tobytes())
    return h.hexdigest()


def load_or_identify(geometry, thickness, young_modulus, poisson_ratio, linear, *,
                     max_force: float, max_moment: float, strap=(), cache_dir=None,
                     level: int = IDENTIFY_LEVEL, rays: int = IDENTIFY_RAYS, patch_gap=None,
                     progress=None, law: str = "neo_hookean", ogden_alpha=None):
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
        Default :func:`~phri_spring.io.cache.surface_stiffness.default_cache_dir`.
    level, rays, patch_gap
        The FE's mesh level, the ray count, the free skin between plates [m] (None: default).
    progress : callable(done, total), optional
        Called after each ray of an identification.
    law, ogden_alpha : str, float
        The layer's law (``neo_hookean`` or ``ogden``) and the Ogden exponent alpha [-].

    Returns
    -------
    HyperReduction
        ``info`` gains ``source`` (``cache`` or ``identified``), ``path``, ``seconds`` and
        ``cache_error`` (None, or why the result could not be cached); ``info``'s
        ``held_out_normal_pct`` is the fit's error on rays left out of it
        (:func:`~phri_spring.physics.hyperelastic.reduced.held_out_error`).

    Raises
    ------
    UsageError
        felupe (extra ``hyper``) is missing and the cache has no entry.
    ConfigError
        The FE did not converge at an identification pose, or the fit's held-out error
        exceeds :data:`HELD_OUT_LIMIT_PCT` (a range too large for the cuff or the cubic;
        the identification is cached all the same).
    """
    from ...physics.hyperelastic import fe as fh

    t0 = time.perf_counter()
    key = reduction_key(geometry, thickness, young_modulus, poisson_ratio, strap,
                        max_force=max_force, max_moment=max_moment, level=level, rays=rays,
                        patch_gap=patch_gap, law=law, ogden_alpha=ogden_alpha)
    folder = Path(cache_dir).expanduser() if cache_dir is not None else default_cache_dir()
    path = folder / f"{law.replace('_', '-')}-{key[:32]}.npz"
    K, n = len(hr.EXPONENTS), geometry.n
    hit = read_cache_entry(path, key, dict(scale=(6,), wrench=(K, 6), normal=(K, n),
                                           patch=(K, 6 * n), range_map=(6, 6)))
    red = None if hit is None else hr.HyperReduction(info=hit[1], **hit[0])
    if red is not None:
        red.info.update(source="cache", cache_error=None)
    else:
        cuff = fh.build_hyper_cuff(geometry, thickness, young_modulus, poisson_ratio,
                                   level=level, delta=linear.delta, patch_gap=patch_gap_value(patch_gap),
                                   law=law, ogden_alpha=ogden_alpha)
        try:
            red = hr.identify(cuff, hr.linear_bonded(linear), max_force=max_force,
                              max_moment=max_moment, rays=rays, progress=progress)
        except ConvergenceError as exc:
            name = "neo-Hookean" if law == "neo_hookean" else "Ogden"
            raise ConfigError(f"the {name} model's identification failed: {exc}, at a "
                              f"pose the range asks for ({max_force:g} N, {max_moment:g} N*m "
                              f"moves this cuff too far); expected a smaller "
                              f"tissue.continuum.max_force / max_moment",
                              key="tissue.continuum.max_force") from None
        red.info["seconds_identify"] = time.perf_counter() - t0
        error = write_cache_entry(path, key, red.arrays(), red.info)
        red.info.update(source="identified", cache_error=error)
    red.info.update(path=str(path), seconds=time.perf_counter() - t0)
    held_out = red.info.get("held_out_normal_pct")
    if held_out is not None and not held_out <= HELD_OUT_LIMIT_PCT:
        # a cubic that swings between its rays: refused, whatever the law
        raise ConfigError(f"the reduced model cannot follow this layer over its range: on "
                          f"identification rays left out of the fit its patch forces are "
                          f"{held_out:.1f} % of the peak off (limit "
                          f"{HELD_OUT_LIMIT_PCT:g} %); expected a smaller "
                          f"tissue.continuum.max_force / max_moment (the loads you apply)",
                          key="tissue.continuum.max_force")
    return red


#: bump when the Ogden exponent's identification changes: old entries are then ignored
OGDEN_FORMAT_VERSION = 1


def ogden_alpha(stiffening, radius, thickness, young_modulus, poisson_ratio, force_max, *,
                cache_dir=None):
    """The Ogden exponent alpha [-] whose punch curve stiffens as the indenter curve does.

    The indenter test simulated on the layer (a rigid flat punch of ``radius`` [m] on the
    bonded layer of ``thickness`` [m], E [Pa], nu), fitted with the exponential law up to
    ``force_max`` [N] as the indenter data were (docs/model.md 10.8), gives ``stiffening``
    beta [1/m] at alpha (:func:`~phri_spring.physics.hyperelastic.punch_ogden.ogden_alpha_from_stiffening`);
    cached under a key of these inputs.

    Raises
    ------
    ConfigError
        No alpha in the searched range gives this stiffening (key ``tissue.stiffening``).
    UsageError
        scikit-fem (extra ``fe``) is missing and the cache has no entry.
    """
    h = hashlib.sha256()
    h.update(f"phri-spring Ogden alpha v{OGDEN_FORMAT_VERSION}\n".encode())
    for value in (stiffening, radius, thickness, young_modulus, poisson_ratio, force_max):
        h.update(np.float64(value).tobytes())
    key = h.hexdigest()
    folder = Path(cache_dir).expanduser() if cache_dir is not None else default_cache_dir()
    path = folder / f"ogden-alpha-{key[:32]}.npz"
    hit = read_cache_entry(path, key, dict(alpha=(1,)))
    if hit is not None:
        return float(hit[0]["alpha"][0])
    from ...physics.hyperelastic.punch_ogden import ogden_alpha_from_stiffening
    try:
        alpha = ogden_alpha_from_stiffening(stiffening, radius, thickness, young_modulus,
                                            poisson_ratio, force_max)
    except ValueError as exc:
        raise ConfigError(f"no Ogden exponent matches the indenter curve: {exc}",
                          key="tissue.stiffening") from None
    except ConvergenceError as exc:
        raise ConfigError(f"the indenter FE that identifies the Ogden exponent failed: {exc}; "
                          "give tissue.continuum.ogden_alpha instead",
                          key="tissue.continuum.ogden_alpha") from None
    write_cache_entry(path, key, dict(alpha=np.array([alpha])),
                      dict(stiffening=float(stiffening), radius=float(radius)))
    return float(alpha)
