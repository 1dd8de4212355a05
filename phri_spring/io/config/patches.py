"""The ``cuff.patches`` config key (docs/model.md section 14): sensor patches placed one by
one (inline, or a CSV beside the config) or a pressure mat, checked into a
:class:`~phri_spring.physics.cuff.patches.PatchLayout`."""

from __future__ import annotations

import difflib
import math
from pathlib import Path

import numpy as np

from ...errors import ConfigError, DataError, ModelInputError

__all__ = ["PATCH_COLUMNS", "MAT_KEYS", "patch_layout", "patch_config_geometry"]

KEY = "cuff.patches"
#: a patch's keys (inline) or columns (CSV), with their units
PATCH_COLUMNS = ("label", "x_m", "theta_deg", "width_deg", "length_m")
#: a mat's keys: required, then optional (the cells' sizes; default: the pitches)
MAT_KEYS = ("rows", "columns", "pitch_axial_m", "pitch_deg", "x0_m", "theta0_deg")
MAT_OPTIONAL = ("cell_length_m", "cell_width_deg")
_FORMS = ("a list of patches {label, x_m, theta_deg, width_deg, length_m}, the path of a CSV "
          "with those columns, or {mat: {rows, columns, pitch_axial_m, pitch_deg, x0_m, "
          "theta0_deg}}")


def _number(v, key, path, *, positive=False, integer=False):
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) \
            or (positive and not v > 0) or (integer and (int(v) != v)):
        want = ("a positive integer" if integer else
                "a positive finite number" if positive else "a finite number")
        raise ConfigError(f"expected {want}, got {v!r}", file=path, key=key)
    return int(v) if integer else float(v)


def _unknown(keys, allowed, path, key):
    extra = [k for k in keys if k not in allowed]
    if extra:
        close = difflib.get_close_matches(str(extra[0]), list(allowed), n=1)
        hint = f"; did you mean {close[0]!r}?" if close else ""
        raise ConfigError(f"unknown key {extra[0]!r}{hint} (expected {', '.join(allowed)})",
                          file=path, key=f"{key}.{extra[0]}")


def _mat(spec, path):
    from ...physics.cuff.patches import mat_layout

    key = f"{KEY}.mat"
    if not isinstance(spec, dict):
        raise ConfigError(f"expected a mapping {{{', '.join(MAT_KEYS)}}}, got {spec!r}",
                          file=path, key=key)
    _unknown(spec, MAT_KEYS + MAT_OPTIONAL, path, key)
    for k in MAT_KEYS:
        if k not in spec:
            raise ConfigError("missing required key", file=path, key=f"{key}.{k}")
    rows = _number(spec["rows"], f"{key}.rows", path, positive=True, integer=True)
    cols = _number(spec["columns"], f"{key}.columns", path, positive=True, integer=True)
    from ..memory.budget import check_elements

    check_elements(rows, cols, path=path)
    vals = {k: _number(spec[k], f"{key}.{k}", path, positive=k in ("pitch_axial_m", "pitch_deg"))
            for k in MAT_KEYS[2:]}
    opt = {k: _number(spec[k], f"{key}.{k}", path, positive=True)
           for k in MAT_OPTIONAL if spec.get(k) is not None}
    if cols * vals["pitch_deg"] > 360.0 + 1e-9:
        raise ConfigError(f"{cols} columns at {vals['pitch_deg']:g} deg span more than 360 deg",
                          file=path, key=f"{key}.pitch_deg")
    return mat_layout(rows, cols, vals["pitch_axial_m"], vals["pitch_deg"], vals["x0_m"],
                      vals["theta0_deg"], opt.get("cell_length_m"), opt.get("cell_width_deg"))


def _rows_from_list(items, path):
    if not items:
        raise ConfigError(f"expected at least one patch: {_FORMS}", file=path, key=KEY)
    out = []
    for i, item in enumerate(items):
        k = f"{KEY}[{i}]"
        if not isinstance(item, dict):
            raise ConfigError(f"expected a mapping {{{', '.join(PATCH_COLUMNS)}}}, got {item!r}",
                              file=path, key=k)
        _unknown(item, PATCH_COLUMNS, path, k)
        for c in PATCH_COLUMNS:
            if c not in item:
                raise ConfigError("missing required key", file=path, key=f"{k}.{c}")
        label = item["label"]
        if not isinstance(label, (str, int)) or isinstance(label, bool) or not str(label).strip() \
                or any(ch.isspace() for ch in str(label)):
            raise ConfigError(f"expected a label without spaces, got {label!r}", file=path,
                              key=f"{k}.label")
        out.append((str(label), *(_number(item[c], f"{k}.{c}", path,
                                          positive=c in ("width_deg", "length_m"))
                                  for c in PATCH_COLUMNS[1:])))
    return out


def _rows_from_csv(value, base: Path, path):
    import io

    import pandas as pd

    from ..logs.textio import read_text

    csv_path = Path(value) if Path(value).is_absolute() else base / value
    if not csv_path.is_file():
        raise ConfigError(f"patch file {str(csv_path)!r} not found (paths are relative to the "
                          "config's folder)", file=path, key=KEY)
    text = read_text(csv_path, what="a patch CSV")
    try:
        df = pd.read_csv(io.StringIO(text), comment="#", dtype=str, skipinitialspace=True)
    except Exception as exc:  # noqa: BLE001 - any parser failure is bad data
        msg = str(exc).replace("\n", " ")
        raise DataError(f"cannot read as CSV ({msg})", file=csv_path) from None
    df.columns = [str(c).strip() for c in df.columns]
    for c in PATCH_COLUMNS:
        if c not in df.columns:
            raise DataError(f"missing column {c!r}; expected columns {', '.join(PATCH_COLUMNS)}",
                            file=csv_path, key=c)
    if df.empty:
        raise DataError("no patches (expected one row per patch)", file=csv_path)
    out = []
    for i, row in enumerate(df.itertuples(index=False)):
        rec = dict(zip(df.columns, row))
        label = str(rec["label"]).strip()
        if not label or label == "nan" or any(ch.isspace() for ch in label):
            raise DataError(f"row {i + 1}: expected a label without spaces, got "
                            f"{rec['label']!r}", file=csv_path, key="label")
        vals = []
        for c in PATCH_COLUMNS[1:]:
            try:
                v = float(rec[c])
            except (TypeError, ValueError):
                v = float("nan")
            if not math.isfinite(v) or (c in ("width_deg", "length_m") and not v > 0):
                what = "a positive finite number" if c in ("width_deg", "length_m") \
                    else "a finite number"
                raise DataError(f"patch {label}: expected {what}, got {rec[c]!r}",
                                file=csv_path, key=c)
            vals.append(v)
        out.append((label, *vals))
    return out


def patch_layout(value, base: Path, path):
    """The :class:`~phri_spring.physics.cuff.patches.PatchLayout` of a ``cuff.patches`` value:
    one-line ConfigError / DataError naming the key (or the CSV and its column)."""
    from ...physics.cuff.patches import PatchLayout, check_layout

    if isinstance(value, dict):
        if set(value) != {"mat"}:
            bad = sorted(set(map(str, value)) - {"mat"})
            raise ConfigError(f"expected {_FORMS}", file=path,
                              key=f"{KEY}.{bad[0]}" if bad else KEY)
        layout = _mat(value["mat"], path)
    else:
        if isinstance(value, list):
            rows = _rows_from_list(value, path)
        elif isinstance(value, str):
            rows = _rows_from_csv(value, base, path)
        else:
            raise ConfigError(f"expected {_FORMS}, got {value!r}", file=path, key=KEY)
        labels, x, th, w, ln = zip(*rows)
        layout = PatchLayout(tuple(labels), np.array(x), np.radians(th), np.radians(w),
                             np.array(ln))
    try:
        check_layout(layout)
    except ModelInputError as exc:
        raise ConfigError(str(exc), file=path, key=KEY) from None
    return layout


def patch_config_geometry(g, value, base: Path, path):
    """The geometry of a config with ``cuff.patches``: (row_labels ("",), row_x, radius,
    row_width, labels, sections, taper, layout, patch_row_x).

    ``geometry.angles`` and ``geometry.row_width`` describe a grid and are refused;
    ``geometry.rows`` is optional and gives the axial positions of per-row radii or
    sections (interpolated in x between them).
    """
    from .geometry import geometry_sections

    for k, what in (("angles", "each patch's theta_deg and width_deg"),
                    ("row_width", "each patch's length_m")):
        if getattr(g, k) is not None:
            raise ConfigError(f"describes the rows x angles grid, which cuff.patches replaces "
                              f"(give {what} instead)", file=path, key=f"geometry.{k}")
    if g.rows is not None:
        row_x = np.array([float(v) for v in g.rows.values()])
        if not np.all(np.isfinite(row_x)):
            raise ConfigError("expected finite axial positions [m]", file=path,
                              key="geometry.rows")
        if len(np.unique(row_x)) != len(row_x):
            raise ConfigError("with cuff.patches the rows are where per-row radii or sections "
                              "are given: expected distinct axial positions", file=path,
                              key="geometry.rows")
    else:
        row_x = np.zeros(1)
    layout = patch_layout(value, base, path)
    if g.scan is not None:   # the scan gives the shape: the outlines at the patches' x
        from .geometry import check_scan_alone

        check_scan_alone(g, path)
        return (("",), np.unique(layout.x), None, np.array([float(np.sum(layout.length))]),
                layout.labels, None, 0.0, layout, np.unique(layout.x))
    sections, radius, taper = geometry_sections(g, len(row_x), path)
    return (("",), row_x, radius, np.array([float(np.sum(layout.length))]), layout.labels,
            sections, taper, layout, row_x)
