"""Speed of the lockstep engine against MuJoCo's own floor, measured in one process.

    python tools/bench.py [SCENE] [--runs 128] [--threads 0] [--repeat 2]

Runs the scene over `--runs` seeds as one lockstep (`simulate_lockstep`, no file output) and,
alternating with it, MuJoCo's floor for the same work: a bare `Batch.step` of a physics-only
copy of the machine over the same runs, physics steps and threads, one call per control period,
with nothing in between. Keeps the best of `--repeat` of each (the machine is shared and noisy)
and prints `floor ratio: X` (lockstep time over floor time; target <= 1.3). Then prints the time
of a single run (a lockstep of one) and the cost of one fuzzy evaluation against scikit-fuzzy's
own `compute()`.
"""

from __future__ import annotations

import argparse
import os
import time
import timeit

import mujoco
import numpy as np
from mujoco.batch import Batch

from bwr_twin.batch.cli import MAX_CHUNK
from bwr_twin.config.scene import load_scene
from bwr_twin.control.fuzzy import FuzzySurface, skfuzzy_compute
from bwr_twin.control.rulebase import RuleBase
from bwr_twin.model.machine import Machine
from bwr_twin.planning.trajectory import Trajectory
from bwr_twin.shipped import DEFAULT_SCENE
from bwr_twin.sim.lockstep import simulate, simulate_lockstep


def floor(scene, runs: int, threads: int, periods: int) -> float:
    """Wall time of bare Batch.step calls, one per control period, s: the machine at the path's
    start, its weight held by constant drive forces (left to fall, it would rest on an end
    stop, whose constraint makes every step dearer than the closed loop's)."""
    sim = scene.simulation
    machine = Machine(scene.machine.mjcf, payloads=scene.plant.payload)
    model = machine.physics_model(sim.timestep)
    data = mujoco.MjData(model)
    data.qpos[:] = Trajectory.plan(scene.trajectory, machine).knots[0]
    mujoco.mj_forward(model, data)
    batch = Batch(model, runs, nthread=threads)
    batch.qpos[:] = data.qpos
    batch.ctrl[:, machine.actuator_ids] = data.qfrc_bias / model.actuator_gear[machine.actuator_ids, 0]
    substeps = round(sim.control_period / sim.timestep)
    started = time.perf_counter()
    for _ in range(periods):
        batch.step(nstep=substeps)
    return time.perf_counter() - started


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("scene", nargs="?", default=str(DEFAULT_SCENE))
    parser.add_argument("--runs", type=int, default=MAX_CHUNK, help="runs in the lockstep (default: a batch's largest)")
    parser.add_argument("--threads", type=int, default=0, help="MuJoCo batch threads (0: all cores)")
    parser.add_argument("--repeat", type=int, default=2)
    args = parser.parse_args()

    base = load_scene(args.scene)
    scenes = [load_scene(args.scene, {"simulation.seed": seed}) for seed in range(1, args.runs + 1)]
    sim = base.simulation
    duration = base.trajectory.via_points[-1].t - base.trajectory.via_points[0].t
    periods = round(duration / sim.control_period) + 1
    simulate(base)  # warm the fuzzy surface cache and imports
    lockstep_times, floor_times = [], []
    for _ in range(args.repeat):
        floor_times.append(floor(base, args.runs, args.threads, periods))
        started = time.perf_counter()
        simulate_lockstep(scenes, nthread=args.threads)
        lockstep_times.append(time.perf_counter() - started)
    lockstep, bare = min(lockstep_times), min(floor_times)
    steps = periods * round(sim.control_period / sim.timestep)
    threads = args.threads or os.cpu_count()
    print(f"scene: {base.path.name}, {duration:g} s simulated, {steps} physics steps of "
          f"{sim.timestep * 1e3:g} ms a run, control every {sim.control_period * 1e3:g} ms; "
          f"{args.runs} runs in one lockstep on {threads} threads")
    print(f"lockstep: {lockstep:.2f} s (best of {args.repeat}), {lockstep / args.runs:.3f} s a run, "
          f"{1e6 * lockstep / (args.runs * steps):.2f} us a physics step")
    print(f"floor, bare Batch.step: {bare:.2f} s, {1e6 * bare / (args.runs * steps):.2f} us a physics step")
    print(f"floor ratio: {lockstep / bare:.2f}")

    started = time.perf_counter()
    simulate(base)
    single = time.perf_counter() - started
    print(f"single run (a lockstep of one): {single:.2f} s, {duration / single:.0f}x real time")

    rule_base = RuleBase.from_toml(base.controller.settings.rule_base)
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
