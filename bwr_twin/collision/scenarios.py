"""Random two-machine scenarios for the anti-collision sweep (docs/anticollision.md), written as
sweep files the batch engine runs, locally or on a Dask cluster (bwr_twin.batch).

Each scenario is heavy_rail_scenario (or its interlocked twin) with a drawn schedule of the
neighbour behind the machine: at rest where it starts, then one move towards the machine along
the rail, its boom towards the rail's line and in luff, within its drives' rated speeds (its
MJCF's), started at a drawn time. It starts between the interlock's warn zone and the watch
(WATCH) clear of the machine (rejection: an interlock cannot stop machines that start in
contact, and one that starts far never meets it). The sweep crosses the drawn schedules with the machine's own moves (PATHS) and with
the fault classes (FAULTS): the run's lockstep is shared by the scenarios of one path and one
fault class. Every number of a scenario is drawn from the generator's seed: the same seed, the
same sweep.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from bwr_twin.collision.machines import MachineClearance
from bwr_twin.collision.monitor import WATCH
from bwr_twin.config.scene import load_scene
from bwr_twin.model.machine import Machine
from bwr_twin.ownership import write_atomically
from bwr_twin.shipped import find_scene
from bwr_twin.tomlfile import toml_value

SCENE, INTERLOCKED = "heavy_rail_scenario", "heavy_rail_scenario_interlocked"
DURATION = 45.0  # s of each scenario
# The machine's own moves, joint values (travel m, slew deg, luff deg) at 0 s and at DURATION:
# slewing towards the pile's side, slewing back across the rail, travelling forward.
PATHS = (((-80.0, 0.0, 5.0), (-80.0, 20.0, 5.0)),
         ((-80.0, -10.0, 0.0), (-80.0, 10.0, 3.0)),
         ((-86.0, 0.0, 5.0), (-76.0, 0.0, 5.0)))
# The neighbour's draws: where it starts (m, deg, deg), when it moves and how long it takes (s).
START_TRAVEL, START_SLEW, LUFF = (-180.0, -115.0), (-30.0, 30.0), (-5.0, 8.0)
MOVE_START, MOVE_TIME = (1.0, 10.0), (15.0, 34.0)
# What fails: its position reported late, or the machine's slew encoder stuck for 10 s.
REPORT_DELAYS = (0.5, 2.0)  # s
FAULTS = ((), ({"kind": "encoder_stuck", "axis": "slew", "start": 15.0, "duration": 10.0},))


def write_sweeps(folder: Path, schedules: int, seed: int) -> tuple[Path, Path]:
    """Two sweep files in `folder`, without and with the interlock, each of `schedules` drawn
    schedules x PATHS x REPORT_DELAYS x FAULTS runs; returns their paths."""
    base = load_scene(find_scene(SCENE))
    machine, neighbour = Machine(base.machine.mjcf), Machine(base.neighbour.mjcf)
    drawn = draw_schedules(machine, neighbour, schedules, seed)
    paths = [[{"t": 0.0, "p": machine.fk(_joints(start)).round(6).tolist()},
              {"t": DURATION, "p": machine.fk(_joints(end)).round(6).tolist()}] for start, end in PATHS]
    written = []
    for name in (SCENE, INTERLOCKED):
        path = folder / f"{name}_{schedules * len(PATHS) * len(REPORT_DELAYS) * len(FAULTS)}.toml"
        vary = {"path.via_points": paths, "neighbour.report_delay": list(REPORT_DELAYS), "faults": list(FAULTS),
                "neighbour.schedule": drawn}
        text = (f"# {schedules} random neighbour schedules (seed {seed}) x {len(PATHS)} paths x "
                f"{len(REPORT_DELAYS)} report delays x {len(FAULTS)} fault classes: bwr_twin.collision.scenarios\n"
                f"scene = {toml_value(str(find_scene(name)))}\n\n[vary]\n"
                + "".join(f'"{key}" = {toml_value(value)}\n' for key, value in vary.items()))
        write_atomically(path, lambda temporary, text=text: temporary.write_text(text))
        written.append(path)
    return written[0], written[1]


def draw_schedules(machine: Machine, neighbour: Machine, count: int, seed: int) -> list[list[dict]]:
    """`count` neighbour schedules, each starting between the interlock's warn zone and WATCH
    clear of the machine at every PATHS start."""
    rng = np.random.default_rng(seed)
    interlocked = load_scene(find_scene(INTERLOCKED))
    clear = interlocked.interlock.warn
    checker = MachineClearance(machine, neighbour, 1, interlocked.simulation.control_period)
    rated = neighbour.rated_speed
    schedules = []
    while len(schedules) < count:
        start = np.array([rng.uniform(*START_TRAVEL), rng.uniform(*START_SLEW), rng.uniform(*LUFF)])
        clearances = [checker.clearance_at(_joints(path[0]), _joints(start)) for path in PATHS]
        if min(clearances) < clear or min(clearances) >= WATCH:
            continue
        begin, span = rng.uniform(*MOVE_START), rng.uniform(*MOVE_TIME)
        reach = span * np.degrees(rated) / 1.5  # a cubic's top speed is 1.5 x its mean
        reach[0] = span * rated[0] / 1.5
        towards_line = -np.sign(start[1]) * min(abs(start[1]), reach[1]) * rng.uniform(0, 1)
        end = start + [rng.uniform(0.2, 1.0) * reach[0], towards_line, rng.uniform(-1, 1) * reach[2]]
        end[1:] = np.clip(end[1:], [START_SLEW[0], LUFF[0]], [START_SLEW[1], LUFF[1]])
        schedules.append([{"t": 0.0, "q": _rounded(start)}, {"t": round(begin, 3), "q": _rounded(start)},
                          {"t": round(begin + span, 3), "q": _rounded(end)}])
    return schedules


def _joints(values) -> np.ndarray:
    """(3,) m, rad, rad from travel m, slew deg, luff deg."""
    return np.array([values[0], np.radians(values[1]), np.radians(values[2])])


def _rounded(q: np.ndarray) -> list[float]:
    return [round(float(v), 3) for v in q]

