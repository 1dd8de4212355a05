"""What a sensor patch of the coupled arm reads: the compressive part of its normal traction.

docs/model.md sections 10.2 and 10.6. A force-sensing resistor (FSR) or a pressure-mat
cell integrates the pressure that squeezes it; skin that pulls at part of a patch (at the
rim of a plate that tilts, or where a neighbour's load drags the skin) is not read as a
negative force, it is read as nothing there. The built-in FE gives the normal traction
at the skin nodes under each patch as a linear map of the patches' motions q (its L2
projection, weighted by each node's share of the patch's area): node i of patch e
contributes g_i = G_i q, and the patch reads

    f_e = sum over the nodes i of patch e of max(g_i, 0),

which equals the traction integral N_e q = sum_i g_i wherever the whole patch presses (the
preload, most of any log) and is above it where part of the patch pulls. A patch that reads
0 N is squeezed nowhere; a patch that presses as a whole always reads more than 0 N.

:class:`PatchReading` holds the node rows G (k, n d) in the patches' local axes, already
multiplied by the tissue compliance (so it maps patch forces P to the node values,
g = G C_t P), grouped by patch.
"""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np

__all__ = ["PatchReading", "grouped_by_patch", "node_parts", "parts_sum"]

#: rows of patch forces turned into node values at a time (bounds the temporary to
#: _CHUNK x k floats: 8 MB for the 3 x 7 cuff's 1,029 nodes)
_CHUNK = 1024
#: rows per thread from which a reading is split over two threads
_SPLIT_AT = 8 * _CHUNK


def _one_blas_thread() -> bool:
    return any(os.environ.get(v) == "1"
               for v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"))


def node_parts(C_skin, traction, skin_dofs):
    """The node rows of the patch reading from the built-in FE.

    Parameters
    ----------
    C_skin : ndarray, shape (s, n)
        int over patch e of phi_i . n(x) dA for the skin dofs s (component-major per node:
        dof 3 k + c is component c of node k) [m^2].
    traction : ndarray, shape (s, p)
        The recovered (L2-projected) traction at the skin dofs per unit of each of the p
        patch dofs [Pa per m or per rad].
    skin_dofs : ndarray of int, shape (s,)
        The skin dofs' global indices.

    Returns
    -------
    rows : ndarray, shape (k, p)
        One row per (node, patch) pair with a share of the patch: the node's contribution
        to the patch's normal traction integral [N per m or per rad].
    owner : ndarray of int, shape (k,)
        The patch of each row, ascending.
    """
    skin_dofs = np.asarray(skin_dofs)
    node = skin_dofs // 3
    order = np.argsort(node, kind="stable")
    nodes, start = np.unique(node[order], return_index=True)
    rows, owner = [], []
    bounds = np.append(start, len(order))
    for a, b in zip(bounds[:-1], bounds[1:]):
        idx = order[a:b]
        w = C_skin[idx]                              # (3, n) this node's weights
        for e in np.flatnonzero(np.any(w != 0.0, axis=0)):
            rows.append(w[:, e] @ traction[idx])
            owner.append(e)
    owner = np.asarray(owner, dtype=np.int64)
    rows = np.asarray(rows, dtype=float).reshape(len(owner), traction.shape[1])
    by_patch = np.argsort(owner, kind="stable")
    return rows[by_patch], owner[by_patch]


def grouped_by_patch(owner, rows: int, n: int) -> bool:
    """Whether ``owner`` (the patch of each of ``rows`` node rows) names whole patch numbers
    in ascending order with every patch 0..n-1 present."""
    owner = np.asarray(owner)
    return (owner.ndim == 1 and len(owner) == rows and np.array_equal(owner, np.round(owner))
            and bool(np.all(np.diff(owner) >= 0))
            and np.array_equal(np.unique(owner), np.arange(n)))


def parts_sum(rows, owner, n):
    """The traction integral N (n, p): the rows summed per patch."""
    N = np.zeros((n, rows.shape[1]))
    np.add.at(N, owner, rows)
    return N


@dataclass(frozen=True, eq=False)
class PatchReading:
    """The patches' sensor reading f (m, n) [N] from their forces P (m, n d), local axes.

    Attributes
    ----------
    G : ndarray, shape (k, n d)
        Node rows times the tissue compliance: node values g = G P [N].
    owner : ndarray of int, shape (k,)
        Patch of each row, ascending, every patch at least once.
    """

    G: np.ndarray
    owner: np.ndarray

    @classmethod
    def build(cls, rows_local, owner, C_t, n):
        """From node rows in local axes (k, n d) [N per m or per rad] and the tissue
        compliance C_t; ``owner`` ascending with every patch 0..n-1 present."""
        if not grouped_by_patch(owner, len(rows_local), n):
            raise ValueError("normal output parts: expected rows grouped by patch, every "
                             "patch with at least one row")
        return cls(G=np.ascontiguousarray(rows_local @ C_t),
                   owner=np.asarray(owner, dtype=np.int64))

    @property
    def starts(self) -> np.ndarray:
        return np.flatnonzero(np.r_[True, np.diff(self.owner) != 0])

    def __call__(self, P) -> np.ndarray:
        P = np.atleast_2d(np.asarray(P, dtype=float))
        m = len(P)
        out = np.empty((m, len(self.starts)))
        # a long chunk's reading is a large product (1,029 node values per row) while the
        # rest of a solve is one thread's small steps: where BLAS is held to one thread
        # (as the command line does), its second half goes to a second thread (numpy lets
        # go of the GIL in it), split at a multiple of _CHUNK so that every row is
        # computed in the same blocks either way
        half = (m // 2 // _CHUNK) * _CHUNK
        if half >= _SPLIT_AT and _one_blas_thread():
            try:
                pool = ThreadPoolExecutor(1)
            except RuntimeError:      # no thread to be had: one does it all
                pool = None
            if pool is not None:
                with pool:
                    rest = pool.submit(self._into, P[half:], out[half:])
                    self._into(P[:half], out[:half])
                    rest.result()
                return out
        self._into(P, out)
        return out

    def _into(self, P, out):
        starts = self.starts
        Gt = self.G.T
        buf = np.empty((min(len(P), _CHUNK), len(self.owner)))
        for a in range(0, len(P), _CHUNK):
            Pc = P[a:a + _CHUNK]
            g = buf[:len(Pc)]
            np.matmul(Pc, Gt, out=g)
            np.maximum(g, 0.0, out=g)
            np.add.reduceat(g, starts, axis=1, out=out[a:a + len(Pc)])
