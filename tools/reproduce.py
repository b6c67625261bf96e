"""Reproduce the paper's results: run both paper scenes, copy their figures into docs/figures/
and print the comparison table of docs/reproduction.md.

    python tools/reproduce.py [--out out/reproduction] [--seeds 1 2 3]
"""

from __future__ import annotations

import argparse
import shutil
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

from bwr_twin.config.scene import load_scene
from bwr_twin.model.machine import AXES, UNITS, to_display
from bwr_twin.results.rundir import write_run
from bwr_twin.shipped import SCENES
from bwr_twin.sim.lockstep import simulate_lockstep

PAPER_SCENES = ("paper_shared_gain", "paper_individual_gains")
FIGURES = ("positions.png", "errors_position.png", "errors_velocity.png", "errors_acceleration.png", "fuzzy_outputs.png", "cp_path.png")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, default=ROOT / "out" / "reproduction")
    parser.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3])
    args = parser.parse_args()

    for name in PAPER_SCENES:
        print(f"\n### {name} (seeds {', '.join(map(str, args.seeds))})\n")
        print("| axis | position error max | at t | velocity error max | acceleration error max | position error RMS |")
        print("| --- | --- | --- | --- | --- | --- |")
        scenes = [load_scene(SCENES / f"{name}.toml", {"simulation.seed": seed}) for seed in args.seeds]
        results = simulate_lockstep(scenes)  # the seeds of a scene run together
        for result in results:
            if isinstance(result, Exception):
                raise SystemExit(f"error: {result}")
        run_dir = args.out / name
        write_run(results[0], run_dir, overwrite=True)
        figures = ROOT / "docs" / "figures" / name
        figures.mkdir(parents=True, exist_ok=True)
        for figure in FIGURES:
            shutil.copy(run_dir / figure, figures / figure)
        runs = [result.metrics for result in results]
        for j, axis in enumerate(AXES):
            unit = UNITS[j]

            def span(key, per="", sign="+"):
                values = [to_display(j, m[axis][key]) for m in runs]
                return f"{min(values):{sign}.3g} to {max(values):{sign}.3g} {unit}{per}"

            times = [m[axis]["position_error_max_time"] for m in runs]
            print(f"| {axis} | {span('position_error_max')} | {min(times):.0f}–{max(times):.0f} s | "
                  f"{span('velocity_error_max', '/s')} | {span('acceleration_error_max', '/s²')} | "
                  f"{span('position_error_rms', sign='')} |")
    print(f"\nfigures of seed {args.seeds[0]} in docs/figures/, full runs in {args.out}/")


if __name__ == "__main__":
    main()
