"""The stacking target of docs/blending.md: heavy_chevron_stack, 20,000 t stacked by the heavy
stacker at 10,000 t/h (7,200 s simulated), against 5 minutes of this machine.

    python tools/stacking_speed.py [--scene heavy_chevron_stack]

Simulates the scene once (after a first run of two minutes of it, to compile the kernels) and
prints the simulated time, the wall and CPU time against the target and the simulated time,
and the balances.
"""

from __future__ import annotations

import argparse
import time

from bwr_twin.config.scene import load_scene
from bwr_twin.shipped import find_scene
from bwr_twin.sim.lockstep import simulate

TARGET_S = 300.0  # s of wall time for the 20 kt pile (the target)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scene", default="heavy_chevron_stack")
    args = parser.parse_args()
    scene = load_scene(find_scene(args.scene))
    small = scene.stacking.rate / 30.0  # t of two minutes' stream on a 20 m axis: compiles every kernel
    middle = sum(scene.stacking.axis_x) / 2
    simulate(load_scene(find_scene(args.scene), {"stacking.tonnes": small, "stacking.layers": 1,
                                                 "stacking.axis_x": [middle - 10.0, middle + 10.0]}))

    wall, cpu = time.perf_counter(), time.process_time()
    result = simulate(scene)
    wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    simulated = float(result.time[-1])
    metrics = result.metrics["stacking"]
    print(f"{args.scene}: {metrics['tonnes_in_t']:,.0f} t in {metrics['layers']} layers, {simulated:,.0f} s simulated")
    print(f"wall {wall:.1f} s ({wall / TARGET_S:.2f} of the {TARGET_S:g} s target), CPU {cpu:.1f} s; "
          f"{simulated / wall:.0f}x real time")
    print(f"balance: tonnes {metrics['balance_relative']:.1e}, tonnes x grade {metrics['grade_balance_relative']:.1e}; "
          f"steepest slope {metrics['slope_excess_m']:.1e} m above the talus")


if __name__ == "__main__":
    main()
