"""The table of docs/model.md section 12.4: what the cuff passes to the skin, by kind.

The human preset (configs/human_upper_arm.yaml) on examples/wrench_log.csv, every arm,
bonded and with interface.friction_coefficient = 0.5 (friction runs with the linear tissue
law: the preset's tissue.stiffening is dropped for them, as the friction benchmark does).
Prints a Markdown table of the summary's shares (``SimulateSummary.load_shares``).

    python -m benchmarks.load_shares [--mu 0.5]
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import yaml

from phri_spring.workflows.simulate import simulate_file

ROOT = Path(__file__).resolve().parent.parent
PRESET = ROOT / "configs" / "human_upper_arm.yaml"
LOG = ROOT / "examples" / "wrench_log.csv"


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--mu", type=float, default=0.5)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        raw = yaml.safe_load(PRESET.read_text())
        raw.setdefault("interface", {})["friction_coefficient"] = args.mu
        raw["tissue"].pop("stiffening", None)
        friction = Path(tmp) / "human_mu.yaml"
        friction.write_text(yaml.safe_dump(raw))
        runs = [("compliant", "bonded (preset: exponential law)", PRESET),
                ("rigid", "bonded", PRESET),
                ("coupled", "bonded (linear continuum)", PRESET),
                ("compliant", f"mu = {args.mu:g} (linear law)", friction),
                ("coupled", f"mu = {args.mu:g}", friction)]
        print(f"`{LOG.relative_to(ROOT)}` ({sum(1 for _ in open(LOG)) - 2:,} samples), "
              f"`{PRESET.relative_to(ROOT)}`\n")
        print("| arm | interface | normal | tangential in contact | lifted elements | "
              "unconverged |")
        print("| --- | --- | --- | --- | --- | --- |")
        for arm, interface, cfg in runs:
            s = simulate_file(cfg, LOG, Path(tmp) / "forces.csv", arm=arm)
            n, t, lift = (100 * x for x in s.load_shares)
            print(f"| {arm} | {interface} | {n:.1f} % | {t:.1f} % | {lift:.2f} % | "
                  f"{s.not_converged} |")


if __name__ == "__main__":
    main()
