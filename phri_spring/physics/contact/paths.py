"""The solve paths beside the spring kernel: what a model with a nonlinear law, one that
solves its samples itself, or one with Coulomb friction needs on top of (or instead of)
the active-set loop of :mod:`~phri_spring.physics.contact.active_set`.

:func:`~phri_spring.physics.contact.solver.solve` (many samples) and
:class:`~phri_spring.physics.contact.single.Solver` (one sample at a time) both use
them.
"""

from __future__ import annotations

import numpy as np

from .active_set import ContactSystem, FactorCache
from .solution import Solution

__all__ = ["HUGE", "DIRECT_ROWS", "make_system", "nonlinear_finish", "solve_direct",
           "solve_friction", "friction_solution", "path_wrenches"]

#: a cuff displacement beyond this [m, rad] is no answer (an absurd input: forces overflow)
HUGE = 1e100
#: rows per call of a model's own solver (bounds its (rows x monomials) temporaries)
DIRECT_ROWS = 2048


def make_system(model, cache: FactorCache | None = None) -> ContactSystem:
    """The kernel's system for a model (any arm model: ``model.contact_system``)."""
    return model.contact_system(cache)


def nonlinear_finish(model, r, u, its, conv, max_iterations):
    """For a spring model with a nonlinear law: Newton from the linear model's answer u, in
    place (docs/model.md section 11); returns the compression g (m, n) and the element
    forces (m, n) the iteration converged to."""
    from ..springs.newton import solve_newton   # on demand: the linear laws never need it

    f = np.empty((len(r), model.n))
    u[:], itn, conv_n = solve_newton(model, r, u, max_iterations=max_iterations,
                                     forces_out=f)
    its += itn
    conv &= conv_n
    return model.delta0 + u @ model.bT, f



def solve_direct(model, W, single: bool, out, max_iterations: int) -> Solution:
    """A model that solves its samples itself (``model.solve_wrenches``, e.g. the reduced
    neo-Hookean coupled model): its rows in blocks, into ``out`` if given."""
    m, n = len(W), model.n
    if out is not None and not (isinstance(out, np.ndarray) and out.shape == (m, n)
                                and out.dtype == np.float64 and out.flags.c_contiguous):
        raise ValueError(f"out: expected a C-contiguous float64 array of shape ({m}, {n})")
    forces = np.empty((m, n)) if out is None else out
    u = np.empty((m, 6))
    its = np.empty(m, dtype=np.int64)
    conv = np.empty(m, dtype=bool)
    contact = np.empty((m, n), dtype=bool)
    for s in range(0, m, DIRECT_ROWS):
        e = min(m, s + DIRECT_ROWS)
        u[s:e], forces[s:e], its[s:e], conv[s:e], contact[s:e] = model.solve_wrenches(
            W[s:e], max_iterations)
    if single:
        return Solution(u=u[0], forces=forces[0], iterations=its[0], converged=conv[0],
                        contact=contact[0])
    return Solution(u=u, forces=forces, iterations=its, converged=conv, contact=contact)



def solve_friction(model, W, single: bool, cache: FactorCache | None,
                    state=None) -> Solution:
    """:func:`solve` with Coulomb friction: the rows of W are a loading path, solved in order
    from the state ``cache`` carries (a fresh cache: the strap's state at zero wrench)."""
    from ..friction.path import interface_form, solve_path

    cache = FactorCache(0) if cache is None else cache
    if cache.path_form is None or cache.path_form[0] is not model:
        cache.path_form = (model, interface_form(model))
    form = cache.path_form[1]
    r, finite = path_wrenches(W, model.W_pre)
    u, P, cls, solves, conv, end = solve_path(form, r, cache.path_state if state is None
                                              else state, cache.path_maps)
    cache.path_state = end
    return friction_solution(model, u, P, cls, solves, conv & finite, single)


def path_wrenches(W, W_pre):
    """``(r, finite)``: the wrenches W (m, 6) plus the strap's W_pre (6,) for a loading path,
    and which rows are an answerable load (finite, within :data:`HUGE`); the others are
    solved as the strap alone and reported as not converged."""
    with np.errstate(over="ignore", invalid="ignore"):
        r = W + W_pre
    finite = np.isfinite(r).all(axis=1) & (np.abs(r).max(axis=1) <= HUGE)
    return np.where(finite[:, None], r, W_pre), finite


def friction_solution(model, u, P, cls, solves, conv, single: bool) -> Solution:
    """The :class:`Solution` of a path solved by
    :func:`~phri_spring.physics.friction.path.solve_path`: u (m, 6), patch forces P (m, n d),
    states ``cls`` (m, n), linear solves and convergence (m,); NaN where not converged."""
    n = model.n
    d = P.shape[1] // n
    Pe = P.reshape(len(u), n, d)
    normal = Pe[:, :, 0].copy()
    tangential = Pe[:, :, 1:3].copy()
    moments = Pe[:, :, 3:6].copy() if d == 6 else None
    contact = (cls > 0) & conv[:, None]
    if hasattr(model, "reported_normal"):   # a coupled patch reports its traction integral
        forces = model.reported_normal(P, contact)
    else:
        forces = np.maximum(normal, 0.0)
    for a in (forces, normal, tangential, moments):
        if a is not None:
            a[~conv] = np.nan
    its = np.maximum(solves, 1)
    if single:
        return Solution(u=u[0], forces=forces[0], iterations=its[0], converged=conv[0],
                        contact=contact[0], tangential=tangential[0],
                        moments=None if moments is None else moments[0], normal=normal[0])
    return Solution(u=u, forces=forces, iterations=its, converged=conv, contact=contact,
                    tangential=tangential, moments=moments, normal=normal)
