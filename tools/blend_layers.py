"""The blend against the number of layers, on piles the twin stacks and reclaims (docs/blending.md):
heavy_chevron_stack with N layers, then heavy_stack_and_reclaim on that pile.

    python tools/blend_layers.py [--layers 16 32 64 128] [--out out/blend_layers]

The tonnes and the axis stay the scene's; the rate falls as N grows (10,000 t/h x 32 / N) so that
the passes keep the same speed, within the travel's rating. Prints a markdown table: per N, the
stacked grade's spread (per deposit and in a minute's lots), the reclaimed grade's (per bucket and
in a minute's lots), their ratios and 1/sqrt(N). Every pile and reclaim is a run directory under
--out.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from bwr_twin.config.scene import load_scene
from bwr_twin.results.rundir import PILE_FILE, write_run
from bwr_twin.shipped import find_scene
from bwr_twin.sim.lockstep import simulate
from bwr_twin.stockpile.reclaim import lot_sd

REFERENCE_LAYERS = 32  # heavy_chevron_stack's: its rate keeps their passes within the rated travel speed


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--layers", type=int, nargs="+", default=[16, 32, 64, 128])
    parser.add_argument("--out", type=Path, default=Path("out/blend_layers"))
    args = parser.parse_args()
    stacking = load_scene(find_scene("heavy_chevron_stack"))
    rows = []
    for layers in args.layers:
        rate = stacking.stacking.rate * REFERENCE_LAYERS / layers
        stacked = simulate(load_scene(find_scene("heavy_chevron_stack"),
                                      {"stacking.layers": layers, "stacking.rate": rate}))
        pile_dir = args.out / f"stack_{layers}"
        write_run(stacked, pile_dir, overwrite=True, plots=False)
        reclaimed = simulate(load_scene(find_scene("heavy_stack_and_reclaim"),
                                        {"stockpile.surface_file": str(pile_dir / PILE_FILE)}))
        write_run(reclaimed, args.out / f"reclaim_{layers}", overwrite=True, plots=False)
        blend, record = reclaimed.metrics["blend"], stacked.stacking
        per_minute = round(60.0 / stacked.scene.stacking.deposit_period)  # a minute's deposits
        lot_in = lot_sd(record.tonnes, record.grade, per_minute)
        rows.append((layers, rate, blend["grade_in_sd"], lot_in, blend["grade_out_sd"], blend["grade_out_sd_minute"],
                     blend["tonnes_out_t"]))
        print(f"N = {layers}: done", flush=True)
    print("\n| N | rate t/h | sd in, deposits | sd in, minute lots | sd out, buckets | sd out, minute lots "
          "| buckets / deposits | minute lots | 1/sqrt(N) | t reclaimed |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for layers, rate, sd_in, lot_in, sd_out, lot_out, tonnes in rows:
        print(f"| {layers} | {rate:,.0f} | {sd_in:.3f} | {lot_in:.3f} | {sd_out:.3f} | {lot_out:.3f} | "
              f"{sd_out / sd_in:.3f} | {lot_out / lot_in:.3f} | {1 / math.sqrt(layers):.3f} | {tonnes:,.0f} |")


if __name__ == "__main__":
    main()
