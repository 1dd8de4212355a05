"""Write tests/data/stored_outputs.npz: solver outputs kept to prove that refactors change nothing.

Run once with the code whose results are to be kept (it was run on 2026-11-23 with the
solver before the active-set kernel was restructured, commit d7d7e86);
tests/workflows/test_stored_outputs.py then checks that the current code gives the same bits.

    python tests/data/make_stored_outputs.py
"""

from pathlib import Path

import numpy as np

from phri_spring.io.config import load_config
from phri_spring.io.logs import read_wrench_log
from phri_spring.physics.cuff.geometry import cuff_geometry
from phri_spring.physics.springs.model import build_model, tissue_element_stiffness
from phri_spring.physics.contact.solver import Solver, solve
from phri_spring.synthetic.wrench import smooth_random_log
from phri_spring.workflows.simulate import simulate

ROOT = Path(__file__).resolve().parents[2]


def corpus():
    """(name, model, wrench) of a random corpus: meshes, straps, arms, smooth and rough logs."""
    cases = []
    for i, (rows, angles, strap, arm) in enumerate([(3, 7, "hoop", "compliant"),
                                                    (3, 7, "handles", "rigid"),
                                                    (2, 5, "hoop", "rigid"),
                                                    (6, 24, "handles", "compliant"),
                                                    (4, 40, "hoop", "compliant")]):
        rng = np.random.default_rng(100 + i)
        step = 245.0 / angles
        g = cuff_geometry(np.linspace(-0.025, 0.025, rows), 0.045, 0.075 / rows,
                          57.5 + step / 2, step, angles)
        k_t = tissue_element_stiffness(rng.uniform(3500, 5000, g.n), g.areas)
        k_c = rng.uniform(3e4, 1e6, g.n)
        model = build_model(g, k_t, k_c, arm=arm, strap_model=strap,
                            strap_tension=float(rng.uniform(0, 40)))
        _, smooth = smooth_random_log(400, seed=i)
        rough = rng.normal(size=(200, 6)) * np.array([150, 150, 150, 6, 6, 6])
        cases.append((f"case{i}", model, np.vstack([smooth, rough])))
    return cases


def outputs():
    out = {}
    for name, model, W in corpus():
        sol = solve(model, W)
        out[f"{name}_forces"] = sol.forces
        out[f"{name}_u"] = sol.u
        out[f"{name}_iterations"] = sol.iterations
        solver = Solver(model)
        out[f"{name}_single"] = np.array([solver.forces(w) for w in W[:150]])
    cfg = load_config(ROOT / "configs" / "harmony_upper_arm.yaml")
    t, w = read_wrench_log(ROOT / "examples" / "wrench_log.csv")
    for arm in ("compliant", "rigid"):
        res = simulate(cfg, w, time=t, arm=arm, baseline="first:5")
        keep = slice(None, None, 11)  # every 11th sample keeps the file small
        out[f"example_{arm}_forces"] = res.forces[keep]
        out[f"example_{arm}_peak_kpa"] = res.peak_pressure_kpa[keep]
        out[f"example_{arm}_iterations"] = res.iterations
    return out


if __name__ == "__main__":
    np.savez_compressed(Path(__file__).with_name("stored_outputs.npz"), **outputs())
