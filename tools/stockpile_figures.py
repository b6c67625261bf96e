"""The stockpile's figures in docs/stockpile.md: what each heavy scene digs, and what the digging
load does to the tracking, with the cost of the pile in simulation time.

    python tools/stockpile_figures.py [--seed N] [--figures docs/figures/stockpile]

Prints two markdown tables and writes heavy_dig_pile's pile and reclaim figures into --figures.
"""

from __future__ import annotations

import argparse
import dataclasses
import time
from pathlib import Path

import numpy as np

from bwr_twin.config.scene import load_scene
from bwr_twin.results.reclaim_plots import save_reclaim_figures
from bwr_twin.shipped import SCENES
from bwr_twin.sim.lockstep import simulate

ROOT = Path(__file__).resolve().parents[1]
DIGGING_SCENES = ("heavy_reclaim", "heavy_coulomb_friction", "heavy_wind", "heavy_model_mismatch", "heavy_dig_pile")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--figures", type=Path, default=ROOT / "docs" / "figures" / "stockpile")
    args = parser.parse_args()
    seed = {"simulation.seed": args.seed}

    print("| scene | reclaimed | mean rate while carrying | reclaim rate CV while carrying (std/mean) | peak "
          "| spill | dug | largest digging load |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- |")
    for name in DIGGING_SCENES:
        m = simulate(load_scene(SCENES / f"{name}.toml", seed)).metrics["reclaim"]
        load = f"{m['digging_force_max_N'] / 1e3:.0f} kN" if m["digging_force_max_N"] else "none (random stand-in)"
        print(f"| `{name}` | {m['mass_t']:.0f} t | {m['rate_mean_tph']:,.0f} t/h over {m['carrying_time_s']:.0f} s "
              f"| {m['rate_cv']:.2f} | {m['rate_max_tph']:,.0f} t/h | {m['spill_t']:.0f} t | {m['dug_m3']:.0f} m³ | {load} |")

    dig = load_scene(SCENES / "heavy_dig_pile.toml", seed)
    paper_controller = load_scene(SCENES / "heavy_reclaim.toml", seed).controller
    cases = {
        "PID, digging load (the scene)": dig,
        "PID, no digging load": load_scene(SCENES / "heavy_dig_pile.toml", {**seed, "digging.cutting_energy": 0.0,
                                                                              "digging.idle_power": 0.0}),
        "PID, no pile at all": dataclasses.replace(dig, stockpile=None, digging=None),
        "the paper's controller and gains, digging load": dataclasses.replace(dig, controller=paper_controller),
    }
    print()
    print("| heavy_dig_pile | travel error max | slew error max | luff error max | reclaimed | spill | simulated in |")
    print("| --- | --- | --- | --- | --- | --- | --- |")
    for label, scene in cases.items():
        start = time.perf_counter()
        result = simulate(scene)
        seconds = time.perf_counter() - start
        m = result.metrics
        reclaim = m.get("reclaim")
        dug = f"{reclaim['mass_t']:.0f} t | {reclaim['spill_t']:.0f} t" if reclaim else "– | –"
        print(f"| {label} | {m['travel']['position_error_max'] * 1e3:+,.1f} mm "
              f"| {np.degrees(m['slew']['position_error_max']):+.3f} deg | {np.degrees(m['luff']['position_error_max']):+.3f} deg "
              f"| {dug} | {seconds:.1f} s |")
        if scene is dig:
            args.figures.mkdir(parents=True, exist_ok=True)
            subtitle = f"heavy_dig_pile, {scene.controller.type}, seed {args.seed}"
            for path in save_reclaim_figures(result, args.figures, subtitle):
                print(f"wrote {path.relative_to(ROOT) if path.is_relative_to(ROOT) else path}")


if __name__ == "__main__":
    main()
