"""The tissue's condensed surface stiffness on disk: a build cache and users' own FE exports.

* :func:`load_or_build_operators` returns the built-in FE's K and its local-normal
  output N (a :class:`~phri_spring.physics.continuum.tissue.SurfaceOperators`), from a disk
  cache keyed by everything K depends on, building and caching them when needed. A
  corrupt or unreadable cache entry is rebuilt; a cache folder that cannot be written
  is skipped (the matrices are still returned). :func:`load_or_build` is the same as
  ``(K, info)`` with N in ``info['N']``.
* :func:`load_surface_stiffness` reads a user's own FE export (``docs/coupled-fe.md``,
  "Using your own FE"): an ``.npz`` with ``K`` (6n x 6n or 3n x 3n, SI units, the patch
  dof ordering of :func:`phri_spring.physics.continuum.tissue.condensed_surface_stiffness`)
  and ``labels`` (the n patch labels, in the geometry's order). Every problem is a
  :class:`~phri_spring.errors.DataError` naming the file and what was expected.
"""

from __future__ import annotations

import hashlib
import os
import time
import zipfile
from pathlib import Path

import numpy as np

from ...errors import ConfigError, DataError
from ...physics.continuum import tissue as fe_tissue
from ...physics.continuum.reading import grouped_by_patch
from ..outputs.atomic import atomic_file

__all__ = ["CACHE_FORMAT_VERSION", "default_cache_dir", "cache_key", "load_or_build_operators",
           "load_or_build", "load_surface_stiffness", "SYMMETRY_RTOL"]

#: bump when the FE or the file layout changes: old cache entries are then ignored
#: (3: patch gaps, tissue.continuum.patch_gap, and the angular seam at a patch edge;
#: 4: N's rows split by skin node, what a patch's sensor reads)
CACHE_FORMAT_VERSION = 4
#: relative tolerance (of the largest entry) of the symmetry check of a user's K
SYMMETRY_RTOL = 1e-8


def default_cache_dir() -> Path:
    """The cache folder.

    ``$PHRI_SPRING_CACHE``, else ``$XDG_CACHE_HOME/phri-spring``, else
    ``~/.cache/phri-spring``.
    """
    env = os.environ.get("PHRI_SPRING_CACHE")
    if env:
        return Path(env).expanduser()
    xdg = os.environ.get("XDG_CACHE_HOME")
    if xdg:
        return Path(xdg).expanduser() / "phri-spring"
    return Path("~/.cache/phri-spring").expanduser()


def patch_gap_value(patch_gap) -> float:
    """The patch gap [m] the FE is built with: ``fe_tissue.DEFAULT_PATCH_GAP`` for None."""
    return fe_tissue.DEFAULT_PATCH_GAP if patch_gap is None else float(patch_gap)


def cache_key(geometry, thickness, poisson_ratio, *, level=fe_tissue.DEFAULT_LEVEL,
              length_factor=fe_tissue.DEFAULT_LENGTH_FACTOR, ends="fixed",
              patch_gap=None, bone=None) -> str:
    """SHA-256 (hex) of everything the E = 1 matrices depend on.

    Geometry arrays (labels, x, radius, row width, theta, span, points), thickness,
    Poisson ratio, mesh level, modelled length, end condition, patch gap (None: the
    default, ``fe_tissue.DEFAULT_PATCH_GAP``) and the format version; on a limb that is
    not a circular cylinder, or with a ``bone``, the layer's shape too (its skin on 64 rays
    per row, the taper, the bone: two limbs with the same patch points but different
    outlines do not share an entry). Young's modulus is not part of it (K is linear in E).
    """
    h = hashlib.sha256()
    h.update(f"phri-spring surface stiffness v{CACHE_FORMAT_VERSION}\n".encode())
    h.update("\x1f".join(geometry.labels).encode())
    for name in ("x", "radius", "row_width", "theta", "span", "points"):
        arr = np.ascontiguousarray(np.asarray(getattr(geometry, name), dtype="<f8"))
        h.update(name.encode())
        h.update(str(arr.shape).encode())
        h.update(arr.tobytes())
    for value in (thickness, poisson_ratio, length_factor, patch_gap_value(patch_gap)):
        h.update(np.float64(value).tobytes())
    h.update(f"level={int(level)};ends={ends}".encode())
    shape = fe_tissue.layer_shape(geometry, float(thickness), bone)
    if shape is not None:       # a circular cylinder's key is as before
        h.update(shape.fingerprint())
    return h.hexdigest()


def read_cache_entry(path: Path, key: str, shapes: dict):
    """(arrays, info) of a cache file written by :func:`write_cache_entry`, or None when it
    is missing, stale (another key), corrupt, or an array is not finite or not of its shape.

    ``shapes`` maps each array's name to its expected shape (None for a length of any
    size); ``info`` holds the scalars.
    """
    try:
        with np.load(path, allow_pickle=False) as z:
            if str(z["key"]) != key:
                return None
            arrays = {name: np.array(z[name], dtype=float) for name in shapes}
            info = {k[5:]: z[k].item() for k in z.files if k.startswith("info_")}
    except Exception:  # noqa: BLE001 - any unreadable entry is rebuilt, never an error
        return None
    if any(arrays[k].ndim != len(s)
           or any(want is not None and got != want for got, want in zip(arrays[k].shape, s))
           or not np.all(np.isfinite(arrays[k])) for k, s in shapes.items()):
        return None
    return arrays, info


def write_cache_entry(path: Path, key: str, arrays: dict, info: dict) -> str | None:
    """Write ``key``, the arrays and the scalars of ``info`` atomically; return None, or the
    reason the file could not be written."""
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        meta = {f"info_{k}": np.asarray(v) for k, v in info.items()
                if isinstance(v, (int, float, str, bool))}
        with atomic_file(path) as tmp:
            with open(tmp, "wb") as fh:
                np.savez(fh, key=np.asarray(key), **arrays, **meta)
    except OSError as exc:
        return f"{exc.strerror or exc} ({path})"
    return None


def load_or_build_operators(geometry, thickness, young_modulus, poisson_ratio, *,
                            cache_dir=None, level: int = fe_tissue.DEFAULT_LEVEL,
                            length_factor: float = fe_tissue.DEFAULT_LENGTH_FACTOR,
                            ends: str = "fixed", patch_gap=None,
                            bone=None) -> fe_tissue.SurfaceOperators:
    """The built-in FE's condensed surface stiffness and normal-force output, cached on disk.

    Parameters
    ----------
    geometry : CuffGeometry
    thickness : float
        Tissue thickness [m], 0 < t < R.
    young_modulus : float
        E [Pa] > 0.
    poisson_ratio : float
        nu [-], -1 < nu < 0.5.
    cache_dir : str or path-like, optional
        Cache folder; default :func:`default_cache_dir`.
    level, length_factor, ends
        FE settings, see :func:`phri_spring.physics.continuum.tissue.condensed_surface_operators`.
    patch_gap : float, optional
        Free skin between neighbouring patches [m] (``tissue.continuum.patch_gap``); None:
        ``fe_tissue.DEFAULT_PATCH_GAP``.
    bone : sequence (y_c, z_c, r_b) [m], optional
        A circular bone (``geometry.bone``); None: the skin moved inward by the thickness.

    Returns
    -------
    SurfaceOperators
        ``K`` (ndarray (6n, 6n), the condensed surface stiffness for this E, SI units,
        patch-major dofs), ``N`` (ndarray (n, 6n), the local-normal output for this E
        [N/m, N/rad]) and ``info``: ``source`` (``'cache'`` or ``'built'``), ``path``
        (the cache file), ``key``, ``seconds`` (time spent here), ``cache_error`` (None,
        or why the cache was not written), and the FE's mesh figures (``level``,
        ``n_dofs``, ...).

    Raises
    ------
    ValueError
        Thickness, E or nu out of range, rows of different radii.
    ConfigError
        ``tissue.continuum.patch_gap``: a gap that leaves a patch no plate.
    UsageError
        The FE has to be built and scikit-fem (extra ``fe``) is not installed.
    """
    t0 = time.perf_counter()
    fe_tissue.check_material(thickness=thickness, poisson_ratio=poisson_ratio,
                             young_modulus=young_modulus,
                             radius=fe_tissue.reference_radius(geometry))
    gap = patch_gap_value(patch_gap)
    problem = fe_tissue.patch_gap_problem(geometry, gap)
    if problem is not None:
        raise ConfigError(problem, key="tissue.continuum.patch_gap")
    n = geometry.n
    key = cache_key(geometry, thickness, poisson_ratio, level=level,
                    length_factor=length_factor, ends=ends, patch_gap=gap, bone=bone)
    folder = Path(cache_dir).expanduser() if cache_dir is not None else default_cache_dir()
    path = folder / f"surface-stiffness-{key[:32]}.npz"
    hit = read_cache_entry(path, key, {"K": (6 * n, 6 * n), "N": (n, 6 * n),
                                       "parts": (None, 6 * n), "part_patch": (None,)})
    if hit is not None and not _parts_fit(hit[0], n):
        hit = None
    E = float(young_modulus)
    if hit is not None:
        arrays, meta = hit
        K1, N1, parts, owner = (arrays["K"], arrays["N"], arrays["parts"],
                                arrays["part_patch"].astype(np.int64))
        info = dict(meta, source="cache", cache_error=None)
    else:
        ops = fe_tissue.condensed_surface_operators(geometry, thickness, 1.0, poisson_ratio,
                                                    level=level, length_factor=length_factor,
                                                    ends=ends, patch_gap=gap, bone=bone)
        K1, N1, parts, owner = ops.K, ops.N, ops.parts, ops.part_patch
        info = dict(ops.info, source="built")
        info["cache_error"] = write_cache_entry(path, key, {"K": K1, "N": N1, "parts": parts,
                                                            "part_patch": owner}, ops.info)
    info.update(path=str(path), key=key, seconds=time.perf_counter() - t0)
    return fe_tissue.SurfaceOperators(K=K1 * E, N=N1 * E, info=info, parts=parts * E,
                                      part_patch=owner)


def _parts_fit(arrays, n) -> bool:
    """A cached node split that belongs to its N: one patch per row, ascending, every
    patch present."""
    return grouped_by_patch(arrays["part_patch"], len(arrays["parts"]), n)


def load_or_build(geometry, thickness, young_modulus, poisson_ratio, **kwargs):
    """:func:`load_or_build_operators` as ``(K, info)``, with N in ``info['N']``.

    Parameters
    ----------
    geometry, thickness, young_modulus, poisson_ratio, **kwargs
        As :func:`load_or_build_operators`.

    Returns
    -------
    K : ndarray, shape (6n, 6n)
        Condensed surface stiffness for this E (SI units, patch-major dofs).
    info : dict
        The operators' ``info``, ``N`` (ndarray (n, 6n), the local-normal output for
        this E [N/m, N/rad]) and ``N_parts`` (``(parts, part_patch)`` of
        :class:`~phri_spring.physics.continuum.tissue.SurfaceOperators`).
    """
    ops = load_or_build_operators(geometry, thickness, young_modulus, poisson_ratio, **kwargs)
    return ops.K, dict(ops.info, N=ops.N, N_parts=(ops.parts, ops.part_patch))


def load_surface_stiffness(path, geometry) -> np.ndarray:
    """A user's own condensed surface stiffness (``.npz`` with ``K`` and ``labels``).

    Parameters
    ----------
    path : str or path-like
        The ``.npz`` file.
    geometry : CuffGeometry
        Its labels must equal the file's ``labels``, in order.

    Returns
    -------
    ndarray, shape (6n, 6n) or (3n, 3n)
        K in SI units, symmetrised ((K + K^T) / 2).

    Raises
    ------
    DataError
        One line naming the file and what was expected: missing or unreadable file,
        not an npz, missing ``K`` or ``labels``, wrong shape, labels that differ from
        the geometry's, non-finite entries, not symmetric (relative tolerance
        ``SYMMETRY_RTOL`` of the largest entry), not positive definite.
    """
    p = Path(path)
    n = geometry.n
    if not p.exists():
        raise DataError("file not found; expected an .npz with arrays K and labels", file=p)
    if p.is_dir():
        raise DataError("is a folder; expected an .npz file with arrays K and labels", file=p)
    try:
        z = np.load(p, allow_pickle=False)
    except (OSError, ValueError, EOFError, zipfile.BadZipFile) as exc:
        kind = "unreadable" if isinstance(exc, OSError) else "not an .npz archive"
        raise DataError(f"{kind}; expected an .npz with arrays K and labels "
                        "(numpy.savez)", file=p) from None
    if not isinstance(z, np.lib.npyio.NpzFile):
        raise DataError("is a single .npy array, not an .npz archive; expected an .npz with "
                        "arrays K and labels (numpy.savez)", file=p)
    with z:
        missing = [k for k in ("K", "labels") if k not in z.files]
        if missing:
            raise DataError(f"missing array {missing[0]!r}; expected arrays K "
                            f"({6 * n} x {6 * n} or {3 * n} x {3 * n}) and labels "
                            f"({n} patch labels)", file=p, key=missing[0])
        try:
            K = np.asarray(z["K"])
            labels = np.asarray(z["labels"])
        except (ValueError, OSError, zipfile.BadZipFile, EOFError):
            raise DataError("an array cannot be read (corrupt, or saved with pickled "
                            "objects); expected plain numeric K and string labels",
                            file=p) from None
    if labels.ndim != 1 or labels.dtype.kind not in "US":
        raise DataError(f"expected {n} strings, got an array of dtype {labels.dtype} "
                        f"and shape {labels.shape}", file=p, key="labels")
    got = tuple(x.decode("utf-8", "replace") if isinstance(x, bytes) else str(x)
                for x in labels.tolist())
    if got != tuple(geometry.labels):
        raise DataError(f"patch labels {list(got)} do not match the geometry's "
                        f"{list(geometry.labels)} (same labels, same order expected)",
                        file=p, key="labels")
    if K.dtype.kind not in "fiu":
        raise DataError(f"expected numbers, got dtype {K.dtype}", file=p, key="K")
    if K.shape not in ((6 * n, 6 * n), (3 * n, 3 * n)):
        raise DataError(f"shape {K.shape}; expected ({6 * n}, {6 * n}) (force and moment "
                        f"per patch) or ({3 * n}, {3 * n}) (force per patch) for {n} patches",
                        file=p, key="K")
    K = K.astype(float)
    if not np.all(np.isfinite(K)):
        raise DataError("has NaN or infinite entries; expected finite numbers (SI units)",
                        file=p, key="K")
    scale = float(np.max(np.abs(K)))
    asym = float(np.max(np.abs(K - K.T)))
    if asym > SYMMETRY_RTOL * scale:
        raise DataError(f"not symmetric: max |K - K^T| = {asym:.3g} is more than "
                        f"{SYMMETRY_RTOL:g} of the largest entry {scale:.3g}",
                        file=p, key="K")
    K = 0.5 * (K + K.T)
    try:
        if scale == 0:
            raise np.linalg.LinAlgError
        np.linalg.cholesky(K)
    except np.linalg.LinAlgError:
        raise DataError("not positive definite (Cholesky failed); expected the stiffness "
                        "of tissue on a fixed bone", file=p, key="K") from None
    return K
