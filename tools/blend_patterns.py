"""The blend of each stacking pattern (docs/blending.md): heavy_chevron_stack's 20,000 t stacked
as a chevron, a windrow, strata and cone shells, each pile then reclaimed as heavy_stack_and_reclaim
(the first 30 m in two benches), for several seeds.

    python tools/blend_patterns.py [--seeds 1 2] [--out out/blend_patterns]

Each pattern at the most layers the heavy stacker lays within its rated travel speed (32 chevron
passes; 5 windrow bottom rows, 15 rows; 7 strata; 8 cones). Prints a markdown table of the spread
of the grade, pooled over the seeds, as a ratio to the stream's (as tools/blend_layers.py does):
in full-face slices of the stacked pile, bucket by bucket and in minute lots as reclaimed, against
1/sqrt(N) for the N equal layers the pattern's passes amount to. Writes the numbers to --out's
blend_patterns.json.
"""

from __future__ import annotations

import argparse
import json
import math
import time
from pathlib import Path

from blend_layers import pm, pooled, stack_and_reclaim

from bwr_twin.config.scene import load_scene
from bwr_twin.shipped import find_scene

PATTERNS = {  # each within the rated 0.5 m/s travel at 10,000 t/h on 100 m (docs/blending.md)
    "chevron": {"stacking.pattern": "chevron", "stacking.layers": 32},
    "windrow": {"stacking.pattern": "windrow", "stacking.layers": 5},
    "strata": {"stacking.pattern": "strata", "stacking.layers": 7},
    "cone_shell": {"stacking.pattern": "cone_shell", "stacking.layers": 8},
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--out", type=Path, default=Path("out/blend_patterns"))
    args = parser.parse_args()
    mean = load_scene(find_scene("heavy_chevron_stack")).stacking.grade.mean  # the stream's own mean
    rows, start = [], time.perf_counter()
    for name, overrides in PATTERNS.items():
        runs = []
        for seed in args.seeds:
            runs.append(stack_and_reclaim(overrides, seed, args.out / f"{name}_seed_{seed}"))
            print(f"{name}, seed {seed}: done, {time.perf_counter() - start:.0f} s", flush=True)
        rows.append({"pattern": name, "layers": overrides["stacking.layers"], **pooled(runs, mean)})
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "blend_patterns.json").write_text(json.dumps({"stream_mean": mean, "rows": rows}, indent=1))
    print(f"\n{len(args.seeds)} seeds a row; ratios to the stream's spread per deposit, about the stream's mean "
          f"{mean:g} (± the standard error over the seeds) and (own) about the sample's own mean\n")
    print("| pattern | `layers` | N, equal layers | slices | buckets | minute lots | minute lots (own) | 1/sqrt(N) "
          "| t reclaimed a run |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for row in rows:
        n = row["equivalent_layers"]
        law = "-" if math.isnan(n) else f"{1 / math.sqrt(n):.3f}"
        print(f"| {row['pattern']} | {row['layers']} | {n:.1f} | {pm(row, 'slices')} | {pm(row, 'buckets')} | "
              f"{pm(row, 'lots')} | {row['lots_own']:.3f} | {law} | {row['tonnes_out']:,.0f} |")


if __name__ == "__main__":
    main()
