"""The cost of the clearance checks (docs/anticollision.md): a scene with its checks (the shapes
against the pile, and against the neighbour's where it has one) against the same scene with the
checks taken out, alternated, the best of each kept.

    python tools/bench_collision.py [--scene heavy_bench_reclaim] [--repeat 3]
    python tools/bench_collision.py --scene heavy_two_machines

Run times are CPU seconds of this process: the machine is shared, and its other work lengthens
wall time far more than CPU time. Also prints how often the shapes were measured (the rest of the
periods their clearance was bounded by the machine's motion, bwr_twin.collision.monitor).
"""

from __future__ import annotations

import argparse
import time
from unittest import mock

from bwr_twin.collision.machines import MachineClearance
from bwr_twin.collision.monitor import PileClearance
from bwr_twin.config.scene import load_scene
from bwr_twin.shipped import find_scene
from bwr_twin.sim.lockstep import simulate


def timed(scene, checks: bool) -> float:
    """CPU seconds of one run, with or without the clearance checks (their steps made no-ops)."""
    with (mock.patch.object(PileClearance, "step", PileClearance.step if checks else _skip),
          mock.patch.object(MachineClearance, "step", MachineClearance.step if checks else _skip)):
        started = time.process_time()
        simulate(scene)
        return time.process_time() - started


def _skip(*_args) -> None:
    """A clearance check taken out."""


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scene", default="heavy_bench_reclaim")
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    scene = load_scene(find_scene(args.scene))
    simulate(scene)  # compiled kernels loaded
    pairs = [(timed(scene, True), timed(scene, False)) for _ in range(args.repeat)]
    best_with, best_without = min(p[0] for p in pairs), min(p[1] for p in pairs)
    ratios = [a / b for a, b in pairs]
    collision = simulate(scene).metrics.get("collision")
    print(f"{args.scene}: with the clearance checks {best_with:.2f} s, without {best_without:.2f} s CPU "
          f"(best of {args.repeat}); ratio {best_with / best_without:.2f} (pairs {min(ratios):.2f}-{max(ratios):.2f}; "
          "target <= 1.3)")
    if collision is not None:
        print(f"shapes measured against the pile in {collision['measured_periods']:,} of {collision['periods']:,} "
              "control periods; least clearances: "
              + ", ".join(f"{part} {v['clearance_m']:.2f} m" for part, v in collision["pile"].items()))
        if "machines" in collision:
            pair, least = min(collision["machines"].items(), key=lambda item: item[1]["clearance_m"])
            print(f"... against the neighbour in {collision['machine_measured_periods']:,}; least {pair} "
                  f"{least['clearance_m']:.2f} m")

if __name__ == "__main__":
    main()
