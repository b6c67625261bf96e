"""Throughput of a Monte Carlo batch, and where its time goes.

    python tools/bench_batch.py [--runs 1000] [--workers N] [--skip-breakdown]

Runs the shipped paper scene over `--runs` seeds through `python -m bwr_twin.batch` (a fresh
command in a fresh directory, no per-run figures, default workers), and prints its wall time,
runs per minute and the minutes a 1,000-seed Monte Carlo takes at that rate (target: <= 7 at a
2 ms physics step). Then, in this process, it takes one lockstep of the size the batch used
apart: MuJoCo's floor for its physics (a bare `Batch.step` per control period on one thread),
the whole lockstep, and writing its run directories, and prints the batch's time per run beside
them, so the time beyond the floor is accounted for. The machine is shared and noisy: the load
average is printed before and after.
"""

from __future__ import annotations

import argparse
import math
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from bench import floor as floor_seconds  # tools/bench.py: MuJoCo's floor, measured the same way

from bwr_twin.batch.cli import MAX_CHUNK
from bwr_twin.config.scene import load_scene
from bwr_twin.results.rundir import write_run
from bwr_twin.shipped import DEFAULT_SCENE
from bwr_twin.sim.lockstep import simulate_lockstep


def batch_command(folder: Path, runs: int, workers: int) -> float:
    """Wall time of the whole batch command, s."""
    sweep = folder / "monte_carlo.toml"
    sweep.write_text(f'scene = "{DEFAULT_SCENE}"\nseeds = {runs}\n')
    command = [sys.executable, "-m", "bwr_twin.batch", str(sweep), "--out", str(folder / "out"),
               "--workers", str(workers)]
    started = time.perf_counter()
    subprocess.run(command, check=True, stdout=subprocess.DEVNULL)
    return time.perf_counter() - started


def breakdown(folder: Path, size: int) -> dict[str, float]:
    """Seconds per run of one lockstep of `size` runs on one thread, by part."""
    scenes = [load_scene(DEFAULT_SCENE, {"simulation.seed": seed}) for seed in range(1, size + 1)]
    sim = scenes[0].simulation
    duration = scenes[0].trajectory.via_points[-1].t - scenes[0].trajectory.via_points[0].t
    floor = floor_seconds(scenes[0], size, 1, round(duration / sim.control_period) + 1)
    started = time.perf_counter()
    results = simulate_lockstep(scenes, nthread=1)
    lockstep = time.perf_counter() - started
    started = time.perf_counter()
    for i, result in enumerate(results):
        write_run(result, folder / f"run_{i}", plots=False)
    writing = time.perf_counter() - started
    return {"floor": floor / size, "lockstep": lockstep / size, "writing": writing / size}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--runs", type=int, default=1000)
    parser.add_argument("--workers", type=int, default=os.cpu_count())
    parser.add_argument("--skip-breakdown", action="store_true", help="only time the batch command")
    args = parser.parse_args()

    print(f"{os.cpu_count()} cores, load average {os.getloadavg()[0]:.2f} before; {DEFAULT_SCENE.name} "
          f"over {args.runs} seeds, {args.workers} workers, no per-run figures")
    with tempfile.TemporaryDirectory() as tmp:
        wall = batch_command(Path(tmp), args.runs, args.workers)
        print(f"batch: {wall / 60:.2f} min wall, {60 * args.runs / wall:.1f} runs/min; "
              f"a 1,000-seed Monte Carlo at this rate: {1000 * wall / args.runs / 60:.2f} min")
        if args.skip_breakdown:
            return
        size = min(MAX_CHUNK, math.ceil(args.runs / args.workers))
        parts = breakdown(Path(tmp), size)
    per_run = wall * args.workers / args.runs  # worker-seconds a run
    print(f"one lockstep of {size} runs on one thread, per run: MuJoCo floor {parts['floor']:.2f} s, "
          f"lockstep {parts['lockstep']:.2f} s ({parts['lockstep'] / parts['floor']:.2f}x the floor), "
          f"writing its run directory {parts['writing']:.2f} s")
    rest = per_run - parts["lockstep"] - parts["writing"]
    print(f"batch, per run and worker: {per_run:.2f} s = floor {parts['floor']:.2f} + control loop "
          f"{parts['lockstep'] - parts['floor']:.2f} + files {parts['writing']:.2f} + the rest {rest:.2f} "
          f"(start-up, publishing, summary, other load)")
    print(f"load average {os.getloadavg()[0]:.2f} after")


if __name__ == "__main__":
    main()
