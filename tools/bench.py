"""Speed of the twin against MuJoCo's own floor, each figure measured in one process.

    python tools/bench.py [--runs 128] [--threads 0] [--repeat 3] [--only NAME ...]

MuJoCo's floor is bare stepping of a physics-only copy of the machine: `Batch.step`, one call
per control period, over the same runs, physics steps and threads, with nothing in between; the
machine rests at the path's start, its weight held by constant drive forces (left to fall, it
would rest on an end stop, whose constraint makes every step dearer than the closed loop's).
Each figure alternates the measured code with its floor `--repeat` times, keeps the best of
each (the machine is shared and noisy), and prints the spread of the ratios beside it:

    floor ratio:        a lockstep of `--runs` paper runs (700 s) against its floor  (target <= 1.15),
                        then its split: MuJoCo's steps along the path (the machine moving, which
                        costs more than at rest), and the rest, the twin's own
    single-run ratio:   one paper run alone against one run's floor                   (target <= 3)
    bench-reclaim ratio: heavy_bench_reclaim alone against its floor                  (target <= 8)
    cli ratio:          `python -m bwr_twin.run SCENE --no-plots`, start to exit, warm, against one
                        run's floor: the paper run (target <= 3.5) and heavy_bench_reclaim (target <= 7)
    gym ratio:          a Gymnasium single-env step against one floor control period  (target <= 4)
    replay timeline:    s from the machine on screen to the timeline ready            (target <= 3 s)

The replay's figure needs Debian's chromium and playwright (tools/bench_replay.py).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import mujoco
import numpy as np
from mujoco.batch import Batch

from bwr_twin.batch.cli import MAX_CHUNK
from bwr_twin.config.scene import load_scene
from bwr_twin.model.machine import Machine
from bwr_twin.shipped import DEFAULT_SCENE, find_scene
from bwr_twin.sim.lockstep import Lockstep, simulate, simulate_lockstep

FIGURES = ("floor", "single-run", "bench-reclaim", "cli", "gym", "replay")


def floor(scene, runs: int, threads: int, periods: int, q0: np.ndarray) -> float:
    """Wall time of bare Batch.step calls, one per control period, s, the machine held at q0."""
    sim = scene.simulation
    machine = Machine(scene.machine.mjcf, payloads=scene.plant.payload)
    model = machine.physics_model(sim.timestep)
    data = mujoco.MjData(model)
    data.qpos[:] = q0
    mujoco.mj_forward(model, data)
    batch = Batch(model, runs, nthread=threads)
    batch.qpos[:] = data.qpos
    batch.ctrl[:, machine.actuator_ids] = data.qfrc_bias / model.actuator_gear[machine.actuator_ids, 0]
    substeps = round(sim.control_period / sim.timestep)
    started = time.perf_counter()
    for _ in range(periods):
        batch.step(nstep=substeps)
    return time.perf_counter() - started


def compare(name: str, measured, bare, repeat: int) -> tuple[float, float]:
    """Alternate `measured()` and `bare()` (each returns its own time, s) `repeat` times; print
    and return (best measured, best floor)."""
    pairs = []
    for _ in range(repeat):
        floor_time = bare()
        pairs.append((measured(), floor_time))
    best, best_floor = min(m for m, _ in pairs), min(f for _, f in pairs)
    ratios = sorted(m / f for m, f in pairs)
    scale, unit = (1e6, "us") if best_floor < 0.01 else (1.0, "s")
    print(f"{name} ratio: {best / best_floor:.2f}  (best {best * scale:.3f} {unit} against a floor of "
          f"{best_floor * scale:.3f} {unit}; ratios of the {repeat} pairs {ratios[0]:.2f}-{ratios[-1]:.2f})", flush=True)
    return best, best_floor


def timed(work) -> float:
    started = time.perf_counter()
    work()
    return time.perf_counter() - started


class StepClock:
    """Within it, the wall time spent in MuJoCo's `Batch.step`, whoever calls it (s)."""

    def __init__(self):
        self.seconds = 0.0

    def __enter__(self) -> StepClock:
        original, clock = Batch.step, self
        self._original = original

        def step(batch, *args, **kwargs):
            started = time.perf_counter()
            try:
                return original(batch, *args, **kwargs)
            finally:
                clock.seconds += time.perf_counter() - started

        Batch.step = step
        return self

    def __exit__(self, *exc) -> None:
        Batch.step = self._original


def lockstep_figure(base, args) -> None:
    scenes = [load_scene(base.path, {"simulation.seed": seed}) for seed in range(1, args.runs + 1)]
    periods, q0 = path_periods(base)
    threads = args.threads or os.cpu_count()
    print(f"{args.runs} paper runs of {(periods - 1) * base.simulation.control_period:g} s in one lockstep "
          f"on {threads} threads:")
    stepping = {}  # each measured run's wall time: its time in Batch.step

    def measured() -> float:
        with StepClock() as clock:
            elapsed = timed(lambda: simulate_lockstep(scenes, nthread=args.threads))
        stepping[elapsed] = clock.seconds
        return elapsed

    best, best_floor = compare("floor", measured, lambda: floor(base, args.runs, args.threads, periods, q0),
                               args.repeat)
    steps = periods * round(base.simulation.control_period / base.simulation.timestep)
    print(f"  {best / args.runs:.3f} s a run, {1e6 * best / (args.runs * steps):.2f} us a physics step")
    mujoco_own = stepping[best]
    print(f"  of the best: MuJoCo's steps along the path {mujoco_own:.1f} s ({mujoco_own / best_floor:.3f} x the "
          f"floor, which holds the machine at rest); the twin's own {best - mujoco_own:.1f} s "
          f"({(best - mujoco_own) / best_floor:.1%} of the floor)")


def single_figure(base, args) -> None:
    periods, q0 = path_periods(base)
    best, _ = compare("single-run", lambda: timed(lambda: simulate(base)),
                      lambda: floor(base, 1, 1, periods, q0), args.repeat)
    duration = (periods - 1) * base.simulation.control_period
    print(f"  one paper run: {duration:g} s simulated in {best:.2f} s, {duration / best:.0f}x real time")


def bench_reclaim_figure(args) -> None:
    scene = load_scene(find_scene("heavy_bench_reclaim"))
    result = simulate(scene)  # its length, and the numba caches warm
    periods = round(result.metrics["run"]["duration"] / scene.simulation.control_period) + 1
    q0 = Lockstep([scene], nthread=1, observe=False).tracking.start
    best, _ = compare("bench-reclaim", lambda: timed(lambda: simulate(scene)),
                      lambda: floor(scene, 1, 1, periods, q0), args.repeat)
    duration = result.metrics["run"]["duration"]
    print(f"  heavy_bench_reclaim: {duration:.0f} s simulated in {best:.2f} s")


# A warm start reads the modules' byte code from __pycache__, as an engineer's Python does; an
# environment that forbids writing it (PYTHONDONTWRITEBYTECODE) would compile every module each run.
_BYTE_CODE_CACHED = {key: value for key, value in os.environ.items() if key != "PYTHONDONTWRITEBYTECODE"}


def cli_figure(base, args) -> None:
    """A run as an engineer starts it, a process from start to exit (imports, scene, model,
    simulation, metrics and time series written; no figures), against the run's floor."""
    for scene in (base, load_scene(find_scene("heavy_bench_reclaim"))):
        result = simulate(scene)  # its length, and the numba caches warm
        periods = round(result.metrics["run"]["duration"] / scene.simulation.control_period) + 1
        q0 = Lockstep([scene], nthread=1, observe=False).tracking.start

        def run(scene=scene) -> float:
            with tempfile.TemporaryDirectory() as scratch:
                command = [sys.executable, "-m", "bwr_twin.run", str(scene.path), "--out", f"{scratch}/run",
                           "--no-plots"]
                started = time.perf_counter()
                subprocess.run(command, check=True, capture_output=True, env=_BYTE_CODE_CACHED)
                return time.perf_counter() - started

        run()  # warm: the byte code and the kernels' caches
        best, _ = compare(f"cli ({scene.path.stem})", run, lambda: floor(scene, 1, 1, periods, q0), args.repeat)
        print(f"  python -m bwr_twin.run {scene.path.stem} --no-plots: {best:.2f} s")


def gym_figure(base, args) -> None:
    import gymnasium

    import bwr_twin.gym  # noqa: F401  (registers the id)
    from bwr_twin.gym import ENV_ID

    env = gymnasium.make(ENV_ID, scene=str(base.path), disable_env_checker=True)
    steps, action = 5000, np.zeros(3, dtype=np.float32)
    _, q0 = path_periods(base)

    def steps_time() -> float:
        env.reset(seed=1)
        started = time.perf_counter()
        for _ in range(steps):
            env.step(action)
        return (time.perf_counter() - started) / steps

    steps_time()  # warm
    best, _ = compare("gym", steps_time, lambda: floor(base, 1, 1, steps, q0) / steps, args.repeat)
    print(f"  {1 / best:,.0f} steps/s ({1e6 * best:.1f} us a step)")


def replay_figure(args) -> None:
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from bench_replay import machine_triangles, measure

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
    from headless import chromium_context, find_chromium

    chromium = find_chromium()
    if chromium is None:
        print("replay timeline: not measured (no chromium)")
        return
    triangles = machine_triangles(DEFAULT_SCENE)
    gaps = []
    with chromium_context(chromium) as browser:
        for _ in range(args.repeat):
            page = browser.new_page()
            shown, ready = measure(page, DEFAULT_SCENE, False, triangles)
            page.close()
            gaps.append(ready - shown if ready is not None else float("inf"))
    gaps.sort()
    print(f"replay timeline: {gaps[0]:.2f} s from the machine on screen to the timeline ready "
          f"(best of {args.repeat}, spread {gaps[0]:.2f}-{gaps[-1]:.2f} s)")


def path_periods(scene) -> tuple[int, np.ndarray]:
    """The control periods of a path scene, and where it starts."""
    tracking = Lockstep([scene], nthread=1, observe=False).tracking
    return tracking.samples, tracking.start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--runs", type=int, default=MAX_CHUNK, help="runs in the lockstep (default: a batch's largest)")
    parser.add_argument("--threads", type=int, default=0, help="MuJoCo batch threads (0: all cores)")
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--only", nargs="+", choices=FIGURES, default=FIGURES)
    args = parser.parse_args()

    base = load_scene(DEFAULT_SCENE)
    simulate(base)  # warm the fuzzy surface cache, the compiled kernels and the imports
    for figure in args.only:
        if figure == "floor":
            lockstep_figure(base, args)
        elif figure == "single-run":
            single_figure(base, args)
        elif figure == "bench-reclaim":
            bench_reclaim_figure(args)
        elif figure == "cli":
            cli_figure(base, args)
        elif figure == "gym":
            gym_figure(base, args)
        else:
            replay_figure(args)


if __name__ == "__main__":
    main()
