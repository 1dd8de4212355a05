"""Write examples/design/task_log.csv: a SYNTHETIC 10-minute assistance log (fixed seed).

An elbow-assisting exoskeleton pushes on the upper-arm cuff in repeated
reach-and-lift cycles (period 4 to 6 s) at 100 Hz for 10 minutes (60,000
samples): up to about 45 N horizontal (load-cell z) and 30 N vertical
(load-cell y) with small moments, plus Gaussian sensor noise (0.3 N,
0.01 N*m), rounded to 4 decimals like a load-cell export. The file is about
4 MB, so it is generated rather than committed. Run from the repository root:

    python examples/design/make_task_log.py
"""

from pathlib import Path

import numpy as np
import pandas as pd

HERE = Path(__file__).resolve().parent
SEED = 12


def task_log(seed: int = SEED, minutes: float = 10.0, rate_hz: float = 100.0):
    """(time [s], wrench (m, 6) [N, N*m]) in load-cell axes."""
    rng = np.random.default_rng(seed)
    t = np.arange(int(minutes * 60 * rate_hz)) / rate_hz
    # cycle phase with a slowly wandering period (4-6 s)
    period = 5.0 + 1.0 * np.sin(2 * np.pi * t / 97.0)
    phase = 2 * np.pi * np.cumsum(1.0 / (period * rate_hz))
    lift = np.clip(np.sin(phase), 0.0, None) ** 1.5             # assistance bursts
    effort = 0.75 + 0.25 * np.sin(2 * np.pi * t / 180.0 + 1.0)   # fatigue / task changes
    W = np.zeros((len(t), 6))
    W[:, 2] = 45.0 * effort * lift + 3.0 * np.sin(phase + 0.4)   # Fz horizontal push
    W[:, 1] = -30.0 * effort * lift ** 2 + 2.0                   # Fy vertical support
    W[:, 0] = 4.0 * np.sin(0.5 * phase)                          # Fx along the arm
    W[:, 3] = 0.4 * effort * lift                                # Mx
    W[:, 4] = -0.01 * W[:, 2]                                    # My (push off-centre)
    W[:, 5] = 0.15 * np.sin(phase + 1.3)                         # Mz
    W[:, :3] += rng.normal(0.0, 0.3, (len(t), 3))
    W[:, 3:] += rng.normal(0.0, 0.01, (len(t), 3))
    return t, W


def main() -> None:
    t, W = task_log()
    df = pd.DataFrame(np.round(W, 4), columns=["Fx", "Fy", "Fz", "Mx", "My", "Mz"])
    df.insert(0, "time", np.round(t, 3))
    out = HERE / "task_log.csv"
    with open(out, "w", newline="") as fh:
        fh.write(f"# SYNTHETIC 10-minute assistance log made by examples/design/make_task_log.py "
                 f"(seed {SEED}); units s, N, N*m\n")
        df.to_csv(fh, index=False)
    print(f"wrote {out} ({len(df):,} samples)")


if __name__ == "__main__":
    main()
