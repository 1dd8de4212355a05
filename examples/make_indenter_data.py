"""Write the bundled SYNTHETIC indenter example: examples/indenter/ (42 trials).

21 locations (rows A-C x angles 0-6) x 2 trials, hand-like irregular strokes
(one to three pushes), mild hysteresis (loading softer than unloading), 0.025 mm
encoder steps, force noise and offset, 100-200 Hz, made by
:mod:`phri_spring.synthetic.indenter` with a fixed seed. The true stiffness map
(mean 4242 N/m, SD 251.5 N/m over the locations, as in the paper) goes to
examples/indenter_truth.csv, outside the trial folder; examples/indenter/TRUTH.md
says the data are synthetic (the folder reader ignores files that are not
*.csv or *.mat).

Run from the repository root:  python examples/make_indenter_data.py
"""

from __future__ import annotations

import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))

from phri_spring.synthetic.indenter import (synth_dataset, truth_map,  # noqa: E402
                                            write_trials, write_truth)

TRUTH_SEED = 4242
DATA_SEED = 2024
FOLDER = HERE / "indenter"
TRUTH = HERE / "indenter_truth.csv"


def main() -> None:
    truth = truth_map(seed=TRUTH_SEED)
    trials = synth_dataset(truth, seed=DATA_SEED, trials_per_location=2,
                           rates=(100.0, 125.0, 150.0, 200.0))
    FOLDER.mkdir(exist_ok=True)
    for old in FOLDER.glob("*.csv"):
        old.unlink()
    write_trials(trials, FOLDER, layout="folder", displacement_unit="mm",
                 time_decimals=4, force_decimals=3)
    write_truth(truth, TRUTH)
    lines = [
        "# SYNTHETIC indenter data (not measurements)",
        "",
        "Made by `python examples/make_indenter_data.py` with "
        "`phri_spring.synthetic.indenter` (truth seed "
        f"{TRUTH_SEED}, data seed {DATA_SEED}).",
        "",
        "42 trials `<label>_<trial>.csv` (21 locations A0..C6 x 2 trials), columns "
        "`time` [s], `displacement` [mm, encoder reading, 0.025 mm steps], `force` [N, "
        "with sensor offset and noise]. Each trial rests 3.5-4.5 s, then holds one to "
        "three hand-like pushes 2.5-5 mm deep; loading is softer than unloading "
        "(hysteresis ratio 0.04-0.12); 100-200 Hz.",
        "",
        "True unloading stiffness per location (also in `../indenter_truth.csv`): the "
        "mean of the true stiffnesses of its two trials, which differ by about 1.5 % "
        "(SD). Over the locations: mean 4242 N/m, sample SD 251.5 N/m, the paper's "
        "values.",
        "",
        "| row | " + " | ".join(str(j) for j in range(7)) + " |",
        "|---|" + "---|" * 7,
    ]
    for r in "ABC":
        lines.append(f"| {r} | " + " | ".join(f"{truth[f'{r}{j}']:.1f}" for j in range(7))
                     + " |")
    lines += ["", "This file is not a trial: the folder reader reads only `*.csv` and `*.mat`.",
              ""]
    (FOLDER / "TRUTH.md").write_text("\n".join(lines), encoding="utf-8")
    size = sum(p.stat().st_size for p in FOLDER.iterdir())
    print(f"wrote {len(trials)} trials to {FOLDER} ({size / 1e6:.2f} MB) and {TRUTH}")


if __name__ == "__main__":
    main()
