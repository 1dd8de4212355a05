"""Write the SYNTHETIC viscoelastic indenter example: examples/indenter_qlv/ (3 trials).

Three locations (B2, B3, B4), one trial each: 3.5 s at rest, a ramp of 1 s to 4 mm, a hold
of 20 s, a release of 1 s and 3.5 s at rest, sampled at 100 Hz. The tissue is quasi-linear
viscoelastic: a linear elastic part k d (k per location below) and the Prony series
G(t) = 1 - 0.30 (1 - exp(-t / 0.4 s)) - 0.20 (1 - exp(-t / 5 s)), the force computed in
closed form (:mod:`phri_spring.synthetic.indenter_qlv`), then a sensor offset, white noise
of 0.5 % of the peak force and 0.025 mm encoder steps, with a fixed seed. The truth goes to
examples/indenter_qlv/TRUTH.md (not a trial: the folder reader reads *.csv and *.mat only).

Run from the repository root:  python examples/make_indenter_qlv_data.py
Fit it:  phri fit-stiffness examples/indenter_qlv -o qlv.csv --law qlv --plots figs/
"""

from __future__ import annotations

import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))

import numpy as np  # noqa: E402

from phri_spring.synthetic.indenter import write_trials  # noqa: E402
from phri_spring.synthetic.indenter_qlv import synth_qlv_trial  # noqa: E402

SEED = 35
FOLDER = HERE / "indenter_qlv"
#: true k [N/m] of the elastic part per location
STIFFNESS = {"B2": 4100.0, "B3": 4300.0, "B4": 3900.0}
FRACTIONS = (0.30, 0.20)
TIMES_S = (0.4, 5.0)


def main(folder: Path = FOLDER) -> None:
    rng = np.random.default_rng(SEED)
    trials = [synth_qlv_trial(k, FRACTIONS, TIMES_S, depth=4e-3, ramp_s=1.0, hold_s=20.0,
                              rest=3.5, rate=100.0, noise=0.005,
                              offset=float(rng.uniform(-0.5, 0.5)), encoder=True, seed=rng,
                              location=lab, trial=1)
              for lab, k in STIFFNESS.items()]
    folder = Path(folder)
    folder.mkdir(exist_ok=True)
    for old in folder.glob("*.csv"):
        old.unlink()
    write_trials(trials, folder, layout="folder", displacement_unit="mm", time_decimals=2,
                 force_decimals=4)
    lines = [
        "# SYNTHETIC viscoelastic indenter data (not measurements)",
        "",
        f"Made by `python examples/make_indenter_qlv_data.py` (seed {SEED}) with "
        "`phri_spring.synthetic.indenter_qlv`.",
        "",
        "3 trials `<label>_1.csv`, columns `time` [s], `displacement` [mm, encoder reading, "
        "0.025 mm steps], `force` [N, with sensor offset and noise 0.5 % of the peak]. Each: "
        "3.5 s rest, ramp 1 s to 4 mm, hold 20 s, release 1 s, 3.5 s rest; 100 Hz.",
        "",
        "True tissue: quasi-linear viscoelastic, elastic part k d, relaxation "
        f"`tissue.relaxation: {{fractions: [{FRACTIONS[0]}, {FRACTIONS[1]}], "
        f"times_s: [{TIMES_S[0]}, {TIMES_S[1]}]}}`.",
        "",
        "| location | k [N/m] |",
        "|---|---|",
    ]
    lines += [f"| {lab} | {k:.0f} |" for lab, k in STIFFNESS.items()]
    lines += ["", "This file is not a trial: the folder reader reads only `*.csv` and `*.mat`.",
              ""]
    (folder / "TRUTH.md").write_text("\n".join(lines), encoding="utf-8")
    size = sum(p.stat().st_size for p in folder.iterdir())
    print(f"wrote {len(trials)} trials to {folder} ({size / 1e3:.0f} kB)")


if __name__ == "__main__":
    main()
