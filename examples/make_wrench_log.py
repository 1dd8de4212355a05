"""Write examples/wrench_log.csv: a SYNTHETIC I-Act-like wrench log (fixed seed).

The arm is loaded horizontally (+z of the load cell) with 0, 11.1, 33.4 and
55.6 N steps held 8 s each, then unloaded, at 100 Hz, with Gaussian sensor
noise (0.3 N, 0.01 N*m), as the Harmony load cell of configs/harmony_upper_arm.yaml
would read it. Run from the repository root:

    python examples/make_wrench_log.py
"""

from pathlib import Path

import numpy as np
import pandas as pd

from phri_spring.io.config import load_config
from phri_spring.synthetic.wrench import iact_like_log

HERE = Path(__file__).resolve().parent


def main() -> None:
    cfg = load_config(HERE.parent / "configs" / "harmony_upper_arm.yaml")
    time, w = iact_like_log(seed=2024, loadcell_position=cfg.loadcell_position,
                            rotation=cfg.loadcell_rotation)
    df = pd.DataFrame(np.round(w, 4), columns=["Fx", "Fy", "Fz", "Mx", "My", "Mz"])
    df.insert(0, "time", np.round(time, 3))
    out = HERE / "wrench_log.csv"
    with open(out, "w", newline="") as fh:
        fh.write("# SYNTHETIC I-Act-like log made by examples/make_wrench_log.py (seed 2024): "
                 "horizontal loading 0, 11.1, 33.4, 55.6 N; units s, N, N*m\n")
        df.to_csv(fh, index=False)
    print(f"wrote {out} ({len(df)} samples)")


if __name__ == "__main__":
    main()
