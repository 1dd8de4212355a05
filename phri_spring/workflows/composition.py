"""The composition matrix: every arm x tissue law x continuum law x interface x cuff x
patch gap either runs, with outputs that obey the physics, or is refused in one line
naming a config key with a physical reason (docs/composition.md).

The axes come from the registries, so that a new arm (:data:`~.common.ARM_MODELS`), tissue
law (:data:`~phri_spring.physics.laws.TISSUE_LAWS`) or continuum law
(:data:`~phri_spring.physics.hyperelastic.coupled.CONTINUUM_LAWS`) joins the matrix by itself.
The continuum law and the patch gap only matter for arms that read ``tissue.continuum``
(:data:`CONTINUUM_ARMS`): for the others they are collapsed, not multiplied.

Each combination runs a small config (the human preset cut to one row of five patches) on
a short log (:data:`LOG_SAMPLES` samples) through :func:`~.simulate.simulate_file`, as
``phri simulate --shear`` does. A hyperelastic continuum is checked up to its reduced
model (loaded or identified once, minutes, extra ``hyper``): the identification is not run
here; the reduced model's outputs are tested by tests/workflows/test_hyper_arm.py and
tests/workflows/test_ogden_arm.py.

Regenerate the docs' table (after a change to any registry or refusal)::

    python -m phri_spring.workflows.composition --write docs/composition.md
"""

from __future__ import annotations

import contextlib
import itertools
import math
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

import numpy as np

from ..errors import PhriError
from ..plugins import arm_models, arm_record

__all__ = ["Combination", "Outcome", "combinations", "run_combination", "base_config",
           "markdown_table", "CONTINUUM_ARMS", "INTERFACES", "CUFFS", "CUFF_STRAPS", "PATCH_GAPS",
           "LIMBS",
           "TISSUE_TIMES",
           "LOG_SAMPLES"]



class _ContinuumArms:
    """The registered arms that read tissue.continuum (their declared ``continuum``), a live
    view: ``arm in CONTINUUM_ARMS``, ``list(CONTINUUM_ARMS)``."""

    def __contains__(self, arm) -> bool:
        return arm_record(arm).continuum

    def __iter__(self):
        return (a for a, m in arm_models().items() if m.continuum)

    def __repr__(self) -> str:
        return repr(tuple(self))


#: arms that read tissue.continuum: the continuum law and the patch gap are axes for these
CONTINUUM_ARMS = _ContinuumArms()
#: interface name -> interface.friction_coefficient (None: bonded)
INTERFACES = {"bonded": None, "mu 0.5": 0.5, "mu 0": 0.0}
#: cuff name -> cuff.stiffness (None: the preset's compliant cuff)
CUFFS = {"compliant": None, "rigid": math.inf, "compliant, band": None}
#: cuff name -> its strap where not the preset's hoop: an elastic band over the skin the
#: shell leaves bare (docs/model.md section 3.1)
CUFF_STRAPS = {"compliant, band": {"tension": 15.0, "model": "band", "width": 0.05,
                                   "stiffness": 500.0}}
#: limb name -> geometry keys replacing geometry.radius (None: the preset's circle): an
#: elliptic section of the preset's perimeter (axis ratio 0.8, turned) on a tapered limb
LIMBS = {"circle": None,
         "ellipse, taper": {"section": {"ellipse": [0.0502, 0.0402], "rotation": 15.0},
                            "taper_deg": 5.0}}
#: tissue time name -> (tissue.relaxation or None, whether the log has a muscle activation
#: column) (docs/model.md section 15)
TISSUE_TIMES = {"elastic": (None, False),
                "activation": (None, True),
                "QLV, activation": ({"fractions": [0.3, 0.2], "times_s": [0.02, 0.5]}, True)}
#: patch gap name -> tissue.continuum.patch_gap (None: the default)
PATCH_GAPS = {"default": None, "0": 0.0}
#: samples of the composition log
LOG_SAMPLES = 24
#: a tissue law parameter's value in the matrix where its default would be the linear law:
#: the human preset's (configs/human_upper_arm.yaml)
PRESET_PARAMETERS = {"stiffening": 115.0}
#: slack of the output checks [N]: forces are solved to the solver's tolerance
_TOL_N = 1e-6


def base_config() -> dict:
    """The human preset (configs/human_upper_arm.yaml) cut to one row of five patches
    (angles 110-250 deg), its compliant cuff's five stiffnesses at those angles."""
    return {
        "name": "composition matrix: human preset, one row of five patches",
        "geometry": {"radius": 0.045, "rows": {"A": 0.0}, "row_width": 0.025,
                     "angles": {"start": 110.0, "step": 35.0, "count": 5}},
        "load_cell": {"position": [0.0, -0.07, 0.0], "euler_xyz_deg": [0, 0, 0],
                      "convention": "robot_on_cuff"},
        "tissue": {"stiffness": 414.0, "basis": "indenter", "indenter_diameter": 0.009,
                   "poisson_ratio": 0.45,
                   "continuum": {"thickness": 0.025, "young_modulus": 3.0e4}},
        "cuff": {"stiffness": {"per_angle": [62500, 125000, 250000, 500000, 1.0e6]}},
        "interface": {"pain_threshold_kpa": 120},
        "strap": {"tension": 15.0, "model": "hoop"},
        "solver": {"max_iterations": 100},
    }


def composition_log() -> np.ndarray:
    """(LOG_SAMPLES, 7) samples: time [s] and a load-cell wrench that grows to 12 N and
    0.5 N*m while turning through the plane of the cuff and along the arm."""
    s = np.linspace(0.0, 1.0, LOG_SAMPLES)
    phi = np.pi * s
    F = 12.0 * s
    w = np.column_stack([0.3 * F * np.sin(2 * phi), -F * np.cos(phi / 2), F * np.sin(phi / 2),
                         0.04 * F * np.sin(phi), 0.02 * F, 0.03 * F * np.cos(phi)])
    return np.column_stack([0.01 * np.arange(LOG_SAMPLES), w])


@dataclass(frozen=True)
class Combination:
    """One cell of the matrix (None: an axis the arm does not read)."""

    arm: str
    tissue_law: str
    interface: str
    cuff: str
    continuum_law: Optional[str] = None
    patch_gap: Optional[str] = None
    limb: str = "circle"
    tissue_time: str = "elastic"

    def config(self) -> dict:
        """The base config with this combination's keys set."""
        from ..physics.laws import TISSUE_LAWS

        raw = base_config()
        tissue = raw["tissue"]
        if self.tissue_law != "linear":
            tissue["law"] = self.tissue_law
            for p in TISSUE_LAWS[self.tissue_law].parameters:
                value = PRESET_PARAMETERS.get(p.key, max(p.default, p.minimum))
                tissue[p.key] = float(min(value, p.maximum))
        mu = INTERFACES[self.interface]
        if mu is not None:
            raw["interface"]["friction_coefficient"] = mu
        if CUFFS[self.cuff] is not None:
            raw["cuff"]["stiffness"] = CUFFS[self.cuff]
        if self.cuff in CUFF_STRAPS:
            raw["strap"] = dict(CUFF_STRAPS[self.cuff])
        if self.continuum_law is not None:
            tissue["continuum"]["law"] = self.continuum_law
        if self.patch_gap is not None and PATCH_GAPS[self.patch_gap] is not None:
            tissue["continuum"]["patch_gap"] = PATCH_GAPS[self.patch_gap]
        if LIMBS[self.limb] is not None:
            del raw["geometry"]["radius"]
            raw["geometry"].update(LIMBS[self.limb])
        relaxation = TISSUE_TIMES[self.tissue_time][0]
        if relaxation is not None:
            tissue["relaxation"] = relaxation
        return raw

    def cells(self) -> tuple:
        return (self.arm, self.tissue_law, self.continuum_law or "-", self.interface,
                self.cuff, self.patch_gap or "-", self.limb, self.tissue_time)


def _ours(obj) -> bool:
    return getattr(obj, "__module__", "").startswith("phri_spring.")


def combinations(package_only: bool = False) -> list:
    """Every combination, from the registries (spring arms without the continuum axes);
    ``package_only``: of the arms and laws phri_spring itself registers (the docs' table),
    not those a user's or a test's module added."""
    from ..physics.hyperelastic.coupled import CONTINUUM_LAWS
    from ..physics.laws import TISSUE_LAWS
    from .common import ARM_MODELS

    arms = [a for a, m in ARM_MODELS.items() if not package_only or _ours(m.build)]
    laws = [n for n, cls in TISSUE_LAWS.items() if not package_only or _ours(cls)]
    out = []
    for arm, law, itf, cuff, limb, tt in itertools.product(arms, laws, INTERFACES, CUFFS, LIMBS,
                                                           TISSUE_TIMES):
        if arm not in CONTINUUM_ARMS:
            out.append(Combination(arm, law, itf, cuff, limb=limb, tissue_time=tt))
            continue
        for cont, gap in itertools.product(CONTINUUM_LAWS, PATCH_GAPS):
            out.append(Combination(arm, law, itf, cuff, cont, gap, limb, tt))
    return out


@dataclass(frozen=True)
class Outcome:
    """``status``: ``runs``, ``refused`` (one line naming ``key``) or ``fails`` (an
    internal error or a broken output check: a bug); ``message``: the refusal, the failure,
    or what the run gave."""

    status: str
    message: str
    key: Optional[str] = None
    #: a run checked up to its reduced model only (a hyperelastic layer)
    partial: bool = False


class _ReducedModelReached(Exception):
    """Raised where a hyperelastic layer's reduced model would be loaded or identified."""


@contextlib.contextmanager
def _stop_at_the_reduced_model():
    # the checks of a hyperelastic layer all come before its reduced model, which needs
    # minutes (and the hyper extra) the first time: the matrix stops there
    from ..io.cache import hyper_reduction as store

    def stop(*args, **kwargs):
        raise _ReducedModelReached()

    saved = store.load_or_identify, store.ogden_alpha
    store.load_or_identify = store.ogden_alpha = stop
    try:
        yield
    finally:
        store.load_or_identify, store.ogden_alpha = saved


def run_combination(comb: Combination, folder=None, *, cache_dir=None) -> Outcome:
    """Run one combination on the base config and the composition log; its outcome."""
    import yaml

    from ..io.config import load_config
    from .simulate import simulate_file

    with contextlib.ExitStack() as stack:
        if folder is None:
            folder = stack.enter_context(tempfile.TemporaryDirectory())
        folder = Path(folder)
        cfg_path = folder / "composition.yaml"
        cfg_path.write_text(yaml.safe_dump(comb.config()))
        log = folder / "composition_log.csv"
        data, header = composition_log(), "time,Fx,Fy,Fz,Mx,My,Mz"
        if TISSUE_TIMES[comb.tissue_time][1]:               # the muscle contracts, then rests
            act = np.clip(np.sin(np.linspace(0.0, np.pi, len(data))) * 1.2, 0.0, 1.0)
            data, header = np.column_stack([data, act]), header + ",activation"
        np.savetxt(log, data, delimiter=",", header=header, comments="", fmt="%.9g")
        out = folder / "composition_forces.csv"
        try:
            with _stop_at_the_reduced_model():
                cfg = load_config(cfg_path)
                summary = simulate_file(cfg, log, out, arm=comb.arm, shear=True, decimals=None,
                                        cache_dir=cache_dir)
        except _ReducedModelReached:
            return Outcome("runs", "every check passed up to the reduced model (identified "
                                   "once per config, cached)", partial=True)
        except PhriError as exc:
            text = exc.message
            if exc.key is None or "\n" in text:
                return Outcome("fails", f"a refusal naming no key: {exc}")
            prefix = exc.key + ": "       # a message that names its key again
            return Outcome("refused", text[len(prefix):] if text.startswith(prefix) else text,
                           exc.key)
        except Exception as exc:  # noqa: BLE001 - what the command line calls an internal error
            return Outcome("fails", f"internal error: {type(exc).__name__}: {exc}")
        problem = check_outputs(cfg, comb, out)
        if problem is not None:
            return Outcome("fails", problem)
        n = summary.samples
        return Outcome("runs", f"{n - summary.not_converged} of {n} samples converged")


def check_outputs(cfg, comb: Combination, out: Path, log=None) -> Optional[str]:
    """What is wrong with a run's forces file (None: nothing): every sample converged or
    flagged, forces finite where converged, normal forces >= 0, tangential forces within
    mu times the normal force, and the forces on the arm in balance with the load where
    the file has per-element resultant forces (``A0_force_x_N`` ...). ``log``: the run's
    load-cell wrenches (m, 6) (default: the composition log's); mu is the config's
    ``interface.friction_coefficient``."""
    import pandas as pd

    from .common import cuff_wrench, model_from_config

    df = pd.read_csv(out, comment="#")
    labels = list(cfg.labels)
    conv = df["converged"].astype(str).str.lower().isin(["true", "1"]).to_numpy()
    N = df[labels].to_numpy(float)
    log = composition_log()[:, 1:] if log is None else np.asarray(log, dtype=float)
    if len(df) != len(log):
        return f"{len(df)} rows for {len(log)} samples"
    if not np.isfinite(N[conv]).all():
        return "a converged sample with a force that is not finite"
    if np.isfinite(N[~conv]).any():
        return "a sample not converged but not flagged (finite forces)"
    if (N[conv] < -_TOL_N).any():
        return f"a negative normal force {N[conv].min():.3g} N"
    ax = df[[f"{lab}_shear_axial_N" for lab in labels]].to_numpy(float)
    ci = df[[f"{lab}_shear_circumferential_N" for lab in labels]].to_numpy(float)
    mu = cfg.friction_coefficient
    force_cols = [f"{lab}_force_{c}_N" for lab in labels for c in "xyz"]
    if mu is not None:
        T, Fn = np.hypot(ax, ci)[conv], N[conv]
        if all(c in df.columns for c in force_cols):
            # the cone holds the force along n_e (a coupled patch's label column is what
            # its sensor reads, not that force): split the resultant on n_e
            f = df[force_cols].to_numpy(float).reshape(len(df), len(labels), 3)[conv]
            nrm = cfg.geometry().normals
            Fn = np.einsum("mei,ei->me", f, nrm)
            T = np.linalg.norm(f - Fn[..., None] * nrm, axis=-1)
        excess = T - mu * Fn
        if (excess > _TOL_N + 1e-9 * np.abs(Fn)).any():
            return f"a tangential force beyond mu N by {excess.max():.3g} N"
        # and on the label column (a coupled patch's: what its sensor reads)
        excess = np.hypot(ax, ci)[conv] - mu * N[conv]
        if (excess > _TOL_N + 1e-9 * np.abs(N[conv])).any():
            return f"a shear force beyond mu times the label column by {excess.max():.3g} N"
    # released contact carries nothing: with friction, and on the linear coupled arm (its
    # default releases what lifts off); the spring arms' bonded springs hold lifted elements
    releases = mu is not None or (comb.arm in CONTINUUM_ARMS
                                  and comb.continuum_law in (None, "linear"))
    if releases and conv.any():
        # an element or patch whose label column reads 0 N (a coupled patch's: what its
        # sensor reads, docs/model.md 10.6) is out of contact
        lifted = N[conv] <= _TOL_N
        carried = np.hypot(ax, ci)[conv]
        # each patch's own moment columns (local axes and cuff frame), by label: the file
        # groups columns by kind, not by patch
        per_label = [[c for c in df.columns if c.startswith(f"{lab}_moment_") and c.endswith("_Nm")]
                     for lab in labels]
        if all(per_label):
            m = np.stack([np.abs(df[cols].to_numpy(float)[conv]).max(axis=1)
                          for cols in per_label], axis=1)
            carried = carried + m
        if (carried[lifted] > _TOL_N).any():
            return (f"an element at 0 N normal force carries {carried[lifted].max():.3g} "
                    "N (N*m) of tangential force or moment")
    g = cfg.geometry()
    point_springs = not any("_moment_" in c and c.endswith("_Nm") for c in df.columns)
    if point_springs:
        # point springs (no patch moments): the force on the arm is N n_e along the inward
        # normal plus the shear along the skin's meridian and circumferential directions
        rebuilt = (N[..., None] * g.normals + ax[..., None] * g.meridian
                   + ci[..., None] * g.circumferential)
    if all(c in df.columns for c in force_cols):
        f = df[force_cols].to_numpy(float).reshape(len(df), len(labels), 3)
        if point_springs and conv.any():
            diff = np.abs(f - rebuilt)[conv].max()
            if diff > _TOL_N + 1e-9 * np.abs(f[conv]).max():
                return (f"the resultant force columns disagree with the normal and shear "
                        f"columns by {diff:.3g} N")
    elif point_springs:
        f = rebuilt
    else:
        return None
    if conv.any():
        # what the arm carries = the load on the cuff + the strap's wrench (an elastic
        # band's at each sample's tension, docs/model.md section 3.1)
        W = cuff_wrench(cfg, log)
        model = model_from_config(cfg, comb.arm)
        strap = np.broadcast_to(np.asarray(model.W_pre, float), W.shape)
        if "strap_tension_N" in df.columns:
            extra = df["strap_tension_N"].to_numpy(float) - model.band_tension
            strap = strap + extra[:, None] * model.band_h
        load = W[:, :3] + strap[:, :3]
        gap = np.abs(f.sum(axis=1) - load).max(axis=1)[conv]
        if (gap > 1e-6 * (1.0 + np.abs(load[conv]).max())).any():
            return f"element forces out of balance with the load by {gap.max():.3g} N"
        moment_cols = [f"{lab}_moment_{c}_Nm" for lab in labels for c in "xyz"]
        if all(c in df.columns for c in force_cols):
            # and the moments about the cuff origin: sum of p_e x f_e plus the patches' own
            pts = cfg.geometry().points
            M = np.cross(pts[None], f).sum(axis=1)
            if all(c in df.columns for c in moment_cols):
                M = M + df[moment_cols].to_numpy(float).reshape(len(df), len(labels), 3).sum(1)
            pre = strap[:, 3:]
            mgap = np.abs(M - W[:, 3:] - pre).max(axis=1)[conv]
            if (mgap > 1e-6 * (0.1 + np.abs(W[conv, 3:] + pre[conv]).max())).any():
                return f"element moments out of balance with the load by {mgap.max():.3g} N*m"
    return None


def markdown_table(outcomes) -> str:
    """The docs' table: one row per combination, its outcome and, for a refusal, its key
    and line."""
    head = ("| arm | tissue law | continuum law | interface | cuff | patch gap | limb | tissue time "
            "| outcome |\n"
            "|---|---|---|---|---|---|---|---|---|\n")
    rows = []
    for comb, oc in outcomes:
        what = ("runs (checked up to its reduced model)" if oc.partial else "runs") \
            if oc.status == "runs" else (
            f"refused: `{oc.key}`: {oc.message}" if oc.status == "refused"
            else f"**FAILS**: {oc.message}")
        rows.append("| " + " | ".join((*comb.cells(), what.replace("|", "\\|"))) + " |")
    return head + "\n".join(rows) + "\n"


BEGIN, END = "<!-- composition table: begin -->", "<!-- composition table: end -->"


def write_table(doc: Path, table: str) -> None:
    """Put ``table`` between the BEGIN and END markers of ``doc``."""
    text = doc.read_text()
    i, j = text.index(BEGIN) + len(BEGIN), text.index(END)
    doc.write_text(text[:i] + "\n" + table + text[j:])


def table_in(doc: Path) -> str:
    """The table between the markers of ``doc``."""
    text = doc.read_text()
    return text[text.index(BEGIN) + len(BEGIN):text.index(END)].lstrip("\n")


def main(argv=None) -> int:
    import argparse

    ap = argparse.ArgumentParser(prog="python -m phri_spring.workflows.composition",
                                 description="Run the composition matrix; print its table "
                                             "or write it into a docs page.")
    ap.add_argument("--write", metavar="DOC", help="the docs page to write the table into")
    args = ap.parse_args(argv)
    outcomes = [(c, run_combination(c)) for c in combinations(package_only=True)]
    table = markdown_table(outcomes)
    if args.write:
        write_table(Path(args.write), table)
    else:
        print(table, end="")
    return 1 if any(oc.status == "fails" for _, oc in outcomes) else 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
