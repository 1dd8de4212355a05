"""The YAML config of docs/model.md section 6: safe loading and validation.

Loading never runs code (``yaml.SafeLoader``: a ``!!python/...`` tag is an
error), unknown keys are rejected with the closest valid name, duplicate keys
are rejected, and every value is checked. Errors are :class:`ConfigError`
naming the file and the key path (``cuff.stiffness.per_angle``).

The result is a plain :class:`Config` dataclass holding arrays. The schema every
section is checked against (and :func:`config_units`) lives in
:mod:`phri_spring.io.config.schema`, the bounded YAML loader (:func:`load_yaml`) in
:mod:`phri_spring.io.config.yaml_loader`.
"""

from __future__ import annotations

import difflib
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Optional

import numpy as np

from ...errors import ConfigError
# the wrench-log columns of docs/model.md section 7, importable from here too
from ..logs.columns import LOG_COLUMNS, LOG_GROUP_KEY  # noqa: F401
from .geometry import (check_scan_alone, geometry_sections, per_row_values, read_scan,
                              scan_geometry)
from .geometry import parse_bone
from .history import ACTIVATION_FACTOR
# the schema's unit table, importable from here too
from .schema import config_units, validate_config_mapping  # noqa: F401
from .tolerance import parse_tolerance
from .values import check_plausible
from .values import resolve_stiffness  # noqa: F401 - importable from here too
from .yaml_loader import (MAX_INT_DIGITS, MAX_YAML_BYTES, MAX_YAML_DEPTH,  # noqa: F401
                          MAX_YAML_VALUES, load_yaml)

__all__ = ["Config", "load_config", "config_from_dict", "resolve_stiffness", "LOG_COLUMNS"]


# --------------------------------------------------------------------------- result
@dataclass(eq=False)
class Config:
    """A validated config, as plain values and arrays (SI units)."""

    path: Optional[Path]
    name: str
    row_labels: tuple
    row_x: np.ndarray
    radius: np.ndarray
    row_width: np.ndarray
    angle_start_deg: float
    angle_step_deg: float
    angle_count: int
    angle_width_deg: Optional[float]
    labels: tuple
    #: the rows' sections (physics.sections objects, one per row), None: circles of radius
    sections: Optional[tuple] = field(default=None, kw_only=True)
    #: taper half-angle alpha [deg] (geometry.taper_deg)
    taper_deg: float = field(default=0.0, kw_only=True)
    #: geometry.scan, read (io.scan.ScanCuff): the elements' geometry on the scan; None without
    scan: Optional[Any] = field(default=None, kw_only=True, repr=False)
    #: geometry.bone as (y_c, z_c, r_b) [m], None: the skin moved inward by the thickness
    bone: Optional[tuple] = field(default=None, kw_only=True)
    #: cuff.patches (a physics.patches.PatchLayout), None: the rows x angles grid. With
    #: patches, row_labels is ("",) and angle_count the patch count (one "row"), and
    #: patch_row_x the positions where radius / sections are given
    patches: Optional[object] = field(default=None, kw_only=True)
    patch_row_x: Optional[np.ndarray] = field(default=None, kw_only=True)
    tissue_stiffness: np.ndarray           # (n,), as configured, in tissue_basis
    tissue_basis: str
    indenter_diameter: float
    poisson_ratio: float
    cuff_stiffness: np.ndarray             # (n,) [N/m], inf allowed
    loadcell_position: np.ndarray
    loadcell_rotation: np.ndarray
    loadcell_sign: float
    force_unit: str
    moment_unit: str
    log_columns: dict = field(default_factory=dict)   # spec name -> the log's column name
    log_group: Optional[str] = None        # load_cell.group: TDMS group / MAT struct of the log
    pain_threshold_kpa: float = 120.0
    shear_ratio: Optional[float] = None
    strap_tension: float = 15.0
    strap_model: str = "hoop"
    handle_angles_deg: Optional[tuple] = None
    strap_axial_position: Optional[float] = None
    strap_width: Optional[float] = None          # [m] strap.width (band)
    strap_stiffness: Optional[float] = None      # [N] strap.stiffness (band)
    max_iterations: int = 100
    continuum_thickness: Optional[float] = None        # [m] tissue.continuum.thickness
    continuum_young_modulus: Optional[float] = None    # [Pa] tissue.continuum.young_modulus
    continuum_surface_stiffness: Optional[Path] = None  # a user's FE export (.npz)
    continuum_spread: str = "mean"                     # mean | per_patch
    continuum_patch_gap: Optional[float] = None        # [m] tissue.continuum.patch_gap
    continuum_law: str = "linear"                      # linear | neo_hookean | ogden
    continuum_ogden_alpha: Optional[float] = None      # [-] tissue.continuum.ogden_alpha
    continuum_max_force: float = 70.0                  # [N] tissue.continuum.max_force
    continuum_max_moment: float = 4.0                  # [N*m] tissue.continuum.max_moment
    friction_coefficient: Optional[float] = None       # [-] interface.friction_coefficient
    tissue_law: str = "linear"                         # a name of physics.tissue_laws.TISSUE_LAWS
    # the law's class: pickled by reference with the config, so that worker processes (a
    # design's pool, dask) import the module that defines a law registered in this process
    tissue_law_class: Optional[type] = None
    #: the law's parameters: config key -> (n,) array in the parameter's unit
    tissue_law_parameters: dict = field(default_factory=dict)
    #: tissue.relaxation as (fractions, times_s), or None (elastic)
    tissue_relaxation: Optional[tuple] = None
    activation_factor: float = ACTIVATION_FACTOR       # [-] tissue.activation_factor
    raw: dict = field(default_factory=dict, repr=False)
    #: stiffness CSV files the config reads (inputs: never to be written over)
    stiffness_files: tuple = ()
    #: the 'phri fit-stiffness' CSV tissue_stiffness came from, if any (its SDs are the
    #: stiffness scatter of a Monte Carlo with tissue=from_csv)
    tissue_stiffness_csv: Optional[Path] = None
    #: tolerance.curve (a physics.tolerance.ToleranceCurve), None without the section
    tolerance: Optional[Any] = None

    def geometry(self):
        """The element geometry (:class:`~phri_spring.physics.cuff.geometry.CuffGeometry`) it describes."""
        from ...physics.cuff.geometry import cuff_geometry, section_geometry

        if self.scan is not None:
            return scan_geometry(self)
        if self.patches is not None:
            from ...physics.cuff.patches import patch_geometry

            return patch_geometry(self.patches, self.patch_row_x, self.sections, self.taper_deg,
                                  circular_radius=self.radius if self.sections is None else None)
        if self.sections is None:
            return cuff_geometry(self.row_x, self.radius, self.row_width, self.angle_start_deg,
                                 self.angle_step_deg, self.angle_count, self.angle_width_deg,
                                 row_labels=self.row_labels, taper_deg=self.taper_deg)
        return section_geometry(self.row_x, self.sections, self.row_width,
                                self.angle_start_deg, self.angle_step_deg, self.angle_count,
                                self.angle_width_deg, row_labels=self.row_labels,
                                taper_deg=self.taper_deg)

    @property
    def is_circular_cylinder(self) -> bool:
        """Whether the limb is the circular cylinder of docs/model.md section 1 (no
        geometry.section other than circle, no taper, no scan)."""
        return self.sections is None and self.taper_deg == 0 and self.scan is None

    @property
    def n_rows(self) -> int:
        return len(self.row_labels)

    @property
    def n_elements(self) -> int:
        return len(self.labels)


def _label_list(row_labels, count) -> tuple:
    return tuple(f"{r}{j}" for r in row_labels for j in range(count))


def config_from_dict(data: Any, *, path=None, base_dir=None) -> Config:
    """Validate a parsed config mapping (as from YAML) into a :class:`Config`."""
    if not isinstance(data, dict):
        raise ConfigError(f"expected a mapping at the top level (name, geometry, tissue, cuff, "
                          f"...), got {type(data).__name__}", file=path)
    # the tissue law's parameters are keys of the tissue section too: taken out here by the
    # law the section names, the rest validated strictly (a misspelt key is still refused)
    original = data
    data, law_values, law_keys = _split_law_parameters(data, path)
    root = validate_config_mapping(data, path, {"tissue": law_keys})

    g = root.geometry
    base = Path(base_dir) if base_dir is not None else (Path(path).parent if path else Path("."))
    if root.cuff.patches is not None:
        from .patches import patch_config_geometry

        (row_labels, row_x, radius, row_width, labels, sections, taper, layout,
         patch_row_x) = patch_config_geometry(g, root.cuff.patches, base, path)
        n_rows, n_ang = 1, len(labels)
        angles = (0.0, 0.0, n_ang, None)
    else:
        layout = patch_row_x = None
        (row_labels, row_x, radius, row_width, labels, sections, taper,
         angles) = _grid_geometry(g, path)
        n_rows, n_ang = len(row_labels), angles[2]
    free = layout is not None

    k_t = resolve_stiffness(root.tissue.stiffness, n_rows, n_ang, labels, path=path,
                            key="tissue.stiffness", allow_inf=False, base_dir=base,
                            free_layout=free)
    k_c = resolve_stiffness(root.cuff.stiffness, n_rows, n_ang, labels, path=path,
                            key="cuff.stiffness", allow_inf=True, base_dir=base,
                            free_layout=free)
    for key, k in (("tissue.stiffness", k_t), ("cuff.stiffness", k_c)):
        bad = ~(k >= 1.0)
        check_plausible(k, key, path, f" at {labels[int(np.argmax(bad))]}" if bad.any() else "")
    stiffness_files = tuple(_csv_path(v, base) for v in (root.tissue.stiffness, root.cuff.stiffness)
                            if isinstance(v, str))
    if free and isinstance(root.cuff.patches, str):
        stiffness_files += (_csv_path(root.cuff.patches, base),)

    lc = root.load_cell
    from ...physics.cuff.loadcell import convention_sign, rotation_from_euler_xyz

    if lc.rotation is not None:
        R = np.array(lc.rotation, dtype=float)
        if not (np.all(np.isfinite(R)) and np.allclose(R @ R.T, np.eye(3), atol=1e-6)
                and np.linalg.det(R) > 0):
            raise ConfigError("expected a proper rotation matrix (orthonormal, det +1; "
                              "v_cuff = R v_lc)", file=path, key="load_cell.rotation")
    elif lc.euler_xyz_deg is not None:
        if not all(math.isfinite(a) for a in lc.euler_xyz_deg):
            raise ConfigError(f"expected finite angles [deg], got {list(lc.euler_xyz_deg)}",
                              file=path, key="load_cell.euler_xyz_deg")
        R = rotation_from_euler_xyz(lc.euler_xyz_deg)
    else:
        R = np.eye(3)
    pos = np.array(lc.position, dtype=float)
    if not np.all(np.isfinite(pos)):
        raise ConfigError("expected finite coordinates [m]", file=path, key="load_cell.position")
    check_plausible(pos, "load_cell.position", path)
    unknown_cols = [c for c in lc.columns if c not in LOG_COLUMNS]
    if unknown_cols:
        close = difflib.get_close_matches(unknown_cols[0], LOG_COLUMNS, n=1, cutoff=0.5)
        hint = f"; did you mean {close[0]!r}?" if close else ""
        raise ConfigError(f"unknown log column {unknown_cols[0]!r}{hint} (expected keys among "
                          f"{', '.join(LOG_COLUMNS)}, mapped to the names in your log)",
                          file=path, key=f"load_cell.columns.{unknown_cols[0]}")

    st = root.strap
    if not math.isfinite(st.tension):
        raise ConfigError("expected a finite tension [N]", file=path, key="strap.tension")
    check_plausible(st.tension, "strap.tension", path)
    check_plausible(root.tissue.indenter_diameter, "tissue.indenter_diameter", path)
    itf = root.interface
    for key, value in (("interface.shear_ratio", itf.shear_ratio),
                       ("interface.friction_coefficient", itf.friction_coefficient)):
        if value is not None:
            check_plausible(value, key, path)
    if st.handle_angles is not None and not all(math.isfinite(a) for a in st.handle_angles):
        raise ConfigError(f"expected two finite angles [deg], got {list(st.handle_angles)}",
                          file=path, key="strap.handle_angles")
    if st.axial_position is not None and not math.isfinite(st.axial_position):
        raise ConfigError(f"expected a finite axial position [m], got {st.axial_position!r}",
                          file=path, key="strap.axial_position")
    for key, value in (("strap.axial_position", st.axial_position),
                       ("strap.handle_angles", st.handle_angles)):
        if value is not None:
            check_plausible(value, key, path)
    for key, value, what in (("strap.stiffness", st.stiffness, "tension per unit strain [N]"),
                             ("strap.width", st.width, "axial width [m]")):
        if st.model == "band" and (value is None or not math.isfinite(value)):
            raise ConfigError(f"the band strap needs its finite {what}, got {value!r}",
                              file=path, key=key)
        if st.model != "band" and value is not None:
            raise ConfigError(f"expected {key} only with strap.model: band (the {st.model} strap "
                              "is not elastic)", file=path, key=key)

    scan = None
    if g.scan is not None and st.model == "band":
        raise ConfigError("the band strap is not available on a scanned limb yet (the band's "
                          "path over the scan is not defined); use hoop or handles",
                          file=path, key="geometry.scan")
    if g.scan is not None:
        width = angles[3] if angles[3] is not None else angles[1]
        scan = read_scan(g, st, row_x, row_width, width, base, path, row_labels, layout)
        radius = scan.radius

    law, law_cls, law_params = _tissue_law(root.tissue.law, law_values, n_rows, n_ang,
                                           labels, path, base, free)
    cont = root.tissue.continuum
    if cont is not None:
        check_plausible(cont.thickness, "tissue.continuum.thickness", path)
        if cont.young_modulus is not None:
            check_plausible(cont.young_modulus, "tissue.continuum.young_modulus", path)
        if cont.patch_gap:                       # 0: tiled plates
            check_plausible(cont.patch_gap, "tissue.continuum.patch_gap", path)
        for key in ("max_force", "max_moment"):
            if getattr(cont, key) is not None:
                check_plausible(getattr(cont, key), f"tissue.continuum.{key}", path)
    if cont is not None and cont.ogden_alpha is not None and cont.law != "ogden":
        raise ConfigError(f"applies to tissue.continuum.law ogden only, got law {cont.law!r}",
                          file=path, key="tissue.continuum.ogden_alpha")
    surface = None
    if cont is not None and cont.surface_stiffness is not None:
        surface = Path(cont.surface_stiffness)
        surface = surface if surface.is_absolute() else base / surface

    return Config(
        path=Path(path) if path else None, name=root.name, row_labels=row_labels, row_x=row_x,
        radius=radius, row_width=row_width, angle_start_deg=angles[0],
        angle_step_deg=angles[1], angle_count=int(angles[2]), angle_width_deg=angles[3],
        labels=labels, sections=sections, taper_deg=taper, patches=layout,
        bone=None if g.scan is not None else parse_bone(g.bone, sections, radius, path),
        patch_row_x=patch_row_x, tissue_stiffness=k_t, tissue_basis=root.tissue.basis,
        scan=scan,
        indenter_diameter=float(root.tissue.indenter_diameter),
        poisson_ratio=float(root.tissue.poisson_ratio), cuff_stiffness=k_c,
        loadcell_position=pos, loadcell_rotation=R, loadcell_sign=convention_sign(lc.convention),
        force_unit=lc.force_unit, moment_unit=lc.moment_unit,
        log_columns=dict(lc.columns), log_group=lc.group or None,
        pain_threshold_kpa=float(root.interface.pain_threshold_kpa),
        shear_ratio=root.interface.shear_ratio, strap_tension=float(st.tension),
        strap_model=st.model,
        handle_angles_deg=None if st.handle_angles is None else tuple(st.handle_angles),
        strap_axial_position=st.axial_position, strap_width=st.width,
        strap_stiffness=st.stiffness, max_iterations=int(root.solver.max_iterations),
        raw=original, stiffness_files=stiffness_files + ((surface,) if surface else ())
        + tuple(_csv_path(v, base) for v in law_values.values() if isinstance(v, str))
        + ((scan.file,) if scan is not None else ()),
        tissue_stiffness_csv=_csv_path(root.tissue.stiffness, base),
        continuum_thickness=None if cont is None else float(cont.thickness),
        continuum_young_modulus=None if cont is None or cont.young_modulus is None
        else float(cont.young_modulus),
        continuum_surface_stiffness=surface,
        continuum_spread="mean" if cont is None else cont.spread,
        continuum_patch_gap=None if cont is None or cont.patch_gap is None
        else float(cont.patch_gap),
        continuum_law="linear" if cont is None else cont.law,
        continuum_ogden_alpha=None if cont is None or cont.ogden_alpha is None
        else float(cont.ogden_alpha),
        continuum_max_force=_range(cont, "max_force", 0),
        continuum_max_moment=_range(cont, "max_moment", 1),
        friction_coefficient=None if root.interface.friction_coefficient is None
        else float(root.interface.friction_coefficient),
        tissue_law=law, tissue_law_class=law_cls, tissue_law_parameters=law_params,
        tissue_relaxation=None if root.tissue.relaxation is None else
        (tuple(root.tissue.relaxation.fractions), tuple(root.tissue.relaxation.times_s)),
        activation_factor=float(root.tissue.activation_factor),
        tolerance=parse_tolerance(root.tolerance, path),
    )


def _grid_geometry(g, path):
    """The rows x angles grid of the geometry schema: (row_labels, row_x, radius,
    row_width, labels, sections, taper, (start, step, count, width))."""
    for k in ("rows", "row_width", "angles"):
        if getattr(g, k) is None:
            raise ConfigError("missing required key (or give cuff.patches)", file=path,
                              key=f"geometry.{k}")
    row_labels = tuple(str(k) for k in g.rows)
    if len(set(row_labels)) != len(row_labels):
        raise ConfigError("row labels must be unique", file=path, key="geometry.rows")
    row_x = np.array([float(v) for v in g.rows.values()])
    if not np.all(np.isfinite(row_x)):
        raise ConfigError("expected finite axial positions [m]", file=path, key="geometry.rows")
    n_rows, n_ang = len(row_labels), g.angles.count
    # before the labels and per-element arrays exist: a count of a billion must end in one
    # line, not in the out-of-memory killer; and first, naming the count (the key to change)
    # rather than the slivers such a grid is made of
    from ..memory.budget import check_elements

    check_elements(n_rows, n_ang, path=path)
    check_plausible(row_x, "geometry.rows", path)
    if g.scan is not None:
        check_scan_alone(g, path)
        sections, radius, taper = None, None, 0.0
    else:
        # the radius (and every section's distance from the axis) is checked against
        # physics.sections.RHO_RANGE_M there
        sections, radius, taper = geometry_sections(g, n_rows, path)
    row_width = per_row_values(g.row_width, n_rows, path, "geometry.row_width")
    check_plausible(row_width, "geometry.row_width", path)
    for k in ("start", "step"):
        if not math.isfinite(getattr(g.angles, k)):
            raise ConfigError("expected a finite angle [deg]", file=path, key=f"geometry.angles.{k}")
    check_plausible(g.angles.start, "geometry.angles.start", path)
    if n_ang > 1 and not g.angles.step > 0:
        raise ConfigError(f"expected a positive step [deg], got {g.angles.step}", file=path,
                          key="geometry.angles.step")
    width = g.angles.width if g.angles.width is not None else g.angles.step
    if not width > 0:
        raise ConfigError("expected a positive angular width [deg] (give geometry.angles.width "
                          "when count is 1)", file=path, key="geometry.angles.width")
    if n_ang * width > 360.0 + 1e-9:
        raise ConfigError(f"{n_ang} elements of {width} deg span more than 360 deg", file=path,
                          key="geometry.angles")
    if n_ang > 1:
        check_plausible(g.angles.step, "geometry.angles.step", path)
    if g.angles.width is not None:
        check_plausible(g.angles.width, "geometry.angles.width", path)
    labels = _label_list(row_labels, n_ang)
    angles = (float(g.angles.start), float(g.angles.step), int(n_ang),
              None if g.angles.width is None else float(g.angles.width))
    return row_labels, row_x, radius, row_width, labels, sections, taper, angles



def _csv_path(value, base: Path) -> Optional[Path]:
    """The CSV file a stiffness value names, resolved against the config's folder."""
    if not isinstance(value, str):
        return None
    return Path(value) if Path(value).is_absolute() else base / value


#: the hyperelastic continuum laws' default identified range (max_force [N], max_moment
#: [N*m]): the Ogden layer stiffens too steeply for one cubic over the neo-Hookean one's
#: (docs/model.md 10.9); 60 N / 2.1 N*m is the paper's largest loads with 8 % to spare
CONTINUUM_RANGES = {"linear": (70.0, 4.0), "neo_hookean": (70.0, 4.0), "ogden": (60.0, 2.1)}


def _range(cont, key: str, i: int) -> float:
    """tissue.continuum.max_force / max_moment, or the law's default."""
    law = "linear" if cont is None else cont.law
    value = None if cont is None else getattr(cont, key)
    return float(CONTINUUM_RANGES[law][i] if value is None else value)


def _split_law_parameters(data: dict, path):
    """(data without the tissue law's parameter keys, those keys' values, the law's keys)."""
    from ...physics.laws import TISSUE_LAWS

    tissue = data.get("tissue")
    if not isinstance(tissue, dict) or not isinstance(tissue.get("law", "linear"), str):
        return data, {}, []
    # a stiffening rate without a law asks for the exponential law (0: linear, exactly)
    law = tissue.get("law", "exponential" if "stiffening" in tissue else "linear")
    if "law" not in tissue and law != "linear":
        data = {**data, "tissue": {**tissue, "law": law}}
        tissue = data["tissue"]
    if law not in TISSUE_LAWS:  # before its parameters are taken for unknown keys
        close = difflib.get_close_matches(law, list(TISSUE_LAWS), n=1, cutoff=0.5)
        hint = f"; did you mean {close[0]!r}?" if close else ""
        raise ConfigError(f"unknown tissue law {law!r}{hint} (expected one of "
                          f"{', '.join(sorted(TISSUE_LAWS))})", file=path, key="tissue.law")
    keys = [p.key for p in TISSUE_LAWS[law].parameters]
    values = {k: v for k, v in tissue.items() if k in keys}
    if not values:
        return data, {}, keys
    rest = {k: v for k, v in tissue.items() if k not in values}
    return {**data, "tissue": rest}, values, keys


def _tissue_law(law, values, n_rows, n_angles, labels, path, base, free_layout=False):
    """(law name, law class, its parameters as (n,) arrays in their units)."""
    from ...physics.laws import TISSUE_LAWS

    params = {p.key: p for p in TISSUE_LAWS[law].parameters}
    out = {}
    for key, value in values.items():
        p = params[key]
        out[key] = resolve_stiffness(value, n_rows, n_angles, labels, path=path,
                                     key=f"tissue.{key}", minimum=p.minimum, unit=p.unit,
                                     what=key.replace("_", " "), csv_column=p.csv_column,
                                     base_dir=base, maximum=p.maximum,
                                     free_layout=free_layout)
    return law, TISSUE_LAWS[law], out


def load_config(path) -> Config:
    """Load and validate a YAML config file.

    Parameters
    ----------
    path : str or path-like
        The YAML file. Relative stiffness-CSV paths inside it are resolved
        against its folder.

    Raises
    ------
    ConfigError
        One line naming the file, the key path and what was expected.
    """
    path = Path(path)
    data = load_yaml(path)
    return config_from_dict(data, path=path, base_dir=path.parent)
