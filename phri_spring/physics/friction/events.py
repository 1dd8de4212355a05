"""The samples where something slips, lifts off or comes back (docs/model.md section 12).

:func:`~phri_spring.physics.friction.path.solve_path` solves a loading path in affine blocks
while the interface keeps its state; a sample where the state changes is solved here,
from the state the path has reached:

* the spring model (independent elements): given the cuff displacement u every element's
  forces follow by its own return mapping, so the equilibrium is six equations in u,
  solved by a semismooth Newton method (:func:`solve_event_elements`);
* the coupled model (patches coupled through the skin): all patch forces P and u at once,
  with the contact and friction laws written as the nonsmooth equations of Alart and
  Curnier (Comput. Methods Appl. Mech. Eng. 92 (1991) 353-375), also by a semismooth
  Newton method (:func:`solve_event_coupled`).

Both end on the state they found, solved once more as a linear system in that state
(exact zeros for released patches, equilibrium to round-off) and checked.
"""

from __future__ import annotations

import numpy as np

from .form import (PathState, RELEASED, SLIDING, STATE_RTOL, STUCK, InterfaceForm,
                            relative, scales, solve_state, lu_solve_or_none)

__all__ = ["solve_event_elements", "solve_event_coupled"]

#: most Newton steps per sample
_MAX_STEPS = 60
#: Newton steps without halving the residual before a sample is given up
_STALL = 6
#: a Newton step this long [m, rad] means a mode without stiffness (see the event solvers)
_HUGE_STEP = 0.1


def _newton_step(K, R):
    """K du = -R; where every contact on a mode slides (e.g. all of them around the arm)
    the tangent has almost no stiffness along it and the forces hardly depend on it: the
    least-norm step leaves the cuff where it is along that mode."""
    if not (np.isfinite(K).all() and np.isfinite(R).all()):
        # a law overflowed (an absurd load): no step; the iteration stalls and the sample
        # is flagged
        return np.zeros_like(R)
    try:
        du = np.linalg.solve(K, -R)
    except np.linalg.LinAlgError:
        du = None
    if du is None or not np.abs(du).max() < _HUGE_STEP:
        try:
            du = np.linalg.lstsq(K, -R, rcond=1e-10)[0]
        except np.linalg.LinAlgError:   # LAPACK's SVD did not converge
            du = np.zeros_like(R)
    return du


def _line_search(evaluate, x, dx, res):
    """Backtracking on the residual's largest entry: halve the step until the residual
    falls (or the step is 1e-4). ``evaluate(x)`` returns a tuple led by the residual;
    returns the new x, its evaluation, its residual and the step length taken."""
    step = 1.0
    while True:
        cand = evaluate(x + step * dx)
        new_res = np.abs(cand[0]).max()
        if new_res < res or step < 1e-4:
            return x + step * dx, cand, new_res, step
        step *= 0.5


def solve_event_elements(form: InterfaceForm, r, state: PathState, u0=None):
    """One sample of the spring model (independent elements) from ``state``.

    Given u every element's forces follow by its own return mapping (normal: compressive
    only; tangential: the trial force k_s (J_e u - z_e) from where it stuck, scaled back
    onto the cone when outside), so the equilibrium is six equations in u, solved by a
    semismooth Newton method with the consistent tangent and a backtracking line search
    on the residual, from ``u0`` (default: the last sample's u). With a nonlinear tissue
    law (``form.normal_response``) the normal force and its tangent are the series
    element's (:mod:`phri_spring.physics.friction.normal`). Returns (u, P, new state,
    solves, ok) as :func:`solve_event`.
    """
    el = form.elements
    n, mu = form.n, form.mu
    kn, kt, dn = el.kn, el.kt, el.dn
    normal = form.normal_response
    # the tissue's share of every element, carried between evaluations as the next guess
    share = [None if normal is None else state.memo if state.memo is not None else
             normal.memo_from_force(state.P[0::3], el.Tn @ state.u + dn)]
    # where each element's tie starts: stuck or sliding ones from their slip, released
    # ones land where they were at the last sample (their skin does not move)
    z0 = state.z[:, 1:3].copy()
    rel = state.cls == RELEASED
    if rel.any():
        z0[rel] = (el.Tt @ state.u).reshape(n, 2)[rel]
    force_scale = np.abs(r).max() + np.abs(form.W_pre).max() + 1e-300
    if normal is not None:
        force_scale += normal.preload_scale(dn)
    tol = 1e-13 * force_scale

    T3 = form.T
    kt2 = kt[:, None]

    def forces(u):
        a = (T3 @ u).reshape(n, 3)          # each element's normal and two tangential rows
        g = a[:, 0] + dn
        c = g > 0
        if normal is None:
            Pn = kn * g
            Pn[~c] = 0.0
            kN = kn
        else:
            Pn, kN, share[0] = normal.response(g, share[0])
        trial = a[:, 1:3] - z0
        trial *= kt2
        tn = np.hypot(trial[:, 0], trial[:, 1])
        slide = tn > mu * Pn
        slide &= c
        Pt = trial
        dirn = None
        if slide.any():
            dirn = trial[slide] / tn[slide, None]
            Pt = trial.copy()
            Pt[slide] = (mu * Pn[slide])[:, None] * dirn
        Pt[~c] = 0.0
        R = el.TnT @ Pn
        R += el.TtT @ Pt.ravel()
        R -= r
        return R, c, Pn, Pt, slide, dirn, tn, kN

    u = (state.u if u0 is None else u0).copy()
    # one errstate for the whole iteration: a tissue law may overflow at an absurd load
    # (the sample then fails its checks)
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        R, c, Pn, Pt, slide, dirn, tn, kN = forces(u)
        res = np.abs(R).max()
        its = 0
        history = []
        while its < _MAX_STEPS and res > tol:   # tol is round-off: Newton ends quadratically
            if len(history) >= _STALL and res > 0.5 * history[-_STALL]:
                # no progress: typically a load friction cannot hold (the cuff would slide
                # along or around the arm), which has no equilibrium
                break
            history.append(res)
            its += 1
            stick = c & ~slide
            K = ((kN * c) @ el.NN + (kt * stick) @ el.TT).reshape(6, 6)
            if dirn is not None:
                sl = np.flatnonzero(slide)
                Tts = el.Tt3[sl]
                # d(mu Pn d)/du = mu kn d Tn^T + mu Pn / |trial| kt (I - d d^T) Tt
                proj = np.eye(2)[None] - dirn[:, :, None] * dirn[:, None, :]
                dPt = (mu * kN[sl])[:, None, None] * dirn[:, :, None] * el.Tn[sl, None, :]
                dPt += ((mu * Pn[sl] / tn[sl]) * kt[sl])[:, None, None] * (proj @ Tts)
                K += Tts.reshape(-1, 6).T @ dPt.reshape(-1, 6)
            u, cand, res, _ = _line_search(forces, u, _newton_step(K, R), res)
            R, c, Pn, Pt, slide, dirn, tn, kN = cand
    ok = res <= tol * 10 and np.all(np.isfinite(u))
    if not ok:
        return state.u, state.P, state, max(its, 1), False
    cls = np.where(c, np.where(slide, SLIDING, STUCK), RELEASED).astype(state.cls.dtype)
    z = state.z.copy()
    z[:, 1:3] = z0
    s_dir = state.s.copy()
    if dirn is not None:
        z[slide, 1:3] = (el.Tt @ u).reshape(n, 2)[slide] - Pt[slide] / kt[slide, None]
        s_dir[slide] = dirn
    P = np.zeros((n, 3))
    P[:, 0], P[:, 1:3] = Pn, Pt
    P = P.ravel()
    return u, P, PathState(cls=cls, z=z, s=s_dir, u=u, P=P, memo=share[0]), max(its, 1), True




def solve_event_coupled(form: InterfaceForm, r, state: PathState, u0=None):
    """One sample of the coupled model from ``state`` (Alart-Curnier, semismooth Newton).

    Unknowns: the patch forces P (n d) and u (6). With rel = T u + delta - C P and z the
    ties' offsets where the sample began (a released patch lands where it was at the last
    sample, with no tangential force or moment), per patch e:

    * normal: P_n = max(0, P_n + rho_n rel_n) (pressing with the gap closed, or released);
    * tangential: P_t = proj_B(mu [P_n + rho_n rel_n]_+)(P_t + rho_t (rel_t - z_t)), the
      projection on the disc of the friction cone (stuck inside, sliding on its rim); with
      ``form.cone_normal`` (the coupled model's reading, f = M P) the disc's radius is
      mu [min(P_n, f) + rho_n rel_n]_+ for a touching patch;
    * rotations: tied (rel_r = z_r) while pressing, free moments of 0 when released;

    and the cuff: T^T P = r. rho is each dof's own stiffness 1/C_ii (with friction set, a
    patch's two tangential dofs share their mean: the force then lies along the slip,
    :class:`~phri_spring.physics.friction.form.EventArrays`). Returns (u, P, new
    state, solves, ok) as :func:`solve_event_elements`.
    """
    n, d, mu = form.n, form.d, form.mu
    N = n * d
    C, T = form.C, form.T
    ar = form.event_arrays
    nrm, tan, rot = ar.nrm, ar.tan, ar.rot
    rho, rho_n, rho_t = ar.rho, ar.rho_n, ar.rho_t
    dRel, J0, TT = ar.dRel, ar.J0, ar.TT
    cone = form.cone_normal
    z0 = state.z.copy()
    rel_prev = relative(form, state.u, state.P).reshape(n, d)
    back = state.cls == RELEASED
    z0[back, 1:] = rel_prev[back, 1:]
    z0[:, 0] = 0.0
    zf = z0.ravel()
    force_scale, _ = scales(form, r)
    tol = 1e-12 * force_scale
    minus_rho = -rho

    def residual(x):
        P, u = x[:N], x[N:]
        Pe = P.reshape(n, d)
        rel = T @ u + form.delta - C @ P - zf
        w = minus_rho * rel                       # phi of the tied rows
        we = w.reshape(n, d)
        yn = Pe[:, 0] - we[:, 0]
        touch = yn > 0
        rd = None
        if cone is None:
            Rt = mu * np.maximum(yn, 0.0)
        else:   # the cone on min(P_n, f), f = cone_normal P augmented as P_n is
            fa = cone @ P - we[:, 0]
            rd = fa < yn
            Rt = mu * np.maximum(np.where(rd, fa, yn), 0.0)
            Rt[~touch] = 0.0
        y = Pe[:, 1:3] - we[:, 1:3]
        ny = np.sqrt(y[:, 0] ** 2 + y[:, 1] ** 2)
        slide = ny > Rt
        phi = np.empty(N + 6)
        phi[:N] = w
        ph = phi[:N].reshape(n, d)
        off = ~touch
        if off.any():
            ph[off, 0] = Pe[off, 0]
            ph[off, 3:] = Pe[off, 3:]
        with np.errstate(invalid="ignore", divide="ignore"):
            yh = np.where(ny[:, None] > 0, y / ny[:, None], 0.0)
        if cone is not None:
            # a touching patch whose cone has closed (it reads nothing yet still touches)
            # slides freely: P_t = 0, with no direction for the state's solve to scale
            yh[touch & (Rt == 0.0)] = 0.0
        if slide.any():
            ph[slide, 1:3] = Pe[slide, 1:3] - Rt[slide, None] * yh[slide]
        phi[N:] = TT @ P - r
        return phi, (touch, slide, yh, ny, Rt, rd)

    def jacobian(info, keep=None):
        """J, or only its rows ``keep`` (a mask; the rows of every patch left out must be
        identity rows, see :func:`_reduced_step`)."""
        touch, slide, yh, ny, Rt, rd = info
        if keep is None:
            J, at = J0.copy(), np.arange(N + 6)
        else:
            J, at = J0[keep], np.cumsum(keep) - 1     # at: a kept row's place in J
            slide = slide & touch                     # the others' rows are left out
        off = ~touch
        if keep is not None:
            off &= keep[nrm]
        if off.any():
            # released: P_e = 0 on the normal and rotation rows
            cols = nrm[off] if d != 6 else np.concatenate([nrm[off], rot[off].ravel()])
            rows = at[cols]
            J[rows] = 0.0
            J[rows, cols] = 1.0
        sl = np.flatnonzero(slide)
        if sl.size:
            # phi_t = P_t - R_t yh: d = dP_t - yh mu d yn [touch] - R_t/|y| (I - yh yh^T) dy
            dyn = dRel[nrm[sl]] * rho_n[sl, None]
            if cone is None:
                dyn[np.arange(sl.size), nrm[sl]] += 1.0
                dyn *= (mu * touch[sl])[:, None]
            else:
                on = rd[sl]
                dyn[on, :N] += cone[sl[on]]
                dyn[np.flatnonzero(~on), nrm[sl[~on]]] += 1.0
                dyn *= (mu * (Rt[sl] > 0))[:, None]
            dy = dRel[tan[sl]] * rho_t[sl, :, None]
            dy[np.arange(sl.size)[:, None], np.arange(2)[None, :], tan[sl]] += 1.0
            with np.errstate(invalid="ignore", divide="ignore"):
                g = np.where(ny[sl] > 0, Rt[sl] / ny[sl], 0.0)
            proj = np.eye(2)[None] - yh[sl, :, None] * yh[sl, None, :]
            block = -yh[sl, :, None] * dyn[:, None, :] - g[:, None, None] * (proj @ dy)
            block[np.arange(sl.size)[:, None], np.arange(2)[None, :], tan[sl]] += 1.0
            J[at[tan[sl].ravel()]] = block.reshape(-1, N + 6)
        return J

    def classes(info):
        touch, slide = info[0], info[1]
        return np.where(touch, np.where(slide, SLIDING, STUCK), RELEASED).astype(state.cls.dtype)

    x = np.concatenate([state.P, state.u if u0 is None else u0])
    phi, info = residual(x)
    res = np.abs(phi).max()
    its, history, seen = 0, [], []
    exact = False
    while its < _MAX_STEPS and res > tol:
        if len(history) >= _STALL and res > 0.5 * history[-_STALL]:
            break
        history.append(res)
        its += 1
        dx = None
        if _REDUCE:
            keep = _kept_rows(info, d)
            dx = _reduced_step(jacobian(info, keep), phi, keep)
        if dx is None:
            J = jacobian(info)
            dx = lu_solve_or_none(J, -phi)
            if dx is None:
                dx = np.linalg.lstsq(J, -phi, rcond=1e-12)[0]
        before = classes(info)
        # a released patch's tangential rows are P_t = 0 unless its trial slip is exactly 0
        linear = not (before == SLIDING).any() and bool(np.all(info[0] | info[1]))
        x, cand, res, step = _line_search(residual, x, dx, res)
        phi, info = cand
        seen.append((classes(info), info[2], info[5]))
        # without a sliding patch the equations are linear within a state: a full step
        # that ends in the state it was taken in has solved that state's own system
        # (rows scaled by rho, released rows P_e = 0), the system _finish would solve
        exact = linear and step == 1.0 and np.array_equal(before, seen[-1][0])
    out = _finish(form, r, state, classes(info), z0, info[2], its, res <= 1e3 * tol,
                  x if _REDUCE and exact and res <= tol else None, info[5])
    if out[-1] or res <= 1e3 * tol:
        return out
    return _visited_states(form, r, state, z0, seen[-2 * _STALL:], its)


#: solve each Newton step, and the final state's system, on the dofs of the patches in
#: contact only; False: the full systems (the reference the tests compare against)
_REDUCE = True


def _kept_rows(info, d):
    """The rows of an event's Newton system that are not identity rows: a patch out of
    contact whose trial slip is not zero has the rows P_e = 0 (normal, tangential and
    rotations alike); every other row is kept, the cuff's six included."""
    touch, slide = info[0], info[1]
    keep = np.ones(len(touch) * d + 6, dtype=bool)
    keep[:-6] = np.repeat(touch | ~slide, d)
    return keep


def _reduced_step(Jk, phi, keep):
    """The Newton step J dx = -phi from J's rows ``keep`` (``Jk``), all other rows of J
    being identity rows: their step is -phi, and the kept dofs solve the remaining block,
    a smaller LU (its cost grows with the cube of the size, and events are where patches
    let go). None where that block is singular (the caller falls back to the full
    system)."""
    if keep.all():
        return lu_solve_or_none(Jk, -phi)
    dx = -phi
    rhs = Jk[:, ~keep] @ phi[~keep]
    rhs -= phi[keep]
    sub = lu_solve_or_none(Jk[:, keep], rhs)
    if sub is None:
        return None
    dx[keep] = sub
    return dx


def _visited_states(form, r, state, z0, seen, its):
    """A stalled iteration's way out. Around an event (a sliding patch lifting off, one
    reaching its cone) the semismooth Newton can cycle between states without settling,
    and which way round-off tips it differs between CPUs and BLAS builds. Each state it
    visited, latest first, is solved exactly and checked as any answer is (equilibrium,
    cone, compression, no penetration, slip direction); the first that passes is the
    answer. ``seen``: (classes, slip directions, patches whose cone is on the reading)
    per step."""
    tried = []
    for cls, yh, rd in reversed(seen):
        if any(np.array_equal(cls, t) for t in tried):
            continue
        tried.append(cls)
        out = _finish(form, r, state, cls, z0, yh, its + len(tried), True, on_reading=rd)
        if out[-1]:
            return out
    return state.u, state.P, state, its + len(tried), False


def _finish(form, r, state, cls, z0, s_dir, its, close, x=None, on_reading=None):
    """Solve the state found exactly (a linear system) and check it; the event's result.
    ``x``: (P, u) already solving that system (Newton's last step), taken instead of a
    new solve; the count of solves is the same either way. ``on_reading``: the patches
    whose cone is on the reading (:func:`~phri_spring.physics.friction.form.solve_state`)."""
    if not close or not (cls != RELEASED).any():
        return state.u, state.P, state, max(its, 1), False
    s = state.s.copy()
    sl = cls == SLIDING
    s[sl] = s_dir[sl]
    n, d, mu = form.n, form.d, form.mu
    if x is None:
        sol = solve_state(form, r, cls, z0, s, reduce=_REDUCE, on_reading=on_reading)
        if sol is None:
            return state.u, state.P, state, max(its, 1), False
        u, P = sol
    else:
        u, P = x[n * d:].copy(), x[:n * d].copy()
        P.reshape(n, d)[cls == RELEASED] = 0.0    # exactly, as the state's solve leaves them
    Pe = P.reshape(n, d)
    rel = relative(form, u, P).reshape(n, d) - z0
    f_tol, x_tol = (STATE_RTOL * v for v in scales(form, r))
    press = cls != RELEASED
    tn = np.sqrt(Pe[:, 1] ** 2 + Pe[:, 2] ** 2)
    fc = form.cone_force(P)
    ok = (np.all(Pe[press, 0] >= -f_tol) and np.all(tn[press] <= mu * np.maximum(fc[press], 0.0) + f_tol)
          and np.all(rel[~press, 0] <= x_tol)
          and np.all(np.einsum("ek,ek->e", rel[sl, 1:3], s[sl]) >= -x_tol))
    if not ok:
        return state.u, state.P, state, max(its, 1) + 1, False
    z = z0.copy()
    z[sl, 1:3] += rel[sl, 1:3]
    return u, P, PathState(cls=cls, z=z, s=s, u=u, P=P), max(its, 1) + 1, True
