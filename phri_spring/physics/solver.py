"""Equilibrium of the cuff on the arm (SPEC section 4).

The cuff displacement u* is the unique minimiser of the strictly convex,
piecewise quadratic energy

    Pi(u) = sum_e 1/2 k_e [delta0_e + b_e . u]_+^2 + 1/2 u^T K_s u - (W + W_pre) . u

Method
------
For a fixed active set S (elements in contact) the minimiser solves the 6x6
system (sum_{e in S} k_e b_e b_e^T + K_s) u = W + W_pre - sum_{e in S} k_e delta0_e b_e.
The fast path is the plain "solve, update S, re-solve" loop, vectorised over
samples: samples that share an active set share one cached factorisation, and
each sample starts from the contact set of a neighbouring sample (warm start).
The plain loop is a semismooth Newton method with full steps; it usually
settles in 1 to 3 solves but is not guaranteed to terminate, so samples that
have not settled after :data:`PLAIN_ITERATIONS` solves continue with the same
Newton direction safeguarded by an exact line search on Pi, which makes it a
globally convergent descent method. A sample is converged when its active set
is consistent with its displacement (the KKT conditions hold); samples that do
not converge within ``max_iterations`` are flagged and their forces are NaN.
"""

from __future__ import annotations

import numpy as np

from .model import SpringModel

__all__ = ["Solution", "solve", "solve_per_sample", "Solver", "compression", "normal_forces", "shear_forces",
           "energy", "equilibrium_residual", "PLAIN_ITERATIONS"]

#: plain (undamped) active-set iterations before the line-search safeguard takes over
PLAIN_ITERATIONS = 8
#: relative tolerance on the compression sign when checking an active set
_SET_RTOL = 1e-12
#: samples per internal block (bounds the (samples x elements) temporaries)
_BLOCK_ENTRIES = 1 << 21
#: stride of the neighbour warm start
_WARM_STRIDE = 16
_CACHE_MAX = 1 << 14


class Solution:
    """Result of :func:`solve` for m samples and n elements.

    Attributes
    ----------
    u : ndarray, shape (m, 6)
        Cuff displacement (t [m], w [rad]).
    forces : ndarray, shape (m, n)
        Normal force on the arm f_e [N] (NaN where not converged).
    contact : ndarray of bool, shape (m, n)
        Element in contact (compression > 0, i.e. f_e > 0); computed on first
        access (False where not converged).
    iterations : ndarray of int, shape (m,)
        Linear solves the sample needed.
    converged : ndarray of bool, shape (m,)
    """

    __slots__ = ("u", "forces", "iterations", "converged", "_contact")

    def __init__(self, u, forces, iterations, converged, contact=None):
        self.u = u
        self.forces = forces
        self.iterations = iterations
        self.converged = converged
        self._contact = contact

    @property
    def contact(self) -> np.ndarray:
        if self._contact is None:
            self._contact = self.forces > 0
        return self._contact

    def __repr__(self):
        return (f"Solution(samples={np.shape(self.forces)[0] if np.ndim(self.forces) > 1 else 1}, "
                f"converged={bool(np.all(self.converged))})")


def compression(model: SpringModel, u) -> np.ndarray:
    """Compression delta0_e + b_e . u of every element [m], shape (..., n)."""
    return model.delta0 + np.asarray(u, dtype=float) @ model.b.T


def normal_forces(model: SpringModel, u) -> np.ndarray:
    """f_e = k_e [delta0_e + b_e . u]_+ [N], shape (..., n)."""
    return model.k * np.maximum(compression(model, u), 0.0)


def shear_forces(model: SpringModel, u) -> np.ndarray:
    """Shear force on the arm s_e = k_s,e (I3 - n_e n_e^T) B_e u [N], shape (..., n, 3)."""
    u = np.asarray(u, dtype=float)
    g = model.geometry
    d = u[..., None, :3] + np.cross(u[..., None, 3:], g.points)      # d_e = t + w x p_e
    dn = np.sum(d * g.normals, axis=-1, keepdims=True)
    return model.k_shear[:, None] * (d - dn * g.normals)


def energy(model: SpringModel, u, wrench) -> np.ndarray:
    """Pi(u) [J] for displacement(s) u and applied wrench(es) W."""
    u = np.asarray(u, dtype=float)
    gp = np.maximum(compression(model, u), 0.0)
    r = np.asarray(wrench, dtype=float) + model.W_pre
    return (0.5 * np.sum(model.k * gp * gp, axis=-1)
            + 0.5 * np.einsum("...i,ij,...j->...", u, model.K_s, u)
            - np.sum(r * u, axis=-1))


def equilibrium_residual(model: SpringModel, u, wrench) -> np.ndarray:
    """sum_e f_e b_e + K_s u - (W + W_pre), shape (..., 6): zero at equilibrium."""
    u = np.asarray(u, dtype=float)
    return normal_forces(model, u) @ model.b + u @ model.K_s.T - (np.asarray(wrench) + model.W_pre)


# --------------------------------------------------------------------------- active sets
def _set_keys(S: np.ndarray) -> np.ndarray:
    """One uint64 key per row of a boolean matrix (a contact set).

    Exact (the packed bits) up to 64 elements; above that a 64-bit hash of the
    packed bits, so results never depend on it: :func:`_solve_block` checks
    every converged sample's contact set exactly.
    """
    packed = np.packbits(S, axis=1, bitorder="little")
    m, nb = packed.shape
    nw = (nb + 7) // 8
    if nb != 8 * nw:
        full = np.zeros((m, 8 * nw), dtype=np.uint8)
        full[:, :nb] = packed
        packed = full
    words = packed.view("<u8")
    if nw == 1:
        return words.ravel()
    with np.errstate(over="ignore"):
        return words @ _hash_multipliers(nw)


def _hash_multipliers(nw: int) -> np.ndarray:
    mult = _HASH_CACHE.get(nw)
    if mult is None:
        rng = np.random.default_rng(0x5EED)
        mult = _HASH_CACHE[nw] = rng.integers(1, 2**63, size=nw, dtype=np.uint64) | np.uint64(1)
    return mult


_HASH_CACHE: dict = {}


def _spd_solve_batched(Hf: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """Solve many 6x6 SPD systems at once by a vectorised Cholesky factorisation.

    Hf has shape (36, m) (row-major 6x6 entries, samples last), rhs (m, 6).
    numpy's batched ``linalg.solve`` calls LAPACK once per matrix; this does
    about 150 array operations over all samples instead.
    """
    L = {}
    for j in range(6):
        d = Hf[7 * j].copy()
        for k in range(j):
            d -= L[j, k] * L[j, k]
        L[j, j] = np.sqrt(d)
        inv = 1.0 / L[j, j]
        L[j, j, "inv"] = inv
        for i in range(j + 1, 6):
            v = Hf[6 * i + j].copy()
            for k in range(j):
                v -= L[i, k] * L[j, k]
            L[i, j] = v * inv
    y = []
    for i in range(6):
        v = rhs[:, i].copy()
        for k in range(i):
            v -= L[i, k] * y[k]
        y.append(v * L[i, i, "inv"])
    x = [None] * 6
    for i in range(5, -1, -1):
        v = y[i]
        for k in range(i + 1, 6):
            v = v - L[k, i] * x[k]
        x[i] = v * L[i, i, "inv"]
    return np.stack(x, axis=1)


def _factors(model: SpringModel, key, S_row: np.ndarray):
    """(H_S^-1 transposed, c_S) for active set S, cached on the model.

    u = (r + c_S) @ Mt solves H_S u = r - sum_{e in S} k_e delta0_e b_e.
    """
    cache = model._cache
    hk = key.item() if isinstance(key, np.generic) else key
    hit = cache.get(hk)
    if hit is None:
        kS = model.k * S_row
        H = model.K_s + (model.b.T * kS) @ model.b
        Mt = np.ascontiguousarray(np.linalg.inv(H).T)
        c = -(kS * model.delta0) @ model.b
        if len(cache) >= _CACHE_MAX:
            cache.clear()
        hit = cache[hk] = (Mt, c)
    return hit


def _outer_bb(model: SpringModel) -> np.ndarray:
    bb = model._cache.get("__bb__")
    if bb is None:
        bb = model._cache["__bb__"] = (model.b[:, :, None] * model.b[:, None, :]).reshape(-1, 36)
    return bb


def _bT(model: SpringModel) -> np.ndarray:
    bT = model._cache.get("__bT__")
    if bT is None:
        bT = model._cache["__bT__"] = np.ascontiguousarray(model.b.T)
    return bT


def _compression(model: SpringModel, u: np.ndarray) -> np.ndarray:
    g = u @ _bT(model)
    g += model.delta0
    return g


def _solve_sets(model: SpringModel, keys: np.ndarray, S: np.ndarray, r: np.ndarray) -> np.ndarray:
    """u for every row of r with the active set in the same row of S (keys = its row keys)."""
    m = len(keys)
    if m == 0:
        return np.empty((0, 6))
    if np.all(keys == keys[0]):
        Mt, c = _factors(model, keys[0], S[0])
        u = r + c
        return u @ Mt
    uniq, first, inv = np.unique(keys, return_index=True, return_inverse=True)
    G = len(uniq)
    if G <= 4 or 20 * G <= m:
        out = np.empty((m, 6))
        if G <= 8:
            groups = (np.flatnonzero(inv == j) for j in range(G))
        else:
            order = np.argsort(inv, kind="stable")
            bounds = np.concatenate([[0], np.cumsum(np.bincount(inv, minlength=G))])
            groups = (order[bounds[j]:bounds[j + 1]] for j in range(G))
        for j, idx in enumerate(groups):
            Mt, c = _factors(model, uniq[j], S[first[j]])
            out[idx] = (r[idx] + c) @ Mt
        return out
    # many distinct sets: assemble and solve every 6x6 system at once
    kS = S * model.k
    Hf = _outer_bb(model).T @ kS.T
    Hf += model.K_s.reshape(36, 1)
    db = model._cache.get("__db__")
    if db is None:
        db = model._cache["__db__"] = model.delta0[:, None] * model.b
    rhs = r - kS @ db
    return _spd_solve_batched(Hf, rhs)


def _consistent(S: np.ndarray, g: np.ndarray, model: SpringModel, u: np.ndarray) -> np.ndarray:
    """Rows whose active set S agrees with the sign of the compression g, to round-off.

    The tolerance follows the round-off of g_e = delta0_e + b_e . u itself,
    _SET_RTOL * (max_e |delta0_e| + sum_j max_e |b_ej| |u_j|), so that it also
    holds when every compression is zero (shear alone carrying the load).
    """
    bmax = model._cache.get("__bmax__")
    if bmax is None:
        bmax = model._cache["__bmax__"] = (np.max(np.abs(model.b), axis=0),
                                           float(np.max(np.abs(model.delta0), initial=0.0)))
    tol = (_SET_RTOL * (np.abs(np.atleast_2d(u)) @ bmax[0] + bmax[1]))[:, None]
    wrong = (S & (g < -tol)) | (~S & (g > tol))
    return ~wrong.any(axis=-1)


# --------------------------------------------------------------------------- safeguard
def _exact_step(k, g, h, a0, q) -> float:
    """Exact minimiser alpha >= 0 of Pi(u + alpha d).

    phi'(alpha) = sum_e k_e [g_e + alpha h_e]_+ h_e + a0 + alpha q is piecewise
    linear and non-decreasing, with phi'(0) < 0 along a descent direction.
    """
    with np.errstate(divide="ignore", invalid="ignore"):
        bp = -g / h
    bp = np.sort(bp[(h != 0) & (bp > 0) & np.isfinite(bp)])
    edges = np.concatenate([[0.0], bp])
    # slope pieces on each segment [edges[i], edges[i+1]]: active set at the segment's start+
    for i in range(len(edges)):
        lo = edges[i]
        hi = edges[i + 1] if i + 1 < len(edges) else np.inf
        probe = lo + (0.5 * (hi - lo) if np.isfinite(hi) else 1.0 + lo)
        act = (g + probe * h) > 0
        A = np.sum(k[act] * g[act] * h[act]) + a0
        C = np.sum(k[act] * h[act] ** 2) + q
        alpha = -A / C
        if alpha <= hi:
            return float(max(alpha, lo))
    return float(edges[-1])  # pragma: no cover - unreachable for q > 0


def _newton_safeguarded(model: SpringModel, r: np.ndarray, u: np.ndarray, budget: int):
    """Globalised semismooth Newton with exact line search for one sample."""
    k, b, d0, Ks = model.k, model.b, model.delta0, model.K_s
    its = 0
    while its < budget:
        g = d0 + b @ u
        S = g > 0
        H = Ks + (b.T * (k * S)) @ b
        grad = b.T @ (k * np.maximum(g, 0.0)) + Ks @ u - r
        d = -np.linalg.solve(H, grad)
        its += 1
        u_full = u + d
        g_full = d0 + b @ u_full
        if _consistent(S[None], g_full[None], model, u_full)[0]:
            return u_full, its, True
        if not np.any(np.abs(d) > 1e-15 * (np.abs(u) + 1e-12)):
            return u_full, its, True
        alpha = _exact_step(k, g, b @ d, float((Ks @ u - r) @ d), float(d @ Ks @ d))
        u = u + alpha * d
    # budget spent without a consistent full step: not converged (reported, never hidden)
    return u, its, False


# --------------------------------------------------------------------------- batch solver
def _solve_block(model: SpringModel, r: np.ndarray, S: np.ndarray, max_iterations: int,
                 keys: np.ndarray | None = None, g_out: np.ndarray | None = None):
    """Solve a block of samples from initial active sets S; returns (u, g, keys, its, conv).

    g is the compression of every element at the solution, keys the packed contact sets.
    """
    m = len(r)
    S = np.array(S, dtype=bool, copy=True)
    keys = _set_keys(S) if keys is None else keys.copy()
    its = np.zeros(m, dtype=np.int64)
    conv = np.zeros(m, dtype=bool)
    u = g = None
    todo = None  # None: every sample of the block
    for _ in range(min(PLAIN_ITERATIONS, max_iterations)):
        if todo is None:
            ut = _solve_sets(model, keys, S, r)
            if g_out is None:
                gt = _compression(model, ut)
            else:  # straight into the caller's array: no extra pass, no fresh pages
                gt = np.matmul(ut, _bT(model), out=g_out)
                gt += model.delta0
            u, g = ut, gt
            its += 1
            St, kt = S, keys
        else:
            St, kt = S[todo], keys[todo]
            ut = _solve_sets(model, kt, St, r[todo])
            gt = _compression(model, ut)
            u[todo], g[todo] = ut, gt
            its[todo] += 1
        newS = gt > 0
        newk = _set_keys(newS)
        changed = newk != kt
        if changed.any():
            # a set that differs only by round-off on an element at the boundary is consistent
            ci = np.flatnonzero(changed)
            changed[ci[_consistent(St[ci], gt[ci], model, ut[ci])]] = False
        idx = np.arange(m) if todo is None else todo
        conv[idx[~changed]] = True
        todo = idx[changed]
        if todo.size == 0:
            break
        S[todo] = newS[changed]
        keys[todo] = newk[changed]
    if todo is not None and todo.size:
        for i in todo:
            ui, n_it, ok = _newton_safeguarded(model, r[i], u[i], max_iterations - int(its[i]))
            u[i] = ui
            its[i] += n_it
            conv[i] = ok
        g[todo] = _compression(model, u[todo])
        S[todo] = g[todo] > 0
        keys[todo] = _set_keys(S[todo])
    if model.n > 64:
        # hashed keys: confirm every converged sample's set exactly (never trust a hash)
        ok = np.all((g > 0) == S, axis=1)
        bad = np.flatnonzero(conv & ~ok)
        if bad.size:
            bad = bad[~_consistent(S[bad], g[bad], model, u[bad])]
        for i in bad:
            budget = max(0, max_iterations - int(its[i]))
            ui, n_it, ok_i = _newton_safeguarded(model, r[i], u[i], budget)
            u[i], its[i], conv[i] = ui, its[i] + n_it, ok_i
            g[i] = _compression(model, ui[None])[0]
    return u, g, keys, its, conv


def solve_per_sample(model: SpringModel, wrench, *, max_iterations: int = 100) -> Solution:
    """The plain, unoptimised path: one sample at a time, np.linalg.solve in an active-set loop.

    Same method and stopping rule as :func:`solve` (including the line-search
    safeguard), without vectorisation, caching or warm start. Kept as the
    reference the optimised path is tested and benchmarked against.
    """
    W = np.atleast_2d(np.asarray(wrench, dtype=float))
    k, b, d0, Ks = model.k, model.b, model.delta0, model.K_s
    m = len(W)
    u = np.zeros((m, 6))
    its = np.zeros(m, dtype=np.int64)
    conv = np.zeros(m, dtype=bool)
    for i in range(m):
        r = W[i] + model.W_pre
        S = np.ones(model.n, dtype=bool)
        ok = False
        n_it = 0
        ui = np.zeros(6)
        while n_it < min(PLAIN_ITERATIONS, max_iterations):
            kS = k * S
            H = Ks + (b.T * kS) @ b
            ui = np.linalg.solve(H, r - (kS * d0) @ b)
            n_it += 1
            g = d0 + b @ ui
            if _consistent(S[None], g[None], model, ui)[0]:
                ok = True
                break
            S = g > 0
        if not ok:
            ui, extra, ok = _newton_safeguarded(model, r, ui, max_iterations - n_it)
            n_it += extra
        u[i], its[i], conv[i] = ui, n_it, ok
    g = d0 + u @ b.T
    forces = k * np.maximum(g, 0.0)
    forces[~conv] = np.nan
    return Solution(u=u, forces=forces, iterations=its, converged=conv)


def _solve_warm(model: SpringModel, r: np.ndarray, carry, max_iterations: int, g_out=None):
    """Neighbour warm start, applied recursively (multilevel).

    Every _WARM_STRIDE-th sample (and the last) is solved first, itself warm-started
    the same way from an even coarser subset; each sample then starts from the
    contact set predicted by interpolating the displacements of its two solved
    neighbours. On smooth logs nearly every sample settles in one solve, and the
    subsets cost 1/16 + 1/256 + ... of the log.
    """
    mb, n = len(r), model.n
    if mb >= 4 * _WARM_STRIDE:
        idx = np.arange(0, mb, _WARM_STRIDE)
        if idx[-1] != mb - 1:
            idx = np.append(idx, mb - 1)
        us, gs = _solve_warm(model, r[idx], carry, max_iterations)[:2]
        Ss = gs > 0
        seg = np.minimum(np.arange(mb) // _WARM_STRIDE, len(idx) - 2)
        S0 = Ss[seg]
        # where both neighbours share a contact set, start from it; elsewhere predict the
        # set from the interpolated displacement
        ks = _set_keys(Ss)
        rows = np.flatnonzero((ks[:-1] != ks[1:])[seg])
        if rows.size:
            sr = seg[rows]
            wgt = ((rows - idx[sr]) / (idx[sr + 1] - idx[sr]))[:, None]
            u_pred = us[sr] + (us[sr + 1] - us[sr]) * wgt
            S0[rows] = _compression(model, u_pred) > 0
    else:
        S0 = np.ones((mb, n), dtype=bool) if carry is None else np.broadcast_to(carry, (mb, n))
    u, g, _, its, conv = _solve_block(model, r, S0, max_iterations, g_out=g_out)
    return u, g, its, conv


def solve(model: SpringModel, wrench, *, max_iterations: int = 100, warm_start: bool = True,
          initial_active=None, out: np.ndarray | None = None) -> Solution:
    """Solve the equilibrium for every sample of a wrench log.

    Parameters
    ----------
    model : SpringModel
    wrench : array_like, shape (m, 6) or (6,)
        Wrench W applied by the robot to the cuff, cuff frame, about the cuff
        origin: (Fx, Fy, Fz [N], Mx, My, Mz [N*m]).
    max_iterations : int
        Most linear solves per sample (>= 1).
    warm_start : bool
        Start each sample from the contact set of a neighbouring sample (solved
        first on a strided subset of the log) instead of full contact.
    initial_active : array_like of bool, shape (n,) or (m, n), optional
        Initial contact set(s); overrides ``warm_start``.
    out : ndarray, shape (m, n), optional
        Array (float64, C-contiguous) to write the forces into. Reusing one
        array across the chunks of a long stream avoids faulting in fresh
        memory for every chunk, which dominates on fine meshes.

    Returns
    -------
    Solution
        Arrays with a leading sample axis (dropped for a single (6,) wrench).
    """
    W = np.asarray(wrench, dtype=float)
    single = W.ndim == 1
    W = np.atleast_2d(W)
    if W.ndim != 2 or W.shape[1] != 6:
        raise ValueError(f"wrench: expected shape (m, 6) or (6,), got {np.shape(wrench)}")
    if not np.all(np.isfinite(W)):
        raise ValueError("wrench: expected finite numbers, got NaN or inf")
    if int(max_iterations) < 1:
        raise ValueError("max_iterations: expected >= 1")
    max_iterations = int(max_iterations)
    m, n = len(W), model.n
    r = W + model.W_pre

    u = np.empty((m, 6))
    if out is None:
        forces = np.empty((m, n))
    else:
        forces = out
        if not (isinstance(out, np.ndarray) and out.shape == (m, n) and out.dtype == np.float64
                and out.flags.c_contiguous):
            raise ValueError(f"out: expected a C-contiguous float64 array of shape ({m}, {n})")
    its = np.empty(m, dtype=np.int64)
    conv = np.empty(m, dtype=bool)
    block = max(256, _BLOCK_ENTRIES // max(n, 1))
    carry = None  # warm start across blocks: the last solved sample's contact set
    for s in range(0, m, block):
        e = min(m, s + block)
        rb = r[s:e]
        mb = e - s
        gb = forces[s:e]  # compressions are computed in place, then turned into forces
        if initial_active is not None:
            S0 = np.broadcast_to(np.asarray(initial_active, dtype=bool), (m, n))[s:e]
            ub, gb, _, itb, cb = _solve_block(model, rb, S0, max_iterations, g_out=gb)
        elif warm_start:
            ub, gb, itb, cb = _solve_warm(model, rb, carry, max_iterations, g_out=gb)
        else:
            S0 = np.ones((mb, n), dtype=bool) if carry is None else np.broadcast_to(carry, (mb, n))
            ub, gb, _, itb, cb = _solve_block(model, rb, S0, max_iterations, g_out=gb)
        u[s:e], its[s:e], conv[s:e] = ub, itb, cb
        carry = gb[-1] > 0
        np.maximum(gb, 0.0, out=gb)
        gb *= model.k

    if not conv.all():
        forces[~conv] = np.nan
    if single:
        return Solution(u=u[0], forces=forces[0], iterations=its[0], converged=conv[0])
    return Solution(u=u, forces=forces, iterations=its, converged=conv)


class Solver:
    """Single-sample solver for control loops, warm-started from the previous call.

    Keeps the contact set of the last call and the cached factorisation of
    every contact set met, so a call usually costs one 6x6 product and one
    consistency check.

    >>> solver = Solver(model)                                # doctest: +SKIP
    >>> f = solver.forces(np.array([0, 0, 20.0, 0, 0, 0]))    # doctest: +SKIP

    Parameters
    ----------
    model : SpringModel
    max_iterations : int
        Most linear solves per call.
    """

    def __init__(self, model: SpringModel, max_iterations: int = 100):
        self.model = model
        self.max_iterations = int(max_iterations)
        self._b = model.b
        self._d0 = model.delta0
        self._k = model.k
        self._wpre = model.W_pre
        S = np.ones(model.n, dtype=bool)
        self._S = S
        self._Mt, self._c = _factors(model, _set_keys(S[None])[0], S)
        self.last_iterations = 0
        self.last_converged = True

    def displacement(self, wrench) -> np.ndarray:
        """Cuff displacement u (6,) for one wrench W (6,) [N, N*m] in the cuff frame."""
        r = np.asarray(wrench, dtype=float) + self._wpre
        if r.shape != (6,) or not np.isfinite(r).all():
            raise ValueError(f"wrench: expected 6 finite numbers, got {wrench!r}")
        b, d0 = self._b, self._d0
        S, Mt, c = self._S, self._Mt, self._c
        limit = min(PLAIN_ITERATIONS, self.max_iterations)
        for it in range(1, limit + 1):
            u = (r + c) @ Mt
            g = b @ u
            g += d0
            S_new = g > 0
            if np.array_equal(S_new, S) or _consistent(S[None], g[None], self.model, u)[0]:
                self._S, self._Mt, self._c = S, Mt, c
                self.last_iterations, self.last_converged = it, True
                return u
            S = S_new
            Mt, c = _factors(self.model, _set_keys(S[None])[0], S)
        u, n_it, ok = _newton_safeguarded(self.model, r, u, self.max_iterations - limit)
        self.last_iterations, self.last_converged = limit + n_it, ok
        S = (d0 + b @ u) > 0
        self._S = S
        self._Mt, self._c = _factors(self.model, _set_keys(S[None])[0], S)
        return u

    def forces(self, wrench) -> np.ndarray:
        """Normal force of every element f_e (n,) [N] for one wrench W (6,) [N, N*m].

        NaN everywhere if the solver did not converge (see ``last_converged``).
        """
        u = self.displacement(wrench)
        g = self._b @ u
        g += self._d0
        f = self._k * np.maximum(g, 0.0)
        if not self.last_converged:
            f[:] = np.nan
        return f
