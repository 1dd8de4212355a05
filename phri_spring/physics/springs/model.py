"""The assembled spring network: plain arrays the solver works on."""

from __future__ import annotations

from dataclasses import dataclass, field, fields

import numpy as np

from ...errors import ModelInputError
from ..cuff.geometry import CuffGeometry, element_jacobians
from ..cuff.preload import strap_preload
from .stiffness import (indenter_to_element, series_stiffness, shear_ratio_from_poisson,
                      shear_stiffness_matrix)
from ..laws import LinearLaw, SeriesElement, TissueLaw, make_law

__all__ = ["SpringModel", "build_model", "check_friction", "tissue_element_stiffness", "field_table", "field_unit"]


def field_unit(unit: str, source: str) -> dict:
    """Metadata of a model's array field: its unit and where docs/model.md defines it
    (read by :func:`field_table` and ``config_units``)."""
    return {"unit": unit, "source": source}


class OnGeometry:
    """What every arm model reads off its ``geometry`` (n, labels, b, areas)."""

    @property
    def n(self) -> int:
        return self.geometry.n

    @property
    def labels(self) -> tuple:
        return self.geometry.labels

    @property
    def b(self) -> np.ndarray:
        return self.geometry.b

    @property
    def areas(self) -> np.ndarray:
        return self.geometry.areas

    @property
    def is_linear(self) -> bool:
        """Whether the model is linear for a fixed contact set (the active-set kernel alone
        solves it); a model with a nonlinear law overrides it."""
        return True

    @property
    def law(self):
        """The model's tissue law (a :class:`~phri_spring.physics.laws.TissueLaw`), or
        None where the tissue is not a law of its elements (the rigid arm, the continuum)."""
        return None


@dataclass(frozen=True, eq=False)
class SpringModel(OnGeometry):
    """A cuff-arm spring network ready to solve (docs/model.md sections 1-4).

    Every array field declares its unit and the section of docs/model.md that
    defines it in ``dataclasses.fields(SpringModel)[i].metadata`` (see
    :func:`field_table`). Derived arrays the solver reuses (``bT``, ``bb``, ...)
    are computed once when the model is made; a model holds no cache.

    Attributes
    ----------
    geometry : CuffGeometry
    arm : str
        ``compliant`` or ``rigid``.
    k : ndarray, shape (n,)
        Normal stiffness k_e [N/m].
    k_shear : ndarray, shape (n,)
        Tangential stiffness k_s,e [N/m].
    K_s : ndarray, shape (6, 6)
        Shear stiffness matrix of the cuff displacement u = (t [m], w [rad]), about
        the cuff origin: blocks [N/m, N/rad; N*m/m, N*m/rad].
    delta0 : ndarray, shape (n,)
        Initial compression [m] (hoop preload), zero otherwise.
    f0 : ndarray, shape (n,)
        Initial normal force [N] (hoop preload), zero otherwise.
    W_pre : ndarray, shape (6,)
        Constant wrench of the strap on the cuff [N, N*m].
    strap_model : str
        ``hoop``, ``handles`` or ``band``.
    pain_threshold_kpa : float
        Pressure pain threshold [kPa].
    bT : ndarray, shape (6, n)
        b transposed, C-contiguous [-, m] (derived).
    bb : ndarray, shape (n, 36)
        Row-major outer products b_e b_e^T [-, m, m^2] (derived).
    delta0_b : ndarray, shape (n, 6)
        delta0_e b_e [m, m^2] (derived).
    b_absmax : ndarray, shape (6,)
        ``max_e |b_ej|`` [-, m] (derived; round-off scale of the compression).
    delta0_absmax : float
        ``max_e |delta0_e|`` [m] (derived).
    inv_area_kpa : ndarray, shape (n,)
        1 / (1000 A_e) [1/(kPa*m^2) = 1/(1000 N)]: force [N] times it is pressure [kPa] (derived).
    friction_coefficient : float or None
        mu [-] (docs/model.md section 12): elements that lift off carry nothing and touching
        ones hold by Coulomb friction, along the loading path; None: bonded shear springs.
    element : phri_spring.physics.laws.series.SeriesElement
        Each element's normal law: the tissue law in series with its cuff spring
        (the cuff spring alone for the rigid arm); k above is its stiffness at small
        compression. Default: the linear spring k (docs/model.md section 11).
    """

    geometry: CuffGeometry
    arm: str
    k: np.ndarray = field(metadata=field_unit("N/m", "docs/model.md section 2"))
    k_shear: np.ndarray = field(metadata=field_unit("N/m", "docs/model.md section 2"))
    K_s: np.ndarray = field(metadata=field_unit("[[N/m, N/rad], [N*m/m, N*m/rad]]",
                                           "docs/model.md section 2"))
    delta0: np.ndarray = field(metadata=field_unit("m", "docs/model.md section 3"))
    f0: np.ndarray = field(metadata=field_unit("N", "docs/model.md section 3"))
    W_pre: np.ndarray = field(metadata=field_unit("[N, N, N, N*m, N*m, N*m]", "docs/model.md section 3"))
    strap_model: str = "hoop"
    pain_threshold_kpa: float = field(default=120.0, metadata=field_unit("kPa", "docs/model.md section 4"))
    #: Coulomb coefficient of the skin on the cuff; None: bonded (the paper's springs)
    friction_coefficient: float | None = field(default=None, metadata=field_unit(
        "-", "docs/model.md section 12"))
    bT: np.ndarray = field(init=False, repr=False, metadata=field_unit("[-, m]", "derived"))
    bb: np.ndarray = field(init=False, repr=False, metadata=field_unit("[-, m, m^2]", "derived"))
    delta0_b: np.ndarray = field(init=False, repr=False, metadata=field_unit("[m, m^2]", "derived"))
    b_absmax: np.ndarray = field(init=False, repr=False, metadata=field_unit("[-, m]", "derived"))
    delta0_absmax: float = field(init=False, repr=False, metadata=field_unit("m", "derived"))
    inv_area_kpa: np.ndarray = field(init=False, repr=False, metadata=field_unit("1/(1000 N)", "derived"))
    element: SeriesElement | None = field(default=None, repr=False)

    def __post_init__(self):
        b = self.geometry.b
        derived = {
            "bT": np.ascontiguousarray(b.T),
            "bb": (b[:, :, None] * b[:, None, :]).reshape(-1, 36),
            "delta0_b": self.delta0[:, None] * b,
            "b_absmax": np.max(np.abs(b), axis=0),
            "delta0_absmax": float(np.max(np.abs(self.delta0), initial=0.0)),
            "inv_area_kpa": 1.0 / (1000.0 * self.geometry.areas),
        }
        for name, value in derived.items():
            object.__setattr__(self, name, value)
        if self.element is None:
            object.__setattr__(self, "element", SeriesElement(LinearLaw(self.k), np.inf))

    @property
    def law(self) -> TissueLaw | None:
        """The tissue law (None for the rigid arm: no tissue)."""
        return self.element.law

    @property
    def is_linear(self) -> bool:
        """True when every element is a linear spring (the exact active-set path solves it)."""
        return self.element.is_linear

    def contact_system(self, cache=None):
        """The active-set kernel's system of the linear model with stiffness k (docs/model.md
        section 9); a nonlinear law is then solved from the answer of its tangent model at
        the preload (section 11, :meth:`newton_start`)."""
        from ..contact.solver import SpringSystem

        return SpringSystem(self if self.is_linear else self.newton_start()[0], cache)

    def newton_start(self):
        """For a nonlinear law: (the linear model tangent to it at the preload, the tissue
        shares d_t (n,) [m] and the tissue tangents (n,) [N/m] there).

        The tangent model's element e carries f0_e + k_T,e (d - delta0_e) with k_T,e the
        series tangent at the preloaded compression delta0_e: at zero wrench it gives the
        preload itself, so a log's quiet samples start at their answer and loaded ones
        within the curvature of the law. Made once per model.
        """
        cached = self.__dict__.get("_newton_start")
        if cached is None:
            el = self.element
            dt_pre = el.tissue_compression(self.delta0)
            kt_pre = el.law.tangent(dt_pre)
            k_T = el.tangent(self.delta0)
            k_T = np.where(k_T > 0, k_T, self.k)          # an element unloaded at preload
            start = SpringModel(geometry=self.geometry, arm=self.arm, k=k_T,
                                k_shear=self.k_shear, K_s=self.K_s, delta0=self.f0 / k_T,
                                f0=self.f0, W_pre=self.W_pre, strap_model=self.strap_model,
                                pain_threshold_kpa=self.pain_threshold_kpa)
            cached = (start, dt_pre, kt_pre)
            object.__setattr__(self, "_newton_start", cached)
        return cached

    def shear_forces(self, u) -> np.ndarray:
        """Shear force on the arm s_e = k_s,e (I3 - n_e n_e^T) B_e u [N], shape (..., n, 3).

        The bonded shear springs of docs/model.md section 2, for displacement(s) u (..., 6).
        """
        u = np.asarray(u, dtype=float)
        g = self.geometry
        d = u[..., None, :3] + np.cross(u[..., None, 3:], g.points)      # d_e = t + w x p_e
        dn = np.sum(d * g.normals, axis=-1, keepdims=True)
        return self.k_shear[:, None] * (d - dn * g.normals)

    def shear_components(self, u, contact=None) -> np.ndarray:
        """Shear force on the arm, (m, n, 2) [N]: along the skin's meridian a_e (+x on an
        untapered limb) and along c_e (increasing angle), the geometry's
        ``meridian`` and ``circumferential``, for displacements u (m, 6); ``contact``
        unused (the shear springs are bonded)."""
        s = self.shear_forces(np.atleast_2d(u))
        g = self.geometry
        return np.stack([np.sum(s * g.meridian, axis=-1),
                         np.sum(s * g.circumferential, axis=-1)], axis=-1)

    def tangent_stiffness(self, u, contact=None) -> np.ndarray:
        """Tangent stiffness K_s + sum_{e in contact} k_e b_e b_e^T (6, 6) at displacement u (6,).

        ``contact`` (n,) bool overrides the contact set read off u.
        """
        g = self.delta0 + self.b @ np.asarray(u, dtype=float)
        if contact is None:
            contact = g > 0
        k = self.k if self.is_linear else self.element.tangent(np.maximum(g, 0.0))
        kS = k * np.asarray(contact, dtype=bool)
        return self.K_s + (self.b.T * kS) @ self.b


def field_table(model_class=SpringModel) -> list:
    """``(name, unit, source)`` of every field of a model class that declares a unit.

    >>> ("k", "N/m", "docs/model.md section 2") in field_table()
    True
    """
    return [(f.name, f.metadata["unit"], f.metadata["source"])
            for f in fields(model_class) if "unit" in f.metadata]


def tissue_element_stiffness(values, areas, basis: str = "indenter",
                             indenter_diameter: float = 0.009) -> np.ndarray:
    """Element tissue stiffness k_t,e [N/m] from configured values.

    ``basis='indenter'`` converts indenter stiffness by area; ``'element'`` uses the values as given.
    """
    values = np.asarray(values, dtype=float)
    if basis == "indenter":
        return indenter_to_element(values, areas, indenter_diameter)
    if basis == "element":
        return values.copy()
    raise ValueError(f"basis: expected 'indenter' or 'element', got {basis!r}")


def build_model(geometry: CuffGeometry, k_tissue, k_cuff, *, arm: str = "compliant",
                shear_ratio: float | None = None, poisson_ratio: float = 0.45,
                strap_tension: float = 15.0, strap_model: str = "hoop",
                handle_angles_deg=None, handle_axial_position: float | None = None,
                pain_threshold_kpa: float = 120.0, law="linear",
                law_parameters: dict | None = None,
                friction_coefficient: float | None = None) -> SpringModel:
    """Assemble the spring network of docs/model.md sections 2 and 3.

    Parameters
    ----------
    geometry : CuffGeometry
    k_tissue : array_like, shape (n,)
        Element tissue stiffness k_t,e [N/m] (already converted from the indenter basis).
    k_cuff : array_like, shape (n,)
        Cuff stiffness k_c,e [N/m]; ``inf`` allowed.
    arm : {'compliant', 'rigid'}
    shear_ratio : float, optional
        eta = k_s,e / k_e [-]; default 1 / (2 (1 + poisson_ratio)).
    poisson_ratio : float
        Tissue Poisson ratio nu [-].
    strap_tension : float
        T [N].
    strap_model : {'hoop', 'handles', 'band'}
        ``band``: the handles' wrench at ``strap_tension`` (the band's tension at zero
        wrench); :func:`~phri_spring.physics.contact.band_solve.band_model` adds its
        elasticity.
    handle_angles_deg : (float, float), optional
        Handle angles [deg] (``handles`` only); default the cuff's edges.
    handle_axial_position : float, optional
        Handles' axial position [m]; default the mean row position.
    pain_threshold_kpa : float
        Pressure pain threshold [kPa].
    law : str or TissueLaw subclass
        Tissue law of the compliant arm, a name of
        :data:`~phri_spring.physics.laws.TISSUE_LAWS` or the class, with k_tissue its
        stiffness at small compression; the rigid arm has no tissue.
    law_parameters : dict, optional
        The law's parameters (name -> number or (n,) array, in their units).
    friction_coefficient : float, optional
        Coulomb coefficient mu >= 0 [-] of docs/model.md section 12 (with any tissue law:
        the normal response is the series element); None keeps the bonded shear springs.

    Raises
    ------
    ValueError
        If an element is infinitely stiff, a stiffness is not positive, or K_s is singular.
    """
    n = geometry.n
    k_t = np.broadcast_to(np.asarray(k_tissue, dtype=float), (n,))
    k_c = np.broadcast_to(np.asarray(k_cuff, dtype=float), (n,))
    if arm not in ("compliant", "rigid"):
        raise ValueError(f"arm: expected 'compliant' (tissue and cuff springs in series) or "
                         f"'rigid' (cuff springs only), got {arm!r}")
    tissue = arm == "compliant"
    k = series_stiffness(k_t, k_c) if tissue else k_c.astype(float, copy=True)
    bad = ~np.isfinite(k) | ~(k > 0)
    if bad.any():
        first = geometry.labels[int(np.argmax(bad))]
        raise ModelInputError(f"element {first} has stiffness {k[bad][0]!r} N/m in the {arm} "
                              "model; expected a positive finite value (an infinitely stiff "
                              "element has no defined contact force)", "stiffness")
    eta = shear_ratio_from_poisson(poisson_ratio) if shear_ratio is None else float(shear_ratio)
    if not eta > 0:
        raise ModelInputError(f"shear_ratio: expected > 0, got {eta}", "shear_ratio")
    k_s = eta * k
    B = element_jacobians(geometry.points)
    K_s = shear_stiffness_matrix(k_s, B, geometry.normals)
    eig = np.linalg.eigvalsh(0.5 * (K_s + K_s.T))
    if not eig[0] > 1e-9 * max(eig[-1], 1e-300):
        raise ModelInputError("the shear stiffness matrix K_s is singular for this geometry "
                              "(e.g. a single angular location): the cuff is not held in every "
                              "direction", "geometry")

    f0, W_handles = strap_preload(geometry, strap_tension, strap_model, handle_angles_deg,
                                  handle_axial_position)
    element = SeriesElement(make_law(law, k_t, **(law_parameters or {})) if tissue else None, k_c)
    if W_handles is None:  # hoop: u = 0 at zero load
        # each element carries f0_e: the compression of its series element at f0_e
        delta0 = f0 / k if element.is_linear else element.compression_at(f0)
        W_pre = f0 @ geometry.b
    else:
        delta0 = np.zeros(n)
        W_pre = W_handles

    mu = check_friction(friction_coefficient)
    return SpringModel(geometry=geometry, arm=arm, k=k, k_shear=k_s, K_s=K_s, delta0=delta0,
                       f0=f0, W_pre=W_pre, strap_model=strap_model,
                       pain_threshold_kpa=float(pain_threshold_kpa), element=element,
                       friction_coefficient=mu)


def check_friction(mu) -> float | None:
    """A Coulomb coefficient as a float (None stays None: bonded); typed error otherwise."""
    if mu is None:
        return None
    try:
        mu = float(mu)
    except (TypeError, ValueError):
        mu = float("nan")
    if not (np.isfinite(mu) and mu >= 0):
        raise ModelInputError(f"interface.friction_coefficient: expected a finite number >= 0, "
                              f"got {mu!r}", "friction_coefficient")
    return mu
