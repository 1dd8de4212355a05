"""Value forms of per-element config values (stiffness maps, tissue-law parameters).

A value is a scalar, ``{per_row: [...]}``, ``{per_angle: [...]}``, a nested rows x
angles list, a mapping label -> value, or (stiffness only) the path of a CSV written by
``phri fit-stiffness`` (docs/model.md section 6).
"""

from __future__ import annotations

import difflib
import math
from pathlib import Path
from typing import Optional

import numpy as np

from ...errors import ConfigError, ConfigTypeError, DataError

__all__ = ["resolve_stiffness", "PLAUSIBLE_RANGES", "check_plausible"]

#: key -> (lowest, highest, unit, why): values outside run into overflow or a singular
#: model, or describe no cuff and no arm; docs/model.md section 6 ("Plausible ranges")
#: gives each range's source. Values inside are solved (or refused with a physical reason).
PLAUSIBLE_RANGES = {
    "geometry.row_width": (0.001, 0.5, "m", "a cuff row's width"),
    # rows and strap handles lie along one limb segment (an upper arm is about 0.3 m long)
    "geometry.rows": (-1.0, 1.0, "m", "a row's position along a limb segment"),
    "strap.axial_position": (-1.0, 1.0, "m", "a strap's position along a limb segment"),
    "strap.handle_angles": (-720.0, 720.0, "deg", "two turns either way"),
    "geometry.angles.start": (-360.0, 360.0, "deg", "one turn either way"),
    # a pressure mat's cells are about 1 deg; below 1e-6 deg (a 1 nm element on a 45 mm
    # arm) an element's area and stiffness fall under the solver's tolerances. Between, a
    # fine grid is refused by its size (the memory check names geometry.angles.count)
    "geometry.angles.step": (1e-6, 360.0, "deg", "an element at least 1e-6 deg wide"),
    "geometry.angles.width": (1e-6, 360.0, "deg", "an element at least 1e-6 deg wide"),
    # the load cell sits on the cuff's mount, centimetres from the limb's axis
    "load_cell.position": (-2.0, 2.0, "m", "a load cell on the cuff's mount"),
    # 414 N/m: the human preset under a 9 mm indenter; 1 N/m is 400 times softer
    "tissue.stiffness": (1.0, math.inf, "N/m", "a tissue that holds a cuff"),
    "cuff.stiffness": (1.0, math.inf, "N/m", "a cuff that holds a load (.inf: rigid)"),
    # indenters of soft-tissue studies: 2-20 mm (the paper's: 9 mm)
    "tissue.indenter_diameter": (0.0005, 0.1, "m", "an indenter's diameter"),
    # eta = k_s / k_n; the default 1 / (2 (1 + nu)) is 0.33-0.5
    "interface.shear_ratio": (0.01, 100.0, "-", "shear to normal stiffness"),
    # reviews of human skin friction (Derler & Gerhardt 2012, Tribol. Lett. 45:1-27) find
    # coefficients of about 0.1 to 2, wet skin on rubbers a few; 10 is far past any
    "interface.friction_coefficient": (0.0, 10.0, "-", "skin on any cuff material"),
    # the paper's measured pretension is 15 N; at 1 kN a 25 mm strap on a 45 mm arm
    # presses 890 kPa (T / (R w)), seven times the lowest upper-arm pain threshold
    "strap.tension": (0.0, 1000.0, "N", "a strap on a limb"),
    # skin alone is 1-2 mm thick; a thinner layer is no continuum to mesh
    "tissue.continuum.thickness": (0.001, math.inf, "m", "soft tissue over the bone"),
    # in-vivo initial moduli of relaxed limb tissue span 0.22-58.4 kPa (Zheng & Mak 1999,
    # J. Biomech. Eng. 121:330-339); 100 MPa is tendon, no longer soft tissue
    "tissue.continuum.young_modulus": (100.0, 1.0e8, "Pa", "soft tissue"),
    # 0 tiles the plates; a positive gap thinner than 0.01 mm leaves slivers no mesh resolves
    "tissue.continuum.patch_gap": (1.0e-5, 0.05, "m", "0, or free skin 0.01-50 mm wide"),
    # the hyperelastic layer's identified range: the paper's largest loads are about 55 N
    # and 2 N*m; far below 10 kN and 1 kN*m the identification itself tells a range its FE
    # cannot reach
    "tissue.continuum.max_force": (0.0, 1.0e4, "N", "a load on a limb"),
    "tissue.continuum.max_moment": (0.0, 1.0e3, "N*m", "a moment on a limb"),
}


def check_plausible(value, key: str, path=None, where: str = "") -> None:
    """Refuse (one line naming ``key``) a value outside :data:`PLAUSIBLE_RANGES`."""
    lo, hi, unit, why = PLAUSIBLE_RANGES[key]
    arr = np.asarray(value, dtype=float).ravel()
    bad = ~((arr >= lo) & (arr <= hi))
    if bad.any():
        i = int(np.argmax(bad))
        span = f">= {lo:g}" if math.isinf(hi) else f"{lo:g} to {hi:g}"
        raise ConfigError(f"expected {span} [{unit}] ({why}; docs/model.md section 6, "
                          f"plausible ranges){where}, got {arr[i]:g}", file=path, key=key)


def _read_stiffness_csv(csv_path: Path, labels, path, key, allow_inf: bool = False, *,
                        column: str = "stiffness_N_per_m",
                        minimum: Optional[float] = None) -> np.ndarray:
    """One per-location column of a ``phri fit-stiffness`` CSV, in the order of ``labels``:
    positive values, or (``minimum``) finite ones >= minimum."""
    import pandas as pd

    if not csv_path.is_file():
        raise ConfigError(f"stiffness file {str(csv_path)!r} not found (paths are relative to the "
                          "config's folder)", file=path, key=key)
    import io

    from ..logs.textio import read_text

    text = read_text(csv_path, what="a stiffness CSV")
    try:
        df = pd.read_csv(io.StringIO(text), comment="#", dtype={column: str})  # raw text
    except Exception as exc:  # noqa: BLE001 - any parser failure is bad data
        msg = str(exc).replace("\n", " ")
        raise DataError(f"cannot read as CSV ({msg})", file=csv_path) from None
    for col in ("location", column):
        if col not in df.columns:
            raise DataError(f"missing column {col!r}; expected a CSV written by "
                            "'phri fit-stiffness'", file=csv_path, key=col)
    values = pd.to_numeric(df[column], errors="coerce").astype(float)
    locs = df["location"].astype(str).str.strip()
    mapping = {}
    for loc, v, raw in zip(locs, values, df[column]):
        if loc in mapping:
            raise DataError(f"location {loc!r} appears twice", file=csv_path, key="location")
        if minimum is not None:
            if not (isinstance(v, float) and math.isfinite(v) and v >= minimum):
                raise DataError(f"location {loc}: expected a finite value >= {minimum:g}, got "
                                f"{raw!r}", file=csv_path, key=column)
            mapping[loc] = float(v)
            continue
        too_big = math.isinf(v) and str(raw).strip().lower().lstrip("+") not in (
            "inf", "infinity", ".inf")   # e.g. 1e999: a typo, not a rigid element
        if too_big or not (isinstance(v, float) and v > 0 and (math.isfinite(v) or allow_inf)):
            what = "a positive stiffness (inf allowed)" if allow_inf else \
                "a positive finite stiffness"
            raise DataError(f"location {loc}: expected {what}, got {raw!r}",
                            file=csv_path, key=column)
        mapping[loc] = float(v)
    missing = [lab for lab in labels if lab not in mapping]
    extra = [loc for loc in mapping if loc not in labels]
    if missing or extra:
        parts = []
        if missing:
            parts.append(f"missing locations {', '.join(missing)}")
        if extra:
            parts.append(f"locations not in the config's geometry {', '.join(extra)}")
        raise DataError("; ".join(parts) + f" (the geometry has {len(labels)} elements "
                        f"{labels[0]}..{labels[-1]})", file=csv_path, key="location")
    return np.array([mapping[lab] for lab in labels])


def resolve_stiffness(value, n_rows: int, n_angles: int, labels, *, path=None, key="",
                      allow_inf: bool = False, base_dir: Optional[Path] = None,
                      minimum: Optional[float] = None, unit: str = "N/m",
                      what: str = "stiffness", csv_column: Optional[str] = None,
                      maximum: float = math.inf, free_layout: bool = False) -> np.ndarray:
    """Turn any stiffness value form of docs/model.md section 6 into an (n,) array [N/m], row-major.

    Forms: a scalar, ``{per_row: [...]}``, ``{per_angle: [...]}``, a nested
    rows x angles list, a mapping label -> value covering every element, or a
    path (relative to ``base_dir``) to a CSV written by ``phri fit-stiffness``.
    With ``minimum`` (a tissue law's parameter, in ``unit``): finite values >=
    ``minimum`` (and <= ``maximum``) instead of positive ones, read from the CSV's
    ``csv_column`` (no CSV form without one). With ``free_layout`` (``cuff.patches``: no
    rows or angles), the per_row, per_angle and nested-list forms are refused.
    """
    if free_layout and (isinstance(value, list) or (isinstance(value, dict) and any(
            str(k) in ("per_row", "per_angle") for k in value))):
        form = "a nested rows x angles list" if isinstance(value, list) else \
            f"{{{next(str(k) for k in value if str(k) in ('per_row', 'per_angle'))}: [...]}}"
        raise ConfigError(f"{form} refers to rows and angles, which cuff.patches does not "
                          "have; give a scalar, a mapping from patch label to value, or a CSV",
                          file=path, key=key)
    n = n_rows * n_angles
    shape_txt = f"{n_rows} rows x {n_angles} angles"

    def check(arr, k=key):
        arr = np.asarray(arr, dtype=float)
        if minimum is None:
            bad = ~(arr > 0) | (np.isinf(arr) & (not allow_inf)) | np.isnan(arr)
            want = (f"a positive {what} (.inf allowed)" if allow_inf else
                    f"a positive finite {what}")
        else:
            bad = ~(np.isfinite(arr) & (arr >= minimum) & (arr <= maximum))
            want = (f"a finite {what} >= {minimum:g}" if math.isinf(maximum) else
                    f"a finite {what} >= {minimum:g} and <= {maximum:g} (docs/model.md "
                    f"section 6, plausible ranges)")
        if bad.any():
            i = int(np.argmax(bad.ravel()))
            lab = f" at {labels[i]}" if arr.size == n else ""
            raise ConfigError(f"expected {want} [{unit}]{lab}, got {float(arr.ravel()[i])!r}",
                              file=path, key=k)
        return arr

    def numbers(seq, k):
        out = []
        for i, v in enumerate(seq):
            if isinstance(v, bool) or not isinstance(v, (int, float)):
                raise ConfigTypeError(f"item {i}: expected a number [{unit}], got {v!r}",
                                      file=path, key=k)
            out.append(float(v))
        return out

    if isinstance(value, bool):
        raise ConfigTypeError(f"expected a {what} [{unit}], got {value!r}", file=path, key=key)
    if isinstance(value, (int, float)):
        return np.full(n, float(check(float(value))))
    if isinstance(value, str) and minimum is not None and csv_column is None:
        raise ConfigTypeError(f"expected a number, {{per_row: [...]}}, {{per_angle: [...]}}, a "
                              f"{shape_txt} list or a label mapping [{unit}], got {value!r}",
                              file=path, key=key)
    if isinstance(value, str):
        base = base_dir if base_dir is not None else Path(".")
        csv_path = Path(value) if Path(value).is_absolute() else base / value
        if csv_column is not None:
            return check(_read_stiffness_csv(csv_path, labels, path, key, column=csv_column,
                                             minimum=minimum))
        return check(_read_stiffness_csv(csv_path, labels, path, key, allow_inf))
    if isinstance(value, dict):
        if set(value) in ({"per_row"}, {"per_angle"}):
            (form, seq), = value.items()
            want = n_rows if form == "per_row" else n_angles
            k = f"{key}.{form}"
            if not isinstance(seq, list) or len(seq) != want:
                got = len(seq) if isinstance(seq, list) else repr(seq)
                raise ConfigError(f"expected a list of {want} values (one per "
                                  f"{'row' if form == 'per_row' else 'angle'}), got {got}",
                                  file=path, key=k)
            arr = check(numbers(seq, k), k)
            return np.repeat(arr, n_angles) if form == "per_row" else np.tile(arr, n_rows)
        keys = [str(x) for x in value]
        if any(x in ("per_row", "per_angle") for x in keys):
            raise ConfigError("expected exactly one of 'per_row' or 'per_angle'", file=path,
                              key=key)
        unknown = [x for x in keys if x not in labels]
        if unknown:
            close = difflib.get_close_matches(unknown[0], list(labels) + ["per_row", "per_angle"],
                                              n=1, cutoff=0.5)
            hint = f"; did you mean {close[0]!r}?" if close else ""
            raise ConfigError(f"unknown element label {unknown[0]!r}{hint} (expected labels "
                              f"{labels[0]}..{labels[-1]}, 'per_row' or 'per_angle')",
                              file=path, key=f"{key}.{unknown[0]}")
        missing = [lab for lab in labels if lab not in keys]
        if missing:
            raise ConfigError(f"a mapping by element label must cover every element; missing "
                              f"{', '.join(missing)}", file=path, key=key)
        vals = {str(k2): v for k2, v in value.items()}
        arr = numbers([vals[lab] for lab in labels], key)
        return check(arr)
    if isinstance(value, list):
        if len(value) != n_rows or not all(isinstance(r, list) and len(r) == n_angles
                                           for r in value):
            raise ConfigError(f"a nested list must be {shape_txt}", file=path, key=key)
        flat = []
        for i, r in enumerate(value):
            flat.extend(numbers(r, f"{key}[{i}]"))
        return check(flat)
    raise ConfigTypeError(f"expected a number, {{per_row: [...]}}, {{per_angle: [...]}}, a "
                          f"{shape_txt} list, a label mapping or a CSV path, got {value!r}",
                          file=path, key=key)
