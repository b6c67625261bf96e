"""The stages of a control period: each part of the world the loop steps, behind one small interface.

A scene's stages are built once, in order, by `bwr_twin.sim.assembly`. In each control period k
the loop (bwr_twin.sim.lockstep) calls, stage after stage:

1. `measure(k, row)`: as the encoders are read, before the controller computes; what the
   automation measures and hears (the encoders, their faults, the neighbour's report, the
   interlock's decision);
2. `world(k, row)`: before the physics step, with the true state at the period's start; the
   world's forces on the machine and what senses it (disturbances, scans, the stacking stream,
   the cut and the belt, the instruments);
3. `drives(k, applied)`: the (runs, 3) forces the drives apply where they do not apply the
   command (a quick stop, a tripped drive);
4. `stepped(k, row)`: after the physics step, with the period's end state;

then, once the runs have ended, `finish(k)`, and for each run `metrics(run, metrics)` and
`result(run, result, recorder)`, which add the stage's share to the run's metrics.json and
RunResult. A stage implements only the hooks it needs; the loop calls only those.

The world models themselves (bwr_twin.stockpile, bwr_twin.sensing, bwr_twin.collision) know
nothing of the loop and keep no results: the stages here bind them to it, and their accounts
(bwr_twin.stockpile.reclaim_account, bwr_twin.sensing.scan_account) keep what they did. What
only watches, the clearance monitors, is no stage but an observer (bwr_twin.sim.watchers).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import numpy as np

from bwr_twin.collision.guard import Guard
from bwr_twin.config.scene import Scene
from bwr_twin.sensing.faults import Faults
from bwr_twin.sensing.rate_instruments import RateInstruments
from bwr_twin.sensing.scan_account import ScanAccount
from bwr_twin.sensing.scanning import Scanning
from bwr_twin.sim.block import Row
from bwr_twin.sim.disturbances import Disturbances
from bwr_twin.sim.encoders import Encoders
from bwr_twin.sim.fault_report import fault_metrics
from bwr_twin.sim.neighbour import Neighbour
from bwr_twin.sim.plant import Plant
from bwr_twin.sim.plant_faults import PlantFaults
from bwr_twin.sim.record import ReclaimRecord, Recorder, RunResult
from bwr_twin.stockpile.reclaim import Reclaim
from bwr_twin.stockpile.reclaim_account import ReclaimAccount
from bwr_twin.stockpile.stacking import Stacking


class Stage:
    """One part of the control period; every hook does nothing unless a stage overrides it."""

    def measure(self, k: int, row: Row) -> None:
        pass

    def world(self, k: int, row: Row) -> None:
        pass

    def drives(self, k: int, applied: np.ndarray) -> None:
        pass

    def stepped(self, k: int, row: Row) -> None:
        pass

    def finish(self, k: int) -> None:
        """The runs have ended after `k` control periods."""

    def metrics(self, run: int, metrics: dict) -> None:
        """Add this stage's sections to `run`'s metrics."""

    def result(self, run: int, result: RunResult, recorder: Recorder) -> None:
        """Add this stage's records to `run`'s result (its metrics are `result.metrics`)."""


class Hooks(NamedTuple):
    """For each hook, the stages that implement it, in the stages' order."""

    measure: tuple[Stage, ...]
    world: tuple[Stage, ...]
    drives: tuple[Stage, ...]
    stepped: tuple[Stage, ...]
    finish: tuple[Stage, ...]
    metrics: tuple[Stage, ...]
    result: tuple[Stage, ...]

    @classmethod
    def of(cls, stages: Sequence[Stage]) -> Hooks:
        return cls(*(tuple(s for s in stages if getattr(type(s), hook) is not getattr(Stage, hook))
                     for hook in cls._fields))


class EncoderReading(Stage):
    """What the encoders read of the true state."""

    def __init__(self, encoders: Encoders):
        self._encoders = encoders

    def measure(self, k: int, row: Row) -> None:
        self._encoders.measure(row.q, row.qd, row.q_measured, row.qd_measured)


class OwnReferences(Stage):
    """Each run's own reference (a bench plan's, or a path paced by an interlock) changes in
    place: the record keeps the period's, before the interlock moves it on."""

    def __init__(self, tracking):
        self._tracking = tracking

    def stepped(self, k: int, row: Row) -> None:
        for rows, value in zip(row.reference, self._tracking.now()):
            rows[...] = value


class EncoderFaults(Stage):
    """The controller sees what faulty encoders show (bwr_twin.sensing.faults)."""

    def __init__(self, faults: Faults):
        self._faults = faults

    def measure(self, k: int, row: Row) -> None:
        self._faults.measured(k, row.q_measured, row.qd_measured)


class DisturbanceForces(Stage):
    """The random disturbance forces on the joints, and the gusts on the mean wind."""

    def __init__(self, disturbances: Disturbances):
        self._forces, self._gusts = disturbances.forces, disturbances.gusts

    def world(self, k: int, row: Row) -> None:
        row.disturbance[...] = self._forces.sample(k)
        if self._gusts.active:  # still air leaves the row's zeros
            row.gust[...] = self._gusts.sample(k)


class NeighbourMachine(Stage):
    """A second machine on the rail: what the automation hears of it, and its record."""

    def __init__(self, neighbour: Neighbour, plant: Plant):
        self._neighbour, self._plant = neighbour, plant

    def measure(self, k: int, row: Row) -> None:
        self._neighbour.hear(k, self._plant.neighbour_q, self._plant.neighbour_qd)

    def world(self, k: int, row: Row) -> None:
        row.neighbour[1][...] = self._plant.neighbour_q  # where it stands as the period starts

    def stepped(self, k: int, row: Row) -> None:
        row.neighbour[0][...] = self._neighbour.q_reference  # ... and the schedule it held


class ScanningStage(Stage):
    """The boom's scanners on the pile as dug until this period (bwr_twin.sensing.scanning), and
    their account's notes of the scanned pile (bwr_twin.sensing.scan_account)."""

    def __init__(self, scanning: Scanning, account: ScanAccount, reclaim: Reclaim, plant: Plant,
                 survey_end: int | None, duration: float):
        self._scanning, self._account, self._reclaim, self._plant = scanning, account, reclaim, plant
        self._survey_end, self._duration, self._period = survey_end, duration, scanning.period

    def world(self, k: int, row: Row) -> None:
        heights, account = self._reclaim.heights, self._account
        if self._scanning.step(k, row.q, heights, self._plant.alive) and account.awaiting_first_cut:
            account.note_first_cut(k * self._period, self._reclaim.dug > 0, heights)

    def stepped(self, k: int, row: Row) -> None:
        if k + 1 == self._survey_end:  # the survey has ended: the benches are planned on the pile scanned
            self._account.note_plan_start((k + 1) * self._period, self._reclaim.heights)

    def metrics(self, run: int, metrics: dict) -> None:
        metrics["scan"] = self._account.metrics(run, self._reclaim.heights[run])

    def result(self, run: int, result: RunResult, recorder: Recorder) -> None:
        result.scan = self._account.record(run, self._duration)


class StackingStage(Stage):
    """The stream lands where the stacker's discharge point stands (bwr_twin.stockpile.stacking)."""

    def __init__(self, stacking: Stacking, plant: Plant):
        self._stacking, self._plant = stacking, plant

    def world(self, k: int, row: Row) -> None:
        self._stacking.step(k, row.q, self._plant.alive)

    def metrics(self, run: int, metrics: dict) -> None:
        metrics["stacking"] = self._stacking.metrics(run)

    def result(self, run: int, result: RunResult, recorder: Recorder) -> None:
        result.stacking = self._stacking.record(run)


class ReclaimStage(Stage):
    """The wheel's cut, the bucket and the belt, and the digging load on the joints
    (bwr_twin.stockpile.reclaim); its account keeps what they did (bwr_twin.stockpile.reclaim_account)."""

    def __init__(self, reclaim: Reclaim, account: ReclaimAccount, plant: Plant):
        self._reclaim, self._account, self._plant = reclaim, account, plant

    def world(self, k: int, row: Row) -> None:
        reclaim = self._reclaim
        load = reclaim.step(k, row.q, self._plant.alive)
        if load is not None:
            np.add(row.disturbance, load, out=row.disturbance)  # the row is a record of views: write in place
        self._account.observe(k)
        rows = row.reclaim
        rows["rate"][...], rows["cut_depth"][...] = reclaim.rate, reclaim.depth
        rows["wheel_power"][...], rows["digging_force"][...] = reclaim.power, reclaim.force

    def finish(self, k: int) -> None:
        self._reclaim.finish(k - 1)
        self._account.finish(k - 1)

    def metrics(self, run: int, metrics: dict) -> None:
        metrics["reclaim"] = self._account.metrics(run)
        if self._reclaim.stacked is not None:
            metrics["blend"] = self._account.blend_metrics(run)

    def result(self, run: int, result: RunResult, recorder: Recorder) -> None:
        account = self._account
        result.reclaim = ReclaimRecord(**recorder.reclaim_share(run), **account.pile(run),
                                       grade_out=account.grade_out(run))


class RateInstrumentReading(Stage):
    """The belt scale and the wheel motor's current read the cut's rate and power (bwr_twin.sensing.rate_instruments)."""

    def __init__(self, instruments: RateInstruments, reclaim: Reclaim, faults: Faults):
        self._instruments, self._reclaim, self._faults = instruments, reclaim, faults

    def world(self, k: int, row: Row) -> None:
        instruments, faults = self._instruments, self._faults
        instruments.read(k, self._reclaim.rate, self._reclaim.power, faults.active and faults.scale_frozen(k))
        row.reclaim["belt_scale"][...] = instruments.belt_scale
        row.reclaim["wheel_current"][...] = instruments.wheel_current


class InterlockStage(Stage):
    """The anti-collision interlock: its pace from what the automation knows, and its quick stop
    (bwr_twin.collision.guard)."""

    def __init__(self, guard: Guard, plant: Plant, *, tracking, known_pile, neighbour: Neighbour | None):
        """`known_pile()`: the (runs, ny, nx) pile the automation knows (NaN: never seen), or None;
        `tracking`: a bench plan's, which takes the pace from the next period on, or a path's."""
        self._guard, self._plant, self._known_pile, self._neighbour = guard, plant, known_pile, neighbour
        self._tracking = None if tracking.shared else tracking

    def measure(self, k: int, row: Row) -> None:
        guard, neighbour = self._guard, self._neighbour
        guard.decide(k, row.q_measured, row.qd_measured, row.qd, self._known_pile(),
                     neighbour.reported if neighbour is not None else None)
        if self._tracking is not None:
            self._tracking.pace = guard.pace
        if neighbour is not None:  # the same pace holds the neighbour's schedule
            neighbour.pace = guard.pace

    def drives(self, k: int, applied: np.ndarray) -> None:
        stop = self._guard.quick_stop
        if stop.any():  # the drives brake on their own, whatever commanded
            self._plant.quick_stop(stop, applied)

    def stepped(self, k: int, row: Row) -> None:
        self._guard.advance()

    def metrics(self, run: int, metrics: dict) -> None:
        if "collision" in metrics:
            metrics["collision"]["interventions"] = self._guard.interventions(run)


class PlantFaultsStage(Stage):
    """The machine's friction and mass as its faults make them, before the physics step (bwr_twin.sim.plant_faults)."""

    def __init__(self, faults: PlantFaults, plant: Plant):
        self._faults, self._plant = faults, plant

    def drives(self, k: int, applied: np.ndarray) -> None:
        self._faults.step(k, self._plant.alive)


class FaultsOnDrives(Stage):
    """A tripped drive applies nothing, whatever commanded, a derated one less; and what each fault did,
    from the record."""

    def __init__(self, faults: Faults, scenes: Sequence[Scene]):
        self._faults, self._scenes = faults, scenes

    def drives(self, k: int, applied: np.ndarray) -> None:
        self._faults.command(k, applied)

    def result(self, run: int, result: RunResult, recorder: Recorder) -> None:
        scene, metrics = self._scenes[run], result.metrics
        metrics["faults"] = fault_metrics(
            scene.faults, result.time, result.q_desired, result.q, metrics,
            result.reclaim.rate if result.reclaim is not None else None,
            scene.reclaim.target_rate if scene.reclaim is not None else None)
