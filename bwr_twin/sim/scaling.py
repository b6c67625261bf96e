"""What in a scene scales the work besides its duration over its timestep, counted from the
scene's numbers before anything is planned, built or allocated (bwr_twin.sim.budget adds it up).

Each `Part` names the key it scales with, what it counts and what that costs: CPU seconds and
bytes of memory a run. A part with a `limit` is a count the twin refuses beyond without `--force`
(`check_counts`): the passes a plan will make, the faults of a run. The rest (the stacking's
grid, the rings of late readings, of the neighbour's reports and of the interlock's encoder
window) weigh in the estimate's time and memory, and a refusal names the largest of them.

The costs were measured on the 2-core reference machine (docs/performance.md), rounded up.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from bwr_twin.config.scene import Scene
from bwr_twin.errors import BwrError
from bwr_twin.planning.patterns import extent
from bwr_twin.planning.stacking import pile_grid

# Planning, a pass: a bench reclaim's (its IK, the cut predicted on the planner's copy of the pile;
# 10,000 passes took 17 s) and a stacking's (its IK and turn; 1,000,000 passes took 40 s and 0.87 GB).
RECLAIM_PASS_S = 1.7e-3
STACKING_PASS_S = 40e-6
PASS_BYTES = 1_000
MAX_PASSES = 5_000  # a plan's passes: a 120 m pile of three benches at 0.1 m a pass is 3,600

# A [[faults]] table: 100,000 took 64 s and 1.5 GB (its schedule, its checks, its line of output).
FAULT_S = 0.7e-3
FAULT_BYTES = 16_000
MAX_FAULTS = 1_000  # a run's faults without --force: the shipped scenarios schedule a handful

# The stacking's deposit: 1.5 ms (tools/relaxation_speed.py: about 1 ms on 47,500 cells of 0.5 m), and
# its relaxation, whose moves grow with the cells and whose rounds with the cells a face spans: a cell
# and (0.5 m / spacing)^2, measured on heavy_chevron_stack of 2,000 t (2,880 deposits) at 0.5, 0.125 and
# 0.0625 m: 11 s, 51 s and more than 400 s a run.
DEPOSIT_S = 1.5e-3
DEPOSIT_CELL_S = 1.2e-8
DEPOSIT_SPACING = 0.5  # m
LAYER_BYTES = 16  # a layer's thickness and grade, float64, a cell
RELAXATION_CELL_BYTES = 64  # the heights and the relaxation's work arrays, a cell

# Rings a run holds, a control period of each: late readings (q and qd of 3 axes, float64: 22.4 GiB
# for 1e9 periods), the neighbour's reports (joints and speeds twice), the encoder window's
# readings and integrated speeds.
LATE_PERIOD_BYTES = 24
REPORT_PERIOD_BYTES = 48
WINDOW_PERIOD_BYTES = 48

# The export of a fuzzy control surface's table (bwr_twin.export.plc --grid): skfuzzy's inference
# of a point (145 x 145 points and their cell centres took 7 s and 50 MB), and its text.
SURFACE_POINT_S = 0.17e-3
SURFACE_POINT_BYTES = 1_400
SURFACE_POINT_TEXT = 20
MAX_SURFACE_POINTS = 250_000  # as fis surface: a table a PLC holds (the twin's is 145 x 145)


@dataclass(frozen=True)
class Part:
    """What one key of a scene (or one option) scales: `count` of `what`, costing `seconds` of
    CPU and `bytes` of memory a run; beyond `limit` (if any) refused without --force."""

    key: str
    what: str
    count: float
    seconds: float
    bytes: float
    limit: float | None = None

    def describe(self) -> str:
        count = f"{self.count:,.0f}" if self.count < 1e9 else f"{self.count:.3g}"
        return f"'{self.key}' gives {count} {self.what}"


def plan_passes(scene: Scene) -> Part | None:
    """The passes the scene's bench reclaim or stacking will plan, counted before planning."""
    if scene.reclaim is not None:
        r, pile = scene.reclaim, scene.stockpile
        each = max(int(round(r.bench_length / r.cut_depth)), 1)
        if r.stop.benches is not None:
            benches = r.stop.benches
        elif pile is not None and pile.windrow is not None:
            benches = max(math.ceil(pile.windrow.height / r.bench_height), 1)
        else:
            benches = 1  # a survey's pile: its height is read as the plan is made
        passes = benches * each
        key = "reclaim.cut_depth" if each >= benches else "reclaim.bench_height"
        return Part(key, f"passes ({benches} bench(es) of 'bench_length' / 'cut_depth' = {each})", passes,
                    passes * RECLAIM_PASS_S, passes * PASS_BYTES, MAX_PASSES)
    if scene.stacking is not None:
        s = scene.stacking
        n = s.layers
        if s.pattern == "windrow":
            passes = n * (n + 1) / 2
        elif s.pattern == "strata":
            passes = n * max(1, round(2 * extent(s)[1] / s.row_spacing))
        else:
            passes = n
        return Part("stacking.layers", f"passes of the {s.pattern} pattern", passes, passes * STACKING_PASS_S,
                    passes * PASS_BYTES, MAX_PASSES)
    return None


def counted(scene: Scene) -> list[Part]:
    """The parts with a limit: the passes of its plan and its faults, none needing it planned."""
    found = []
    passes = plan_passes(scene)
    if passes is not None:
        found.append(passes)
    if scene.faults:
        n = len(scene.faults)
        found.append(Part("faults", "[[faults]] tables", n, n * FAULT_S, n * FAULT_BYTES, MAX_FAULTS))
    return found


def parts(scene: Scene, duration: float) -> list[Part]:
    """What scales in `scene` besides its physics, for a run of `duration` s."""
    found = counted(scene)
    period = scene.simulation.control_period
    for number, fault in enumerate(scene.faults):
        if fault.kind == "late_inputs" and fault.periods is not None:
            found.append(Part(f"faults[{number}].periods", "control periods of late readings held", fault.periods,
                              0.0, fault.periods * LATE_PERIOD_BYTES))
    if scene.neighbour is not None:
        held = scene.neighbour.report_delay / period
        found.append(Part("neighbour.report_delay", "control periods of the neighbour's reports held", held, 0.0,
                          held * REPORT_PERIOD_BYTES))
    if scene.interlock is not None:
        held = scene.interlock.encoder_window / period
        found.append(Part("interlock.encoder_window", "control periods of encoder readings held", held, 0.0,
                          held * WINDOW_PERIOD_BYTES))
    if scene.stacking is not None:
        s = scene.stacking
        x, y = pile_grid(s)
        cells = float(len(x)) * float(len(y))
        deposits = duration / s.deposit_period
        found.append(Part("stacking.grid_spacing", "cells of the stacked pile", cells,
                          deposits * (DEPOSIT_S + DEPOSIT_CELL_S * cells * (DEPOSIT_SPACING / s.grid_spacing) ** 2),
                          cells * (s.max_layers * LAYER_BYTES + RELAXATION_CELL_BYTES)))
    return found


def check_counts(scenes, *, force: bool = False) -> None:
    """BwrError, naming the scene, the key, the count, the limit and its cost, for the first scene
    whose plan or faults count beyond their limit (unless `force`): before anything is planned."""
    if force:
        return
    for scene in scenes:
        for part in counted(scene):
            if part.count > part.limit:
                raise BwrError(f"{scene.path}: {part.describe()}, more than {part.limit:,.0f} a run takes "
                               f"without --force: about {duration_text(part.seconds)} and {bytes_text(part.bytes)} for them "
                               "alone; pass --force to go on")


def surface_points(grid: int) -> Part:
    """A fuzzy control surface tabled on `grid` x `grid` points, and its cell centres."""
    points = float(grid) ** 2 + float(grid - 1) ** 2
    return Part("--grid", "points of the control surface", points, points * SURFACE_POINT_S,
                points * SURFACE_POINT_BYTES, MAX_SURFACE_POINTS)


def check_surface_grid(grid: int | None, step: int) -> None:
    """BwrError naming --grid, its points, the limit and the cost, for a table beyond the limit;
    `step` is the rule base's grid step (a grid is k x step + 1)."""
    if grid is None or grid < 2:
        return
    part = surface_points(grid)
    if part.count > part.limit:
        largest = max(1, int((math.sqrt(part.limit / 2) - 1) // step)) * step + 1
        raise BwrError(f"--grid {grid}: {part.count:.3g} points of the control surface, beyond the limit of "
                       f"{part.limit:,.0f} points: about {duration_text(part.seconds)}, {bytes_text(part.bytes)} "
                       f"of memory and {bytes_text(part.count * SURFACE_POINT_TEXT)} of Structured Text; the "
                       f"largest --grid within it is {largest}")


def duration_text(seconds: float) -> str:
    if seconds < 120:
        return f"{seconds:.0f} s"
    if seconds < 2 * 3600:
        return f"{seconds / 60:.0f} min"
    if seconds < 2 * 86400:
        return f"{seconds / 3600:.1f} h"
    days = seconds / 86400
    return f"{days:.3g} days" if days < 1000 else f"{days:,.0f} days"


def bytes_text(count: float) -> str:
    for unit in ("B", "kB", "MB", "GB", "TB"):
        if count < 1000 or unit == "TB":
            return f"{count:.3g} {unit}" if unit != "B" else f"{count:.0f} B"
        count /= 1000
    raise AssertionError("unreachable")
