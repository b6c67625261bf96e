"""A second machine on the rail, in the plant's world: its schedule and its drives' hold on it.

The plant's model holds both machines (bwr_twin.model.spec attaches the neighbour's MJCF, every
name prefixed): the neighbour's joints and actuators follow the first machine's, and MuJoCo
steps both in the same lockstep. The neighbour has no controller plug-in: its drives hold each
run's schedule (one cubic between the steps, at rest at each, as a path's) with a PD on its own
inertia at its start, critically damped at the scene's bandwidth, its bias forces (gravity)
compensated, within its drives' force limits. What the automation hears of it is its position
`report_delay` late (bwr_twin.collision.guard). An interlock's pace holds it too: its schedule's
clock runs at the pace of its run, as the first machine's path does.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from bwr_twin.config.scene import Scene
from bwr_twin.errors import EnvelopeError
from bwr_twin.model.machine import AXES, Machine, describe
from bwr_twin.planning.trajectory import Trajectory
from bwr_twin.sim.drives import hold, inertia_at


class Neighbour:
    """Every run's second machine: its schedule's reference and its drives' forces.

    Attributes:
        machine: the neighbour's own compiled model (contract, envelope, kinematics, shapes).
        start: (runs, 3) where each run's neighbour stands at t = 0 (m, rad, rad).
        report_delay: s the automation hears its position late.
        clock: (runs,) s along each run's schedule; `pace` (runs,) how fast it runs this period.
        q_reference: (runs, 3) the schedule's position the drives held this period.
        reported: (runs, 2, 3) its joints and speeds (m, rad; m/s, rad/s) as its latest report
            gives them, `report_delay` late (`hear`); `report_time` (s) when they were true.
    """

    def __init__(self, scenes: Sequence[Scene], period: float):
        """Raises ModelError for a file that breaks the model contract and EnvelopeError, naming
        the scene and the schedule's step, for a schedule outside the neighbour's envelope."""
        section = scenes[0].neighbour
        self.machine = machine = Machine.shared(section.mjcf)
        self.period, self.report_delay = period, section.report_delay
        self._schedules = [neighbour_schedule(scene, machine) for scene in scenes]
        self.start = np.array([schedule.sample(0.0)[0] for schedule in self._schedules])
        # Each axis a mass-spring-damper of natural frequency w and damping 1 on the inertia it
        # has at the start (the diagonal of M), the drives' limits the bounds of its force.
        self._inertia, self._bandwidth = inertia_at(machine, self.start[0]), section.bandwidth
        self._limits = machine.drive_limits
        self.q_reference = np.zeros((len(scenes), 3))
        self.clock = np.zeros(len(scenes))
        self.pace = np.ones(len(scenes))
        self._late = round(section.report_delay / period)  # control periods
        self._reports = np.zeros((self._late + 1, len(scenes), 2, 3))  # the true states in transit, a ring
        self.reported = self._reports[0]
        self.report_time = 0.0

    def hear(self, k: int, q: np.ndarray, qd: np.ndarray) -> None:
        """Period k's true joints and speeds (runs, 3) go out; `reported` is the report that
        arrives now, of report_delay ago (before then, of where it started)."""
        reports = self._reports
        reports[k % len(reports), :, 0], reports[k % len(reports), :, 1] = q, qd
        heard = max(k - self._late, 0)
        self.reported, self.report_time = reports[heard % len(reports)], heard * self.period

    def forces(self, q: np.ndarray, qd: np.ndarray, bias: np.ndarray) -> np.ndarray:
        """(runs, 3) drive forces for this period from each run's neighbour joints q, qd and bias
        forces (runs, 3), at its schedule's clock (its velocity scaled by the pace, its
        acceleration by the pace's square); then the clock moves on a pace of a period."""
        reference = np.array([schedule.sample(t) for schedule, t in zip(self._schedules, self.clock)])
        reference[:, 1] *= self.pace[:, None]
        reference[:, 2] *= (self.pace**2)[:, None]
        self.q_reference[:] = reference[:, 0]
        out = np.empty_like(q)
        hold(reference, q, qd, bias, self._inertia, self._bandwidth, self._limits, out)
        self.clock += self.pace * self.period
        return out


def neighbour_schedule(scene: Scene, machine: Machine) -> Trajectory:
    """A scene's neighbour schedule as a joint-space path; EnvelopeError naming the step."""
    steps = scene.neighbour.schedule
    times = np.array([step.t for step in steps])
    knots = np.array([[step.q[0], *np.radians(step.q[1:])] for step in steps])
    for i, knot in enumerate(knots):
        for j, axis in enumerate(AXES):
            low, high = machine.envelope[j]
            if not low - 1e-9 <= knot[j] <= high + 1e-9:
                raise EnvelopeError(f"{scene.path}: 'neighbour.schedule[{i}]' puts {axis} at "
                                    f"{describe(j, knot[j])}, outside the envelope [{describe(j, low)}, "
                                    f"{describe(j, high)}] of {machine.path.name}")
    if len(times) == 1:  # it stands still
        times, knots = np.array([0.0, 1.0]), np.repeat(knots, 2, axis=0)
    elif times[0] > 0:  # at rest at its first step until then
        times, knots = np.concatenate([[0.0], times]), np.concatenate([knots[:1], knots])
    return Trajectory(times=times, knots=knots, points=machine.fk(knots))
