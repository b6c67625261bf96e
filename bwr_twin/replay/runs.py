"""The runs one replay shows: run directories, and the run directories that a `compare` or a
`batch` output folder holds, narrowed by `--runs`; at most MAX_RUNS of them, and of one machine
and path unless they stand side by side. Each refusal is one BwrError that names the folder or
the option and what is wrong.
"""

from __future__ import annotations

import csv
import fnmatch
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from bwr_twin.errors import BwrError
from bwr_twin.replay.recording import Plan, Recording, path_difference

MAX_RUNS = 8  # machines in one scene: each has its own colour, trail and chart lines
NAMES_SHOWN = 4  # run names an error lists before "..."
SAME_POINT = 1e-6  # m: a bench plan's via points closer than this are the same
COMPARISON_FILE = "comparison.csv"  # bwr_twin.compare's table, its controllers in their order
SEED_SUFFIX = "-seed="  # a comparison's run directory: <controller>-seed=<n>


@dataclass(frozen=True)
class Run:
    """A run as the replay shows it: its recording and the name the chooser gives it."""

    recording: Recording
    name: str  # its run directory's name (or, while it is simulated, its scene's)

    @property
    def label(self) -> str:
        """The name and the controller: "pid_paper-seed=1 (pid)"."""
        controller = self.recording.controller
        return f"{self.name} ({controller})" if controller else self.name


def run_folders(source: Path) -> list[Path]:
    """`source` if it is a run directory; else the run directories it holds (a compare or a batch
    output folder), a batch's failed runs left out, in the order its comparison lists the
    controllers (a batch's, by name: its sweep's order); [source] when it holds none, so that
    reading it says what is missing."""
    from bwr_twin.results.rundir import SCENE_FILE, TIMESERIES_FILE

    if not source.is_dir() or (source / TIMESERIES_FILE).is_file():
        return [source]
    held = sorted(folder for folder in source.iterdir()
                  if (folder / TIMESERIES_FILE).is_file() and (folder / SCENE_FILE).is_file())
    controllers = _compared_controllers(source / COMPARISON_FILE)
    rank = {name: i for i, name in enumerate(controllers)}
    held.sort(key=lambda folder: rank.get(folder.name.rsplit(SEED_SUFFIX, 1)[0], len(rank)))  # stable: seeds in order
    return held or [source]


def _compared_controllers(table: Path) -> list[str]:
    """The controllers of a comparison's table, in its order; none if there is no table."""
    if not table.is_file():
        return []
    with table.open(newline="") as rows:
        return list(dict.fromkeys(row.get("controller", "") for row in csv.DictReader(rows)))


def choose_runs(sources: Sequence[Path], patterns: Sequence[str] = (), *, also: int = 0) -> list[Path]:
    """The run directories of `sources` (see `run_folders`) whose names match one of `patterns`
    (shell globs; all of them without patterns), checked to be at least one and, with `also`
    runs shown beside them, at most MAX_RUNS."""
    unique: dict[Path, Path] = {}  # resolved: as first named; a folder named twice is shown once
    for folder in (folder for source in sources for folder in run_folders(source)):
        unique.setdefault(folder.resolve(), folder)
    folders = list(unique.values())
    where = ", ".join(str(source) for source in sources) or "the sources given"
    if patterns:
        chosen = [folder for folder in folders if any(fnmatch.fnmatchcase(folder.name, p) for p in patterns)]
        if not chosen:
            raise BwrError(f"--runs {','.join(patterns)}: matches none of the {len(folders)} runs in {where} "
                           f"({_names(folders)})")
        folders = chosen
    if len(folders) + also > MAX_RUNS:
        option = f"--runs {','.join(patterns)}" if patterns else where
        raise BwrError(f"{option}: {len(folders) + also} runs, more than the {MAX_RUNS} one replay shows; "
                       f"choose at most {MAX_RUNS - also} with --runs NAME,... (names or globs)")
    return folders


def load_runs(folders: Sequence[Path]) -> list[Run]:
    """Read each run directory; runs of the same name in different folders are told apart by the folder's."""
    names = [folder.name for folder in folders]
    return [Run(Recording.from_run_dir(folder),
                name if names.count(name) == 1 else f"{folder.parent.name}/{name}")
            for folder, name in zip(folders, names)]


def check_one_world(plans: Sequence[Plan], folders: Sequence[Path | str]) -> None:
    """Refuse, naming the folder, a run of another machine or path than the first's: such runs
    cannot share one scene (`--side-by-side` sets them apart)."""
    for plan, folder in zip(plans[1:], folders[1:]):
        differs = world_difference(plan, plans[0])
        if differs:
            raise BwrError(f"{folder}: not the machine and path of {folders[0]}: {differs}; "
                           "--side-by-side shows them apart")


def world_difference(plan: Plan, first: Plan) -> str:
    """What keeps two runs out of one scene: another machine file, or another path (`path_difference`);
    of two bench reclaims, other stages or other via points (each reaches them at its own times).
    "" if they share one."""
    mine, theirs = plan.machine.path.resolve(), first.machine.path.resolve()
    if mine != theirs:
        return f"machine {mine} against {theirs}"
    if not (plan.via_stages or first.via_stages):
        return path_difference(plan, first)
    stages, first_stages = _bench_stages(plan), _bench_stages(first)
    if stages != first_stages:
        return f"bench plan stages {', '.join(stages)} against {', '.join(first_stages)}"
    count = len(stages)  # the last via point is where each run stopped
    for i, (p, q) in enumerate(zip(plan.via_points[:count], first.via_points[:count])):
        if not np.allclose(p, q, atol=SAME_POINT):
            return (f"via point {i + 1} at ({', '.join(f'{v:.6g}' for v in p)}) m against "
                    f"({', '.join(f'{v:.6g}' for v in q)}) m, in world coordinates")
    return ""


def _bench_stages(plan: Plan) -> list[str]:
    """A bench plan's stages before its end, as "bench 1", "pass 2", "move"."""
    return [stage.name or stage.kind for stage in plan.via_stages if stage.kind != "end"]


def _names(folders: Sequence[Path]) -> str:
    names = [folder.name for folder in folders[:NAMES_SHOWN]]
    return ", ".join(names) + (", ..." if len(folders) > NAMES_SHOWN else "")
