"""Regenerate the SYNTHETIC compare experiment in examples/experiment/.

    python examples/make_experiment.py

Writes manifest.yaml, twelve trial CSVs and truth_tissue_stiffness.csv from a
hidden "truth" spring network that is neither of the two models 'phri compare'
compares (see examples/experiment/README.md). The seed is fixed, so the files
are reproducible (numpy's default generator, PCG64).
"""

from __future__ import annotations

from pathlib import Path

from phri_spring.synthetic.experiment import make_experiment

HERE = Path(__file__).resolve().parent
SEED = 20230611


def main() -> None:
    manifest = make_experiment(HERE.parent / "configs" / "harmony_upper_arm.yaml",
                               HERE / "experiment", seed=SEED,
                               script="examples/make_experiment.py")
    print(f"wrote {manifest.parent}")


if __name__ == "__main__":
    main()
