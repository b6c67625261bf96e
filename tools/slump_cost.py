"""What slumping costs a reclaim (docs/stockpile.md): heavy_stack_and_reclaim with its
`stockpile.angle_of_repose`, the cut faces slumping after every cut, against the same reclaim
with the faces left standing, in one process, one after the other.

    python tools/slump_cost.py [--pile out/chevron/pile.npz] [--repeat 1]

The pile is a stacking run's pile.npz (python -m bwr_twin.run heavy_chevron_stack --out
out/chevron). Prints each run's CPU time, the ratio, the m^3 that slumped and the tonnes reclaimed.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from bwr_twin.config.scene import load_scene
from bwr_twin.shipped import find_scene
from bwr_twin.sim.lockstep import simulate


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pile", type=Path, default=Path("out/chevron/pile.npz"))
    parser.add_argument("--repeat", type=int, default=1, help="pairs of runs; the least CPU time of each side")
    args = parser.parse_args()
    pile = {"stockpile.surface_file": str(args.pile.resolve())}
    sides = {"slumping": pile, "standing": {**pile, "stockpile.angle_of_repose": None}}
    simulate(load_scene(find_scene("heavy_stack_and_reclaim"), {**pile, "reclaim.stop": {"time": 30.0}}))  # compile
    best, results = {}, {}
    for _ in range(args.repeat):
        for name, overrides in sides.items():
            start = time.process_time()
            results[name] = simulate(load_scene(find_scene("heavy_stack_and_reclaim"), overrides))
            best[name] = min(best.get(name, float("inf")), time.process_time() - start)
    for name, result in results.items():
        reclaim = result.metrics["reclaim"]
        print(f"{name}: {best[name]:.1f} s CPU for {result.time[-1]:.0f} s simulated, {reclaim['mass_t']:,.0f} t "
              f"reclaimed, {reclaim.get('slumped_m3', 0.0):,.0f} m3 slumped")
    print(f"slumping costs {best['slumping'] / best['standing']:.2f} x the reclaim with standing faces")


if __name__ == "__main__":
    main()
