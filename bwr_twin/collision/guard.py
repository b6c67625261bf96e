"""The twin's side of an anti-collision interlock: what it measures for the interlock, and the
path followed at the pace the interlock decides (bwr_twin.collision.interlock).

Every control period, as the encoders are read, each collision shape's clearance is measured
where the encoders put it (not the true joints: a stuck or drifting encoder misleads the interlock
as it would a real one) to the pile the runs know: the scanned pile where they scan, a cell never
seen holding nothing, else the true one (bwr_twin.collision.monitor). The interlock returns each
run's pace, and the reference of that same period is the path's at the run's own path time,
which advances a pace of a control period each period: at rest while stopped, its velocity scaled
by the pace and its acceleration by its square while slowed. The path time is kept as whole
control periods and a fraction, so that a run the interlock never slows follows the path's rows
exactly. A bench plan's follower takes the pace itself from the next period on: a move's time
runs at it, a pass's speed law is scaled by it, the slew braking to it within its acceleration.

With a neighbour on the rail, each shape is also measured against the neighbour where its last
report put it (`report_delay` late, bwr_twin.sim.neighbour): the interlock sees one more column a shape, its clearance to
the neighbour less the distance the neighbour may cover before it stands (its reported speed on
its own shapes' levers over the report's delay and the reaction, then braking at the
deceleration: it is slowed and stopped by the same pace, bwr_twin.sim.neighbour).

The interlock may also quick-stop a run's drives (its `quick_stop`): the twin then replaces the
controller's forces with the drives' own quick stop (bwr_twin.sim.drives) from that period on, and
the run's pace is 0.
"""

from __future__ import annotations

import math

import numpy as np

from bwr_twin.collision.machines import MachineClearance
from bwr_twin.collision.monitor import PileClearance, levers_of
from bwr_twin.config.plugin_calls import call, checked, construct, describe, reported
from bwr_twin.config.plugins import interlock_class
from bwr_twin.config.scene import Scene
from bwr_twin.errors import PluginError
from bwr_twin.model.machine import Machine
from bwr_twin.pile.surface import Surface


class Guard:
    """Every run's interlocked reference.

    Attributes:
        interlock: the scene's interlock; its `quick_stop` (runs,) the runs whose drives it stops.
        pace: (runs,) this period's, in [0, 1].
        q, qd, qdd: (runs, 3) the reference of the period.
    """

    def __init__(self, scene: Scene, machine: Machine, surface: Surface | None, runs: int, period: float,
                 rows: tuple[np.ndarray, np.ndarray, np.ndarray] | None, neighbour: Machine | None = None):
        """`rows`: a path's (samples, 3) positions, velocities and accelerations, which the guard
        follows at the pace; None for a bench plan, whose follower takes the pace itself
        (bwr_twin.planning.follower), from the next period on. `neighbour`: a second machine's
        model, measured where its reports put it. Without a pile (`surface` None) the interlock
        keeps the machine clear of the neighbour alone."""
        settings = scene.interlock
        self.period, self.settings = period, settings
        self.monitor = PileClearance(machine.collision_shapes, surface, runs, period) if surface is not None else None
        parts, levers = (self.monitor.parts, self.monitor.levers) if self.monitor else ([], np.zeros(3))
        self.machines = None
        if neighbour is not None:
            self.machines = MachineClearance(machine, neighbour, runs, period)
            parts = parts + [f"{part} | neighbour" for part in self.machines.parts]
            levers = np.maximum(levers, levers_of(machine.collision_shapes))  # the wheel's too
            self._neighbour_levers = levers_of(neighbour.collision_shapes)
            self._report_delay = scene.neighbour.report_delay
        cls = interlock_class(settings.type)
        self._label = f"{scene.path}: interlock {describe(settings.type, cls)}"  # an engineer's failures are theirs
        self.interlock = construct(self._label, cls, settings, runs, period, parts, levers)
        self._rows = rows  # the path's (samples, 3) positions, velocities, accelerations
        self.pace = np.ones(runs)
        self._whole = [0] * runs  # path time: whole control periods ...
        self._fraction = [0.0] * runs  # ... and a fraction of one
        self.q, self.qd, self.qdd = (np.zeros((runs, 3)) for _ in range(3))

    @property
    def quick_stop(self) -> np.ndarray:
        """(runs,) bool: the runs whose drives the interlock stops this period."""
        return self.interlock.quick_stop

    def decide(self, k: int, q_measured: np.ndarray, qd_measured: np.ndarray, drive_speed: np.ndarray,
               known: np.ndarray, neighbour: tuple[np.ndarray, np.ndarray] | None = None) -> None:
        """Period k's pace of every run, and the runs whose drives it quick-stops, from its
        encoders' (runs, 3) readings, its drives' own speed feedback (runs, 3), the pile it knows,
        (runs, ny, nx) m (NaN: never seen), and the neighbour's joints and speeds as its latest
        report gives them, (runs, 2, 3); then its reference for the period."""
        monitor, time = self.monitor, round(k * self.period, 9)
        clearance = np.empty((len(self.pace), 0))
        if monitor is not None:
            monitor.step(k, q_measured, qd_measured, known, None)
            clearance = monitor.now.copy()
        if self.machines is not None:
            clearance = np.concatenate([clearance, self._to_neighbour(k, q_measured, qd_measured, neighbour)], axis=1)
        interlock = self.interlock
        interlock.drive_speed[...] = drive_speed
        pace = checked(self._label, "pace", call(self._label, interlock.pace, "pace", time, time, q_measured,
                                                 qd_measured, clearance), (len(self.pace),), time)
        if not ((pace >= 0.0) & (pace <= 1.0)).all():
            raise PluginError(f"{self._label}: pace() returned {pace} at t = {time:.2f} s; paces lie in [0, 1]")
        stop = interlock.quick_stop
        if not (isinstance(stop, np.ndarray) and stop.dtype == bool and stop.shape == self.pace.shape):
            raise PluginError(f"{self._label}: its quick_stop is {stop!r} at t = {time:.2f} s; it must be a "
                              f"({len(self.pace)},) array of bools")
        self.pace = np.where(stop, 0.0, pace)  # a quick-stopped machine follows nothing
        if self._rows is not None:
            self._reference()

    def _to_neighbour(self, k: int, q_measured: np.ndarray, qd_measured: np.ndarray,
                      reported: np.ndarray) -> np.ndarray:
        """(runs, parts) each shape's clearance to the neighbour where its report of `report_delay`
        ago put it, less what the neighbour may cover since and before it stands."""
        self.machines.step(k, q_measured, qd_measured, reported[:, 0], reported[:, 1], None)
        s = self.settings
        speed = np.abs(reported[:, 1]) @ self._neighbour_levers
        covered = speed * (self._report_delay + s.reaction) + speed**2 / (2.0 * s.deceleration)
        return self.machines.nearest() - covered[:, None]

    def _reference(self) -> None:
        """Each run's reference at its path time: the rows between which it lies, interpolated;
        the velocity scaled by the pace, the acceleration by its square."""
        positions, velocities, accelerations = self._rows
        last = len(positions) - 1
        for run, pace in enumerate(self.pace.tolist()):
            i, f = min(self._whole[run], last), self._fraction[run]
            if f == 0.0 or i == last:
                q, qd, qdd = positions[i], velocities[i], accelerations[i]
            else:
                q = positions[i] + (positions[i + 1] - positions[i]) * f
                qd = velocities[i] + (velocities[i + 1] - velocities[i]) * f
                qdd = accelerations[i] + (accelerations[i + 1] - accelerations[i]) * f
            self.q[run] = q
            self.qd[run] = qd * pace
            self.qdd[run] = qdd * pace * pace

    def advance(self) -> None:
        """On along each run's path, a pace of a control period."""
        if self._rows is None:
            return
        for run, pace in enumerate(self.pace.tolist()):
            if pace == 1.0 and self._fraction[run] == 0.0:
                self._whole[run] += 1  # the path's own rows, exactly
                continue
            fraction = self._fraction[run] + pace
            whole = math.floor(fraction)
            self._whole[run] += whole
            self._fraction[run] = fraction - whole

    def interventions(self, run: int) -> list[dict]:
        return reported(self._label, f"interventions of run {run}", list(self.interlock.interventions[run]))
