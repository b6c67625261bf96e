"""How far the exported lookup table is from the rule base's own Mamdani inference.

    python tools/surface_error.py [--points 1000000] [--grid N]

Draws random (e, ec) over the input universes and compares the control surface the twin evaluates,
and the PLC export carries (bwr_twin.control.fuzzy.FuzzySurface: skfuzzy on a grid, four triangles a
cell), with skfuzzy's Mamdani inference at each point, in blocks. Prints the largest and the RMS
difference, in the output universe and as a share of the output range.
"""

from __future__ import annotations

import argparse
import time

from tqdm import tqdm

from bwr_twin.control.fuzzy import FuzzySurface, surface_error
from bwr_twin.control.rulebase import RuleBase
from bwr_twin.shipped import RULE_BASES


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--points", type=int, default=1_000_000)
    parser.add_argument("--grid", type=int, default=None, help="grid points per input (default: the twin's)")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    rule_base = RuleBase.from_toml(RULE_BASES / "paper_table2.toml")
    surface = FuzzySurface.load(rule_base, grid_points=args.grid)
    started = time.perf_counter()
    with tqdm(total=args.points, unit=" points", desc="skfuzzy") as bar:
        largest, rms = surface_error(surface, args.points, args.seed, bar.update)
    width = rule_base.output_range[1] - rule_base.output_range[0]
    print(f"{args.points:,} random inputs, a {surface.values.shape[0]} x {surface.values.shape[0]} grid, "
          f"in {time.perf_counter() - started:.0f} s")
    print(f"largest difference {largest:.5f} ({100 * largest / width:.3f} % of the output range), "
          f"RMS {rms:.5f} ({100 * rms / width:.4f} %)")


if __name__ == "__main__":
    main()
