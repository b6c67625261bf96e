"""The blend of each stacking pattern (docs/blending.md): heavy_chevron_stack's 20,000 t stacked
as a chevron, a windrow, strata and cone shells, each pile then reclaimed as heavy_stack_and_reclaim
(the first 30 m in two benches), for several seeds.

    python tools/blend_patterns.py [--seeds 1 2] [--out out/blend_patterns] [--redraw]

Each pattern at the most layers the heavy stacker lays within its rated travel speed (32 chevron
passes; 5 windrow bottom rows, 15 rows; 7 strata; 8 cones). Prints a markdown table of the spread
of the grade, pooled over the seeds, as a ratio to the stream's (as tools/blend_layers.py does):
in full-face slices of the stacked pile, bucket by bucket and in minute lots as reclaimed, against
1/sqrt(N) for the N equal layers the pattern's passes amount to. Writes the numbers to --out's
blend_patterns.json and draws them into blend_patterns.png (the figure in docs/blending.md);
--redraw does both again from the numbers, without running.
"""

from __future__ import annotations

import json
import math
import time

import numpy as np
from blend_layers import pm, pooled, saved_numbers, stack_and_reclaim, study_parser
from matplotlib.figure import Figure

from bwr_twin.config.scene import load_scene
from bwr_twin.results.summary import pattern_text
from bwr_twin.shipped import find_scene

PATTERNS = {  # each within the rated 0.5 m/s travel at 10,000 t/h on 100 m (docs/blending.md)
    "chevron": {"stacking.pattern": "chevron", "stacking.layers": 32},
    "windrow": {"stacking.pattern": "windrow", "stacking.layers": 5},
    "strata": {"stacking.pattern": "strata", "stacking.layers": 7},
    "cone_shell": {"stacking.pattern": "cone_shell", "stacking.layers": 8},
}


def main() -> None:
    args = study_parser(__doc__.splitlines()[0], [1, 2], "out/blend_patterns").parse_args()
    numbers, saved = saved_numbers(args, "blend_patterns.json")
    if saved is not None:
        mean, rows = saved["stream_mean"], saved["rows"]
    else:
        mean = load_scene(find_scene("heavy_chevron_stack")).stacking.grade.mean  # the stream's own mean
        rows, start = [], time.perf_counter()
        for name, overrides in PATTERNS.items():
            runs = []
            for seed in args.seeds:
                runs.append(stack_and_reclaim(overrides, seed, args.out / f"{name}_seed_{seed}"))
                print(f"{name}, seed {seed}: done, {time.perf_counter() - start:.0f} s", flush=True)
            rows.append({"pattern": name, "layers": overrides["stacking.layers"], **pooled(runs, mean)})
        args.out.mkdir(parents=True, exist_ok=True)
        numbers.write_text(json.dumps({"stream_mean": mean, "rows": rows}, indent=1))
    print(f"\n{len(rows[0]['seeds'])} seeds a row; ratios to the stream's spread per deposit, about the stream's mean "
          f"{mean:g} (± the standard error over the seeds) and (own) about the sample's own mean\n")
    print("| pattern | `layers` | N, equal layers | slices | buckets | minute lots | minute lots (own) | 1/sqrt(N) "
          "| t reclaimed a run |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for row in rows:
        n = row["equivalent_layers"]
        law = "-" if math.isnan(n) else f"{1 / math.sqrt(n):.3f}"
        print(f"| {row['pattern']} | {row['layers']} | {n:.1f} | {pm(row, 'slices')} | {pm(row, 'buckets')} | "
              f"{pm(row, 'lots')} | {row['lots_own']:.3f} | {law} | {row['tonnes_out']:,.0f} |")
    _figure(rows).savefig(args.out / "blend_patterns.png", dpi=110)
    print(f"\nfigure: {args.out / 'blend_patterns.png'}; numbers: {numbers}")


def _figure(rows: list[dict]) -> Figure:
    """Each pattern's ratios side by side, its law a bar's width of black line above them."""
    fig = Figure(figsize=(8.5, 5), layout="constrained")
    ax = fig.subplots()
    width = 0.25
    for i, (key, colour, label) in enumerate((("slices", "C2", "the stacked pile, full-face slices"),
                                              ("buckets", "C0", "bench-reclaimed, bucket by bucket"),
                                              ("lots", "C1", "bench-reclaimed, lots of a minute"))):
        ax.bar(np.arange(len(rows)) + (i - 1) * width, [row[key] for row in rows], width,
               yerr=[row[key + "_se"] for row in rows], capsize=3, color=colour, label=label)
    for k, row in enumerate(rows):
        n = row["equivalent_layers"]
        if not math.isnan(n):
            ax.hlines(1 / math.sqrt(n), k - 1.5 * width, k + 1.5 * width, colors="k", linestyles="--",
                      label="1/sqrt(N), N the equal layers its passes amount to" if k == 0 else None)
    ax.set_xticks(np.arange(len(rows)), [pattern_text(row["pattern"], row["layers"]) for row in rows])
    ax.set_ylim(0.0, 1.0)
    ax.set_ylabel("sigma_out / sigma_in, about the stream's mean")
    ax.grid(alpha=0.3, axis="y")
    ax.legend(fontsize=8, loc="upper center", ncols=2)
    ax.set_title(f"The blend of each pattern: 20,000 t stacked, the first 30 m reclaimed in two benches "
                 f"({len(rows[0]['seeds'])} seeds each;\nbars: the standard error over them)", fontsize=10)
    return fig


if __name__ == "__main__":
    main()
