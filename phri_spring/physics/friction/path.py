"""Coulomb friction at the cuff-skin interface: contact that lets go and slides.

docs/model.md section 12. With ``interface.friction_coefficient`` (mu) set, each
element (spring model) or patch (coupled model) is in one of three states:

* **released** -- it has lifted off and carries nothing: no normal force, no
  tangential force, no moment;
* **stuck** -- it presses (normal force >= 0) and its tangential force stays within
  the friction cone ``|P_t| <= mu P_n``; its tangential (and, for a patch, rotational)
  motion is tied to the cuff, offset by the slip z it has accumulated;
* **sliding** -- it presses and its tangential force is on the cone,
  P_t = mu P_n s with s the unit direction of its slip increment.

For a coupled patch with ``friction_coefficient`` set, P_n in the cone is the smaller of
P_n and its reading's traction integral (:attr:`InterfaceForm.cone_normal`); a patch
whose cone has closed that way slides freely (P_t = 0, s = 0).

Both arm models are written in one compliance form (the coupled model's, docs/model.md
section 10.3): patch forces P (n d, local axes: normal, axial, circumferential[, three
rotations]), total compliance C, the rigid map T (n d, 6) and the preload offset delta.
For the spring model C is diagonal (1/k_e normal, 1/k_s,e tangential, d = 3) and T's rows
are b_e and the tangential rows of B_e; with a nonlinear tissue law its normal springs are
the series elements instead (:mod:`phri_spring.physics.friction.normal`: the states'
samples are then solved by Newton's method per row rather than affinely). For a given
state the equilibrium is linear:

    stuck or sliding, normal and rotational dofs:  (C P)_i = (T u + delta - z)_i
    stuck, tangential dofs:                        (C P)_i = (T u + delta - z)_i
    sliding, tangential dofs:                      P_i = mu P_n,e s_e,i
    released:                                      P_e = 0
    the cuff:                                      T^T P = W + W_pre

Friction makes the answer depend on the loading path, so a log is solved in order,
each sample from the state the previous one left (backward-Euler return mapping):
the state is updated until it is consistent -- stuck patches inside the cone and
pressing, sliding ones pressing with their slip increment along s, released ones not
penetrating. Samples that leave the state unchanged (every pressing patch stuck, the
set of released ones the same) are affine in the wrench and solved together, so a
log costs a few vectorised products between the samples where something slips,
lifts off or comes back. Those samples are events: the spring model's by a semismooth
Newton method on u (:mod:`.events`); the coupled model's, with a friction coefficient
set, by active sets on the sliding patches' forces (:mod:`.active`), the semismooth
Newton on all patch forces where those find no state (and for the default's lift-off
cone). The problem is not convex (Coulomb friction is not the
minimum of an energy); what the solver guarantees is that every sample it reports as
converged satisfies equilibrium to round-off, the cone, compressive normal forces and
no penetration, checked; otherwise the sample is flagged and its forces are NaN, and
the next sample starts from the last consistent state.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import nnls

from .events import solve_event_coupled, solve_event_elements
from .active import active_step
from . import loader
from .maps import stuck_maps
from .normal import block_nonlinear, frictionless_unheld
# the shared pieces, importable from here too
from .form import (RELEASED, SLIDING, STATE_RTOL, STUCK, InterfaceForm,  # noqa: F401
                            PathState, relative, scales, initial_state, interface_form)

__all__ = ["InterfaceForm", "PathState", "interface_form", "initial_state", "solve_path",
           "RELEASED", "STUCK", "SLIDING"]

#: samples solved together while the state holds
_BLOCK = 4096
_FIRST_BLOCK = 8


def _block(form, maps, state, r, f_tol, x_tol):
    """Solve rows r (m, 6) in the state ``state`` (no sliding patch); returns
    (u, P, k, u_next): the first k rows keep the state (k = m if all do); u_next is the
    state's displacement at row k (a start for the event there), None if k = m."""
    n, d, mu = form.n, form.d, form.mu
    c, P0 = maps.offsets(form, state.z)
    u = (r - c) @ maps.Hinv.T
    PD = u @ maps.GT.T + P0
    m = len(r)
    ok = np.ones(m, dtype=bool)
    PS = PD if not maps.free.size else PD[:, maps.stuck_at]
    nd = PS.reshape(m, -1, d)
    Pn = nd[:, :, 0]
    ok &= np.all(Pn >= -f_tol[:, None], axis=1)
    if mu < np.inf:
        tn = np.sqrt(nd[:, :, 1] ** 2 + nd[:, :, 2] ** 2)
        fc = maps.cone_force(PD, Pn)
        ok &= np.all(tn <= mu * np.maximum(fc, 0.0) + f_tol[:, None], axis=1)
    if maps.free.size:
        # free patches: still pressing, their cone still closed
        ok &= np.all(PD[:, maps.free_normal_at] >= -f_tol[:, None], axis=1)
        fc = (PD[:, maps.free_normal_at] if maps.cone_free is None
              else np.minimum(PD[:, maps.free_normal_at], PD @ maps.cone_free.T))
        ok &= np.all(fc <= f_tol[:, None], axis=1)
    if maps.rel.size:
        pen = u @ maps.Q.T + maps.d_rel
        if maps.Cs is not None:
            pen -= P0 @ maps.Cs.T
        ok &= np.all(pen <= x_tol[:, None], axis=1)
    bad = np.flatnonzero(~ok)
    k = int(bad[0]) if bad.size else m
    P = np.zeros((k, n * d))
    P[:, maps.D] = PD[:k]
    return u[:k], P, k, (u[k] if k < m else None)


def _free_sliders(state):
    """The sliding patches of ``state`` whose cone has closed (slip direction 0), or None
    where a patch slides on an open cone (then every sample is an event)."""
    if state.cls.max() < SLIDING:         # SLIDING is the largest state code
        return np.zeros(len(state.cls), dtype=bool)
    sl = state.cls == SLIDING
    if state.s[sl].any():
        return None
    return sl


def _frictionless_reachable(form, cache, r, f_tol) -> bool:
    """Whether compressive normal forces, with the patches' tied moments, can make the
    wrench r (6,) at all: the necessary condition of an equilibrium without friction
    (mu = 0). With Q the projector off the pure moments the rotations carry (none for the
    spring model), it is min over f >= 0 of |Q (T_n^T f - r)| <= f_tol, a non-negative
    least-squares problem on n unknowns. On a cylinder the normals have no axial part:
    any axial force has no frictionless equilibrium, however small."""
    key = "frictionless"
    if key not in cache:
        n, d = form.n, form.d
        dof = np.arange(n * d).reshape(n, d)
        A = form.T[dof[:, 0]].T                                   # (6, n)
        B = form.T[dof[:, 3:].ravel()].T if d == 6 else np.zeros((6, 0))
        Q = np.eye(6) - B @ np.linalg.pinv(B) if B.size else np.eye(6)
        cache[key] = (Q @ A, Q)
    QA, Q = cache[key]
    _, res = nnls(QA, Q @ r)
    return res <= f_tol


#: most changes of the contact set tried by :func:`_stuck_transition`
_HOPS = 4


def _stuck_transition(form, cache, state, r, f_tol, x_tol):
    """The coupled model's usual event, cheaply: patches lift off or come back and every
    touching one stays inside its cone. From the path's state (no patch sliding), the
    patches the wrench r pulls off are released and the released ones it presses come
    back (landing where they were, as in :func:`solve_event_coupled`), solved with the
    cached maps of the new set and checked as a block row is; repeated up to _HOPS times.
    Returns the event's (u, P, state, solves, True), or None where a patch would slide or
    the set does not settle (then the semismooth Newton takes the sample)."""
    n, d, mu = form.n, form.d, form.mu
    cls = state.cls.copy()
    z = state.z.copy()
    was_off = cls == RELEASED
    if was_off.any():
        land = relative(form, state.u, state.P).reshape(n, d)
        z[was_off, 1:] = land[was_off, 1:]
    for hop in range(1, _HOPS + 1):
        maps = stuck_maps(form, cache, cls)
        if not maps:
            return None
        c, P0 = maps.offsets(form, z)
        u = (r - c) @ maps.Hinv.T
        PD = u @ maps.GT.T + P0
        nd = PD.reshape(-1, d)
        tn = np.sqrt(nd[:, 1] ** 2 + nd[:, 2] ** 2)
        if np.any(tn > mu * np.maximum(maps.cone_force(PD, nd[:, 0]), 0.0) + f_tol):
            return None
        lift = nd[:, 0] < -f_tol
        back = np.zeros(0, dtype=bool)
        if maps.rel.size:
            pen = maps.Q @ u + maps.d_rel
            if maps.Cs is not None:
                pen -= maps.Cs @ P0
            back = pen > x_tol
        if not lift.any() and not back.any():
            P = np.zeros(n * d)
            P[maps.D] = PD
            new = PathState(cls=cls, z=z, s=state.s.copy(), u=u, P=P)
            return u, P, new, hop, True
        cls[np.flatnonzero(cls == STUCK)[lift]] = RELEASED
        cls[maps.rel[back]] = STUCK
        if not (cls == STUCK).any():
            return None
    return None


#: the spring model: after a sample where elements slid, they are first tried stuck again
#: (as a block); False: the event solver at once
_REGRIP = True
#: the coupled model without a friction coefficient: a sample the semismooth Newton does
#: not answer goes to the active sets before its increments; False: the increments alone
_RESCUE = True

#: the coupled model's events by active sets first (:mod:`.active`); False: the
#: semismooth Newton alone (the reference the tests compare against)
_ACTIVE_SETS = True


def solve_path(form: InterfaceForm, r, state: PathState | None = None, cache: dict | None = None,
               max_updates: int | None = None):
    """Solve wrenches r = W + W_pre (m, 6) in order along the loading path.

    Returns
    -------
    u : ndarray, shape (m, 6)
    P : ndarray, shape (m, n d)
        Patch forces on the skin, local axes (0 for released patches) [N, N*m].
    cls : ndarray of int, shape (m, n)
        Each patch's state at each sample.
    solves : ndarray of int, shape (m,)
        Linear solves the sample took (0 for a sample solved in a block).
    converged : ndarray of bool, shape (m,)
    state : PathState
        Where the path ends (pass it to the next chunk of the same log).
    """
    r = np.atleast_2d(np.asarray(r, dtype=float))
    m = len(r)
    n, d = form.n, form.d
    state = initial_state(form) if state is None else state.copy()
    cache = {} if cache is None else cache
    if _COMPILED and form.diagonal and form.mu > 0:
        kernel = loader.kernel()
        if kernel is not None and kernel.NUMBA and kernel.supports(form):
            return _solve_compiled(form, kernel, r, state, cache)
    u = np.zeros((m, 6))
    P = np.zeros((m, n * d))
    cls = np.zeros((m, n), dtype=np.int8)
    solves = np.zeros(m, dtype=np.int64)
    conv = np.ones(m, dtype=bool)
    fs, xs = scales(form, np.zeros(6))
    scale = np.abs(r).max(axis=1) + np.abs(form.W_pre).max() + 1e-300
    f_tol = STATE_RTOL * scale
    x_tol = f_tol * (xs / fs)
    # the wrench at which ``state`` was reached: its forces balance it
    r_state = form.T.T @ state.P
    i = 0
    width = _FIRST_BLOCK
    unheld = None
    if form.diagonal and form.mu == 0:
        key = ("frictionless_unheld", id(form))
        unheld = cache.get(key)
        if unheld is None:
            unheld = cache[key] = frictionless_unheld(form)
    active = (_ACTIVE_SETS and not form.diagonal and form.cone_normal is not None
              and form.mu > 0)
    while i < m:
        guess = None
        if unheld is not None and np.abs(unheld @ r[i]).max() > f_tol[i]:
            # frictionless elements push only along their normals: a wrench outside their
            # span (an axial force, a torsion) has no equilibrium, whatever the state
            conv[i] = False
            u[i], P[i] = np.nan, np.nan
            cls[i] = RELEASED
            i += 1
            continue
        free = _free_sliders(state)
        slid = probe = None
        if free is None and form.diagonal and _REGRIP:
            # the spring model's sliding elements usually grip again at the next sample:
            # that state (every element that slid stuck where its slip left it) is tried
            # as a block first, its checks (pressing, inside the cone) deciding
            slid = state
            state = state.copy()
            probe = state.cls == SLIDING
            state.cls[probe] = STUCK
            free = np.zeros(n, dtype=bool)
        if free is not None and (state.cls == STUCK).any():
            maps = (True if form.normal_response is not None
                    else stuck_maps(form, cache, state.cls, free))
            if maps:
                # the state usually holds for long stretches between events: grow the
                # block while it does, start small again after an event
                e = min(m, i + width)
                if form.normal_response is None:
                    ub, Pb, k, guess = _block(form, maps, state, r[i:e], f_tol[i:e],
                                              x_tol[i:e])
                else:   # a nonlinear tissue law: Newton per row, the state fixed
                    ub, Pb, k, guess, memo = block_nonlinear(form, state, r[i:e],
                                                             f_tol[i:e], x_tol[i:e], probe)
                full = k == e - i
                width = min(_BLOCK, 2 * width) if full else _FIRST_BLOCK
                if k:
                    u[i:i + k], P[i:i + k] = ub, Pb
                    cls[i:i + k] = state.cls
                    state.u, state.P = ub[-1].copy(), Pb[-1].copy()
                    if form.normal_response is not None:
                        state.memo = memo
                    if free.any():
                        # a free patch's tie follows the skin: where it is now
                        at = relative(form, state.u, state.P).reshape(n, d)
                        state.z[free, 1:3] = at[free, 1:3]
                    r_state = r[i + k - 1]
                    i += k
                    slid = None
                    if i >= m:
                        break
                    if full and form.normal_response is not None:
                        # the whole block kept the state: the next one may too (a nonlinear
                        # block costs a Newton iteration, an event several)
                        continue
        if slid is not None:
            # they did not grip: an event from the sliding state, started where the
            # block's first row ended (closer than the last sample's answer)
            state = slid
        event = solve_event_elements if form.diagonal else solve_event_coupled
        # no equilibrium at all: without friction only the normal forces (and a patch's
        # tied rotations, pure moments) hold the cuff, and they cannot make this wrench
        hopeless = form.mu == 0 and (
            np.abs(unheld @ r[i]).max() > f_tol[i] if unheld is not None
            else not _frictionless_reachable(form, cache, r[i], f_tol[i]))
        if hopeless:
            ui, Pi, new, its, ok = state.u, state.P, state, 1, False
        else:
            hop = None
            if active:
                # friction set by the user: slips, sticks and lifts by active sets
                hop = active_step(form, cache, state, r[i], f_tol[i], x_tol[i])
            elif guess is not None and not form.diagonal and not (state.cls == SLIDING).any():
                hop = _stuck_transition(form, cache, state, r[i], f_tol[i], x_tol[i])
            if hop is not None:
                ui, Pi, new, its, ok = hop
            else:
                ui, Pi, new, its, ok = event(form, r[i], state, guess)
        if not ok and not hopeless and _RESCUE and not form.diagonal and not active:
            # the default's lift-off cone: where the semismooth Newton finds no state (it
            # cycles between two, a patch on the edge of its cone), the active sets often do
            hop = active_step(form, cache, state, r[i], f_tol[i], x_tol[i])
            if hop is not None and hop[4]:
                ui, Pi, new, more, ok = hop
                its += more
        if not ok and not hopeless:
            # the semismooth Newton can cycle between two sets where a patch sits on the
            # edge of its cone or of contact: the wrench since the last consistent state is
            # then applied in 2, 4, ... equal increments (a finer path), each from the last
            # (the spring model's elements are independent: one halving, into 2)
            ui, Pi, new, more, ok = _substeps(event, form, r_state, r[i], state,
                                              _MAX_HALVINGS if form.diagonal else 1)
            its += more
        solves[i] = its
        if ok:
            u[i], P[i], cls[i] = ui, Pi, new.cls
            state, r_state = new, r[i]
        else:
            conv[i] = False
            u[i], P[i] = np.nan, np.nan
            cls[i] = RELEASED
        i += 1
    return u, P, cls, solves, conv, state


#: the spring model with friction on the compiled loop where numba is installed and the
#: law is covered (:mod:`.kernel`); False: the numpy path (the reference of the tests)
_COMPILED = True


def _solve_compiled(form, kernel, r, state, cache):
    """:func:`solve_path` of the spring model by the compiled loop (:mod:`.kernel`): every
    sample by the event solver's semismooth Newton method from the one before, with the
    numpy path's fallbacks where it does not settle."""
    r = np.ascontiguousarray(r)
    m, n = len(r), form.n
    key = ("compiled", id(form))
    arrays = cache.get(key)
    if arrays is None:
        el = form.elements
        arrays = cache[key] = (el.Tn, np.ascontiguousarray(el.Tt3), el.dn, el.kt,
                               *kernel.law_arrays(form))
    Tn, Tt, dn, kt, law_exp, k0, beta, c = arrays
    # the force scale of a sample's round-off: its wrench, the strap's, and the preload's
    # element forces, which cancel on the cuff under a hoop (a zero wrench is then no scale)
    normal = form.normal_response
    preload = (normal.preload_scale(dn) if normal is not None
               else float(np.abs(k0 * np.maximum(dn, 0.0)).max(initial=0.0)))
    scale = np.abs(r).max(axis=1) + (np.abs(form.W_pre).max() + preload + 1e-300)
    u = np.zeros((m, 6))
    P = np.zeros((m, 3 * n))
    cls = np.zeros((m, n), dtype=np.int8)
    solves = np.zeros(m, dtype=np.int64)
    conv = np.ones(m, dtype=bool)
    # the state as the loop's arrays, updated in place (copies: the caller's is kept)
    sc, sz, ss = state.cls.astype(np.int8), np.ascontiguousarray(state.z[:, 1:3]), state.s.copy()
    su, sP = state.u.copy(), state.P.reshape(n, 3).copy()
    dsh = (state.memo[1].copy() if state.memo is not None and state.memo[1].shape == (n,)
           else np.full(n, -1.0))

    fs, xs = scales(form, np.zeros(6))
    kernel.solve_elements(r, scale, Tn, Tt, dn, kt, form.mu, law_exp, k0, beta, c,
                          sc, sz, ss, su, sP, dsh, u, P, cls, solves, conv, float(xs / fs))
    z = np.zeros((n, 3))
    z[:, 1:3] = sz
    memo = None
    if normal is not None:      # the numpy path's memo of the split where the path ends
        g = Tn @ su + dn
        gp = np.maximum(g, 0.0)
        memo = normal.evaluate(g, (gp, np.clip(dsh, 0.0, gp), np.zeros(n)))[2]
    return u, P, cls, solves, conv, PathState(cls=sc, z=z, s=ss, u=su, P=sP.ravel(), memo=memo)


#: most halvings of a sample's increment before it is flagged (2**4 = 16 increments)
_MAX_HALVINGS = 4


def _substeps(event, form, r0, r1, state, depth):
    """From ``state`` (consistent at r0) to r1 in two halves, each halved again where it
    fails, down to _MAX_HALVINGS: (u, P, state, solves, ok) at r1."""
    solves = 0
    mid = 0.5 * (r0 + r1)
    for a, b in ((r0, mid), (mid, r1)):
        u, P, new, its, ok = event(form, b, state, None)
        solves += its
        if not ok:
            if depth >= _MAX_HALVINGS:
                return u, P, state, solves, False
            u, P, new, its, ok = _substeps(event, form, a, b, state, depth + 1)
            solves += its
            if not ok:
                return u, P, state, solves, False
        state = new
    return u, P, state, solves, True
