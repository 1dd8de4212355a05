"""The result of a solve: :class:`Solution` (docs/model.md section 9)."""

from __future__ import annotations

import numpy as np

__all__ = ["Solution"]


class Solution:
    """Result of :func:`~phri_spring.physics.contact.solver.solve` for m samples and n elements.

    Attributes
    ----------
    u : ndarray, shape (m, 6)
        Cuff displacement (t [m], w [rad]).
    forces : ndarray, shape (m, n)
        Normal force on the arm f_e [N] (NaN where not converged).
    contact : ndarray of bool, shape (m, n)
        The contact set the solver settled on: the elements or patches whose
        contact indicator is positive at the solution (pressing), False where not
        converged. For the spring model this is f_e > 0. For the coupled model with
        an output map (the built-in FE's traction integral) it is the set of patches
        whose normal force in the program is positive, which a reported force
        clipped at 0 cannot tell (a pressing patch can report 0 N).
    iterations : ndarray of int, shape (m,)
        Linear solves the sample needed.
    converged : ndarray of bool, shape (m,)
    tangential : ndarray, shape (m, n, 2), or None
        With friction (docs/model.md section 12): the tangential force on the arm of every
        element or patch (axial, circumferential) [N], which depends on the loading path
        and so cannot be recomputed from u. None otherwise.
    moments : ndarray, shape (m, n, 3), or None
        With friction and patches with rotations: each patch's moment on the skin about
        its centre, local axes (normal, axial, circumferential) [N*m]. None otherwise.
    normal : ndarray, shape (m, n), or None
        With friction (and on the linear coupled arm): each element's or patch's normal
        force along n_e [N], 0 when released, the one the balance of forces uses (a coupled
        patch *reports* in ``forces`` its traction integral, which differs). None otherwise.
    """

    __slots__ = ("u", "forces", "iterations", "converged", "contact", "tangential", "moments",
                 "normal")

    def __init__(self, u, forces, iterations, converged, contact, tangential=None,
                 moments=None, normal=None):
        self.u = u
        self.forces = forces
        self.iterations = iterations
        self.converged = converged
        self.contact = contact
        self.tangential = tangential
        self.moments = moments
        self.normal = normal

    def __repr__(self):
        return (f"Solution(samples={np.shape(self.forces)[0] if np.ndim(self.forces) > 1 else 1}, "
                f"converged={bool(np.all(self.converged))})")
