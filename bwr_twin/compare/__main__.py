"""Run several controllers on the same path and the same disturbance seeds, side by side.

    python -m bwr_twin.compare paper_individual_gains --controllers paper_individual_gains pid_paper \
        computed_torque_paper --seeds 4 --out out/compare
    python -m bwr_twin.compare SCENE --controllers A B ... [--seeds N] --out DIR [--overwrite] [--force]

SCENE gives the machine, the path, the timing and the disturbances; each of A, B, ... is a scene
(a file or a shipped name) whose `[controller]` table is used, labelled by its file name. Every
controller runs seeds 1..N as one lockstep.

DIR holds comparison.csv and comparison.md (per controller and axis: the worst max and the mean
RMS error, peak and RMS drive force, drive energy and time at saturation, over the seeds, in
engineering units), errors.png (seed 1 of every controller overlaid), drive_forces.png (each
controller's band from the least to the most over its seeds, and its mean) and
one run directory per controller and seed, as `bwr_twin.run` writes it without figures, for
`bwr_twin.replay`. DIR appears only when complete. Bad input exits with status 2 and one line.
"""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path

from bwr_twin.arguments import CommandParser
from bwr_twin.config.sweep import MAX_RUNS, PLANNABLE_RUNS
from bwr_twin.errors import BwrError, exit_status, leave
from bwr_twin.sim.budget import FORCE_HELP, Estimate, check_estimate, estimate


def main(argv: list[str] | None = None) -> int:
    parser = CommandParser(prog="python -m bwr_twin.compare", description=__doc__.split("\n\n")[0])
    parser.add_argument("scene", help="scene giving the path and disturbances (a file or a shipped name)")
    parser.add_argument("--controllers", nargs="+", required=True, metavar="SCENE",
                        help="scenes whose [controller] tables are compared (at least two)")
    parser.add_argument("--seeds", type=int, default=1, help="disturbance seeds 1..N for every controller")
    parser.add_argument("--out", required=True, type=Path, help="output directory")
    parser.add_argument("--overwrite", action="store_true", help="replace DIR, a comparison the twin wrote")
    parser.add_argument("--force", action="store_true", help=f"{FORCE_HELP}, or {MAX_RUNS} runs")
    args = parser.parse_args(argv)
    if args.seeds < 1:
        parser.error("--seeds must be at least 1")
    if len(args.controllers) < 2:
        parser.error("--controllers needs at least two scenes to compare")

    return exit_status(lambda: _compare(args))


def _compare(args: argparse.Namespace) -> int:
    from bwr_twin.compare.report import write_comparison
    from bwr_twin.config.scene import load_scene
    from bwr_twin.ownership import check_output
    from bwr_twin.progress import simulated_seconds
    from bwr_twin.shipped import find_scene
    from bwr_twin.sim.lockstep import simulate_grouped

    base = find_scene(args.scene)
    sources = [find_scene(name) for name in args.controllers]
    labels = [source.stem for source in sources]
    if len(set(labels)) != len(labels):
        raise BwrError(f"--controllers: two scenes share the name {_first_twice(labels)!r}; rename one")
    tables = [_plain(load_scene(source).controller.to_dict()) for source in sources]
    # One scene per controller first: the seeds change no file and no cost, so the inputs and the
    # estimate are known before thousands of scenes are built.
    firsts = [load_scene(base, {"controller": table, "simulation.seed": 1}) for table in tables]
    inputs = {file for scene in firsts for file in scene.input_files} | set(sources)
    check_output(args.out, "comparison", overwrite=args.overwrite, inputs=inputs)
    runs = len(sources) * args.seeds
    if runs > PLANNABLE_RUNS or (runs > MAX_RUNS and not args.force):
        limit = f"{PLANNABLE_RUNS:,}" if runs > PLANNABLE_RUNS else f"{MAX_RUNS:,} without --force"
        raise BwrError(f"--seeds {args.seeds}: {len(sources)} controllers x {args.seeds} seeds are {runs:,} runs, "
                       f"more than the {limit}; choose fewer --seeds")
    check_estimate(_scaled(estimate(firsts, chunk=args.seeds, force=args.force), args.seeds), where=f"{base}: --seeds {args.seeds}",
                   out_dir=args.out, force=args.force)
    groups = [[first, *(load_scene(base, {"controller": table, "simulation.seed": seed})
                        for seed in range(2, args.seeds + 1))] for first, table in zip(firsts, tables)]
    scenes = [scene for group in groups for scene in group]
    with simulated_seconds("comparing") as progress:
        outcomes = simulate_grouped(scenes, progress=progress)
    results = []
    for label, group in zip(labels, groups):
        outcome, outcomes = outcomes[: len(group)], outcomes[len(group) :]
        failed = [r for r in outcome if isinstance(r, BwrError)]
        if failed:
            raise BwrError(f"controller {label}: {failed[0]}")
        results.append(outcome)
    table = write_comparison(args.out, labels, results, overwrite=args.overwrite)
    print(table, end="")
    print(f"{len(labels)} controllers x {args.seeds} seeds on {base.name}; results in {args.out}/")
    return 0


def _scaled(cost: Estimate, seeds: int) -> Estimate:
    """The cost of every seed from that of seed 1 (the lockstep's size already in its memory)."""
    return dataclasses.replace(cost, runs=cost.runs * seeds, physics_steps=cost.physics_steps * seeds,
                               seconds=cost.seconds * seeds, disk_bytes=cost.disk_bytes * seeds)


def _plain(table: dict) -> dict:
    """A [controller] table as a scene file holds it: paths as text, per-axis values as lists."""
    return {k: str(v) if isinstance(v, Path) else list(v) if isinstance(v, tuple) else v for k, v in table.items()}


def _first_twice(labels: list[str]) -> str:
    return next(label for i, label in enumerate(labels) if label in labels[:i])


if __name__ == "__main__":
    leave(main())
