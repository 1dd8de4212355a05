"""The active-set kernel: one loop that every contact model of phri-spring solves with.

A contact model with n compression-only contacts and a rigid cuff of six
degrees of freedom u (docs/model.md sections 4 and 9) is, for a fixed contact
set S (the contacts assumed in touch), a linear problem: the cuff displacement
solves one 6x6 symmetric positive definite system

    H_S u = r + c_S          (r = W + W_pre, the wrench on the cuff [N, N*m])

and the contact state follows from u through an *indicator* q_S(u) (n,), affine
in u, whose sign tells whether S was right: a contact in S must have q_e > 0
(it pushes), a contact outside S must have q_e <= 0 (it is open). The plain
iteration "solve, S <- {q > 0}, re-solve" is a semismooth Newton method (the
primal-dual active-set method of Hintermueller, Ito and Kunisch, SIAM J. Optim.
13 (2003) 865-888) and usually settles in one to three solves; it is not
guaranteed to terminate, so rows not settled after :data:`PLAIN_ITERATIONS`
solves are handed to the system's own globally convergent safeguard. A row is
converged when its set is consistent with its indicator (the KKT conditions
hold to round-off).

A *system* (:class:`ContactSystem`) supplies the model-specific pieces; this
module holds the loop (:func:`iterate`, the only place where contact sets are
updated), the neighbour warm start (:func:`solve_warm`), the bounded
least-recently-used cache of factorisations (:class:`FactorCache`) and the
contact-set keys. The spring model (:class:`phri_spring.physics.contact.solver.SpringSystem`)
and the coupled tissue model both plug into it.
"""

from __future__ import annotations

from collections import OrderedDict

import numpy as np

__all__ = ["PLAIN_ITERATIONS", "SET_RTOL", "FactorCache", "ContactSystem", "set_keys", "key_groups",
           "iterate", "next_sets", "solve_warm", "WARM_STRIDE"]

#: plain (undamped) active-set iterations before the system's safeguard takes over
PLAIN_ITERATIONS = 8
#: relative tolerance on the indicator's sign when checking a contact set
SET_RTOL = 1e-12
#: stride of the neighbour warm start
WARM_STRIDE = 16


class FactorCache:
    """Bounded least-recently-used map: contact-set key (int) -> factorisation.

    Owned by whoever solves (a :class:`~phri_spring.physics.contact.solver.Solver`, one
    streaming run of ``simulate``); never stored on a model. With friction it also
    carries the loading path's state from one call to the next (the chunks of one log).

    Parameters
    ----------
    maxsize : int
        Most entries kept; the least recently used one is dropped beyond it
        (0 keeps nothing: every lookup factorises anew).

    Examples
    --------
    >>> cache = FactorCache(maxsize=2)
    >>> cache.put(1, "a"); cache.put(2, "b"); _ = cache.get(1); cache.put(3, "c")
    >>> cache.get(2) is None, cache.get(1), len(cache)       # 2 was the least recently used
    (True, 'a', 2)
    """

    __slots__ = ("_data", "maxsize", "hits", "misses", "path_state", "path_maps", "path_form")

    def __init__(self, maxsize: int = 1 << 14):
        self._data: OrderedDict = OrderedDict()
        self.maxsize = int(maxsize)
        self.hits = 0
        self.misses = 0
        #: with friction (docs/model.md section 12): where the loading path has left the
        #: interface after the last call, so the next chunk of the same log goes on from it
        self.path_state = None
        #: with friction: the affine maps of the states met (state key -> maps)
        self.path_maps: dict = {}
        #: with friction: (model, its compliance form), made once for the calls on one model
        self.path_form = None

    def get(self, key: int):
        """The entry of ``key`` (marked most recently used), or None."""
        hit = self._data.get(key)
        if hit is not None:
            self._data.move_to_end(key)
            self.hits += 1
        else:
            self.misses += 1
        return hit

    def put(self, key: int, value) -> None:
        """Store ``value`` under ``key``, dropping the least recently used entry if full."""
        if self.maxsize <= 0:
            return
        self._data[key] = value
        self._data.move_to_end(key)
        if len(self._data) > self.maxsize:
            self._data.popitem(last=False)

    def __len__(self) -> int:
        return len(self._data)

    def __repr__(self) -> str:
        return f"FactorCache({len(self)}/{self.maxsize} sets, {self.hits} hits, {self.misses} misses)"


class ContactSystem:
    """What a contact model provides to the kernel (an interface; subclass it).

    Attributes
    ----------
    n : int
        Number of compression-only contacts.
    exact_keys : bool
        True when :func:`set_keys` is exact for n contacts (n <= 64); otherwise the
        kernel re-checks every converged row's set against its indicator.
    """

    n: int = 0

    @property
    def exact_keys(self) -> bool:
        return self.n <= 64

    def solve_sets(self, keys: np.ndarray, S: np.ndarray, r: np.ndarray) -> np.ndarray:
        """u (m, 6) solving H_S u = r + c_S for every row, each with the set in its row of S."""
        raise NotImplementedError

    def indicator(self, u: np.ndarray, S: np.ndarray, keys: np.ndarray,
                  out: np.ndarray | None = None) -> np.ndarray:
        """q (m, n): > 0 where a contact pushes (in S) or penetrates (not in S)."""
        raise NotImplementedError

    def consistent(self, S: np.ndarray, q: np.ndarray, u: np.ndarray) -> np.ndarray:
        """Rows whose set S agrees with the sign of q to round-off, (m,) bool."""
        raise NotImplementedError

    #: True when the indicator does not depend on the set (then S = {q > 0} after a safeguard)
    sets_follow_indicator: bool = True

    def safeguard(self, r: np.ndarray, u: np.ndarray, budget: int):
        """Globally convergent fallback for one row, from displacement u (6,).

        Returns ``(u, S, solves, converged)``; S (n,) is the final contact set, or
        None when it follows from the indicator (``sets_follow_indicator``).
        """
        raise NotImplementedError

    def predict_sets(self, u: np.ndarray, S: np.ndarray) -> np.ndarray:
        """Contact sets (m, n) predicted at displacements u near rows solved with sets S."""
        keys = set_keys(S)
        return self.indicator(u, S, keys) > 0


# --------------------------------------------------------------------------- contact-set keys
def set_keys(S: np.ndarray) -> np.ndarray:
    """One uint64 key per row of a boolean matrix (a contact set).

    Exact (the packed bits) up to 64 contacts; above that a 64-bit hash of the
    packed bits, so results never depend on it: :func:`iterate` checks every
    converged row's contact set exactly.
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


_HASH_MULTIPLIERS: dict = {}


def key_groups(keys: np.ndarray, unique=None):
    """(key, row indices) for every distinct contact-set key of ``keys`` (m,).

    The rows of a group share one set, hence one factorisation: one pass when every
    row has the same key, a scan per group for a few groups, one sort for many.
    ``unique``: ``np.unique(keys, return_inverse=True)`` if the caller has it.
    """
    m = len(keys)
    if m == 0:
        return
    if unique is None and (m == 1 or np.all(keys == keys[0])):
        yield keys[0], np.arange(m)
        return
    uniq, inv = np.unique(keys, return_inverse=True) if unique is None else unique
    if len(uniq) <= 8:
        for j in range(len(uniq)):
            yield uniq[j], np.flatnonzero(inv == j)
        return
    order = np.argsort(inv, kind="stable")
    bounds = np.concatenate([[0], np.cumsum(np.bincount(inv, minlength=len(uniq)))])
    for j in range(len(uniq)):
        yield uniq[j], order[bounds[j]:bounds[j + 1]]


def _hash_multipliers(nw: int) -> np.ndarray:
    mult = _HASH_MULTIPLIERS.get(nw)
    if mult is None:
        rng = np.random.default_rng(0x5EED)
        mult = _HASH_MULTIPLIERS[nw] = rng.integers(1, 2**63, size=nw, dtype=np.uint64) | np.uint64(1)
    return mult


# --------------------------------------------------------------------------- the loop
def next_sets(system: ContactSystem, S: np.ndarray, keys: np.ndarray, q: np.ndarray,
              u: np.ndarray):
    """The active-set update: S' = {q > 0}; a row whose S' differs from S only by round-off
    (at a contact on the boundary) keeps S and counts as settled.

    Returns
    -------
    changed : ndarray of bool, shape (m,)
        Rows that must be solved again.
    new_S, new_keys : the updated sets of every row (valid where ``changed``).
    """
    new_S = q > 0
    new_keys = set_keys(new_S)
    changed = new_keys != keys
    if changed.any():
        ci = np.flatnonzero(changed)
        changed[ci[system.consistent(S[ci], q[ci], u[ci])]] = False
    return changed, new_S, new_keys


def iterate(system: ContactSystem, r: np.ndarray, S: np.ndarray, max_iterations: int,
            keys: np.ndarray | None = None, q_out: np.ndarray | None = None):
    """Solve every row of r from the initial contact sets S.

    Contact set -> factorisation (cached by the system) -> solve -> indicator ->
    update (:func:`next_sets`), for all unsettled rows at once; rows still unsettled
    after :data:`PLAIN_ITERATIONS` solves go to the system's safeguard.

    Parameters
    ----------
    system : ContactSystem
    r : ndarray, shape (m, 6)
        Right-hand sides W + W_pre [N, N*m].
    S : ndarray of bool, shape (m, n)
        Initial contact sets.
    max_iterations : int
        Most linear solves per row.
    keys : ndarray of uint64, shape (m,), optional
        :func:`set_keys` of S, if known.
    q_out : ndarray, shape (m, n), optional
        Array to hold the indicator of the first full pass (saves fresh memory).

    Returns
    -------
    u : ndarray, shape (m, 6)
    q : ndarray, shape (m, n)
        Indicator at the solution.
    keys : ndarray of uint64, shape (m,)
    its : ndarray of int64, shape (m,)
        Linear solves each row needed.
    converged : ndarray of bool, shape (m,)
    """
    m = len(r)
    if keys is None:
        keys = set_keys(S)
    limit = min(PLAIN_ITERATIONS, max_iterations)
    # first pass over every row
    u = system.solve_sets(keys, S, r)
    q = system.indicator(u, S, keys, out=q_out)
    its = np.ones(m, dtype=np.int64)
    changed, new_S, new_keys = next_sets(system, S, keys, q, u)
    if system.exact_keys and not changed.any():
        # the common case after a warm start: every row settled at once
        return u, q, keys, its, np.ones(m, dtype=bool)
    S = np.array(S, dtype=bool, copy=True)
    keys = keys.copy()
    conv = ~changed
    todo = np.flatnonzero(changed)
    for _ in range(limit - 1):
        S[todo] = new_S[changed]
        keys[todo] = new_keys[changed]
        St, kt = S[todo], keys[todo]
        ut = system.solve_sets(kt, St, r[todo])
        qt = system.indicator(ut, St, kt)
        u[todo], q[todo] = ut, qt
        its[todo] += 1
        changed, new_S, new_keys = next_sets(system, St, kt, qt, ut)
        conv[todo[~changed]] = True
        todo = todo[changed]
        if todo.size == 0:
            break
    if todo.size:
        _safeguard_rows(system, r, u, q, S, its, conv, todo, max_iterations)
        keys[todo] = set_keys(S[todo])
    if not system.exact_keys:
        # hashed keys: confirm every converged row's set exactly (never trust a hash)
        ok = np.all((q > 0) == S, axis=1)
        bad = np.flatnonzero(conv & ~ok)
        if bad.size:
            bad = bad[~system.consistent(S[bad], q[bad], u[bad])]
        if bad.size:
            _safeguard_rows(system, r, u, q, S, its, conv, bad, max_iterations)
    return u, q, keys, its, conv


def _safeguard_rows(system, r, u, q, S, its, conv, rows, max_iterations):
    """Hand rows to the system's safeguard, then recompute their indicators together."""
    for i in rows:
        ui, Si, n_it, ok = system.safeguard(r[i], u[i], max(0, max_iterations - int(its[i])))
        u[i] = ui
        if Si is not None:
            S[i] = Si
        its[i] += n_it
        conv[i] = ok
    q[rows] = system.indicator(u[rows], S[rows], set_keys(S[rows]))
    if system.sets_follow_indicator:
        S[rows] = q[rows] > 0


def solve_warm(system: ContactSystem, r: np.ndarray, carry, max_iterations: int,
               q_out: np.ndarray | None = None):
    """:func:`iterate` with a neighbour warm start, applied recursively (multilevel).

    Every :data:`WARM_STRIDE`-th row (and the last) is solved first, itself
    warm-started the same way from an even coarser subset; each row then starts
    from the contact set of its solved neighbours where both share one, else
    from the set predicted at the displacement interpolated between them. On
    smooth logs nearly every row settles in one solve, and the subsets cost
    1/16 + 1/256 + ... of the log.

    Parameters
    ----------
    carry : ndarray of bool, shape (n,), or None
        Contact set to start the coarsest rows from (None: full contact).

    Returns
    -------
    u, q, its, converged
        As :func:`iterate`.
    """
    mb, n = len(r), system.n
    if mb >= 4 * WARM_STRIDE:
        idx = np.arange(0, mb, WARM_STRIDE)
        if idx[-1] != mb - 1:
            idx = np.append(idx, mb - 1)
        us, qs = solve_warm(system, r[idx], carry, max_iterations)[:2]
        Ss = qs > 0
        seg = np.minimum(np.arange(mb) // WARM_STRIDE, len(idx) - 2)
        S0 = Ss[seg]
        ks = set_keys(Ss)
        rows = np.flatnonzero((ks[:-1] != ks[1:])[seg])
        if rows.size:
            sr = seg[rows]
            wgt = ((rows - idx[sr]) / (idx[sr + 1] - idx[sr]))[:, None]
            u_pred = us[sr] + (us[sr + 1] - us[sr]) * wgt
            S0[rows] = system.predict_sets(u_pred, S0[rows])
    else:
        S0 = np.ones((mb, n), dtype=bool) if carry is None else np.broadcast_to(carry, (mb, n))
    u, q, _, its, conv = iterate(system, r, S0, max_iterations, q_out=q_out)
    return u, q, its, conv
