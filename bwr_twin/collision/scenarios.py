"""Random two-machine scenarios for the anti-collision sweep (docs/anticollision.md), written as
sweep files the batch engine runs, locally or on a Dask cluster (bwr_twin.batch).

Each scenario is heavy_rail_scenario (or its interlocked twin) with a drawn schedule of the
neighbour behind the machine: at rest where it starts, then one move towards the machine along
the rail, its boom towards the rail's line and in luff, within its drives' rated speeds (its
MJCF's), started at a drawn time. It starts between the interlock's warn zone and the watch
(WATCH) clear of the machine (rejection: an interlock cannot stop machines that start in
contact, and one that starts far never meets it). The sweep crosses the drawn schedules with the
machine's own moves and with the fault classes, all from scenes/scenarios/rail_scenarios.toml: the run's lockstep is shared by the scenarios of one path and one
fault class. Every number of a scenario is drawn from the generator's seed: the same seed, the
same sweep.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from bwr_twin.collision.machines import MachineClearance
from bwr_twin.collision.monitor import WATCH
from bwr_twin.config.scene import load_scene
from bwr_twin.model.machine import Machine
from bwr_twin.ownership import write_atomically
from bwr_twin.shipped import SCENARIOS, find_scene
from bwr_twin.tomlfile import read_toml, toml_value

SCENE, INTERLOCKED = "heavy_rail_scenario", "heavy_rail_scenario_interlocked"


@dataclass(frozen=True)
class Draws:
    """What the scenarios draw from (scenes/scenarios/rail_scenarios.toml, its units and reasons)."""

    duration: float  # s of each scenario
    paths: tuple  # the machine's own moves: ((travel m, slew deg, luff deg) at 0 s, at duration), ...
    start_travel: tuple[float, float]  # m, the neighbour's start drawn within these
    start_slew: tuple[float, float]  # deg
    luff: tuple[float, float]  # deg
    move_start: tuple[float, float]  # s
    move_time: tuple[float, float]  # s
    report_delays: tuple[float, ...]  # s
    faults: tuple  # the fault classes: none, and the encoder_stuck fault

    @classmethod
    def shipped(cls) -> Draws:
        raw = read_toml(SCENARIOS / "rail_scenarios.toml", "scenario")
        machine, neighbour, faults = raw["machine"], raw["neighbour"], raw["faults"]
        return cls(duration=raw["duration"], paths=tuple(tuple(map(tuple, p)) for p in machine["paths"]),
                   **{k: tuple(neighbour[k]) for k in ("start_travel", "start_slew", "luff", "move_start",
                                                         "move_time")},
                   report_delays=tuple(faults["report_delays"]),
                   faults=((), ({"kind": "encoder_stuck", **faults["encoder_stuck"]},)))


def write_sweeps(folder: Path, schedules: int, seed: int) -> tuple[Path, Path]:
    """Two sweep files in `folder`, without and with the interlock, each of `schedules` drawn
    schedules x PATHS x REPORT_DELAYS x FAULTS runs; returns their paths."""
    draws = Draws.shipped()
    base = load_scene(find_scene(SCENE))
    machine, neighbour = Machine(base.machine.mjcf), Machine(base.neighbour.mjcf)
    drawn = draw_schedules(machine, neighbour, schedules, seed, draws)
    paths = [[{"t": 0.0, "p": machine.fk(_joints(start)).round(6).tolist()},
              {"t": draws.duration, "p": machine.fk(_joints(end)).round(6).tolist()}] for start, end in draws.paths]
    written = []
    for name in (SCENE, INTERLOCKED):
        path = folder / f"{name}_{schedules * len(draws.paths) * len(draws.report_delays) * len(draws.faults)}.toml"
        vary = {"path.via_points": paths, "neighbour.report_delay": list(draws.report_delays), "faults": list(draws.faults),
                "neighbour.schedule": drawn}
        text = (f"# {schedules} random neighbour schedules (seed {seed}) x {len(draws.paths)} paths x "
                f"{len(draws.report_delays)} report delays x {len(draws.faults)} fault classes: "
                "bwr_twin.collision.scenarios\n"
                f"scene = {toml_value(str(find_scene(name)))}\n\n[vary]\n"
                + "".join(f'"{key}" = {toml_value(value)}\n' for key, value in vary.items()))
        write_atomically(path, lambda temporary, text=text: temporary.write_text(text))
        written.append(path)
    return written[0], written[1]


def draw_schedules(machine: Machine, neighbour: Machine, count: int, seed: int, draws: Draws) -> list[list[dict]]:
    """`count` neighbour schedules, each starting between the interlock's warn zone and WATCH
    clear of the machine at the start of every one of its paths."""
    rng = np.random.default_rng(seed)
    interlocked = load_scene(find_scene(INTERLOCKED))
    clear = interlocked.interlock.warn
    checker = MachineClearance(machine, neighbour, 1, interlocked.simulation.control_period)
    rated = neighbour.rated_speed
    schedules = []
    while len(schedules) < count:
        start = np.array([rng.uniform(*draws.start_travel), rng.uniform(*draws.start_slew), rng.uniform(*draws.luff)])
        clearances = [checker.clearance_at(_joints(path[0]), _joints(start)) for path in draws.paths]
        if min(clearances) < clear or min(clearances) >= WATCH:
            continue
        begin, span = rng.uniform(*draws.move_start), rng.uniform(*draws.move_time)
        reach = span * np.degrees(rated) / 1.5  # a cubic's top speed is 1.5 x its mean
        reach[0] = span * rated[0] / 1.5
        towards_line = -np.sign(start[1]) * min(abs(start[1]), reach[1]) * rng.uniform(0, 1)
        end = start + [rng.uniform(0.2, 1.0) * reach[0], towards_line, rng.uniform(-1, 1) * reach[2]]
        end[1:] = np.clip(end[1:], [draws.start_slew[0], draws.luff[0]], [draws.start_slew[1], draws.luff[1]])
        schedules.append([{"t": 0.0, "q": _rounded(start)}, {"t": round(begin, 3), "q": _rounded(start)},
                          {"t": round(begin + span, 3), "q": _rounded(end)}])
    return schedules


def _joints(values) -> np.ndarray:
    """(3,) m, rad, rad from travel m, slew deg, luff deg."""
    return np.array([values[0], np.radians(values[1]), np.radians(values[2])])


def _rounded(q: np.ndarray) -> list[float]:
    return [round(float(v), 3) for v in q]

