"""Run one scene headless and write its results.

    python -m bwr_twin.run paper_individual_gains --out out/individual
    python -m bwr_twin.run SCENE --out DIR [--model MJCF] [--seed N] [--pile FILE] [--overwrite] [--no-plots]
                                          [--force]

SCENE is a scene file, or the name of a shipped one (scenes/).

Writes DIR/metrics.json, DIR/timeseries.csv, DIR/scene.json and the paper's figures as PNG,
then prints the maximum errors with their times. DIR appears only when complete. Bad input
exits with status 2 and a one-line message; nothing is written.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from bwr_twin.arguments import CommandParser
from bwr_twin.errors import SceneError, exit_status, leave
from bwr_twin.sim.budget import FORCE_HELP, check_estimate, estimate


def scene_overrides(model: str | None = None, seed: int | None = None, pile: str | None = None) -> dict:
    """Command-line options as scene overrides (paths relative to the cwd)."""
    overrides: dict = {}
    if model is not None:
        overrides["machine.mjcf"] = str(Path(model).resolve())
    if seed is not None:
        overrides["simulation.seed"] = seed
    if pile is not None:
        overrides["stockpile.surface_file"] = str(Path(pile).resolve())
    return overrides


def _without_pile(path: Path) -> bool:
    """Whether the scene at `path` loads and has no [stockpile] (one whose own pile is missing
    loads once --pile replaces it)."""
    from bwr_twin.config.scene import load_scene

    try:
        return load_scene(path).stockpile is None
    except SceneError:
        return False


def main(argv: list[str] | None = None) -> int:
    parser = CommandParser(prog="python -m bwr_twin.run", description=__doc__.split("\n\n")[0])
    parser.add_argument("scene", help="scene TOML file, or a shipped scene's name, e.g. paper_individual_gains")
    parser.add_argument("--out", required=True, type=Path, help="output directory (must not exist)")
    parser.add_argument("--model", help="machine MJCF replacing the scene's (and the controller's belief, "
                        "unless the scene names one)")
    parser.add_argument("--seed", type=int, help="disturbance seed replacing the scene's")
    parser.add_argument("--pile", help="the pile to reclaim, replacing the scene's windrow or surface: a survey "
                        "(.npz, .csv) or a stacking run's pile.npz")
    parser.add_argument("--overwrite", action="store_true", help="replace DIR, a run directory the twin wrote, "
                        "once the new run is complete")
    parser.add_argument("--no-plots", action="store_true", help="skip the PNG figures")
    parser.add_argument("--force", action="store_true", help=FORCE_HELP)
    args = parser.parse_args(argv)

    return exit_status(lambda: _run(args))


def _run(args: argparse.Namespace) -> int:
    from bwr_twin.config.scene import load_scene
    from bwr_twin.ownership import check_output
    from bwr_twin.progress import simulated_seconds
    from bwr_twin.results.rundir import write_run
    from bwr_twin.results.summary import summary_table
    from bwr_twin.shipped import find_scene
    from bwr_twin.sim.lockstep import simulate

    path = find_scene(args.scene)
    if args.pile is not None and _without_pile(path):
        raise SceneError(f"--pile replaces a scene's pile, and {path} has no [stockpile]")
    scene = load_scene(path, scene_overrides(args.model, args.seed, args.pile))
    check_output(args.out, "run", overwrite=args.overwrite, inputs=scene.input_files)
    cost = estimate([scene], plots=not args.no_plots, force=args.force)
    check_estimate(cost, where=scene.path, out_dir=args.out, force=args.force)
    started = time.perf_counter()
    with simulated_seconds() as progress:
        result = simulate(scene, progress=progress)
    simulated = time.perf_counter() - started
    metrics = write_run(result, args.out, overwrite=args.overwrite, plots=not args.no_plots)
    print(f"{scene.path.name}: {result.time[-1] - result.time[0]:g} s simulated in {simulated:.1f} s, "
          f"seed {scene.simulation.seed}, machine {scene.machine.mjcf.name}")
    print(summary_table(metrics))
    print(f"results in {args.out}/")
    return 0

if __name__ == "__main__":
    leave(main())
