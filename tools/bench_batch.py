"""Speed of batch runs: a 16-run batch through `python -m bwr_twin.batch` against one run.

    python tools/bench_batch.py [--runs 16] [--plots]

Times one run of the individual-gains paper scene (700 s reclaim: `simulate` plus `write_run`)
in this process, then the same scene over `--runs` seeds as a batch with 1 and with 2 local
workers, each a fresh command in a fresh directory, so process start-up counts. Prints the
throughput (runs per minute), the speed-up of 2 workers over 1 and over running the runs one
after another (target >= 1.7x), and the batch's overhead per run: the 1-worker batch's time per
run beyond one run's own time (target <= 10 % of a run), in wall time and in CPU time. Other work
on the machine skews the wall times (the load average is printed with them); CPU times much less.
"""

from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

from bwr_twin.config.scene import load_scene
from bwr_twin.results.rundir import write_run
from bwr_twin.shipped import DEFAULT_SCENE
from bwr_twin.sim.lockstep import simulate

SCENE = DEFAULT_SCENE


def one_run(folder: Path, plots: bool) -> tuple[float, float]:
    """Wall and CPU time of one run in this process, s: what a batch worker does for each run."""
    started, cpu = time.perf_counter(), time.process_time()
    write_run(simulate(load_scene(SCENE)), folder, plots=plots)
    return time.perf_counter() - started, time.process_time() - cpu


def children_cpu() -> float:
    """CPU time of every finished child process and its own children, s."""
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def batch(folder: Path, runs: int, workers: int, plots: bool) -> tuple[float, float]:
    """Wall and CPU time of the whole batch command (its workers included), s."""
    sweep = folder / f"bench_{workers}.toml"
    sweep.write_text(f'scene = "{SCENE}"\nseeds = {runs}\n')
    command = [sys.executable, "-m", "bwr_twin.batch", str(sweep), "--out", str(folder / f"out_{workers}"),
               "--workers", str(workers), *([] if plots else ["--no-plots"])]
    started, cpu = time.perf_counter(), children_cpu()
    subprocess.run(command, cwd=ROOT, check=True, stdout=subprocess.DEVNULL)
    return time.perf_counter() - started, children_cpu() - cpu


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--runs", type=int, default=16)
    parser.add_argument("--plots", action="store_true", help="write each run's PNG figures, as the batch does by default")
    args = parser.parse_args()

    print(f"{os.cpu_count()} cores, load average {os.getloadavg()[0]:.2f} before; "
          f"{SCENE.name}, {'with' if args.plots else 'without'} per-run plots")
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        one_run(folder / "warm-up", args.plots)  # imports and the fuzzy surface cache
        single, single_cpu = min(one_run(folder / f"single_{i}", args.plots) for i in range(2))
        serial, serial_cpu = batch(folder, args.runs, 1, args.plots)
        parallel, parallel_cpu = batch(folder, args.runs, 2, args.plots)
    n = args.runs
    print(f"one run:            {single:6.2f} s wall, {single_cpu:6.2f} s CPU (best of 2)")
    print(f"batch, 1 worker:    {serial:6.1f} s wall, {serial_cpu:6.1f} s CPU for {n} runs, {60 * n / serial:5.1f} runs/min")
    print(f"batch, 2 workers:   {parallel:6.1f} s wall, {parallel_cpu:6.1f} s CPU for {n} runs, {60 * n / parallel:5.1f} runs/min")
    print(f"speed-up, 2 workers: {serial / parallel:.2f}x over 1 worker, "
          f"{n * single / parallel:.2f}x over {n} runs one after another (target >= 1.7x)")
    for label, total, run in (("wall", serial, single), ("CPU", serial_cpu, single_cpu)):
        overhead = total / n - run
        print(f"overhead per run ({label}): {overhead:5.2f} s, {100 * overhead / run:.1f} % of a run (target <= 10 %)")
    print(f"load average {os.getloadavg()[0]:.2f} after")


if __name__ == "__main__":
    main()
