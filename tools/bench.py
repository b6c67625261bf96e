"""Speed of the closed loop against bare MuJoCo, measured in one process.

    python tools/bench.py [SCENE] [--repeat N]

Times the scene's whole run (`bwr_twin.simulate.simulate`, no file output) and a bare
`mj_step` loop over the same number of physics steps on the same model, alternating them
`--repeat` times and keeping the best of each (the machine is shared and noisy), then prints
`ratio: X` (run time over bare-loop time; target <= 10). It also prints the cost of one fuzzy
evaluation for the three axes against scikit-fuzzy's own `compute()`.
"""

from __future__ import annotations

import argparse
import sys
import time
import timeit
from pathlib import Path

import mujoco
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from bwr_twin.fuzzy import FuzzySurface, skfuzzy_compute  # noqa: E402
from bwr_twin.machine import Machine  # noqa: E402
from bwr_twin.rulebase import RuleBase  # noqa: E402
from bwr_twin.scene import load_scene  # noqa: E402
from bwr_twin.simulate import simulate  # noqa: E402


def bare_loop(mjcf: Path, timestep: float, steps: int) -> float:
    machine = Machine(mjcf)
    machine.model.opt.timestep = timestep
    data = mujoco.MjData(machine.model)
    started = time.perf_counter()
    for _ in range(steps):
        mujoco.mj_step(machine.model, data)
    return time.perf_counter() - started


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("scene", nargs="?", default=str(ROOT / "scenes" / "paper_individual_gains.toml"))
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()

    scene = load_scene(args.scene)
    simulate(scene)  # warm the fuzzy surface cache and imports
    duration = scene.trajectory.via_points[-1].t - scene.trajectory.via_points[0].t
    steps = int(round(duration / scene.simulation.timestep))
    run_times, bare_times = [], []
    for _ in range(args.repeat):
        bare_times.append(bare_loop(scene.machine.mjcf, scene.simulation.timestep, steps))
        started = time.perf_counter()
        simulate(scene)
        run_times.append(time.perf_counter() - started)
    run, bare = min(run_times), min(bare_times)
    print(f"scene: {Path(args.scene).name}, {duration:g} s simulated, {steps} physics steps of "
          f"{scene.simulation.timestep * 1e3:g} ms, control every {scene.simulation.control_period * 1e3:g} ms")
    print(f"closed-loop run: {run:.3f} s (best of {args.repeat}), {duration / run:.0f}x real time")
    print(f"bare mj_step loop: {bare:.3f} s (best of {args.repeat})")
    print(f"ratio: {run / bare:.2f}")

    rule_base = RuleBase.from_toml(scene.controller.rule_base)
    surface = FuzzySurface.load(rule_base)
    rng = np.random.default_rng(0)
    e, ec, out = rng.uniform(-3, 3, 3), rng.uniform(-3, 3, 3), np.zeros(3)
    n = 100_000
    fast = timeit.timeit(lambda: surface.evaluate(e, ec, out=out), number=n) / n
    slow = min(timeit.repeat(lambda: skfuzzy_compute(rule_base, float(e[0]), float(ec[0])), number=5, repeat=3)) / 5 * 3
    print(f"fuzzy, 3 axes per control period: compiled surface {fast * 1e6:.2f} us, "
          f"skfuzzy compute() {slow * 1e3:.1f} ms ({slow / fast:,.0f}x slower)")


if __name__ == "__main__":
    main()
