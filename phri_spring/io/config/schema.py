"""The config's schema: the pydantic models every section of the YAML config is checked
against (docs/model.md section 6), the unit of every key (:func:`config_units`) and
pydantic's errors turned into one-line :class:`~phri_spring.errors.ConfigError` errors
with the closest valid key.

:func:`~phri_spring.io.config.config_from_dict` validates a mapping with
:func:`validate_config_mapping` and builds the :class:`~phri_spring.io.config.Config`.
"""

from __future__ import annotations

from typing import Any, Literal, Optional, Union

from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator

from ...errors import ConfigError
from ...physics.hyperelastic.laws import checked_continuum_law
from .history import ACTIVATION_FACTOR, Relaxation
from .schema_errors import config_error_from

__all__ = ["config_units", "validate_config_mapping"]


# --------------------------------------------------------------------------- schema
_StiffnessValue = Union[float, str, list, dict]


def _unit(unit: str) -> dict:
    """Field metadata: the unit of a config value (see :func:`config_units`)."""
    return {"unit": unit}


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", strict=False)


class _Angles(_Strict):
    start: float = Field(json_schema_extra=_unit("deg"))
    step: float = Field(json_schema_extra=_unit("deg"))
    count: int = Field(ge=1, json_schema_extra=_unit("-"))
    width: Optional[float] = Field(default=None, gt=0, le=360, json_schema_extra=_unit("deg"))


class _Geometry(_Strict):
    #: required with a circular section (the default), an error with any other
    radius: Optional[Union[float, list[float]]] = Field(default=None,
                                                        json_schema_extra=_unit("m"))
    #: rows, row_width and angles are required for the grid; with cuff.patches, rows
    #: optional (where per-row radii or sections are given), row_width and angles refused
    rows: Optional[dict[str, float]] = Field(default=None, json_schema_extra=_unit("m"))
    row_width: Optional[Union[float, list[float]]] = Field(default=None,
                                                           json_schema_extra=_unit("m"))
    angles: Optional[_Angles] = None
    #: the limb's section (docs/model.md section 13): circle, {ellipse: [a, b], rotation},
    #: {outline: [[y, z], ...]} or {per_row: [...]}; checked by geometry_sections
    section: Optional[Union[str, dict]] = Field(default=None, json_schema_extra=_unit("m"))
    #: taper half-angle, positive when the limb narrows distally (docs/model.md section 13)
    taper_deg: float = Field(default=0.0, json_schema_extra=_unit("deg"))
    #: a 3D surface scan of the limb (docs/scans.md): {file, unit, origin, axis, y_axis,
    #: max_triangles, smoothing}; checked by io.scan, exclusive of radius, section and taper
    scan: Optional[Any] = Field(default=None, json_schema_extra=_unit("the scan's unit"))
    #: the coupled arm's bone, {centre: [y, z], radius} (docs/model.md section 13);
    #: None: the skin moved inward by tissue.continuum.thickness. Checked by parse_bone
    bone: Optional[Any] = Field(default=None, json_schema_extra=_unit("m"))

    @field_validator("rows")
    @classmethod
    def _rows(cls, v):
        if v is None:
            return v
        if not v:
            raise ValueError("expected at least one row, e.g. {A: -0.025, B: 0.0, C: 0.025}")
        for label in v:
            if not str(label).strip() or any(c.isspace() for c in str(label)):
                raise ValueError(f"row label {label!r}: expected a label without spaces")
        return v


class _LoadCell(_Strict):
    position: tuple[float, float, float] = Field(default=(0.0, 0.0, 0.0),
                                                 json_schema_extra=_unit("m"))
    rotation: Optional[tuple[tuple[float, float, float], tuple[float, float, float],
                             tuple[float, float, float]]] = None
    euler_xyz_deg: Optional[tuple[float, float, float]] = Field(default=None,
                                                                json_schema_extra=_unit("deg"))
    convention: Literal["robot_on_cuff", "cuff_on_robot"] = "robot_on_cuff"
    force_unit: Literal["N", "lbf"] = "N"
    moment_unit: Literal["N*m", "N*mm"] = "N*m"
    columns: dict[str, str] = Field(default_factory=dict)
    group: Optional[str] = None        # TDMS group / MAT struct of the log (lab files)

    @model_validator(mode="after")
    def _one_rotation(self):
        if self.rotation is not None and self.euler_xyz_deg is not None:
            raise ValueError("give either 'rotation' or 'euler_xyz_deg', not both")
        return self


def _not_a_bool(v):
    if isinstance(v, bool):
        raise ValueError(f"expected a stiffness [N/m], got {v!r}")
    return v


class _Continuum(_Strict):
    """What ``--arm coupled`` needs (docs/model.md section 10)."""

    thickness: float = Field(gt=0, allow_inf_nan=False, json_schema_extra=_unit("m"))
    young_modulus: Optional[float] = Field(default=None, gt=0, allow_inf_nan=False,
                                           json_schema_extra=_unit("Pa"))
    surface_stiffness: Optional[str] = None
    spread: Literal["mean", "per_patch"] = "mean"
    #: free skin left between neighbouring patches (docs/coupled-fe.md); None: the FE's default
    patch_gap: Optional[float] = Field(default=None, ge=0, allow_inf_nan=False,
                                       json_schema_extra=_unit("m"))
    #: the continuum's material (docs/model.md section 10.8): linear elastic, or the reduced
    #: neo-Hookean model identified by the large-deformation FE (extra ``hyper``)
    law: str = "linear"        # a name of physics.hyperelastic.laws.CONTINUUM_LAW_MODELS
    _law_registered = field_validator("law")(checked_continuum_law)
    #: the Ogden law's exponent; None: identified from the indenter curve (tissue.stiffening)
    ogden_alpha: Optional[float] = Field(default=None, gt=0, le=40, allow_inf_nan=False,
                                         json_schema_extra=_unit("-"))
    #: the hyperelastic model's identified range: wrenches up to these sizes; None: the
    #: law's default (CONTINUUM_RANGES)
    max_force: Optional[float] = Field(default=None, gt=0, allow_inf_nan=False,
                                       json_schema_extra=_unit("N"))
    max_moment: Optional[float] = Field(default=None, gt=0, allow_inf_nan=False,
                                        json_schema_extra=_unit("N*m"))


class _Tissue(_Strict):
    stiffness: _StiffnessValue = Field(json_schema_extra=_unit("N/m"))
    law: str = "linear"
    basis: Literal["indenter", "element"] = "indenter"
    indenter_diameter: float = Field(default=0.009, gt=0, allow_inf_nan=False,
                                     json_schema_extra=_unit("m"))
    poisson_ratio: float = Field(default=0.45, gt=-1.0, le=0.5, json_schema_extra=_unit("-"))
    continuum: Optional[_Continuum] = None
    #: quasi-linear viscoelastic relaxation (docs/model.md section 15); None: elastic
    relaxation: Optional[Relaxation] = None
    #: stiffness of the contracted muscle over the resting one (log column ``activation``)
    activation_factor: float = Field(default=ACTIVATION_FACTOR, gt=0, le=20,
                                     allow_inf_nan=False, json_schema_extra=_unit("-"))

    _stiffness_not_bool = field_validator("stiffness", mode="before")(_not_a_bool)


class _Cuff(_Strict):
    stiffness: _StiffnessValue = Field(json_schema_extra=_unit("N/m"))
    #: sensor patches anywhere (docs/model.md section 14): a list, a CSV path or {mat: ...};
    #: checked by io/config_patches.py
    patches: Any = None

    _stiffness_not_bool = field_validator("stiffness", mode="before")(_not_a_bool)


class _Interface(_Strict):
    pain_threshold_kpa: float = Field(default=120.0, gt=0, allow_inf_nan=False,
                                      json_schema_extra=_unit("kPa"))
    shear_ratio: Optional[float] = Field(default=None, gt=0, allow_inf_nan=False,
                                         json_schema_extra=_unit("-"))
    #: Coulomb coefficient of skin on the cuff (docs/model.md section 12); None: bonded
    friction_coefficient: Optional[float] = Field(default=None, ge=0, allow_inf_nan=False,
                                                  json_schema_extra=_unit("-"))


class _Strap(_Strict):
    tension: float = Field(default=15.0, ge=0, json_schema_extra=_unit("N"))
    model: Literal["hoop", "handles", "band"] = "hoop"
    #: ``band`` only: the elastic band's axial width and tension per unit strain
    width: Optional[float] = Field(default=None, gt=0, json_schema_extra=_unit("m"))
    stiffness: Optional[float] = Field(default=None, ge=0, json_schema_extra=_unit("N"))
    handle_angles: Optional[tuple[float, float]] = Field(default=None,
                                                         json_schema_extra=_unit("deg"))
    axial_position: Optional[float] = Field(default=None, json_schema_extra=_unit("m"))


class _Solver(_Strict):
    max_iterations: int = Field(default=100, ge=1, le=100000, json_schema_extra=_unit("-"))


class _Root(_Strict):
    name: str = ""
    geometry: _Geometry
    load_cell: _LoadCell = Field(default_factory=_LoadCell)
    tissue: _Tissue
    cuff: _Cuff
    interface: _Interface = Field(default_factory=_Interface)
    strap: _Strap = Field(default_factory=_Strap)
    solver: _Solver = Field(default_factory=_Solver)
    #: optional pressure-time tolerance curve (docs/tolerance.md); checked by
    #: io/config_tolerance.py
    tolerance: Any = None


def config_units() -> dict:
    """The unit of every config key that has one, by dotted key path.

    >>> config_units()["tissue.continuum.young_modulus"], config_units()["strap.tension"]
    ('Pa', 'N')
    """
    out = {}

    def walk(cls, prefix):
        for name, f in cls.model_fields.items():
            extra = f.json_schema_extra or {}
            if isinstance(extra, dict) and "unit" in extra:
                out[prefix + name] = extra["unit"]
            for ann in (f.annotation, *getattr(f.annotation, "__args__", ())):
                if isinstance(ann, type) and issubclass(ann, BaseModel):
                    walk(ann, prefix + name + ".")
    walk(_Root, "")
    return out


def _fields_at(model_cls, loc) -> list[str]:
    """Valid keys of the mapping at key path ``loc`` (for 'did you mean')."""
    cls = model_cls
    for part in loc:
        f = getattr(cls, "model_fields", {}).get(part)
        if f is None:
            return []
        models = [a for a in (f.annotation, *getattr(f.annotation, "__args__", ()))
                  if isinstance(a, type) and issubclass(a, BaseModel)]  # also Optional[model]
        if not models:
            return []
        cls = models[0]
    return list(getattr(cls, "model_fields", {}))


def _pydantic_to_config_error(exc: ValidationError, path, more_keys=None) -> ConfigError:
    more = more_keys or {}
    return config_error_from(exc, path, lambda loc: _fields_at(_Root, loc)
                             + list(more.get(".".join(loc), ())))


def validate_config_mapping(data: dict, path, more_keys: Optional[dict] = None):
    """The config mapping ``data`` checked against the schema (the root model), or a
    one-line ConfigError naming ``path`` and the key; ``more_keys``: key path -> more
    valid keys for 'did you mean' (a tissue law's parameters)."""
    try:
        return _Root.model_validate(data)
    except ValidationError as exc:
        raise _pydantic_to_config_error(exc, path, more_keys) from None
