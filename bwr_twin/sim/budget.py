"""What a run or a batch will cost, estimated from its scenes before anything starts, and the
bounds beyond which the twin refuses to start without `--force`.

Every command that simulates a scene (run, batch, compare, tune, replay, serve, export fmu, a
Gymnasium environment) calls `estimate` and `check_estimate`, or `check_scenes`, which does
both. The estimate counts what a scene's plan and faults will make before anything is planned
(bwr_twin.sim.scaling: refused beyond their counts), then adds up the physics steps, the control
periods, the pile, the stacking's grid, the rings a run holds and the records; a refusal names the
key that weighs most in the bound it breaks.

The costs per physics step, per control period and per run directory were measured on the
2-core reference machine (docs/performance.md); the estimate is meant to tell minutes from days
and megabytes from terabytes, not to be exact.
"""

from __future__ import annotations

import math
import os
import shutil
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from bwr_twin.config.plugins import controller_class
from bwr_twin.config.scene import Scene
from bwr_twin.errors import BwrError
from bwr_twin.pile.surface import cell_count
from bwr_twin.planning.stacking import pile_grid
from bwr_twin.sensing.outputs import HIT_BYTES, SCAN_BYTES, SURVEY_CELL_BYTES
from bwr_twin.sensing.scanning import planned_scanners
from bwr_twin.signals import csv_columns, recorded_values
from bwr_twin.sim.scaling import LAYER_BYTES, Part, bytes_text, check_counts, duration_text, parts
from bwr_twin.units import SECONDS_PER_HOUR

# Measured costs (docs/performance.md), rounded up.
STEP_S = 3.8e-6  # s of CPU per physics step of one run (MuJoCo's floor: 1.33 s for 350,000 steps)
PERIOD_PER_RUN_S = 8e-6  # s per control period and run: encoders, controller, records
PERIOD_PER_LOCKSTEP_S = 75e-6  # s per control period of a lockstep, whatever its size: numpy call overheads
FILES_S = 0.2  # s to write one run directory
PLOTS_S = 3.0  # s to draw one run's figures
CSV_VALUE_BYTES = 13  # of timeseries.csv per value: 10 significant digits, sign, exponent, comma
RUN_FILES_BYTES = 8_000  # metrics.json and scene.json
PLOTS_BYTES = 700_000  # one run's PNG figures
SAMPLE_BYTES = 13 * 8  # the path sampled at the control period: time, q, qd, qdd, CP
PILE_PERIOD_S = 150e-6  # s per control period and run with a stockpile: the cut and its accounting
PILE_CELL_BYTES = 8  # a run's pile heights in memory, per cell
PILE_FILE_CELL_BYTES = 8  # pile.npz per cell: z_start and z_end, compressed
# s per ray a scanner casts, with its noise and its cell of the scanned pile, and per scan and run
# besides: docs/sensing.md measures 40 us a scan of 191 rays in heavy_bench_reclaim's loop.
SCAN_RAY_S = 0.3e-6
SCAN_S = 15e-6

# Bounds a command refuses to go beyond without --force.
MAX_HOURS = 12.0  # of CPU on the workers: an overnight run, not a week
MAX_MEMORY_SHARE = 0.5  # of this machine's RAM, all workers' locksteps together
MAX_DISK_SHARE = 0.9  # of the free space where the results go
# An argparse help text, where a percent sign is written %%.
FORCE_HELP = (f"start even if the estimate exceeds {MAX_HOURS:g} h, {100 * MAX_MEMORY_SHARE:.0f}%% of the "
              f"memory or {100 * MAX_DISK_SHARE:.0f}%% of the free disk")


@dataclass(frozen=True)
class Estimate:
    """The cost of simulating some runs, split into locksteps of at most `chunk` runs on `workers`."""

    runs: int
    physics_steps: float  # all runs together
    seconds: float  # wall time on the workers
    memory_bytes: float  # peak, all workers' locksteps together
    disk_bytes: float  # the run directories
    slowest: Part | None = None  # of what scales, by the key it scales with: the most CPU a run
    largest: Part | None = None  # ... and the most memory a run

    def describe(self) -> str:
        return (f"{self.runs} run{'s' if self.runs != 1 else ''}, {self.physics_steps:.3g} physics steps, "
                f"about {duration_text(self.seconds)}, {bytes_text(self.memory_bytes)} of memory and "
                f"{bytes_text(self.disk_bytes)} of results")


def estimate(scenes: Sequence[Scene], *, workers: int = 1, chunk: int = 1, plots: bool = False,
             force: bool = False) -> Estimate:
    """The cost of simulating `scenes` in locksteps of `chunk` runs on `workers` processes.
    Refuses (BwrError) a plan or faults beyond their counts before planning, unless `force`."""
    check_counts(scenes, force=force)
    steps = periods = cpu = pile_cells_written = disk = 0.0
    peak_lockstep = 0.0
    slowest = largest = None
    for scene in scenes:
        sim = scene.simulation
        duration = _duration_of(scene)
        run_periods = duration / sim.control_period + 1
        run_steps = duration / sim.timestep
        run_rows = duration / sim.record_period + 1
        cells = cell_count(scene.stockpile, scene.path) if scene.stockpile is not None else 0
        layer_bytes = 0.0
        if scene.stacking is not None:  # a pile of layers in pile.npz
            x, y = pile_grid(scene.stacking)
            layer_bytes = len(x) * len(y) * scene.stacking.max_layers * LAYER_BYTES
        scaled = parts(scene, duration)  # the plan, faults, rings and the stacking's grid
        scan_bytes, scan_cpu = _scans(scene, duration, cells)
        disk += scan_bytes
        cpu += scan_cpu
        # What a run records a row (bwr_twin.signals): float64 values in memory, CSV columns on disk.
        declared = tuple(getattr(controller_class(scene.controller.type), "signals", ()))
        groups = {"reclaim": scene.stockpile is not None, "neighbour": scene.neighbour is not None}
        row_values = recorded_values(declared, **groups)
        scaled += [Part("simulation.timestep", f"physics steps ({duration:.3g} s of run at {sim.timestep:g} s)",
                        run_steps, run_steps * STEP_S, 0.0),
                   Part(_duration_key(scene), f"s of run ({run_periods:.3g} control periods sampled and "
                        f"{run_rows:.3g} rows recorded)", duration,
                        run_periods * (PERIOD_PER_RUN_S + PERIOD_PER_LOCKSTEP_S / chunk),
                        run_periods * SAMPLE_BYTES + run_rows * row_values * 8)]
        for part in scaled:
            slowest = part if part.seconds > (slowest.seconds if slowest else 0.0) else slowest
            largest = part if part.bytes > (largest.bytes if largest else 0.0) else largest
        disk += run_rows * csv_columns(declared, **groups) * CSV_VALUE_BYTES
        steps += run_steps
        periods += run_periods
        pile_cells_written += cells
        cpu += run_steps * STEP_S + run_periods * (PERIOD_PER_RUN_S + PERIOD_PER_LOCKSTEP_S / chunk)
        cpu += run_periods * PILE_PERIOD_S if cells else 0.0
        cpu += sum(part.seconds for part in scaled[:-2])
        disk += layer_bytes
        cpu += FILES_S + (PLOTS_S if plots else 0.0)
        held = sum(part.bytes for part in scaled[:-2])  # the plan's, the rings', the stacking grid's
        peak_lockstep = max(peak_lockstep, run_periods * SAMPLE_BYTES
                            + chunk * (run_rows * row_values * 8 + cells * PILE_CELL_BYTES + scan_bytes + held))
    runs = len(scenes)
    parallel = max(1, min(workers, math.ceil(runs / chunk)))
    disk += runs * (RUN_FILES_BYTES + (PLOTS_BYTES if plots else 0))
    disk += pile_cells_written * PILE_FILE_CELL_BYTES
    return Estimate(runs, steps, cpu / parallel, parallel * peak_lockstep, disk, slowest, largest)


def _scans(scene: Scene, duration: float, cells: int) -> tuple[float, float]:
    """Bytes a run's scans and scanned pile take (the same in memory as in scans.npz and
    survey.npz), and the s of CPU its scanners cost; 0 for a run that does not scan."""
    scanners = planned_scanners(scene)
    if not scanners:
        return 0.0, 0.0
    size, cpu = cells * SURVEY_CELL_BYTES, 0.0
    for scanner in scanners:
        scans = duration * min(scanner.rate, 1.0 / scene.simulation.control_period) + 1
        size += scans * (scanner.rays * HIT_BYTES + SCAN_BYTES)
        cpu += scans * (scanner.rays * SCAN_RAY_S + SCAN_S)
    return size, cpu


def _duration_of(scene: Scene) -> float:
    """s the scene's run may take: its path's, or the longest its bench plan may take."""
    if scene.reclaim is not None:
        from bwr_twin.planning.bench import plan_scene

        return plan_scene(scene).longest_duration
    if scene.stacking is not None:  # the stream runs until the tonnes are laid
        return scene.stacking.tonnes / scene.stacking.rate * SECONDS_PER_HOUR
    via = scene.trajectory.via_points
    return via[-1].t - via[0].t


def check_estimate(cost: Estimate, *, where: Path | str, out_dir: Path, force: bool) -> None:
    """Refuse (BwrError naming `where`, the bound and the estimate) work beyond the bounds,
    unless `force`."""
    if force:
        return
    limits, weighs = [], []
    if cost.seconds > MAX_HOURS * 3600:
        limits.append(f"more than {MAX_HOURS:g} h")
        weighs.append(cost.slowest)
    memory = os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    if cost.memory_bytes > MAX_MEMORY_SHARE * memory:
        limits.append(f"more than {MAX_MEMORY_SHARE:.0%} of the {bytes_text(memory)} of memory")
        weighs.append(cost.largest)
    free = shutil.disk_usage(_existing(out_dir)).free
    if cost.disk_bytes > MAX_DISK_SHARE * free:
        limits.append(f"more than the {bytes_text(free)} free on disk")
    if limits:
        most = "".join(f"; most of it {_weight(part)}" for part in dict.fromkeys(weighs) if part is not None)
        raise BwrError(f"{where}: would take {' and '.join(limits)}: {cost.describe()}{most}; "
                       "check the timestep, the via point times and the sweep, or pass --force")


def check_scenes(scenes: Sequence[Scene], *, where: Path | str, out_dir: Path, force: bool, workers: int = 1,
                 chunk: int = 1, plots: bool = False) -> Estimate:
    """The one estimate of every command: `estimate` (its counts first), then `check_estimate`."""
    cost = estimate(scenes, workers=workers, chunk=chunk, plots=plots, force=force)
    check_estimate(cost, where=where, out_dir=out_dir, force=force)
    return cost


def _duration_key(scene: Scene) -> str:
    """The key a run's duration comes from."""
    if scene.reclaim is not None:
        return "reclaim.stop"
    if scene.stacking is not None:
        return "stacking.tonnes"
    return "path.via_points"


def _weight(part: Part) -> str:
    cost = [f"{duration_text(part.seconds)} a run"] if part.seconds else []
    cost += [f"{bytes_text(part.bytes)} of memory a run"] if part.bytes else []
    return f"{part.describe()}, {' and '.join(cost)}"


def _existing(path: Path) -> Path:
    path = path.resolve()
    while not path.exists():
        path = path.parent
    return path
