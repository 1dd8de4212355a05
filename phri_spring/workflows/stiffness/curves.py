"""``phri stiffness --curves``: force-displacement curves of the cuff on the arm at the load cell.

The robot loads the cuff at the load-cell origin with a force s e_i along load-cell
axis i, or a moment s e_i about it, s from 0 to ``max_force`` [N] (``max_moment``
[N*m]) in both signs, every other component zero; the curve is s against the
motion of the load-cell point along or about that axis, from the preloaded state
(:func:`phri_spring.physics.response.sweep.sweep_loadcell_axes`). That is the loading
of Schiebl et al. (2025, Sensors 25(15):4605): forces and torques along and about
three orthogonal axes of an upper-arm interface, on 21 people.

Nonlinear curves come from contacts that lift off (any arm) and from a tissue law
that stiffens (``tissue.stiffening``, docs/model.md section 11.3). The slope at zero
load is 1 / (K^-1)_ii, with K the tangent stiffness ``phri stiffness`` reports
(:func:`phri_spring.workflows.stiffness.matrix.interface_stiffness_report`): the inverse
of the compliance's diagonal, because the other five loads are zero and the other
five motions free; K_ii would hold those motions at zero (docs/stiffness.md,
"Force-displacement curves").
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

import numpy as np

from ...errors import UsageError
from ...io.outputs.atomic import atomic_directory, check_output_path, naming
from ...io.config import Config
from ...physics.response.sweep import SIGNS, sweep_loadcell_axes
from .. import common
from .matrix import COLUMNS, HUMAN_REFERENCE, ROWS, check_arm, interface_stiffness_report

__all__ = ["StiffnessCurves", "ReferenceBand", "stiffness_curves", "human_reference_bands",
           "check_curves_output", "write_stiffness_curves", "CSV_NAME", "FIGURE_NAME",
           "CSV_COLUMNS", "DEFAULT_MAX_FORCE", "DEFAULT_MAX_MOMENT", "DEFAULT_POINTS"]

#: files written into the ``--curves`` folder
CSV_NAME, FIGURE_NAME = "stiffness_curves.csv", "stiffness_curves.png"
#: columns of :data:`CSV_NAME`
CSV_COLUMNS = ("axis", "sign", "displacement", "displacement_unit", "force", "force_unit",
               "contacts", "converged")
DEFAULT_MAX_FORCE = 60.0    # N
DEFAULT_MAX_MOMENT = 3.0    # N*m
DEFAULT_POINTS = 31
#: a load-cell axis within this angle of the arm's axis (or of a plane across it) is
#: compared with the human data measured along (across) the arm [deg]
ALIGNMENT_TOLERANCE_DEG = 10.0
#: people's units: displacement per SI unit (mm per m, deg per rad), by axis
_TO_PEOPLE = np.array([1e3] * 3 + [180.0 / math.pi] * 3)
_DISP_UNITS, _LOAD_UNITS = ("mm",) * 3 + ("deg",) * 3, ("N",) * 3 + ("N*m",) * 3


@dataclass(frozen=True)
class ReferenceBand:
    """A measured linear stiffness range to draw beside a curve.

    Attributes
    ----------
    low, high : float
        Range of the slope, people's units (N/mm or N*m/deg).
    unit : str
    what : str
        The direction it was measured in, e.g. ``along the arm``.
    source : str
    """

    low: float
    high: float
    unit: str
    what: str
    source: str


@dataclass(frozen=True, eq=False)
class StiffnessCurves:
    """Load-controlled force-displacement curves of one config and arm model at the load cell.

    Arrays are [axis, branch, sample], shape (6, 2, m): axes x, y, z, rx, ry, rz of the
    load cell, branches +e_i then -e_i, samples from zero load outward.

    Attributes
    ----------
    name : str
    config_path : str or None
    arm : str
    load : ndarray
        Force [N] (axes x, y, z) or moment [N*m] (rx, ry, rz) the robot applies at the
        load-cell origin, signed.
    displacement : ndarray
        Translation [m] or rotation [rad] of the load-cell point along or about the
        loaded axis, from the preloaded state; NaN where the solver did not converge.
    contacts : ndarray of int
        Elements in contact (0 where not converged).
    converged : ndarray of bool
    elements : int
    K : ndarray, shape (6, 6)
        Tangent stiffness at the preloaded state, load-cell origin and axes, SI
        (:class:`~phri_spring.workflows.stiffness.matrix.StiffnessReport` ``K``).
    directions : tuple of str
        How each load-cell axis lies on the arm (``along the arm``, ``across the arm`` or
        its angle to the arm's axis).
    references : tuple of (ReferenceBand or None)
        Measured human ranges of each axis, where the package cites one for its direction.
    max_force, max_moment : float
        Largest load [N], [N*m].
    """

    name: str
    config_path: Optional[str]
    arm: str
    load: np.ndarray
    displacement: np.ndarray
    contacts: np.ndarray
    converged: np.ndarray
    elements: int
    K: np.ndarray
    directions: tuple
    references: tuple
    max_force: float
    max_moment: float

    axes = COLUMNS
    loads = ROWS
    displacement_units = _DISP_UNITS
    load_units = _LOAD_UNITS

    @property
    def slope_at_zero(self) -> np.ndarray:
        """1 / (K^-1)_ii (6,), SI: N/m (x, y, z) and N*m/rad (rx, ry, rz).

        The slope of each curve at zero load under load control (the other five loads
        zero, the other five motions free); not K_ii, which holds those motions at zero.
        """
        return 1.0 / np.diag(np.linalg.inv(self.K))

    @property
    def slope_at_zero_people(self) -> np.ndarray:
        """:attr:`slope_at_zero` in N/mm and N*m/deg, shape (6,)."""
        return self.slope_at_zero / _TO_PEOPLE

    def displacement_people(self) -> np.ndarray:
        """:attr:`displacement` in mm (x, y, z) and degrees (rx, ry, rz)."""
        return self.displacement * _TO_PEOPLE[:, None, None]

    def table(self):
        """The curves as a DataFrame with :data:`CSV_COLUMNS`, one block per axis and sign.

        ``sign`` is +1 for loads along +e_i, -1 along -e_i; ``displacement`` in mm or deg
        and ``force`` in N or N*m (the units in the next column), both signed.
        """
        import pandas as pd

        a, b, m = self.load.shape
        disp = self.displacement_people()
        idx = np.indices((a, b, m)).reshape(3, -1)
        return pd.DataFrame({
            "axis": np.array(self.axes)[idx[0]],
            "sign": np.array(SIGNS)[idx[1]],
            "displacement": disp.ravel(),
            "displacement_unit": np.array(self.displacement_units)[idx[0]],
            "force": self.load.ravel(),
            "force_unit": np.array(self.load_units)[idx[0]],
            "contacts": self.contacts.ravel(),
            "converged": self.converged.ravel(),
        }, columns=list(CSV_COLUMNS))

    @property
    def failed(self) -> int:
        """Samples the solver did not converge on (NaN displacement)."""
        return int(np.count_nonzero(~self.converged))

    def summary(self) -> str:
        """One line: the slopes at zero load."""
        s = self.slope_at_zero_people
        return (f"{self.arm} arm: slope at zero load {_fmt(s[:3])} N/mm (x, y, z), "
                f"{_fmt(s[3:])} N*m/deg (rx, ry, rz) at the load cell, up to "
                f"{self.max_force:g} N and {self.max_moment:g} N*m")


def _fmt(values) -> str:
    return ", ".join(f"{v:.4g}" for v in values)


def human_reference_bands(rotation=None) -> tuple:
    """How each load-cell axis lies on the arm, and the human range cited for that direction.

    Parameters
    ----------
    rotation : array_like, shape (3, 3), optional
        Load-cell rotation R (v_cuff = R v_lc); the arm's axis is the cuff's x.

    Returns
    -------
    directions : tuple of 6 str
    references : tuple of 6 (ReferenceBand or None)
        From :data:`~phri_spring.workflows.stiffness.matrix.HUMAN_REFERENCE` (Schiebl et al.
        2025): translation along the arm 2.1-2.4 N/mm and across it 2.8-4.5 N/mm,
        rotation about the arm's axis 0.03-0.04 N*m/deg and about axes across it
        0.18-0.22 N*m/deg; None for an axis more than
        :data:`ALIGNMENT_TOLERANCE_DEG` off both.

    Examples
    --------
    >>> d, r = human_reference_bands()
    >>> d[0], (r[0].low, r[0].high), d[4], (r[4].low, r[4].high)
    ('along the arm', (2.1, 2.4), 'across the arm', (0.18, 0.22))
    """
    R = np.eye(3) if rotation is None else np.asarray(rotation, dtype=float)
    src = HUMAN_REFERENCE["source"]
    tol = math.radians(ALIGNMENT_TOLERANCE_DEG)
    directions, refs = [], []
    for i in range(6):
        cos = min(1.0, abs(float(R[0, i % 3])))        # load-cell axis . arm axis
        angle = math.degrees(math.acos(cos))
        rot = i >= 3
        unit = "N*m/deg" if rot else "N/mm"
        if cos >= math.cos(tol):
            key, what = ("torsion_Nm_per_deg", "about the arm's axis") if rot else \
                ("along_arm_N_per_mm", "along the arm")
            directions.append("along the arm")
        elif cos <= math.sin(tol):
            key, what = ("bending_Nm_per_deg", "about an axis across the arm") if rot else \
                ("across_arm_N_per_mm", "across the arm")
            directions.append("across the arm")
        else:
            key = None
            directions.append(f"{angle:.0f} deg from the arm's axis")
        refs.append(None if key is None else ReferenceBand(*HUMAN_REFERENCE[key], unit, what, src))
    return tuple(directions), tuple(refs)


def _positive(value: float, option: str, unit: str) -> float:
    value = float(value)
    if not (math.isfinite(value) and value > 0):
        raise UsageError(f"expected a finite number > 0 [{unit}], got {value:g}", key=option)
    return value


def stiffness_curves(cfg: Config, arm: str = "compliant", *,
                     max_force: float = DEFAULT_MAX_FORCE,
                     max_moment: float = DEFAULT_MAX_MOMENT,
                     points: int = DEFAULT_POINTS, model=None) -> StiffnessCurves:
    """Force-displacement curves of a config's cuff on the arm, along and about the load-cell axes.

    Parameters
    ----------
    cfg : Config
        A loaded config.
    arm : str
        A name of :data:`phri_spring.workflows.common.ARM_MODELS`.
    max_force : float
        Largest force [N], > 0.
    max_moment : float
        Largest moment [N*m], > 0.
    points : int
        Samples per branch (zero load included), >= 2.
    model : optional
        The model of ``cfg`` and ``arm`` if already built
        (:func:`~phri_spring.workflows.common.model_from_config`); built here otherwise.

    Returns
    -------
    StiffnessCurves

    Raises
    ------
    UsageError
        For an unknown arm (``--arm``), or a maximum that is not a finite number > 0
        (``--max-force``, ``--max-moment``) or too few ``points``.
    ConfigError
        If the config cannot make the model.
    ConvergenceError
        If the preloaded state (zero wrench) does not converge. A loaded sample that
        does not converge is NaN in the curves instead.
    """
    check_arm(arm)
    max_force = _positive(max_force, "--max-force", "N")
    max_moment = _positive(max_moment, "--max-moment", "N*m")
    if int(points) < 2:
        raise UsageError(f"expected at least 2 samples per branch, got {points}", key="points")
    if model is None:
        model = common.model_from_config(cfg, arm)
    report = interface_stiffness_report(cfg, arm, model=model)
    sweep = sweep_loadcell_axes(model, cfg.loadcell_rotation, cfg.loadcell_position,
                                max_force=max_force, max_moment=max_moment, points=int(points),
                                max_iterations=cfg.max_iterations)
    directions, refs = human_reference_bands(cfg.loadcell_rotation)
    return StiffnessCurves(
        name=cfg.name, config_path=None if cfg.path is None else str(cfg.path), arm=arm,
        load=sweep.load, displacement=sweep.displacement, contacts=sweep.contacts,
        converged=sweep.converged, elements=report.elements, K=report.K,
        directions=directions, references=refs, max_force=max_force, max_moment=max_moment)


def check_curves_output(outdir, inputs=(), option: str = "--curves") -> None:
    """Refuse a ``--curves`` folder that is a file, holds an input or cannot be made.

    Raises
    ------
    UsageError
        If ``outdir`` is an existing file, is or contains an input, or its parent
        folder does not exist (naming ``option``).
    OutputError
        If a file stands where a folder of the path should be.
    """
    out = Path(outdir)
    if out.exists() and not out.is_dir():
        raise UsageError(f"{str(out)!r} is a file; expected a folder for the curves", key=option)
    check_output_path(out, [i for i in inputs if i is not None], option=option, directory=True)


def write_stiffness_curves(curves: StiffnessCurves, outdir, *, inputs=(), dpi=None) -> list:
    """Write :data:`CSV_NAME` and :data:`FIGURE_NAME` into ``outdir``, both or neither.

    Parameters
    ----------
    curves : StiffnessCurves
    outdir : str or Path
        Folder (created if missing; files of the same names in it are replaced).
    inputs : sequence of path
        Inputs the folder must not be or contain (the config and its files).
    dpi : int, optional
        Resolution of the figure (the reports' default if not given).

    Returns
    -------
    list of Path
        The files written.
    """
    from ...reports.compare.figures import DEFAULT_DPI, save_figure
    from ...reports.stiffness_curves_figure import stiffness_curves_figure

    outdir = Path(outdir)
    check_curves_output(outdir, inputs)
    fig = stiffness_curves_figure([curves])
    with atomic_directory(outdir) as tmp:
        with naming(tmp / CSV_NAME):
            curves.table().to_csv(tmp / CSV_NAME, index=False, float_format="%.10g",
                                  na_rep="NaN")
        with naming(tmp / FIGURE_NAME):
            save_figure(fig, tmp / FIGURE_NAME, DEFAULT_DPI if dpi is None else int(dpi))
    return [outdir / CSV_NAME, outdir / FIGURE_NAME]
