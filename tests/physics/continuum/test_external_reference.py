"""External reference: the spring model's forces reproduced by PyNite, an independent frame-analysis package.

Provenance
----------
Reference values are computed, when the test runs, by PyNite (PyPI ``PyNiteFEA``,
D. Craig Brinck, MIT licence), version 3.2.0 when this test was written (the
``test`` extra pins ``PyNiteFEA>=3.2.0``), a general 3D structural finite-element
package that shares no code, formula or author with phri-spring. Its
first-order ``FEModel3D.analyze()`` with compression-only springs is used; no
number below is copied from phri-spring's output.

The PyNite model (global X, Y, Z = the cuff frame x, y, z of docs/model.md
section 1, built here from the raw geometry numbers, not from
``CuffGeometry``):

* one node ``cuff`` at the cuff origin, carrying the applied wrench W (nodal
  forces FX, FY, FZ and moments MX, MY, MZ);
* one node per element at its surface point p_e, tied to ``cuff`` by a very
  stiff beam (PyNite has no rigid link): the element points move with the
  rigid cuff, d_e = t + w x p_e;
* per element three ``Spring3D`` from that node to three fully supported ground
  nodes (the bone) at p_e + L n_e, p_e + L e_x and p_e + L t_e (t_e the
  circumferential tangent, L = 0.1 m; a spring's length does not enter its
  stiffness). A PyNite spring's local stiffness matrix has only the axial
  terms (``Spring3D.ke``: ks at (0, 0), (0, 6), (6, 0), (6, 6), zero
  elsewhere), so each spring acts along its own axis only: the normal one,
  ``comp_only=True``, is k_e [n_e . d_e]_+, and the two two-way tangential ones
  add up to the bonded shear k_s,e (I - n_e n_e^T) d_e of docs/model.md
  section 2, since (e_x, t_e, n_e) is an orthonormal triad.
* strap (docs/model.md section 3). PyNite springs have no preload. ``hoop``: an
  enforced displacement -delta0_e n_e of the normal spring's ground node
  compresses that spring by delta0_e = f0_e / k_e at u = 0, which is the same
  thing, and the strap's push on the cuff is a nodal force f0_e n_e at each
  element node. ``handles``: two extra nodes at the handles, tied to ``cuff``
  like the elements, loaded by the strap forces T t(theta_b) and -T t(theta_a);
  PyNite forms the moment of these forces about the cuff origin itself.
* one load combination per wrench (each keeps its own active set in PyNite).

Why the cases are valid for PyNite's solver:

* small displacements: PyNite's ``analyze()`` is first order (equilibrium on
  the undeformed geometry), as is the spring model (docs/model.md section 4);
* the stiff beams add a compliance in series with each spring, so PyNite's
  forces carry an error that scales as 1/E of the beams, while its round-off
  grows with E. Measured on these cases (largest force difference over the
  case's peak force; statics residual over the largest load): E = 1e10 Pa
  1.9e-5 and 4e-10, 1e11 Pa 1.9e-6 and 5e-9, 1e12 Pa 1.9e-7 and 5.5e-8; at
  1e13 Pa PyNite's own stability check (relative residual above 1e-6) rejects
  the system. The force difference falls exactly as 1/E, so it is the beams'
  compliance, not a disagreement of the models. E = 1e12 Pa is used, with the
  tolerance ``REL_TOL = 1e-6`` of the peak force: five times the largest
  difference measured, 1 uN on a 1 N peak (far below what an FSR resolves),
  and small enough to fail on a 1e-5 change of one element's stiffness or a
  1e-4 change of the strap tension (checked by hand when it was written);
* PyNite's compression-only iteration starts with every spring active and
  switches a spring off when it is in tension, but never switches it back on
  (``Analysis._check_TC_convergence`` in 3.2.0, see its TODO). That is exact
  only when no spring switched off early is compressed at the end. So every
  PyNite result is checked here against the contact conditions using PyNite's
  own node displacements (an inactive spring is not compressed beyond what
  would change a force by the tolerance; an active one is not in tension) and
  against global statics from PyNite's support reactions. Together these are
  the KKT conditions of the strictly convex energy of docs/model.md section 4,
  whose minimiser is unique: a PyNite result that passes them is the solution.
  The wrenches were chosen so that PyNite passes; e.g. on the Harmony cuff with
  the handles strap, W = (5, 10, -15 N, 0.3, -0.5, 0.2 N*m) does not: PyNite
  3.2.0 switches C0 off in its first iteration and ends with C0 compressed by
  0.75 um but inactive (a 3.5e-3 relative force error), so it is not used.
"""

from __future__ import annotations

import math
import sys

import numpy as np
import pytest

if sys.version_info < (3, 11):  # PyNiteFEA 3.2 needs Python >= 3.11
    pytest.skip("PyNiteFEA (the external reference) needs Python >= 3.11",
                allow_module_level=True)
try:
    from Pynite import FEModel3D
except ImportError:  # pragma: no cover - the test extra installs it
    pytest.fail("PyNiteFEA is missing: pip install -e .[test]", pytrace=False)

from phri_spring.physics.cuff.geometry import cuff_geometry
from phri_spring.physics.springs.model import build_model, tissue_element_stiffness
from phri_spring.physics.contact.solver import shear_forces, solve

#: Young's modulus of the beams that tie the element points to the cuff node [Pa]
RIGID_E = 1e12
#: their section: area [m^2], second moments [m^4], torsion constant [m^4]
RIGID_SECTION = {"A": 1e-2, "Iy": 1e-5, "Iz": 1e-5, "J": 2e-5}
#: force tolerance relative to the case's peak force (see the module docstring)
REL_TOL = 1e-6
#: length of the spring elements [m] (does not enter their stiffness)
SPRING_LENGTH = 0.1
#: default shear ratio eta = 1 / (2 (1 + nu)) with nu = 0.45 (docs/model.md section 2)
ETA = 1.0 / (2.0 * (1.0 + 0.45))
INDENTER_DIAMETER = 0.009
DOFS = ("DX", "DY", "DZ", "RX", "RY", "RZ")
LOADS = ("FX", "FY", "FZ", "MX", "MY", "MZ")

#: Harmony cuff stiffness per angular location [N/m] (configs/harmony_upper_arm.yaml)
HARMONY_CUFF = [31250, 62500, 125000, 250000, 500000, 1.0e6, 500000]


# --------------------------------------------------------------------------- the cases
# Wrenches W = (Fx, Fy, Fz [N], Mx, My, Mz [N*m]) on the cuff, cuff frame, about its origin.
# Beside the axis-aligned ones they were drawn at random and kept when PyNite's answer
# passes the contact conditions (about three in four did; see the module docstring).
# The trailing comments count the elements in contact in the answer.
_HARMONY = dict(row_x=[-0.025, 0.0, 0.025], radius=[0.045] * 3, row_width=[0.025] * 3,
                start=75.0, step=35.0, count=7, k_indenter=[4242.0] * 21,
                k_cuff=HARMONY_CUFF * 3, arm="compliant", tension=15.0)
CASES = {
    # the Harmony cuff: 3 rows x 7 angles, R = 45 mm, rows at -25/0/25 mm, 25 mm wide,
    # 75 deg start, 35 deg step; compliant arm, indenter stiffness 4242 N/m, T = 15 N
    "harmony-handles": dict(_HARMONY, strap="handles", wrenches=[
        [0.0, 0.0, 0.0, 0.0, 0.0, 0.0],           # 15 of 21
        [0.0, 20.0, 0.0, 0.0, 0.0, 0.0],          # 15
        [0.0, -40.0, 0.0, 0.0, 0.0, 0.0],         # 6
        [0.0, 0.0, 30.0, 0.0, 0.0, 0.0],          # 12
        [-10.0, 30.0, 10.0, -0.2, 1.0, -0.8],     # 16
        [-20.2, -4.6, -17.3, 1.7, 0.2, -0.3],     # 15
        [-16.4, 1.2, -19.3, 0.4, -1.6, -0.7],     # 14
        [7.1, 23.1, -43.2, -0.2, 0.3, -0.5],      # 13
    ]),
    "harmony-hoop": dict(_HARMONY, strap="hoop", wrenches=[
        [0.0, 0.0, 0.0, 0.0, 0.0, 0.0],           # 21 of 21 (u = 0: the preload alone)
        [0.0, 20.0, 0.0, 0.0, 0.0, 0.0],          # 21
        [0.0, -40.0, 0.0, 0.0, 0.0, 0.0],         # 15
        [0.0, 0.0, 30.0, 0.0, 0.0, 0.0],          # 21
        [-10.0, 30.0, 10.0, -0.2, 1.0, -0.8],     # 21
        [-7.6, -21.6, -11.3, 0.5, -0.2, 1.1],     # 17
        [-15.3, -48.7, 24.0, 0.0, 1.2, 0.0],      # 11
    ]),
    # a small two-row cuff, rows of different radius and width, rigid arm (k_e = k_c,e),
    # uneven stiffness, no strap tension (delta0 = 0, W_pre = 0)
    "small-two-rows": dict(
        row_x=[0.01, 0.04], radius=[0.04, 0.05], row_width=[0.02, 0.03],
        start=60.0, step=45.0, count=5, k_indenter=[4000.0] * 10,
        k_cuff=[20e3, 35e3, 50e3, 80e3, 30e3, 25e3, 60e3, 45e3, 70e3, 40e3],
        arm="rigid", strap="handles", tension=0.0, wrenches=[
            [1.3, -2.6, 12.8, 0.1, -0.4, 0.3],        # 3 of 10
            [-23.3, -4.4, -24.9, -0.4, -0.4, -0.3],   # 4
            [4.1, 20.9, -2.6, 0.7, -0.5, 0.3],        # 6
            [-4.4, -23.4, 34.8, -0.2, 0.3, -0.2],     # 2
            [2.4, 15.2, -33.0, 0.1, 1.0, -0.2],       # 7
        ]),
}


def _phri_model(c):
    geom = cuff_geometry(c["row_x"], c["radius"], c["row_width"], c["start"], c["step"],
                         c["count"])
    k_t = tissue_element_stiffness(np.asarray(c["k_indenter"], dtype=float), geom.areas,
                                   indenter_diameter=INDENTER_DIAMETER)
    return build_model(geom, k_t, np.asarray(c["k_cuff"], dtype=float), arm=c["arm"],
                       strap_model=c["strap"], strap_tension=c["tension"])


# --------------------------------------------------------------------------- the PyNite model
def _elements(c):
    """Points, normals, tangents, normal and shear stiffness and hoop preload force of every
    element, from the case's raw numbers (docs/model.md sections 1-3), in row-major order."""
    width = math.radians(c["step"])
    rows = []
    for r, (x, R, w) in enumerate(zip(c["row_x"], c["radius"], c["row_width"])):
        for j in range(c["count"]):
            th = math.radians(c["start"] + j * c["step"])
            e = r * c["count"] + j
            area = w * R * width
            k_t = c["k_indenter"][e] * area / (math.pi * INDENTER_DIAMETER ** 2 / 4.0)
            k_c = c["k_cuff"][e]
            k = 1.0 / (1.0 / k_t + 1.0 / k_c) if c["arm"] == "compliant" else k_c
            f0 = c["tension"] * width * w / sum(c["row_width"]) if c["strap"] == "hoop" else 0.0
            rows.append(dict(
                p=np.array([x, R * math.cos(th), R * math.sin(th)]),
                n=-np.array([0.0, math.cos(th), math.sin(th)]),
                t=np.array([0.0, -math.sin(th), math.cos(th)]),
                k=k, k_s=ETA * k, f0=f0))
    return rows


def _tie(fe, name, point):
    """A node at ``point`` moving with the rigid cuff (a very stiff beam to the cuff node)."""
    fe.add_node(name, *map(float, point))
    fe.add_member("m_" + name, "cuff", name, "rigid", "rigid")


def pynite_solve(c):
    """Solve every wrench of case ``c`` with PyNite.

    Returns
    -------
    dict of ndarray
        ``u`` (m, 6) cuff node displacements [m, rad]; ``f`` (m, n) normal spring forces
        [N] (compression positive, zero when PyNite switched the spring off); ``active``
        (m, n); ``gap`` (m, n) compression of every normal spring from PyNite's node
        displacements [m]; ``shear`` (m, n, 3) force of the two tangential springs on the
        ground [N]; ``k`` (n,); ``statics`` (m, 6) applied loads plus support reactions,
        resultant about the origin [N, N*m]; ``load_scale`` (m,) largest applied load [N].
    """
    elems = _elements(c)
    fe = FEModel3D()
    fe.add_material("rigid", E=RIGID_E, G=RIGID_E / 2.6, nu=0.3, rho=0.0)
    fe.add_section("rigid", **RIGID_SECTION)
    fe.add_node("cuff", 0.0, 0.0, 0.0)
    strap_loads = []  # (node, point, force) of the strap on the cuff
    for e, el in enumerate(elems):
        node = f"e{e}"
        _tie(fe, node, el["p"])
        for tag, d, ks in (("n", el["n"], el["k"]), ("x", np.array([1.0, 0, 0]), el["k_s"]),
                           ("t", el["t"], el["k_s"])):
            ground = f"g{tag}{e}"
            fe.add_node(ground, *map(float, el["p"] + SPRING_LENGTH * d))
            fe.def_support(ground, True, True, True, True, True, True)
            fe.add_spring(f"s{tag}{e}", node, ground, float(ks), comp_only=(tag == "n"))
        if el["f0"] > 0:  # hoop preload: compress the spring by delta0, push the cuff inward
            for dof, v in zip(DOFS[:3], -el["f0"] / el["k"] * el["n"]):
                fe.def_node_disp(f"gn{e}", dof, float(v))
            strap_loads.append((node, el["p"], el["f0"] * el["n"]))
    if c["strap"] == "handles" and c["tension"] > 0:
        half = c["step"] / 2.0
        mean_x = float(np.mean(c["row_x"]))
        mean_r = float(np.mean(c["radius"]))
        for name, deg, sign in (("ha", c["start"] - half, -1.0),
                                ("hb", c["start"] + (c["count"] - 1) * c["step"] + half, 1.0)):
            th = math.radians(deg)
            p = np.array([mean_x, mean_r * math.cos(th), mean_r * math.sin(th)])
            _tie(fe, name, p)
            strap_loads.append((name, p, sign * c["tension"]
                                * np.array([0.0, -math.sin(th), math.cos(th)])))
    for node, _, force in strap_loads:
        for load, v in zip(LOADS[:3], force):
            fe.add_node_load(node, load, float(v), case="strap")
    for i, W in enumerate(c["wrenches"]):
        for load, v in zip(LOADS, W):
            fe.add_node_load("cuff", load, float(v), case=f"W{i}")
        fe.add_load_combo(f"W{i}", {f"W{i}": 1.0, "strap": 1.0})
    fe.analyze(check_statics=False)

    def disp(name, combo):
        node = fe.nodes[name]
        return np.array([getattr(node, d)[combo] for d in DOFS])

    m, n = len(c["wrenches"]), len(elems)
    out = {key: np.zeros((m, n)) for key in ("f", "gap")}
    out["active"] = np.zeros((m, n), dtype=bool)
    out["u"] = np.zeros((m, 6))
    out["shear"] = np.zeros((m, n, 3))
    out["statics"] = np.zeros((m, 6))
    out["load_scale"] = np.zeros(m)
    out["k"] = np.array([el["k"] for el in elems])
    for i, W in enumerate(c["wrenches"]):
        combo = f"W{i}"
        out["u"][i] = disp("cuff", combo)
        for e, el in enumerate(elems):
            spring = fe.springs[f"sn{e}"]
            # the spring's shortening, from PyNite's displacements of its two nodes
            out["gap"][i, e] = el["n"] @ (disp(f"e{e}", combo)[:3] - disp(f"gn{e}", combo)[:3])
            out["active"][i, e] = spring.active[combo]
            # Spring3D.axial of a switched-off spring is not its force: read zero there
            out["f"][i, e] = spring.axial(combo) if spring.active[combo] else 0.0
            out["shear"][i, e] = (fe.springs[f"sx{e}"].axial(combo) * np.array([1.0, 0, 0])
                                  + fe.springs[f"st{e}"].axial(combo) * el["t"])
        # global statics: applied loads plus support reactions, resultant about the origin
        total = np.array(W, dtype=float)
        scale = float(np.max(np.abs(W), initial=0.0))
        for _, p, force in strap_loads:
            total += np.concatenate([force, np.cross(p, force)])
            scale = max(scale, float(np.max(np.abs(force))))
        for node in fe.nodes.values():
            if node.name.startswith("g"):
                F = np.array([node.RxnFX[combo], node.RxnFY[combo], node.RxnFZ[combo]])
                M = np.array([node.RxnMX[combo], node.RxnMY[combo], node.RxnMZ[combo]])
                total += np.concatenate([F, M + np.cross([node.X, node.Y, node.Z], F)])
        out["statics"][i] = total
        out["load_scale"][i] = scale
    return out


# --------------------------------------------------------------------------- the tests
@pytest.fixture(scope="module", params=sorted(CASES))
def case(request):
    c = CASES[request.param]
    return request.param, c, pynite_solve(c)


def test_pynite_result_is_the_solution(case):
    """PyNite's answer satisfies the contact (KKT) conditions and statics, so it is the
    unique equilibrium of docs/model.md section 4 (see the module docstring)."""
    name, c, ref = case
    for i in range(len(c["wrenches"])):
        peak = np.max(ref["f"][i])
        assert peak > 0, f"{name} W{i}: no element in contact"
        tol = REL_TOL * peak
        compressed_off = ~ref["active"][i] & (ref["k"] * ref["gap"][i] > tol)
        assert not compressed_off.any(), (
            f"{name} W{i}: PyNite left elements {np.flatnonzero(compressed_off)} switched off "
            "though compressed (its compression-only iteration never switches a spring back "
            "on): not a valid reference case")
        assert np.all(ref["f"][i] >= -tol), f"{name} W{i}: active spring in tension"
        # an active spring's force is its stiffness times its shortening
        on = ref["active"][i]
        np.testing.assert_allclose(ref["f"][i, on], ref["k"][on] * ref["gap"][i, on],
                                   rtol=1e-9, atol=1e-9 * peak)
        # the loads are balanced by the reactions to the solver's round-off, which the
        # stiff beams amplify (measured: below 1e-7 of the largest load)
        np.testing.assert_allclose(ref["statics"][i], 0.0, rtol=0,
                                   atol=REL_TOL * ref["load_scale"][i])


def test_cases_lift_contacts_off(case):
    """The cases exercise the compression-only law: some wrenches lift elements off."""
    name, c, ref = case
    lifted = (~ref["active"]).sum(axis=1)
    assert lifted.max() >= 3, f"{name}: no wrench lifts three elements off"


def test_normal_forces_match_pynite(case):
    name, c, ref = case
    model = _phri_model(c)
    np.testing.assert_allclose(model.k, ref["k"], rtol=1e-12)
    sol = solve(model, np.asarray(c["wrenches"], dtype=float))
    assert sol.converged.all()
    for i in range(len(c["wrenches"])):
        peak = np.max(ref["f"][i])
        np.testing.assert_allclose(sol.forces[i], ref["f"][i], rtol=0, atol=REL_TOL * peak,
                                   err_msg=f"{name} W{i}")
        # the same elements carry load (where the force is clear of the tolerance)
        clear = np.abs(ref["f"][i]) > 10 * REL_TOL * peak
        np.testing.assert_array_equal(sol.contact[i][clear], ref["active"][i][clear],
                                      err_msg=f"{name} W{i}")


def test_displacement_and_shear_match_pynite(case):
    name, c, ref = case
    model = _phri_model(c)
    sol = solve(model, np.asarray(c["wrenches"], dtype=float))
    reach = float(np.max(np.abs(model.geometry.points)))  # a rotation's lever [m]
    for i in range(len(c["wrenches"])):
        # the largest displacement of an element point, normal or tangential [m]
        scale = max(np.max(np.abs(ref["gap"][i])),
                    np.max(np.linalg.norm(ref["shear"][i], axis=1) / (ETA * ref["k"])))
        np.testing.assert_allclose(sol.u[i, :3], ref["u"][i, :3], rtol=0,
                                   atol=REL_TOL * scale, err_msg=f"{name} W{i} translation")
        np.testing.assert_allclose(sol.u[i, 3:] * reach, ref["u"][i, 3:] * reach, rtol=0,
                                   atol=REL_TOL * scale, err_msg=f"{name} W{i} rotation")
        s = shear_forces(model, sol.u[i])
        s_peak = np.max(np.abs(ref["shear"][i]))
        np.testing.assert_allclose(s, ref["shear"][i], rtol=0,
                                   atol=REL_TOL * max(s_peak, np.max(ref["f"][i])),
                                   err_msg=f"{name} W{i} shear")
