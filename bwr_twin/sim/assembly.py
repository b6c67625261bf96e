"""A lockstep's parts, built once from its scenes: the machine, the reference, the plant, the
world models, the stages that bind them to the control period, in the order they run
(bwr_twin.sim.stages), and the watchers that only watch (bwr_twin.sim.watchers)."""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass

from bwr_twin.collision.guard import Guard
from bwr_twin.collision.machines import MachineClearance
from bwr_twin.collision.monitor import PileClearance
from bwr_twin.config.faults import check_fault_scanners
from bwr_twin.config.scene import Scene
from bwr_twin.errors import SceneError
from bwr_twin.model.machine import Machine
from bwr_twin.pile.surface import build_surface
from bwr_twin.sensing.faults import Faults
from bwr_twin.sensing.rate_instruments import RateInstruments, rate_instruments, rate_loop_reads_instruments
from bwr_twin.sensing.scan_account import ScanAccount
from bwr_twin.sensing.scanning import Scanning, active_scanners, pile_model
from bwr_twin.sim import stages, watchers
from bwr_twin.sim.disturbances import Disturbances
from bwr_twin.sim.encoders import Encoders
from bwr_twin.sim.neighbour import Neighbour
from bwr_twin.sim.parameters import RunParameters
from bwr_twin.sim.plant import Plant
from bwr_twin.sim.plant_faults import PlantFaults
from bwr_twin.sim.tracking import BenchTracking, PathTracking, StackingTracking
from bwr_twin.stockpile.reclaim import Reclaim
from bwr_twin.stockpile.reclaim_account import ReclaimAccount
from bwr_twin.stockpile.stacking import Stacking


@dataclass
class Parts:
    """What a lockstep is made of. The world models are None where the scene has none; drivers
    read them (the OPC UA server its instruments, say), only the stages step them."""

    machine: Machine  # the plant's machine
    belief_machine: Machine  # the controller's, its own compiled model even from the same file
    tracking: PathTracking | BenchTracking  # what the runs follow
    plant: Plant
    parameters: RunParameters  # what may differ between the runs: seeds, gains, wind, ...
    nthread: int  # threads the plant and the controller may use
    stages: tuple[stages.Stage, ...]  # in the order they run in each period
    watchers: tuple[watchers.Watcher, ...]  # what only watches (none when the runs are not observed)
    faults: Faults  # the scene's scheduled faults; `faults.acting(k)` says which act in period k
    reclaim: Reclaim | None = None  # the piles being dug
    scanning: Scanning | None = None  # the runs' scanners and the piles they know from them
    instruments: RateInstruments | None = None  # the belt scale and the wheel current
    neighbour: Neighbour | None = None  # a second machine on the rail and its schedule
    stacking: Stacking | None = None  # the piles being stacked


def assemble(scenes: Sequence[Scene], *, nthread: int = 0, frame_every: int | None = None,
             observe: bool = True) -> Parts:
    """The parts of a lockstep of `scenes` (which share a lockstep key) on `nthread` threads (0:
    all cores); `frame_every`: keep the pile every that many control periods, for a replay;
    `observe=False`: no watchers, and only each scanner's latest scan kept, for a driver that
    keeps no results. Raises BwrError if the path, a model or the stockpile is bad."""
    scene = scenes[0]
    sim = scene.simulation
    period = sim.control_period
    runs = len(scenes)
    parameters = RunParameters.of(scenes)
    surface = build_surface(scene.stockpile, scene.path) if scene.stockpile is not None else None
    machine = (Machine(scene.machine.mjcf, payloads=scene.plant.payload, stockpile=surface,
                       stockpile_drawing=scene.stockpile) if surface is not None
               else Machine.shared(scene.machine.mjcf, scene.plant.payload))
    faults = Faults(scene.faults, parameters.seed, period)
    scanners = active_scanners(scene, machine) if surface is not None else ()
    check_fault_scanners(scene.path, scene.faults, [s.name for s in scanners], scene.machine.mjcf)
    instruments = rate_instruments(scene, machine, parameters.seed, period)
    reclaim = Reclaim(scenes, machine, surface, period) if surface is not None else None
    scanning = (Scanning(scanners, surface, parameters.seed, period, keep_scans=observe, faults=faults)
                if scanners else None)
    if scene.reclaim is not None:
        scanned = pile_model(scene, scanners) == "scanned"
        measured = rate_loop_reads_instruments(scene, machine)
        tracking = BenchTracking(scenes, machine, period, reclaim, instruments=instruments if measured else None,
                                 known_pile=(lambda: scanning.survey.z[0]) if scanned else None)
    elif scene.stacking is not None:
        tracking = StackingTracking(scene, machine, period)
    else:
        tracking = PathTracking(scene, machine, period)
    stacking = (Stacking(scenes, machine, tracking.pattern, period, (tracking.samples - 1) * period, frame_every)
                if scene.stacking is not None else None)
    neighbour = Neighbour(scenes, period) if scene.neighbour is not None else None
    if neighbour is not None:
        bare = [m.path.name for m in (machine, neighbour.machine) if not m.collision_shapes]
        if bare:
            raise SceneError(f"{scene.path}: [neighbour]: the machines' clearance needs both to have collision "
                             f"shapes, but {' and '.join(bare)} has none (geoms 'collision_<part>' in group 5, "
                             "docs/anticollision.md)")
    nthread = min(nthread or os.cpu_count() or 1, runs)
    plant = Plant(machine, parameters, q0=tracking.start, timestep=sim.timestep, control_period=period,
                  nthread=nthread, neighbour=neighbour)

    order: list[stages.Stage] = [stages.EncoderReading(Encoders(parameters, period, tracking.start))]
    if tracking.own_rows or scene.interlock is not None:  # an interlock paces a path: each run its own
        order.append(stages.OwnReferences(tracking))
    if faults.active:
        order.append(stages.EncoderFaults(faults))
    if neighbour is not None:
        order.append(stages.NeighbourMachine(neighbour, plant))
    order.append(stages.DisturbanceForces(Disturbances(parameters, period)))
    if scanning is not None:
        order.append(stages.ScanningStage(scanning, ScanAccount(scanning, reclaim.density), reclaim, plant,
                                          tracking.survey_end, (tracking.samples - 1) * period))
    if stacking is not None:
        order.append(stages.StackingStage(stacking, plant))
    if reclaim is not None:
        order.append(stages.ReclaimStage(reclaim, ReclaimAccount(reclaim, frame_every), plant))
        if instruments is not None:
            order.append(stages.RateInstrumentReading(instruments, reclaim, faults))
    if scene.interlock is not None:
        order.append(_interlock(scene, machine, surface, runs, tracking, plant, reclaim, scanning, neighbour))
    if faults.active:
        order.append(stages.FaultsOnDrives(faults, scenes))
        plant_faults = PlantFaults(scene.faults, machine, plant.batch, period)
        if plant_faults.active:
            order.append(stages.PlantFaultsStage(plant_faults, plant))
    return Parts(machine=machine, belief_machine=Machine.shared(scene.controller_mjcf), tracking=tracking, plant=plant,
                 parameters=parameters, nthread=nthread, stages=tuple(order),
                 watchers=_watchers(scene, machine, surface, runs, plant, reclaim, neighbour) if observe else (),
                 faults=faults, reclaim=reclaim, scanning=scanning, instruments=instruments, neighbour=neighbour,
                 stacking=stacking)


def _watchers(scene: Scene, machine: Machine, surface, runs: int, plant: Plant, reclaim: Reclaim | None,
              neighbour: Neighbour | None) -> tuple[watchers.Watcher, ...]:
    """The clearance monitors: the shapes against the pile, where there is one, and against the
    neighbour, whose machine must then have shapes too."""
    period, found = scene.simulation.control_period, []
    if reclaim is not None and machine.collision_shapes:
        found.append(watchers.PileWatch(PileClearance(machine.collision_shapes, surface, runs, period), reclaim, plant))
    if neighbour is not None:
        found.append(watchers.MachineWatch(MachineClearance(machine, neighbour.machine, runs, period), plant))
    return tuple(found)


def _interlock(scene: Scene, machine: Machine, surface, runs: int, tracking, plant: Plant, reclaim: Reclaim | None,
               scanning: Scanning | None, neighbour: Neighbour | None) -> stages.InterlockStage:
    """The interlock's stage; a path's reference then follows the pace it decides."""
    if not machine.collision_shapes:
        raise SceneError(f"{scene.path}: [interlock] keeps the machine's collision shapes clear of the pile, "
                         f"but {machine.path.name} has none (geoms 'collision_<part>' in group 5, "
                         "docs/anticollision.md)")
    guard = Guard(scene, machine, surface, runs, scene.simulation.control_period, tracking.rows if tracking.shared else None,
                  neighbour=neighbour.machine if neighbour is not None else None)
    if tracking.shared:
        tracking.pace_by(guard)
    # what the automation knows of the pile: what it scanned, else the truth
    known = (lambda: scanning.survey.z) if scanning is not None else (
        (lambda: reclaim.heights) if reclaim is not None else (lambda: None))
    return stages.InterlockStage(guard, plant, tracking=tracking, known_pile=known, neighbour=neighbour)
