"""``phri stiffness`` as a function: the interface stiffness a config describes, at its load cell.

The interface stiffness is the 6x6 tangent dW/du of the cuff on the arm at the
preloaded state (zero wrench from the robot; the strap preload as configured),
computed by :func:`phri_spring.physics.response.stiffness.interface_stiffness` in the cuff
frame about the cuff origin and expressed at the load-cell origin in the
load-cell axes (docs/model.md sections 2, 4 and 5; docs/stiffness.md). Everything
is in SI units here; :meth:`StiffnessReport.people_units` and
:meth:`StiffnessReport.to_text` give N/mm, N/deg, N*m/mm and N*m/deg.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Optional

import numpy as np

from ...errors import ConvergenceError, UsageError
from ...io.config import Config
from ...physics.response.stiffness import interface_stiffness, principal_stiffness, stiffness_at_loadcell
from .. import common

__all__ = ["StiffnessReport", "interface_stiffness_report", "ROWS", "COLUMNS", "SI_UNITS",
           "PEOPLE_UNITS", "to_people_units", "HUMAN_REFERENCE", "check_arm"]

#: rows of K: the wrench components (force, then moment)
ROWS = ("Fx", "Fy", "Fz", "Mx", "My", "Mz")
#: columns of K: the displacement components (translation, then rotation)
COLUMNS = ("x", "y", "z", "rx", "ry", "rz")
_ROW_SI, _COL_SI = ("N",) * 3 + ("N*m",) * 3, ("m",) * 3 + ("rad",) * 3
_ROW_PEOPLE, _COL_PEOPLE = _ROW_SI, ("mm",) * 3 + ("deg",) * 3
#: unit of each entry of K [row][column] in SI: N/m, N/rad, N*m/m, N*m/rad
SI_UNITS = tuple(tuple(f"{r}/{c}" for c in _COL_SI) for r in _ROW_SI)
#: unit of each entry of :meth:`StiffnessReport.people_units`: N/mm, N/deg, N*m/mm, N*m/deg
PEOPLE_UNITS = tuple(tuple(f"{r}/{c}" for c in _COL_PEOPLE) for r in _ROW_PEOPLE)
#: factor from SI to people's units for each column: per mm = per m / 1000, per deg = per rad * pi/180
_COLUMN_FACTOR = np.array([1e-3] * 3 + [math.pi / 180.0] * 3)

#: Human upper-arm interface stiffness measured by Schiebl et al. (2025), Sensors 25(15):4605,
#: doi:10.3390/s25154605 (21 subjects, linear fits, medians of the subject-group regressions):
#: translational range [N/mm] and torsion about the arm's long axis [N*m/deg]; by direction,
#: over both signs of the load (their appendix B linear fits and the 4.5 N/mm median across the
#: arm): translation along the arm and across it [N/mm], rotation about the two axes across
#: the arm [N*m/deg] (docs/stiffness.md).
HUMAN_REFERENCE = {"translational_N_per_mm": (2.1, 4.5), "torsion_Nm_per_deg": (0.03, 0.04),
                   "along_arm_N_per_mm": (2.1, 2.4), "across_arm_N_per_mm": (2.8, 4.5),
                   "bending_Nm_per_deg": (0.18, 0.22),
                   "source": "Schiebl et al. 2025, Sensors 25(15):4605"}


def to_people_units(K) -> np.ndarray:
    """A stiffness (6, 6) in SI units -> N/mm, N/deg, N*m/mm, N*m/deg (same layout).

    Parameters
    ----------
    K : array_like, shape (6, 6)
        Rows Fx..Mz [N, N*m], columns x..rz [m, rad].

    Returns
    -------
    ndarray, shape (6, 6)
        Each column scaled: translations per mm (x 1e-3), rotations per degree (x pi/180).
    """
    return np.asarray(K, dtype=float) * _COLUMN_FACTOR[None, :]


@dataclass(frozen=True, eq=False)
class StiffnessReport:
    """The interface stiffness of one config and arm model at the preloaded state.

    Attributes
    ----------
    name : str
        The config's ``name``.
    config_path : str or None
        The config file.
    arm : str
        Arm model (a name of :data:`phri_spring.workflows.common.ARMS`).
    K : ndarray, shape (6, 6)
        Stiffness at the load-cell origin in the load-cell axes, SI units (rows
        :data:`ROWS`, columns :data:`COLUMNS`; entries N/m, N/rad, N*m/m, N*m/rad).
    K_cuff : ndarray, shape (6, 6)
        The same stiffness in the cuff frame about the cuff origin (on the arm axis), SI.
    translational : ndarray, shape (3,)
        Principal values of the force-per-translation block of ``K``, ascending [N/m]
        (the same at any reference point).
    translational_directions : ndarray, shape (3, 3)
        Row i: unit direction of ``translational[i]`` in the load-cell axes [-].
    rotational : ndarray, shape (3,)
        Principal values of the moment-per-rotation block of ``K``, ascending [N*m/rad]
        (rotations about axes through the load-cell origin).
    torsion : float
        K_cuff[3, 3]: moment about the arm axis per rotation about it [N*m/rad].
    contacts : int
        Elements in contact at the preloaded state.
    elements : int
        Elements of the cuff.
    strap_model : str
        ``hoop`` or ``handles``.
    """

    name: str
    config_path: Optional[str]
    arm: str
    K: np.ndarray
    K_cuff: np.ndarray
    translational: np.ndarray
    translational_directions: np.ndarray
    rotational: np.ndarray
    torsion: float
    contacts: int
    elements: int
    strap_model: str

    def people_units(self) -> np.ndarray:
        """``K`` (6, 6) in N/mm, N/deg (force rows) and N*m/mm, N*m/deg (moment rows)."""
        return to_people_units(self.K)

    @property
    def translational_N_per_mm(self) -> np.ndarray:
        """Principal translational stiffness [N/mm], ascending, shape (3,)."""
        return self.translational * 1e-3

    @property
    def rotational_Nm_per_deg(self) -> np.ndarray:
        """Principal rotational stiffness at the load-cell origin [N*m/deg], ascending, (3,)."""
        return self.rotational * (math.pi / 180.0)

    @property
    def torsion_Nm_per_deg(self) -> float:
        """Torsional stiffness about the arm axis [N*m/deg]."""
        return self.torsion * (math.pi / 180.0)

    def summary(self) -> str:
        """One line: ranges of the principal values and the torsion about the arm axis."""
        t, r = self.translational_N_per_mm, self.rotational_Nm_per_deg
        return (f"{self.arm} arm: translational {_g(t[0])}-{_g(t[-1])} N/mm, rotational "
                f"{_g(r[0])}-{_g(r[-1])} N*m/deg at the load cell, torsion about the arm axis "
                f"{_g(self.torsion_Nm_per_deg)} N*m/deg ({self.contacts} of {self.elements} "
                "elements in contact)")

    def to_dict(self) -> dict:
        """A JSON-ready mapping (plain lists and floats; ``K`` in SI units)."""
        return {
            "name": self.name,
            "config": self.config_path,
            "arm": self.arm,
            "state": "preloaded (zero wrench), tangent stiffness",
            "frame": "load-cell origin, load-cell axes",
            "rows": list(ROWS),
            "columns": list(COLUMNS),
            "units": [list(r) for r in SI_UNITS],
            "K": self.K.tolist(),
            "principal": {
                "translational_N_per_m": self.translational.tolist(),
                "translational_N_per_mm": self.translational_N_per_mm.tolist(),
                "translational_directions": self.translational_directions.tolist(),
                "rotational_Nm_per_rad": self.rotational.tolist(),
                "rotational_Nm_per_deg": self.rotational_Nm_per_deg.tolist(),
            },
            "K_cuff": self.K_cuff.tolist(),
            "K_cuff_frame": "cuff origin (on the arm axis), cuff axes (x along the arm)",
            "torsion_about_arm_axis_Nm_per_rad": self.torsion,
            "torsion_about_arm_axis_Nm_per_deg": self.torsion_Nm_per_deg,
            "contacts": self.contacts,
            "elements": self.elements,
            "strap_model": self.strap_model,
        }

    def to_text(self) -> str:
        """The report for people: the matrix in N/mm, N/deg, N*m/mm, N*m/deg, principal values."""
        Kp = self.people_units()
        scale = float(np.max(np.abs(Kp)))
        where = f" ({self.config_path})" if self.config_path else ""
        lines = [
            f"interface stiffness of {self.name or 'the config'}{where}, {self.arm} arm",
            f"tangent at the preloaded state (zero wrench, {self.strap_model} strap; "
            f"{self.contacts} of {self.elements} elements in contact), at the load-cell origin "
            "in the load-cell axes",
            "entry = row / column: N/mm, N/deg (forces), N*m/mm, N*m/deg (moments)",
            "",
            " " * 10 + "".join(f"{h:>11}" for h in (f"{c} [{u}]" for c, u in
                                                       zip(COLUMNS, _COL_PEOPLE))),
        ]
        for i, (r, u) in enumerate(zip(ROWS, _ROW_PEOPLE)):
            cells = "".join(f"{_g(v, scale):>11}" for v in Kp[i])
            lines.append(f"{r + ' [' + u + ']':<10}{cells}")
        d = self.translational_directions
        dirs = ", ".join("(" + " ".join(f"{_g(c, 1.0, 3)}" for c in row) + ")" for row in d)
        lines += [
            "",
            "principal translational stiffness [N/mm]: "
            + "  ".join(_g(v) for v in self.translational_N_per_mm)
            + f"   along {dirs} (load-cell axes)",
            "principal rotational stiffness [N*m/deg]: "
            + "  ".join(_g(v) for v in self.rotational_Nm_per_deg)
            + "   (rotations about axes through the load-cell origin)",
            f"torsion about the arm axis [N*m/deg]: {_g(self.torsion_Nm_per_deg)}   "
            "(cuff frame, about the cuff origin)",
            "summary: " + self.summary(),
        ]
        return "\n".join(lines)


def _g(value: float, scale: float = 0.0, digits: int = 4) -> str:
    """``value`` with ``digits`` significant digits; 0 where below 1e-12 of ``scale``."""
    value = float(value)
    if abs(value) <= 1e-12 * scale or value == 0.0:
        return "0"
    return f"{value:.{digits}g}"


def check_arm(arm: str) -> None:
    """Raise a UsageError (key ``--arm``) unless ``arm`` is in the arm registry."""
    if arm not in common.ARMS:
        raise UsageError(f"unknown arm model {arm!r}; expected one of {', '.join(common.ARMS)}",
                         key="--arm")


def interface_stiffness_report(cfg: Config, arm: str = "compliant", *,
                               model=None) -> StiffnessReport:
    """The interface stiffness of a config's cuff at its load cell (the tangent at zero wrench).

    Parameters
    ----------
    cfg : Config
        A loaded config (:func:`phri_spring.io.config.load_config`).
    arm : str
        One of :data:`phri_spring.workflows.common.ARMS`.
    model : optional
        The model of ``cfg`` and ``arm`` if already built
        (:func:`~phri_spring.workflows.common.model_from_config`); built here otherwise.

    Returns
    -------
    StiffnessReport

    Raises
    ------
    UsageError
        For an unknown arm model (key ``--arm``).
    ConfigError
        If the config cannot make the model (e.g. an infinitely stiff element).
    ConvergenceError
        If the equilibrium at zero wrench does not converge.
    """
    check_arm(arm)
    if model is None:
        model = common.model_from_config(cfg, arm)
    try:
        K_cuff = interface_stiffness(model, max_iterations=cfg.max_iterations)
    except RuntimeError as exc:
        raise ConvergenceError(f"{exc} (solver.max_iterations = {cfg.max_iterations})",
                               file=cfg.path, key="solver.max_iterations") from None
    K_cuff = 0.5 * (K_cuff + K_cuff.T)
    K = stiffness_at_loadcell(K_cuff, cfg.loadcell_rotation, cfg.loadcell_position)
    trans, rot = principal_stiffness(K)
    _, vecs = np.linalg.eigh(0.5 * (K[:3, :3] + K[:3, :3].T))
    dirs = vecs.T.copy()
    for row in dirs:                       # a sign convention: largest component positive
        if row[int(np.argmax(np.abs(row)))] < 0:
            row *= -1.0
    contacts = _preloaded_contacts(model, cfg)
    return StiffnessReport(
        name=cfg.name, config_path=None if cfg.path is None else str(cfg.path), arm=arm,
        K=K, K_cuff=K_cuff, translational=trans, translational_directions=dirs,
        rotational=rot, torsion=float(K_cuff[3, 3]), contacts=contacts, elements=int(model.n),
        strap_model=cfg.strap_model)


def _preloaded_contacts(model, cfg: Config) -> int:
    """Elements in contact at zero wrench."""
    from ...physics.contact.solver import solve

    sol = solve(model, np.zeros((1, 6)), max_iterations=cfg.max_iterations)
    return int(np.count_nonzero(np.asarray(sol.contact)[0]))
