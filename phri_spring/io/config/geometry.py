"""The geometry part of the config (docs/model.md sections 6 and 13): the limb's
section and taper, checked into :mod:`phri_spring.physics.limb.sections` objects."""

from __future__ import annotations

import difflib
import math

import numpy as np

from ...errors import ConfigError

__all__ = ["parse_bone", "geometry_sections", "per_row_values", "check_scan_alone", "read_scan",
           "scan_geometry", "config_outlines"]


def per_row_values(value, n_rows, path, key) -> np.ndarray:
    """A positive length [m] per row from a scalar or a list (ConfigError naming the key)."""
    arr = np.atleast_1d(np.asarray(value, dtype=float))
    if arr.size == 1:
        arr = np.full(n_rows, float(arr[0]))
    if arr.shape != (n_rows,):
        raise ConfigError(f"expected a scalar or {n_rows} values (one per row), got {arr.size}",
                          file=path, key=key)
    if not np.all(np.isfinite(arr) & (arr > 0)):
        raise ConfigError(f"expected positive finite values [m], got {arr.tolist()}", file=path,
                          key=key)
    return arr


def check_scan_alone(g, path) -> None:
    """With ``geometry.scan`` the scan gives the limb's shape and taper: a radius, a section
    or a taper_deg given as well is a ConfigError naming that key (they would contradict it)."""
    for key in ("radius", "section", "taper_deg"):
        if key in g.model_fields_set:
            raise ConfigError(f"not allowed with geometry.scan: the scan gives the limb's "
                              f"{'taper' if key == 'taper_deg' else 'shape and size'}; remove "
                              f"geometry.{key} (or geometry.scan)", file=path,
                              key=f"geometry.{key}")


def read_scan(g, strap, row_x, row_width, width_deg: float, base, path, row_labels,
              layout=None):
    """``geometry.scan`` read and the elements placed on it (:class:`~.scan.ScanCuff`): the
    grid's, or with ``layout`` (``cuff.patches``) the patches'; with the strap's section for
    the ``handles`` model at its axial position (default the rows' or patches' mean x, as
    the model puts it). One-line errors naming the file or the key."""
    from ..scan import scan_cuff

    strap_x = None
    if strap.model == "handles":
        mean_x = float(np.mean(row_x if layout is None else layout.x))
        strap_x = mean_x if strap.axial_position is None else float(strap.axial_position)
    if layout is not None:
        return scan_cuff(g.scan, None, None, None, None, base, strap_x=strap_x,
                         config_path=path, layout=layout)
    theta = np.radians(g.angles.start + g.angles.step * np.arange(g.angles.count))
    return scan_cuff(g.scan, row_x, row_width, theta,
                     np.full(g.angles.count, math.radians(width_deg)), base, strap_x=strap_x,
                     config_path=path, row_names=row_labels)


def scan_geometry(cfg):
    """The :class:`~phri_spring.physics.cuff.geometry.CuffGeometry` of a config with
    ``geometry.scan`` (its :class:`~phri_spring.io.scan.ScanCuff` read when it was loaded)."""
    from ...physics.cuff.geometry import CuffGeometry

    el = cfg.scan.elements
    if cfg.patches is not None:   # sensor patches anywhere on the scan
        from dataclasses import replace

        from ...physics.cuff.patches import hoop_shares

        lay = cfg.patches
        geom = CuffGeometry.from_elements(
            lay.labels, ("",), 1, lay.n, x=lay.x, row_width=lay.length, theta=lay.theta,
            span=lay.width, points=el.points, normals=el.normals, areas=el.areas,
            turning=el.turning, strap_section=cfg.scan.strap_section)
        return replace(geom, hoop_share=hoop_shares(lay.x, lay.length), free_layout=True,
                       handles_radius=None)
    n_rows, n_ang = len(cfg.row_labels), int(cfg.angle_count)
    width = cfg.angle_step_deg if cfg.angle_width_deg is None else cfg.angle_width_deg
    theta = np.radians(cfg.angle_start_deg + cfg.angle_step_deg * np.arange(n_ang))
    return CuffGeometry.from_elements(
        cfg.labels, cfg.row_labels, n_rows, n_ang, x=np.repeat(cfg.row_x, n_ang),
        row_width=np.repeat(cfg.row_width, n_ang), theta=np.tile(theta, n_rows),
        span=np.full(n_rows * n_ang, math.radians(width)), points=el.points,
        normals=el.normals, areas=el.areas, turning=el.turning,
        strap_section=cfg.scan.strap_section)


def geometry_sections(g, n_rows: int, path):
    """(sections or None, per-row radius (n_rows,), taper [deg]) of the geometry schema.

    None for the circular sections of ``geometry.radius``; otherwise one
    :mod:`~phri_spring.physics.limb.sections` object per row, and as radius each row's
    equal-perimeter radius. One-line ConfigErrors naming the key.
    """
    from ...physics.limb.bounds import SectionError, check_rho_range, check_taper

    try:
        taper = check_taper(g.taper_deg)
    except SectionError as exc:
        raise ConfigError(str(exc), file=path, key="geometry.taper_deg") from None
    spec = g.section
    if spec is None or spec == "circle":
        if g.radius is None:
            raise ConfigError("expected the radius [m] (scalar or one per row) of the circular "
                              "section, or a geometry.section (ellipse, outline)", file=path,
                              key="geometry.radius")
        radius = per_row_values(g.radius, n_rows, path, "geometry.radius")
        try:
            check_rho_range(float(radius.min()), float(radius.max()), "radius")
        except SectionError as exc:
            raise ConfigError(str(exc), file=path, key="geometry.radius") from None
        return None, radius, taper
    if isinstance(spec, str):
        raise ConfigError(f"expected 'circle', {{ellipse: [a, b], rotation: deg}}, "
                          f"{{outline: [[y, z], ...]}} or {{per_row: [...]}}, got {spec!r}",
                          file=path, key="geometry.section")
    if g.radius is not None:
        raise ConfigError("give either geometry.radius (a circular section) or a non-circular "
                          "geometry.section, not both (the radius would be ambiguous)",
                          file=path, key="geometry.radius")
    if "per_row" in spec and set(spec) != {"per_row"}:
        other = sorted(set(spec) - {"per_row"})[0]
        raise ConfigError("per_row takes no other key: put each row's section in its list",
                          file=path, key=f"geometry.section.{other}")
    if set(spec) == {"per_row"}:
        items = spec["per_row"]
        if not isinstance(items, list) or len(items) != n_rows:
            got = len(items) if isinstance(items, list) else type(items).__name__
            raise ConfigError(f"expected a list of {n_rows} sections (one per row), got {got}",
                              file=path, key="geometry.section.per_row")
        sections = tuple(_one_section(item, path, f"geometry.section.per_row[{i}]")
                         for i, item in enumerate(items))
    else:
        sections = (_one_section(spec, path, "geometry.section"),) * n_rows
    radius = np.array([s.perimeter() / (2.0 * math.pi) for s in sections])
    return sections, radius, taper


def _one_section(spec, path, key):
    """One section mapping -> a physics.sections object (ConfigError naming the key)."""
    from ...physics.limb.sections import EllipseSection, OutlineSection, SectionError

    forms = "{ellipse: [a, b], rotation: deg} or {outline: [[y, z], ...]}"
    if not isinstance(spec, dict) or not spec:
        raise ConfigError(f"expected {forms}, got {spec!r}", file=path, key=key)
    if "ellipse" in spec and "outline" in spec:
        raise ConfigError("give either an ellipse or an outline, not both", file=path, key=key)
    kind = "ellipse" if "ellipse" in spec else "outline" if "outline" in spec else None
    allowed = {"ellipse": {"ellipse", "rotation"}, "outline": {"outline"}}.get(kind, set())
    extra = sorted(set(spec) - allowed)
    if kind is None or extra:
        bad = extra[0] if extra else sorted(spec)[0]
        close = difflib.get_close_matches(str(bad), sorted(allowed or {"ellipse", "outline",
                                                                       "rotation"}), n=1)
        hint = f"; did you mean {close[0]!r}?" if close else ""
        raise ConfigError(f"unknown key {bad!r}{hint} (expected {forms})", file=path,
                          key=f"{key}.{bad}")
    try:
        if kind == "ellipse":
            ab = spec["ellipse"]
            if (not isinstance(ab, list) or len(ab) != 2
                    or not all(isinstance(v, (int, float)) and not isinstance(v, bool)
                               for v in ab)):
                raise ConfigError(f"expected two semi-axes [a, b] [m], got {ab!r}", file=path,
                                  key=f"{key}.ellipse")
            rot = spec.get("rotation", 0.0)
            if isinstance(rot, bool) or not isinstance(rot, (int, float)) \
                    or not math.isfinite(rot):
                raise ConfigError(f"expected a finite angle [deg], got {rot!r}", file=path,
                                  key=f"{key}.rotation")
            return EllipseSection(ab[0], ab[1], math.radians(rot))
        pts = spec["outline"]
        if not isinstance(pts, list) or not all(
                isinstance(p, list) and len(p) == 2
                and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in p)
                for p in pts):
            raise ConfigError("expected a list of [y, z] points [m] around the limb, in order "
                              "of angle", file=path, key=f"{key}.outline")
        return OutlineSection(pts)
    except SectionError as exc:
        raise ConfigError(str(exc), file=path, key=f"{key}.{kind}") from None


def config_outlines(cfg, x=None, k: int = 256) -> list:
    """The skin outline (k, 2) of (y, z) [m] of a config's limb at each axial position ``x``
    (default: its rows' ``row_x``), whatever the geometry: circles of ``geometry.radius``,
    ``geometry.section`` (per row, interpolated in x between rows) or a scan (the scan's
    cut by each row's or patch's plane, as the elements were placed on it; at another x the
    nearest of those cuts)."""
    from ...physics.limb.sections import outlines_at

    if cfg.scan is not None:
        outs = [np.asarray(yz, dtype=float) for yz in cfg.scan.elements.outlines]
        if x is None:
            return outs
        # the scan is cut where the elements were placed: the nearest of those cuts
        known = np.asarray(cfg.row_x if cfg.patches is None else cfg.patch_row_x, dtype=float)
        return [outs[int(np.argmin(np.abs(known - xv)))] for xv in np.atleast_1d(x)]
    row_x = cfg.row_x if cfg.patches is None else cfg.patch_row_x
    radius = cfg.radius if cfg.sections is None else None
    return outlines_at(row_x if x is None else x, row_x, cfg.sections, radius, k=k)


def parse_bone(bone, sections, radius, path):
    """``geometry.bone`` as (y_c, z_c, r_b) [m], or None; one-line ConfigErrors naming the key.

    A circle {centre: [y, z], radius} inside every row's skin outline (``sections``, or the
    circles of ``radius``) with at least :data:`~phri_spring.physics.continuum.shape.BONE_MARGIN_M`
    of tissue on every ray from its centre.
    """
    if bone is None:
        return None
    from ...physics.continuum.shape import BONE_MARGIN_M

    key = "geometry.bone"
    if not isinstance(bone, dict) or set(bone) != {"centre", "radius"}:
        raise ConfigError("expected {centre: [y, z], radius} [m] (a circular bone)", file=path,
                          key=key)
    try:
        c = np.asarray(bone["centre"], dtype=float)
        rb = float(bone["radius"])
    except (TypeError, ValueError):
        raise ConfigError("expected {centre: [y, z], radius} as numbers [m]", file=path,
                          key=key) from None
    if c.shape != (2,) or not np.all(np.isfinite(c)):
        raise ConfigError(f"expected two finite numbers [y, z] [m], got {bone['centre']!r}",
                          file=path, key=f"{key}.centre")
    if not (math.isfinite(rb) and rb > 0):
        raise ConfigError(f"expected a finite radius > 0 m, got {bone['radius']!r}", file=path,
                          key=f"{key}.radius")
    th = np.linspace(0.0, 2.0 * math.pi, 721)[:-1]
    th_c = np.array([math.atan2(c[1], c[0])])
    rho = ((lambda r: (lambda a: np.full(np.shape(a), float(r)))) if sections is None
           else (lambda s: s.rho))
    rows = [rho(r) for r in (np.atleast_1d(radius) if sections is None else sections)]
    # the least distance from the bone's centre to each row's skin (sampled outline), and
    # the centre on the axis's side of the skin on its own ray
    d = min(float(np.min(np.hypot(f(th) * np.cos(th) - c[0], f(th) * np.sin(th) - c[1])))
            for f in rows)
    inside = all(float(np.hypot(*c)) < float(f(th_c)[0]) for f in rows)
    if not inside or d - rb < BONE_MARGIN_M:
        got = f"{(d - rb) * 1e3:.3g} mm" if inside else "its centre outside the skin"
        raise ConfigError(f"expected the bone inside the skin with at least "
                          f"{BONE_MARGIN_M * 1e3:g} mm of tissue around it, got {got}",
                          file=path, key=key)
    return float(c[0]), float(c[1]), rb
