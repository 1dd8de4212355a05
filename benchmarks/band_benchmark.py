"""The elastic band strap (``strap.model: band``, docs/model.md section 3.1) against the hoop.

    python -m benchmarks.band_benchmark speed band     # solve a one-hour log, band strap
    python -m benchmarks.band_benchmark speed hoop     # the same log, the preset's hoop
    python -m benchmarks.band_benchmark peaks          # the presets' peak pressures

``speed``: the human preset (configs/human_upper_arm.yaml, compliant arm, exponential
tissue law) on a one-hour 100 Hz synthetic log (360,000 samples, deterministic: the paper's
horizontal and vertical loads up to 55.6 N turning slowly through the plane of the cuff,
both signs, so that the band stretches and goes slack); prints the solve's seconds and
samples/s (the whole process timed from outside gives the figures of benchmarks/BAND.md).

``peaks``: every preset (configs/human_*.yaml, configs/harmony_upper_arm.yaml), the hoop
and the band (width 0.05 m, stiffness 500 N, the preset's tension at zero wrench), the
compliant and the rigid arm: the peak element pressure at zero load and over the paper's
loads (11.1, 33.4, 55.6 N along the load cell's z and y, both signs), the band's largest
tension and its largest Laplace pressure on the skin it covers; prints a markdown table.
"""

from __future__ import annotations

import sys
import time

import numpy as np


from benchmarks.common import ROOT
from phri_spring.io.config import config_from_dict
from phri_spring.io.config.yaml_loader import load_yaml
from phri_spring.physics.contact.solver import solve
from phri_spring.workflows.common import cuff_wrench, model_from_config

BAND = {"model": "band", "width": 0.05, "stiffness": 500.0}
PRESETS = ("harmony_upper_arm", "human_upper_arm", "human_forearm", "human_shank",
           "human_thigh")
MAGNITUDES = (11.1, 33.4, 55.6)


def config(preset: str, strap: str):
    raw = load_yaml(ROOT / "configs" / f"{preset}.yaml")
    raw.get("tissue", {}).pop("continuum", None)
    if strap == "band":
        raw["strap"] = {"tension": raw.get("strap", {}).get("tension", 15.0), **BAND}
    return config_from_dict(raw, base_dir=ROOT / "configs")


def hour_log(rate_hz: float = 100.0, seconds: float = 3600.0) -> np.ndarray:
    """(m, 6) load-cell wrenches [N, N*m]: 55.6 N turning in the y-z plane once a minute,
    its size swelling with a 7 s period, small moments."""
    t = np.arange(int(rate_hz * seconds)) / rate_hz
    F = 55.6 * np.abs(np.sin(2 * np.pi * t / 7.0))
    phi = 2 * np.pi * t / 60.0
    return np.column_stack([0.1 * F * np.sin(3 * phi), F * np.cos(phi), F * np.sin(phi),
                            0.01 * F * np.sin(phi), 0.01 * F * np.cos(2 * phi),
                            0.005 * F * np.sin(5 * phi)])


def speed(strap: str) -> None:
    cfg = config("human_upper_arm", strap)
    model = model_from_config(cfg, "compliant")
    W = cuff_wrench(cfg, hour_log())
    t0 = time.perf_counter()
    sol = solve(model, W, max_iterations=cfg.max_iterations)
    dt = time.perf_counter() - t0
    extra = ""
    if strap == "band":
        extra = (f", tension {np.min(sol.strap_tension):.3g}-{np.max(sol.strap_tension):.3g} N")
    print(f"{strap}: {len(W)} samples in {dt:.2f} s ({len(W) / dt:,.0f} samples/s), "
          f"{int((~sol.converged).sum())} not converged{extra}")


def paper_loads() -> np.ndarray:
    rows = [np.zeros(6)]
    for axis in (2, 1):
        for sign in (1.0, -1.0):
            for F in MAGNITUDES:
                w = np.zeros(6)
                w[axis] = sign * F
                rows.append(w)
    return np.array(rows)


def peaks() -> None:
    loads = paper_loads()
    print("| preset | arm | strap | no load: peak kPa | paper loads: peak kPa | largest band "
          "tension N | band's largest pressure kPa |")
    print("|---|---|---|---|---|---|---|")
    for preset in PRESETS:
        for arm in ("compliant", "rigid"):
            for strap in ("hoop", "band"):
                cfg = config(preset, strap)
                model = model_from_config(cfg, arm)
                sol = solve(model, cuff_wrench(cfg, loads), max_iterations=cfg.max_iterations)
                assert sol.converged.all()
                p = sol.forces * model.inv_area_kpa
                band = ("-", "-")
                if strap == "band":
                    T = float(np.max(sol.strap_tension))
                    band = (f"{T:.2f}", f"{float(model.band_pressure_kpa(T)):.2f}")
                print(f"| {preset} | {arm} | {strap} | {p[0].max():.2f} | {p[1:].max():.2f} | "
                      f"{band[0]} | {band[1]} |")


if __name__ == "__main__":
    if sys.argv[1:2] == ["speed"]:
        speed(sys.argv[2])
    else:
        peaks()
