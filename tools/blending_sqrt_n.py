"""The sqrt(N) table in docs/blending.md: sigma_out / sigma_in of ideal chevron piles of N layers,
reclaimed in full-face slices, against 1 / sqrt(N) (bwr_twin.stockpile.blending).

    python tools/blending_sqrt_n.py [--slices 250] [--repeats 4] [--seed 1] [--correlation-time 0]

Prints a markdown table. --correlation-time (in slices, the time the stacker takes to lay one)
makes the input's grade correlated, to show what that does to the blend.
"""

from __future__ import annotations

import argparse
import math
import time

from bwr_twin.stockpile.blending import blend

LAYERS = (16, 32, 64, 128)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--slices", type=int, default=250)
    parser.add_argument("--repeats", type=int, default=4)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--correlation-time", type=float, default=0.0)
    args = parser.parse_args()
    last_seed = args.seed + args.repeats - 1
    print(f"{args.repeats} piles x {args.slices} slices a row, seeds {args.seed} to {last_seed}, "
          f"input correlation time {args.correlation_time:g} slices\n")
    print("| N layers | 1 / sqrt(N) | the grid's layer masses give | sigma_out / sigma_in | x sqrt(N) "
          "| time |")
    print("| --- | --- | --- | --- | --- | --- |")
    for layers in LAYERS:
        start = time.perf_counter()
        result = blend(layers, args.slices, args.repeats, args.seed, correlation_time=args.correlation_time)
        seconds = time.perf_counter() - start
        print(f"| {layers} | {1 / math.sqrt(layers):.4f} | {result.expected:.4f} | {result.ratio:.4f} "
              f"| {result.ratio * math.sqrt(layers):.3f} | {seconds:.1f} s |")


if __name__ == "__main__":
    main()
