"""3D limb scans as the cuff's surface: reading the mesh, its unit and frame (docs/scans.md).

``geometry.scan: {file: PATH, unit: mm|m, origin: [x, y, z], axis: [dx, dy, dz],
y_axis: [dx, dy, dz]}`` (optional ``max_triangles``, ``smoothing`` [m]) places the cuff on a
surface scan of the limb: STL (binary or ASCII), OBJ or PLY, read with trimesh (the ``scan``
extra). ``origin``, ``axis`` and ``y_axis`` are in the scan's frame and unit; the cuff frame's
origin is ``origin``, its +x is ``axis`` normalised, its +y is ``y_axis`` made orthogonal to +x,
its +z is x cross y.

:func:`load_scan` returns the mesh as plain arrays in metres in the cuff frame;
:func:`scan_elements` goes on to the elements' points, normals, areas and turnings
(:func:`phri_spring.physics.limb.scan_sections.scan_element_geometry`). A file that is not a mesh,
a mesh that is too large, an implausible size for the unit, a bad frame, or a scan the
elements cannot be placed on is refused in one line naming the file or the key.
"""

from __future__ import annotations

import os
import struct
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import ConfigError, ConfigTypeError, DataError, ModelInputError, UsageError
from ..physics.limb.scan_sections import (ScanElements, prepare_scan_mesh,
                                     scan_element_geometry)

__all__ = ["SCAN_KEY", "SCAN_KEYS", "UNITS", "MAX_TRIANGLES", "PLAUSIBLE_SIZE_M", "MESH_SUFFIXES",
           "ScanFrame", "LoadedScan", "ScanCuff", "scan_frame", "read_mesh", "load_scan",
           "scan_elements", "scan_cuff"]

SCAN_KEY = "geometry.scan"
#: the keys of ``geometry.scan`` (``max_triangles`` and ``smoothing`` are optional)
SCAN_KEYS = ("file", "unit", "origin", "axis", "y_axis", "max_triangles", "smoothing")
_REQUIRED = ("file", "unit", "origin", "axis", "y_axis")
#: metres per scan unit
UNITS = {"mm": 1e-3, "m": 1.0}
#: the default bound on a scan's triangles: more is refused before the file is parsed (a
#: limb needs far fewer; decimate a finer scan)
MAX_TRIANGLES = 1_000_000
#: the largest side of a limb scan's bounding box that is believed [m]: outside it the unit is
#: almost certainly wrong
PLAUSIBLE_SIZE_M = (0.01, 3.0)
MESH_SUFFIXES = (".stl", ".obj", ".ply")
#: generous bytes per triangle of a text mesh (an ASCII STL facet is seven lines, about 250
#: bytes at full precision; an OBJ face with its share of vertex, normal and texture lines
#: stays under 200): a file larger than this times ``max_triangles`` is refused unread (a
#: binary STL or a PLY gives its triangle count in its header)
_TEXT_BYTES_PER_TRIANGLE = {".stl": 300, ".obj": 200}
_EXTRA = 'reading a scan needs trimesh: pip install "phri-spring[scan]"'


@dataclass(frozen=True)
class ScanFrame:
    """The cuff frame in the scan's: ``origin`` [m] and ``rotation`` (rows: +x, +y, +z)."""

    origin: np.ndarray
    rotation: np.ndarray

    def to_cuff(self, points_m: np.ndarray) -> np.ndarray:
        """Points (N, 3) in the scan's frame [m] -> cuff frame [m]."""
        return (np.asarray(points_m, float) - self.origin) @ self.rotation.T


@dataclass(frozen=True, eq=False)
class LoadedScan:
    """A scan in the cuff frame: ``vertices`` (V, 3) [m], ``faces`` (F, 3), its ``file``."""

    vertices: np.ndarray
    faces: np.ndarray
    file: Path
    frame: ScanFrame


def _vector(cfg: dict, name: str, path) -> np.ndarray:
    key = f"{SCAN_KEY}.{name}"
    value = cfg[name]
    if not isinstance(value, (list, tuple)) or len(value) != 3:
        raise ConfigTypeError(f"expected a list of 3 numbers, got {value!r}", file=path, key=key)
    if not all(isinstance(c, (int, float)) and not isinstance(c, bool) for c in value):
        raise ConfigTypeError(f"expected a list of 3 numbers, got {value!r}", file=path, key=key)
    vec = np.asarray(value, float)
    if not np.all(np.isfinite(vec)):
        raise ConfigError(f"expected 3 finite numbers, got {value!r}", file=path, key=key)
    return vec


def scan_frame(cfg: dict, scale: float, path=None) -> ScanFrame:
    """The cuff frame from ``origin``, ``axis`` and ``y_axis`` (scan units; ``scale`` m/unit).

    A zero ``axis`` or ``y_axis``, or a ``y_axis`` (nearly) along ``axis``, is a
    :class:`ConfigError` naming the key.
    """
    origin = _vector(cfg, "origin", path) * scale
    axis, y_axis = _vector(cfg, "axis", path), _vector(cfg, "y_axis", path)
    for name, vec in (("axis", axis), ("y_axis", y_axis)):
        if not np.linalg.norm(vec) > 0:
            raise ConfigError(f"expected a non-zero direction, got {vec.tolist()}", file=path,
                              key=f"{SCAN_KEY}.{name}")
    ex = axis / np.linalg.norm(axis)
    y_dir = y_axis / np.linalg.norm(y_axis)
    ey = y_dir - (y_dir @ ex) * ex
    # below ~0.06 degrees apart the +y direction would be set by rounding, not by the user
    if np.linalg.norm(ey) < 1e-3:
        raise ConfigError(f"{y_axis.tolist()} is (nearly) parallel to {SCAN_KEY}.axis "
                          f"{axis.tolist()}; expected a direction across the limb (where theta "
                          "= 0 lies)", file=path, key=f"{SCAN_KEY}.y_axis")
    ey /= np.linalg.norm(ey)
    return ScanFrame(origin, np.vstack([ex, ey, np.cross(ex, ey)]))


def _check_stl(path: Path, size: int, max_triangles: int) -> None:
    """Refuse a truncated, foreign or oversized STL before it is parsed."""
    with open(path, "rb") as fh:
        head = fh.read(84)
    n_bin = struct.unpack("<I", head[80:84])[0] if size >= 84 else 0
    if size >= 84 and size == 84 + 50 * n_bin:          # binary: the size settles it
        if n_bin > max_triangles:
            raise DataError(f"the binary STL has {n_bin:,} triangles, more than the "
                            f"{max_triangles:,} allowed ({SCAN_KEY}.max_triangles); expected a "
                            "decimated scan", file=path)
        return
    if head.lstrip()[:5].lower() == b"solid" and not _binary(path):   # ASCII
        if size > _TEXT_BYTES_PER_TRIANGLE[".stl"] * max_triangles:
            raise DataError(f"the ASCII STL is {size / 1e6:.0f} MB, more than "
                            f"{max_triangles:,} triangles ({SCAN_KEY}.max_triangles) can take; "
                            "expected a decimated scan", file=path)
        return
    raise DataError(f"not an STL mesh: not ASCII (no 'solid' at the start) and not binary (a "
                    f"binary STL of {n_bin:,} triangles, as its header says, has "
                    f"{84 + 50 * n_bin:,} bytes, this file {size:,}: truncated or another "
                    "kind of file)", file=path)


def _binary(path: Path) -> bool:
    """Whether the file's first 4 KB hold a NUL byte (no text mesh does)."""
    with open(path, "rb") as fh:
        return b"\0" in fh.read(4096)


def _check_ply(path: Path, max_triangles: int) -> None:
    with open(path, "rb") as fh:
        head = fh.read(4096)
    if not head.startswith(b"ply"):
        raise DataError("not a PLY mesh (expected the file to start with 'ply')", file=path)
    for line in head.split(b"end_header")[0].splitlines():
        words = line.split()
        if len(words) == 3 and words[0] == b"element" and words[1] == b"face" \
                and words[2].isdigit() and int(words[2]) > max_triangles:
            raise DataError(f"the PLY has {int(words[2]):,} faces, more than the "
                            f"{max_triangles:,} allowed ({SCAN_KEY}.max_triangles); expected a "
                            "decimated scan", file=path)


def read_mesh(path, *, max_triangles: int = MAX_TRIANGLES):
    """Vertices (V, 3) in the file's unit and triangles (F, 3) of a mesh file.

    STL (binary or ASCII), OBJ or PLY, with coincident vertices merged (an STL stores every
    triangle's corners apart). Raises :class:`DataError` naming the file for anything that is
    not such a mesh, an empty one, or one with more than ``max_triangles`` triangles (checked
    from the header or the file size before parsing, so that a huge file is refused at once),
    and :class:`UsageError` when trimesh is not installed.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in MESH_SUFFIXES:
        raise DataError(f"unknown mesh format {suffix or '(no extension)'!r}; expected a "
                        f"surface mesh: {', '.join(MESH_SUFFIXES)}", file=path)
    try:
        size = path.stat().st_size
    except OSError as exc:
        raise DataError(f"cannot read the scan ({exc.strerror or exc})", file=path) from None
    if size == 0:
        raise DataError("empty file; expected a surface mesh", file=path)
    kind = {".stl": "an STL", ".obj": "an OBJ", ".ply": "a PLY"}[suffix]
    if suffix == ".stl":
        _check_stl(path, size, max_triangles)
    elif suffix == ".obj" and _binary(path):
        raise DataError("not an OBJ mesh (binary content; expected OBJ text: v and f lines)",
                        file=path)
    elif suffix == ".ply":
        _check_ply(path, max_triangles)
    if suffix == ".obj" and size > _TEXT_BYTES_PER_TRIANGLE[suffix] * max_triangles:
        raise DataError(f"the file is {size / 1e6:.0f} MB, more than {max_triangles:,} "
                        f"triangles ({SCAN_KEY}.max_triangles) can take; expected a decimated "
                        "scan", file=path)
    try:
        import trimesh
    except ImportError:
        raise UsageError(_EXTRA, file=path) from None
    try:
        # trimesh reports parse failures with many exception types (ValueError, KeyError,
        # IndexError, struct.error, UnicodeDecodeError ...): any of them means "not a mesh"
        mesh = trimesh.load_mesh(str(path), file_type=suffix[1:], process=True)
        vertices = np.asarray(mesh.vertices, dtype=float)
        faces = np.asarray(mesh.faces, dtype=np.int64)
    except MemoryError:
        raise DataError("not enough memory to read the scan; expected a decimated scan",
                        file=path) from None
    except Exception as exc:  # noqa: BLE001 - a third-party parser's failure is bad data
        detail = f"{type(exc).__name__}: {str(exc).splitlines()[0][:120]}" if str(exc) \
            else type(exc).__name__
        raise DataError(f"cannot read as {kind} mesh ({detail}); expected a triangle surface "
                        "mesh of the limb", file=path) from None
    if len(faces) == 0 or len(vertices) < 3:
        raise DataError(f"no triangles in the file; expected {kind} surface mesh of the limb",
                        file=path)
    if len(faces) > max_triangles:
        raise DataError(f"the mesh has {len(faces):,} triangles, more than the "
                        f"{max_triangles:,} allowed ({SCAN_KEY}.max_triangles); expected a "
                        "decimated scan", file=path)
    if not np.all(np.isfinite(vertices)):
        raise DataError("vertex coordinates that are not finite numbers", file=path)
    return vertices, faces


def _scan_config(cfg, config_path):
    if not isinstance(cfg, dict):
        raise ConfigTypeError("expected a mapping {file, unit, origin, axis, y_axis}, got "
                              f"{cfg!r}", file=config_path, key=SCAN_KEY)
    unknown = sorted(str(k) for k in set(cfg) - set(SCAN_KEYS))
    if unknown:
        raise ConfigError(f"unknown key {unknown[0]!r}; expected {', '.join(SCAN_KEYS)}",
                          file=config_path, key=SCAN_KEY)
    missing = [k for k in _REQUIRED if k not in cfg]
    if missing:
        raise ConfigError(f"missing key {missing[0]!r}; expected "
                          f"{', '.join(_REQUIRED)} (max_triangles, smoothing optional)",
                          file=config_path, key=SCAN_KEY)
    if not isinstance(cfg["unit"], str) or cfg["unit"] not in UNITS:
        raise ConfigError(f"expected one of {', '.join(UNITS)}, got {cfg['unit']!r}",
                          file=config_path, key=f"{SCAN_KEY}.unit")
    if not isinstance(cfg["file"], (str, os.PathLike)) or not str(cfg["file"]).strip():
        raise ConfigTypeError(f"expected the path of a mesh file, got {cfg['file']!r}",
                              file=config_path, key=f"{SCAN_KEY}.file")
    limit = cfg.get("max_triangles", MAX_TRIANGLES)
    if isinstance(limit, bool) or not isinstance(limit, int):
        raise ConfigTypeError(f"expected a whole number >= 1, got {limit!r}", file=config_path,
                              key=f"{SCAN_KEY}.max_triangles")
    if limit < 1:
        raise ConfigError(f"expected a whole number >= 1, got {limit!r}", file=config_path,
                          key=f"{SCAN_KEY}.max_triangles")
    smoothing = cfg.get("smoothing")
    if smoothing is not None and (isinstance(smoothing, bool)
                                  or not isinstance(smoothing, (int, float))):
        raise ConfigTypeError(f"expected a length > 0 [m], got {smoothing!r}", file=config_path,
                              key=f"{SCAN_KEY}.smoothing")
    if smoothing is not None and not (np.isfinite(smoothing) and smoothing > 0):
        raise ConfigError(f"expected a length > 0 [m], got {smoothing!r}", file=config_path,
                          key=f"{SCAN_KEY}.smoothing")
    return limit, smoothing


def load_scan(scan_config: dict, config_dir=".", *, config_path=None) -> LoadedScan:
    """Read ``geometry.scan``'s mesh and place it in the cuff frame, in metres.

    ``file`` is relative to ``config_dir``; ``config_path`` (the config file) is named in
    errors about keys. The mesh's size (largest side of its bounding box, in metres) must be
    within :data:`PLAUSIBLE_SIZE_M`, or the unit is refused as :class:`ConfigError` naming
    ``geometry.scan.unit``.
    """
    limit, _ = _scan_config(scan_config, config_path)
    file = Path(config_dir) / Path(os.fspath(scan_config["file"])).expanduser()
    if not file.is_file():
        raise ConfigError(f"scan file {str(file)!r} not found (paths are relative to the "
                          "config file's folder); expected a mesh file", file=config_path,
                          key=f"{SCAN_KEY}.file")
    unit = scan_config["unit"]
    scale = UNITS[unit]
    frame = scan_frame(scan_config, scale, config_path)
    vertices, faces = read_mesh(file, max_triangles=limit)
    size = float(np.ptp(vertices, axis=0).max()) * scale
    lo, hi = PLAUSIBLE_SIZE_M
    if not lo <= size <= hi:
        other = [u for u in UNITS if u != unit]
        raise ConfigError(f"with unit {unit!r} the scan is {size:.3g} m across (largest side of "
                          f"its bounding box); a limb scan is {lo:g} m to {hi:g} m: is the "
                          f"unit {' or '.join(map(repr, other))}?", file=file,
                          key=f"{SCAN_KEY}.unit")
    return LoadedScan(frame.to_cuff(vertices * scale), faces, file, frame)


def scan_elements(scan_config: dict, rows_x, row_widths, theta, span, config_dir=".", *,
                  config_path=None, row_names=None) -> ScanElements:
    """The elements' geometry on ``geometry.scan``'s mesh (for ``CuffGeometry.from_elements``).

    Parameters
    ----------
    scan_config : dict
        The ``geometry.scan`` mapping.
    rows_x, row_widths : array (R,)
        Row positions and widths [m] (cuff frame).
    theta, span : array (J,)
        Element angles and angular widths [rad].
    config_dir : path
        Folder ``file`` is relative to (the config file's).
    config_path, row_names : optional
        The config file and the row labels, for the error messages.

    Raises
    ------
    ConfigError
        A bad key (naming it), a unit that makes the limb implausibly large or small.
    DataError
        A file that is no mesh, too many triangles, or a scan the elements cannot be placed on
        (not closed around the axis at a row, an axis that misses the limb, a band past the
        scan's end), naming the file.
    UsageError
        trimesh is not installed.
    """
    _, smoothing = _scan_config(scan_config, config_path)
    scan = load_scan(scan_config, config_dir, config_path=config_path)
    try:
        return scan_element_geometry(scan.vertices, scan.faces, rows_x, row_widths, theta, span,
                                     smoothing=smoothing, row_names=row_names)
    except ModelInputError as exc:
        if exc.quantity != "scan":
            raise
        raise DataError(f"{exc} ({SCAN_KEY} in the cuff frame)", file=scan.file) from None


@dataclass(frozen=True, eq=False)
class ScanCuff:
    """What the config keeps of ``geometry.scan``: the elements' geometry, the strap's section
    (``strap.model: handles``; None with the hoop), the scan file, and per row the radius of
    the circle of the outline's perimeter [m] (the rows' ``radius`` where one is reported)."""

    elements: ScanElements
    strap_section: object
    file: Path
    radius: np.ndarray


def scan_cuff(scan_config: dict, rows_x, row_widths, theta, span, config_dir=".", *,
              strap_x=None, config_path=None, row_names=None, layout=None) -> ScanCuff:
    """:func:`scan_elements` and, with ``strap_x`` [m], the scan's section there for the
    strap's handles (the scan cut by the plane at ``strap_x``), the scan read once.

    With ``layout`` (a :class:`~phri_spring.physics.cuff.patches.PatchLayout`: sensor patches
    anywhere) the elements are its patches instead of the grid of ``rows_x`` x ``theta``:
    each patch placed on the scan's cut at its own x as a one-element row of its length and
    angular width, in the layout's order; the outlines (and radii) are per distinct x, by
    increasing x.

    Raises as :func:`scan_elements`; a strap plane that misses the scan or is not closed
    around the axis is a :class:`DataError` naming the file and ``strap.axial_position``.
    """
    from ..physics.limb.scan_strap import scan_strap_section

    _, smoothing = _scan_config(scan_config, config_path)
    scan = load_scan(scan_config, config_dir, config_path=config_path)
    try:
        mesh = prepare_scan_mesh(scan.vertices, scan.faces)
        if layout is None:
            elements = scan_element_geometry(mesh, None, rows_x, row_widths, theta, span,
                                             smoothing=smoothing, row_names=row_names)
        else:
            elements = _layout_elements(mesh, layout, smoothing)
    except ModelInputError as exc:
        if exc.quantity != "scan":
            raise
        raise DataError(f"{exc} ({SCAN_KEY} in the cuff frame)", file=scan.file) from None
    strap = None
    if strap_x is not None:
        try:
            strap = scan_strap_section(mesh, float(strap_x), smoothing,
                                       name="the strap (strap.axial_position)")
        except ModelInputError as exc:
            if exc.quantity != "scan":
                raise
            raise DataError(f"{exc} ({SCAN_KEY} in the cuff frame)", file=scan.file,
                            key="strap.axial_position") from None
    perimeter = [float(np.linalg.norm(np.roll(yz, -1, axis=0) - yz, axis=1).sum())
                 for yz in elements.outlines]
    return ScanCuff(elements, strap, scan.file, np.array(perimeter) / (2 * np.pi))


def _layout_elements(mesh, layout, smoothing) -> ScanElements:
    """The :class:`ScanElements` of a free patch layout on a prepared scan mesh: the patches
    sharing an axial position and a length are placed together (one cut of the scan)."""
    x, ln = np.asarray(layout.x, float), np.asarray(layout.length, float)
    th, w = np.asarray(layout.theta, float), np.asarray(layout.width, float)
    n = len(x)
    points, normals = np.empty((n, 3)), np.empty((n, 3))
    areas, turning, arcs = np.empty(n), np.empty(n), np.empty(n)
    outlines, smooth = {}, {}
    for xv, lv in sorted(set(zip(x.tolist(), ln.tolist()))):
        idx = np.flatnonzero((x == xv) & (ln == lv))
        el = scan_element_geometry(mesh, None, [xv], [lv], th[idx], w[idx], smoothing=smoothing,
                                   row_names=[f"{layout.labels[idx[0]]} (patch)"])
        points[idx], normals[idx] = el.points, el.normals
        areas[idx], turning[idx], arcs[idx] = el.areas, el.turning, el.arcs
        outlines.setdefault(xv, el.outlines[0])
        smooth.setdefault(xv, float(el.smoothing[0]))
    order = sorted(outlines)
    return ScanElements(points=points, normals=normals, areas=areas, turning=turning,
                        arcs=arcs, outlines=tuple(outlines[k] for k in order),
                        smoothing=np.array([smooth[k] for k in order]))
