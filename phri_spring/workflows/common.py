"""Config -> physics glue shared by the commands."""

from __future__ import annotations


import numpy as np

from ..errors import ConfigError, ModelInputError
from ..io.config import Config
from ..physics.cuff.geometry import CuffGeometry
from ..physics.cuff.loadcell import FORCE_UNITS, MOMENT_UNITS, loadcell_to_cuff
from ..physics.springs.model import build_model, tissue_element_stiffness
from ..io.memory.budget import (COUPLED_BYTES_PER_VALUE, COUPLED_GATHER_BYTES_PER_ELEMENT,
                                check_model, dense_coupling_terms, fe_to_build)
from ..physics.hyperelastic.laws import CONTINUUM_LAW_MODELS
from ..plugins import ARM_MODELS, FALLBACK_COLOURS, ArmMemory, ArmModel, ArmUncertainty
from ..reports.tissue_law_text import continuum_law_text

__all__ = ["geometry_from_config", "model_from_config", "cuff_wrench", "ARMS", "ARM_MODELS",
           "ArmModel", "ArmMemory", "ArmUncertainty", "register_arm"]



#: the names of :data:`ARM_MODELS` (:data:`phri_spring.plugins.ARM_MODELS`), in
#: registration order
ARMS: tuple = tuple(ARM_MODELS)


def register_arm(name: str, description: str, *, label: str = "", colour: str = "",
                 memory: ArmMemory = ArmMemory(), uncertainty: ArmUncertainty = ArmUncertainty(),
                 has_tissue: bool = True, tissue_text=None, refuse=None,
                 continuum: bool = False):
    """Decorator: register ``build(cfg, cache_dir) -> model`` as the arm model ``name``, with
    what the rest of the package asks of it (the fields of
    :class:`~phri_spring.plugins.ArmModel`; docs/extending.md). Defaults: label
    ``"Name arm"``, the next free colour, the spring network's memory terms and the compliant
    arm's uncertainty routes."""
    def deco(build):
        global ARMS
        used = {m.colour for m in ARM_MODELS.values()}
        free = [c for c in FALLBACK_COLOURS if c not in used] or list(FALLBACK_COLOURS)
        ARM_MODELS[name] = ArmModel(name, description, build,
                                    label=label or f"{name.replace('_', ' ').capitalize()} arm",
                                    colour=colour or free[0], memory=memory,
                                    uncertainty=uncertainty, has_tissue=has_tissue,
                                    tissue_text=tissue_text, refuse=refuse,
                                    continuum=continuum)
        ARMS = tuple(ARM_MODELS)
        return build
    return deco


def geometry_from_config(cfg: Config) -> CuffGeometry:
    """The element geometry a config describes."""
    return cfg.geometry()


def model_from_config(cfg: Config, arm: str = "compliant", *, cache_dir=None):
    """Assemble the model of a config for an arm of :data:`ARMS`.

    Parameters
    ----------
    cfg : Config
    arm : str or ArmModel
        A name of :data:`ARM_MODELS` (or the record itself): the paper's spring
        network with tissue and cuff springs in series (``compliant``) or cuff
        springs only (``rigid``), the coupled tissue model (``coupled``: needs
        ``tissue.continuum``; docs/model.md section 10), or a registered one.
    cache_dir : path, optional
        ``coupled`` only: where the built-in FE's surface stiffness is cached.

    Returns
    -------
    SpringModel or CoupledModel

    Raises
    ------
    ConfigError
        If an element would be infinitely stiff (e.g. ``cuff.stiffness: .inf``
        with the rigid arm), the geometry cannot hold the cuff (singular K_s), or
        the coupled model's inputs are missing or out of range, or the model
        (for the coupled arm, with its tissue FE) cannot fit in this machine's
        memory (:func:`~phri_spring.io.memory.budget.check_model`).
    UsageError
        ``coupled`` without the ``fe`` extra (and no ``surface_stiffness`` file).
    """
    arm_model = arm if isinstance(arm, ArmModel) else ARM_MODELS.get(arm)
    if arm_model is None:
        raise ValueError(f"arm: expected one of {ARMS}, got {arm!r}")
    if arm_model.refuse is not None:
        arm_model.refuse(cfg)
    # before anything is allocated: an allocation that fails in C++ (the coupled FE, LAPACK)
    # aborts the process instead of raising (io/memory_budget.py)
    check_model(cfg, arm_model, cache_dir=cache_dir)
    return arm_model.build(cfg, cache_dir)


#: config key a physics input error is about (ModelInputError.quantity -> key)
_QUANTITY_KEYS = {"geometry": "geometry.angles", "shear_ratio": "interface.shear_ratio",
                  "strap_model": "strap.model", "strap_stiffness": "strap.stiffness",
                  "strap_width": "strap.width", "strap_handle_angles": "strap.handle_angles",
                  "tissue_law": "tissue.law", "friction_coefficient": "interface.friction_coefficient",
                  "stiffness": "cuff.stiffness", "surface_stiffness": "tissue.continuum",
                  "normal_output": "tissue.continuum"}


@register_arm("compliant", "tissue and cuff springs in series (the paper's compliant arm; "
                           "any tissue law)", label="Compliant arm", colour="#0072B2")
def _compliant_model(cfg: Config, cache_dir=None):
    model = _spring_model(cfg, "compliant")
    return history_model(model, cfg) if cfg.tissue_relaxation is not None else model


@register_arm("rigid", "cuff springs only: the rigid-arm assumption of the literature",
              label="Rigid arm", colour="#E69F00", has_tissue=False,
              tissue_text=lambda cfg: "no tissue (cuff springs only)",
              uncertainty=ArmUncertainty(tissue_route=lambda cfg: "none", stiffening=False,
                                         unused_tissue="has no tissue springs",
                                         unused_stiffening="the rigid arm has no tissue"))
def _rigid_model(cfg: Config, cache_dir=None):
    return _spring_model(cfg, "rigid")


def history_model(model, cfg: Config):
    """``model`` solved sample by sample with the config's tissue relaxation and activation
    factor (:class:`~phri_spring.physics.history.model.HistoryModel`): the compliant arm. The rigid
    arm has no tissue and is returned as it is; the linear coupled arm relaxes
    (:class:`~phri_spring.physics.history.continuum.CoupledRelaxation`) or takes the
    activation alone (:class:`~phri_spring.physics.history.path.PathActivation`)."""
    from ..physics.history.model import HistoryModel
    from ..physics.history.relaxation import Prony

    if getattr(model, "has_history", False) or getattr(model, "arm", "") == "rigid":
        return model
    key = "tissue.relaxation" if cfg.tissue_relaxation is not None else "tissue.activation_factor"
    if hasattr(model, "solve_band"):
        raise ConfigError("relaxation and activation are not available with the band strap "
                          "(the band's tension is solved per sample, not along the tissue's "
                          "time path); use hoop or handles", file=cfg.path, key=key)
    coupled = not hasattr(model, "element")
    if coupled and cfg.tissue_relaxation is not None:   # the layer relaxes (section 15.1)
        from ..physics.history.continuum import CoupledRelaxation

        try:
            return CoupledRelaxation(model, Prony(*cfg.tissue_relaxation),
                                     cfg.activation_factor)
        except ModelInputError as exc:
            raise ConfigError(str(exc), file=cfg.path, key=key) from None
    if coupled or (cfg.tissue_relaxation is None and cfg.friction_coefficient is not None):
        # activation along the interface's loading path: the coupled arm's layer, or the
        # spring arm's tissue springs with friction (docs/model.md section 15.2)
        from ..physics.history.path import PathActivation

        try:
            return PathActivation(model, cfg.activation_factor)
        except ModelInputError as exc:
            raise ConfigError(str(exc), file=cfg.path, key=key) from None
    try:
        prony = None if cfg.tissue_relaxation is None else Prony(*cfg.tissue_relaxation)
        return HistoryModel(model, prony, cfg.activation_factor)
    except ModelInputError as exc:
        raise ConfigError(str(exc), file=cfg.path, key=key) from None


def refuse_activation(cfg: Config, arm: str) -> None:
    """One line (ConfigError) if a log's activation column cannot act on this arm, raised
    before the model is built: the hyperelastic layers' reduced models are identified for
    one modulus (docs/model.md section 15.2)."""
    if arm == "coupled" and CONTINUUM_LAW_MODELS[cfg.continuum_law].reduced:
        raise ConfigError(f"a muscle activation column with tissue.continuum.law "
                          f"{cfg.continuum_law}: its reduced model is identified for one "
                          f"modulus; the linear continuum or the compliant arm takes the "
                          f"column", file=cfg.path, key="tissue.activation_factor")


def _spring_model(cfg: Config, arm: str):
    """The spring network of docs/model.md sections 1-4 for the compliant or rigid arm."""
    geom = geometry_from_config(cfg)
    k_t = tissue_element_stiffness(cfg.tissue_stiffness, geom.areas, cfg.tissue_basis,
                                   cfg.indenter_diameter)
    k_c = cfg.cuff_stiffness
    if arm == "rigid" and np.isinf(k_c).any():
        lab = cfg.labels[int(np.argmax(np.isinf(k_c)))]
        raise ConfigError(f"element {lab} is infinitely stiff in the rigid-arm model "
                          "(k_e = k_c = inf); expected a finite cuff stiffness [N/m]",
                          file=cfg.path, key="cuff.stiffness")
    try:
        model = build_model(geom, k_t, k_c, arm=arm, shear_ratio=cfg.shear_ratio,
                            poisson_ratio=cfg.poisson_ratio, strap_tension=cfg.strap_tension,
                            strap_model=cfg.strap_model, handle_angles_deg=cfg.handle_angles_deg,
                            handle_axial_position=cfg.strap_axial_position,
                            pain_threshold_kpa=cfg.pain_threshold_kpa,
                            law=cfg.tissue_law_class or cfg.tissue_law,
                            law_parameters=cfg.tissue_law_parameters,
                            friction_coefficient=cfg.friction_coefficient)
        if cfg.strap_model != "band":
            return model
        from ..physics.contact.band_solve import band_model   # docs/model.md section 3.1

        return band_model(model, cfg.strap_stiffness, cfg.strap_width, cfg.strap_tension,
                          cfg.handle_angles_deg, cfg.strap_axial_position)
    except ModelInputError as exc:
        key = _QUANTITY_KEYS.get(exc.quantity) if exc.quantity != "stiffness" else None
        if exc.quantity == "geometry" and cfg.patches is not None:
            key = "cuff.patches"      # the patches, not grid angles, failed to hold the cuff
        raise ConfigError(str(exc), file=cfg.path, key=key) from None


def continuum_modulus(cfg: Config, geom: CuffGeometry | None = None) -> np.ndarray:
    """Young's modulus E [Pa] per patch (n,) for the coupled model.

    ``tissue.continuum.young_modulus`` if given; otherwise converted from the
    indenter stiffness in ``tissue.stiffness`` (flat punch of
    ``tissue.indenter_diameter`` on a layer of the continuum's thickness bonded
    to the bone, by the same FE: docs/model.md section 10).
    """
    key = "tissue.continuum"
    n = len(cfg.labels)
    if cfg.continuum_young_modulus is not None:
        return np.full(n, cfg.continuum_young_modulus)
    if cfg.tissue_basis != "indenter":
        raise ConfigError("give tissue.continuum.young_modulus [Pa]: tissue.stiffness is not "
                          "indenter stiffness (tissue.basis: element), so E cannot be derived "
                          "from it", file=cfg.path, key=f"{key}.young_modulus")
    fe = _fe_module(cfg)
    return np.asarray(fe.modulus_from_indenter(cfg.tissue_stiffness, cfg.continuum_thickness,
                                               cfg.poisson_ratio,
                                               radius=cfg.indenter_diameter / 2.0), dtype=float)


def _fe_module(cfg: Config):
    """:mod:`phri_spring.physics.continuum.tissue`, after checking that scikit-fem (the ``fe`` extra)
    is installed (a one-line UsageError naming the extra otherwise)."""
    from ..physics.continuum import tissue as fe_tissue
    from ..physics.continuum.mesh import import_skfem

    import_skfem()
    return fe_tissue


def _require_continuum(cfg: Config) -> None:
    """The coupled arm models the tissue as the layer tissue.continuum describes."""
    if cfg.continuum_thickness is None:
        raise ConfigError("the coupled arm needs tissue.continuum (thickness [m], and "
                          "young_modulus [Pa] unless tissue.stiffness holds indenter values)",
                          file=cfg.path, key="tissue.continuum")


def _coupled_refuses(cfg: Config) -> None:
    """The coupled arm needs its continuum layer; a relaxing layer must be the linear one
    (the hyperelastic layers' reduced models are elastic)."""
    _require_continuum(cfg)
    if cfg.tissue_relaxation is not None and CONTINUUM_LAW_MODELS[cfg.continuum_law].reduced:
        raise ConfigError(f"relaxation with tissue.continuum.law {cfg.continuum_law}: its "
                          f"reduced model is identified elastic; the linear continuum (or the "
                          f"compliant arm) relaxes", file=cfg.path, key="tissue.relaxation")


def _coupled_tissue_route(cfg: Config) -> str:
    """How the tissue-stiffness scatter reaches the coupled arm: through E (derived from the
    indenter stiffness per location, or the continuum's one given modulus); an FE export's
    K is used as given, only per-patch E ratios from the indenter map act on it."""
    derived = cfg.continuum_young_modulus is None
    if cfg.continuum_surface_stiffness is not None:
        return "stiffness" if derived and cfg.continuum_spread == "per_patch" else "none"
    return "stiffness" if derived else "modulus"


@register_arm("coupled", "the tissue as a continuum layer on the bone, condensed by FE onto the "
                         "cuff's patches (needs tissue.continuum; docs/model.md section 10)",
              label="Coupled tissue", colour="#009E73", refuse=_coupled_refuses,
              continuum=True,
              tissue_text=continuum_law_text,
              memory=ArmMemory(model_terms=dense_coupling_terms,
                               bytes_per_value=COUPLED_BYTES_PER_VALUE,
                               bytes_per_element=COUPLED_GATHER_BYTES_PER_ELEMENT,
                               fe_mesh=fe_to_build, advice=" (or --arm compliant)"),
              uncertainty=ArmUncertainty(
                  tissue_route=_coupled_tissue_route, stiffening=False, fe_cache=True,
                  stiffness_via=", through the continuum's Young's modulus",
                  unused_tissue="uses tissue.continuum.surface_stiffness, which does not "
                                "scatter",
                  unused_stiffening="the coupled arm's continuum is linear"))
def _coupled_model(cfg: Config, cache_dir=None):
    """The coupled tissue model of a config (docs/model.md section 10); with
    ``tissue.relaxation``, its layer relaxing (section 15.1)."""
    model = coupled_model(cfg, cache_dir=cache_dir)
    return history_model(model, cfg) if cfg.tissue_relaxation is not None else model


def coupled_model(cfg: Config, *, cache_dir=None, level=None):
    """The coupled tissue model of a config, its built-in FE at mesh ``level``.

    What ``model_from_config(cfg, "coupled")`` builds (without its memory check), with the
    FE's mesh level open to the convergence and reference benchmarks; ``level=None`` is
    the shipped :data:`~phri_spring.physics.continuum.mesh.DEFAULT_LEVEL`. With
    ``tissue.continuum.law`` ``neo_hookean`` or ``ogden`` the reduced hyperelastic model
    (:func:`~phri_spring.workflows.hyper_arm.hyper_coupled_model`) on this linear one.
    """
    _check_coupled_shape(cfg)
    if CONTINUUM_LAW_MODELS[cfg.continuum_law].reduced:
        from .hyper_arm import hyper_coupled_model

        return hyper_coupled_model(
            cfg, lambda c, lv: _linear_coupled_model(c, cache_dir=cache_dir, level=lv),
            continuum_modulus(cfg), cache_dir=cache_dir, level=level)
    return _linear_coupled_model(cfg, cache_dir=cache_dir, level=level)


def _check_coupled_shape(cfg: Config) -> None:
    """Refuse a limb the coupled arm cannot model (docs/model.md section 13): the built-in
    FE meshes the layer between the bone and the skin of a circular, elliptic, outlined or
    tapered limb (physics/continuum/shape.py), not a scan, and the hyperelastic laws are
    identified on a circular cylinder only; the user's own FE export
    (tissue.continuum.surface_stiffness) may be of any shape."""
    if cfg.patches is not None:
        raise ConfigError("the coupled arm's FE meshes its patches as rows x angles of one "
                          "cylindrical layer; a free layout is not available there yet (use "
                          "--arm compliant or rigid)", file=cfg.path, key="cuff.patches")
    own_fe = cfg.continuum_surface_stiffness is not None
    if cfg.bone is not None and own_fe:
        raise ConfigError("geometry.bone shapes the built-in FE's layer; your own FE's "
                          "tissue.continuum.surface_stiffness already holds its bone (remove "
                          "one)", file=cfg.path, key="geometry.bone")
    if cfg.is_circular_cylinder and cfg.bone is None:
        return
    if cfg.scan is not None:
        key, what = "geometry.scan", "a scanned limb"
    elif cfg.bone is not None and cfg.is_circular_cylinder:
        key, what = "geometry.bone", "a bone of its own"
    elif cfg.sections is not None:
        key, what = "geometry.section", "a non-circular section"
    else:
        key, what = "geometry.taper_deg", "a taper"
    if CONTINUUM_LAW_MODELS[cfg.continuum_law].reduced:
        raise ConfigError(f"the coupled arm's {cfg.continuum_law} law is identified on the "
                          f"built-in FE's circular cylindrical layer: {what} is not available "
                          "there yet (use the linear law, or --arm compliant or rigid)",
                          file=cfg.path, key=key)
    if cfg.scan is not None and not own_fe:
        raise ConfigError("the coupled arm's built-in FE meshes sections and tapers, not a "
                          "scanned limb; give your own FE's tissue.continuum.surface_stiffness "
                          "for this limb, or use --arm compliant or rigid", file=cfg.path,
                          key=key)
    if not own_fe and cfg.continuum_thickness is not None:
        from ..physics.continuum.shape import check_layer

        try:
            check_layer(cfg.geometry(), cfg.continuum_thickness, cfg.bone)
        except ValueError as exc:
            raise ConfigError(str(exc), file=cfg.path,
                              key="geometry.bone" if cfg.bone is not None
                              else "tissue.continuum.thickness") from None


def _linear_coupled_model(cfg: Config, *, cache_dir=None, level=None):
    """:func:`coupled_model` with the linear continuum."""
    from ..physics.continuum.coupled import build_coupled_model
    from ..physics.continuum.spread import scale_parts, scale_patches

    key = "tissue.continuum"
    if cfg.strap_model == "band":
        raise ConfigError("the band strap is not available with the coupled arm (its "
                          "continuum is condensed for a strap wrench that does not follow the "
                          "cuff); use --arm compliant or rigid", file=cfg.path, key="strap.stiffness")
    _require_continuum(cfg)
    _check_coupled_shape(cfg)
    geom = geometry_from_config(cfg)
    # a limb of any shape: its thinnest point bounds the layer (the built-in FE's layer
    # is checked ray by ray above)
    radius = np.unique(geom.radius) if cfg.is_circular_cylinder else np.min(geom.radius)[None]
    if len(radius) != 1:
        raise ConfigError("the coupled model needs one cuff radius for every row (a cylindrical "
                          f"arm), got {sorted(radius.tolist())} m", file=cfg.path,
                          key="geometry.radius")
    t = cfg.continuum_thickness
    if not t < radius[0]:
        raise ConfigError(f"expected 0 < thickness < the radius {radius[0]:g} m (the bone's radius "
                          f"is radius - thickness), got {t:g} m", file=cfg.path,
                          key=f"{key}.thickness")
    if not cfg.poisson_ratio < 0.5:
        raise ConfigError(f"the coupled model needs a Poisson ratio below 0.5 (a compressible "
                          f"continuum), got {cfg.poisson_ratio:g}", file=cfg.path,
                          key="tissue.poisson_ratio")
    from ..physics.continuum.mesh import MAX_POISSON_RATIO

    # the built-in FE builds K, or turns indenter stiffness into E for a per-patch spread
    builtin_fe = cfg.continuum_surface_stiffness is None or (
        cfg.continuum_young_modulus is None and cfg.continuum_spread == "per_patch")
    if builtin_fe and cfg.poisson_ratio > MAX_POISSON_RATIO:
        raise ConfigError(f"the built-in FE of the coupled arm is converged up to "
                          f"{MAX_POISSON_RATIO} (its elements lock as nu -> 0.5), got "
                          f"{cfg.poisson_ratio:g}; use <= {MAX_POISSON_RATIO}, or give your own "
                          f"FE's tissue.continuum.surface_stiffness and young_modulus",
                          file=cfg.path, key="tissue.poisson_ratio")
    from ..io.cache.surface_stiffness import load_or_build, load_surface_stiffness

    N = parts = None
    if cfg.continuum_surface_stiffness is not None:
        K = load_surface_stiffness(cfg.continuum_surface_stiffness, geom)
        E = None
    else:
        E = continuum_modulus(cfg, geom)
        _fe_module(cfg)
        at_level = {} if level is None else {"level": int(level)}
        K, info = load_or_build(geom, t, float(np.mean(E)), cfg.poisson_ratio,
                                cache_dir=cache_dir, patch_gap=cfg.continuum_patch_gap,
                                bone=cfg.bone, **at_level)
        N, parts = info.get("N"), info.get("N_parts")
    if cfg.continuum_spread == "per_patch":
        if E is None:
            E = continuum_modulus(cfg, geom)
        s = E / np.mean(E)
        K, N = scale_patches(K, N, s)
        if parts is not None:
            parts = (scale_parts(parts[0], parts[1], s, K.shape[0] // geom.n), parts[1])
    try:
        return build_coupled_model(geom, K, cfg.cuff_stiffness, poisson_ratio=cfg.poisson_ratio,
                                   shear_ratio=cfg.shear_ratio, strap_tension=cfg.strap_tension,
                                   strap_model=cfg.strap_model,
                                   handle_angles_deg=cfg.handle_angles_deg,
                                   handle_axial_position=cfg.strap_axial_position,
                                   pain_threshold_kpa=cfg.pain_threshold_kpa, normal_output=N,
                                   normal_parts=parts,
                                   friction_coefficient=cfg.friction_coefficient)
    except ModelInputError as exc:
        raise ConfigError(str(exc), file=cfg.continuum_surface_stiffness or cfg.path,
                          key=_QUANTITY_KEYS.get(exc.quantity, key)) from None


def cuff_wrench(cfg: Config, wrench_lc) -> np.ndarray:
    """Load-cell readings (log units) -> wrench on the cuff W (m, 6) [N, N*m] (docs/model.md section 5)."""
    return loadcell_to_cuff(wrench_lc, cfg.loadcell_rotation, cfg.loadcell_position,
                            cfg.loadcell_sign, FORCE_UNITS[cfg.force_unit],
                            MOMENT_UNITS[cfg.moment_unit])
