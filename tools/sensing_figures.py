"""The sensing figures of docs/sensing.md: the ray cast's speed, what the boom's scanner costs
heavy_bench_reclaim, and how well the pile known from its scans holds the truth.

    python tools/sensing_figures.py [--repeat 3] [--seed 1]

Rays a second: the heavy scanner's fans, from where heavy_bench_reclaim's machine stands every
0.1 s of its first 400 s, cast against its windrow (`bwr_twin.sensing.raycast.cast_rays`, one
compiled call); and a whole scan in the loop (pose, rays, noise, the scanned pile), per scan.
Run time: heavy_bench_reclaim alone with and without its scanner (`[sensing] scanners = false`),
alternated `--repeat` times, the best of each kept, in CPU seconds of this process (the machine is
shared: its other work lengthens wall time far more than CPU time), with the spread of the pairs'
ratios and the wall times beside them. The scanned pile: its tonnes against the truth as the wheel first
cut and at the end, from the run's metrics.json `scan` object.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from bwr_twin.config.scene import load_scene
from bwr_twin.pile.surface import build_surface
from bwr_twin.sensing.raycast import cast_rays
from bwr_twin.shipped import find_scene
from bwr_twin.sim.lockstep import Lockstep, simulate


def rays_figure(seed: int) -> None:
    scene = load_scene(find_scene("heavy_bench_reclaim"), {"simulation.seed": seed, "reclaim.stop": {"time": 400.0},
                                                           "sensing.scanners": False})
    run = simulate(scene)
    surface = build_surface(scene.stockpile, scene.path)
    scanner = run.machine.scanners[0]
    position, rotation = scanner.mount.poses(run.q)
    directions = np.einsum("nij,rj->nri", rotation, scanner.directions).reshape(-1, 3)
    origins = np.repeat(position, scanner.rays, axis=0)
    cast_rays(surface.z, surface.x, surface.y, origins[:10], directions[:10], scanner.max_range)  # compiled
    started = time.perf_counter()
    distances = cast_rays(surface.z, surface.x, surface.y, origins, directions, scanner.max_range)
    seconds = time.perf_counter() - started
    print(f"ray cast, each ray walked whole: {len(origins):,} rays ({len(run.q):,} scans of {scanner.rays}) in "
          f"{seconds:.3f} s: {len(origins) / seconds / 1e6:.1f} million rays a second, "
          f"{np.mean(~np.isnan(distances)):.0%} hit")

    loop = Lockstep([load_scene(find_scene("heavy_bench_reclaim"), {"simulation.seed": seed})], nthread=1,
                    observe=False)
    scanning, heights = loop.scanning, loop.reclaim.cutter.heights
    q = np.ascontiguousarray(run.q)
    scanning.step(0, q[:1], heights, None)  # compiled
    started = time.perf_counter()
    for k in range(1, len(q)):
        scanning.step(k * 4, q[k:k + 1], heights, None)  # every 4th control period: a scan each
    seconds = (time.perf_counter() - started) / (len(q) - 1)
    print(f"a scan in the loop (the site's pose, {scanner.rays} rays walked along the section, noise, the "
          f"scanned pile): {1e6 * seconds:.0f} us, {scanner.rays / seconds / 1e6:.1f} million rays a second")


def run_time_figure(seed: int, repeat: int) -> dict:
    name = "heavy_bench_reclaim"
    with_scanner = load_scene(find_scene(name), {"simulation.seed": seed})
    without = load_scene(find_scene(name), {"simulation.seed": seed, "sensing.scanners": False})
    result = simulate(with_scanner)  # the numba caches warm
    simulate(without)
    pairs = []  # (CPU s, wall s) with the scanner, and without
    for _ in range(repeat):
        bare = _timed(lambda: simulate(without))
        pairs.append((_timed(lambda: simulate(with_scanner)), bare))
    duration = result.metrics["run"]["duration"]
    for clock, label in ((0, "CPU"), (1, "wall")):
        best, best_bare = min(p[0][clock] for p in pairs), min(p[1][clock] for p in pairs)
        ratios = sorted(m[clock] / b[clock] for m, b in pairs)
        print(f"{name} ({duration:,.0f} s simulated), {label} time: {best:.2f} s with its scanner, {best_bare:.2f} s "
              f"without: {best / best_bare:.2f}x (the {repeat} pairs {ratios[0]:.2f}-{ratios[-1]:.2f}x)")
    return result.metrics


def _timed(work) -> tuple[float, float]:
    """CPU and wall seconds `work()` takes."""
    cpu, wall = time.process_time(), time.perf_counter()
    work()
    return time.process_time() - cpu, time.perf_counter() - wall


def survey_figure(metrics: dict) -> None:
    scan = metrics["scan"]
    print(f"scans {scan['scans']:,}, rays {scan['rays']:,}, {scan['hit_share']:.1%} hit, "
          f"{scan['dropped_share']:.2%} of those that met the pile dropped")
    print("| heavy_bench_reclaim | scanned | true (the cells seen) | error | whole pile | footprint seen |")
    print("| --- | --- | --- | --- | --- | --- |")
    for label, row in ((f"as the wheel first cut ({scan['first_cut']['time_s']:.1f} s)", scan["first_cut"]),
                       ("at the end", scan)):
        print(f"| {label} | {row['scanned_t']:,.0f} t | {row['true_t']:,.0f} t | {row['error_share']:+.2%} "
              f"| {row['pile_t']:,.0f} t | {row['footprint_seen_share']:.1%} |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args()
    rays_figure(args.seed)
    survey_figure(run_time_figure(args.seed, args.repeat))


if __name__ == "__main__":
    main()
