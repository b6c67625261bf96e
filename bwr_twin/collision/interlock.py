"""The built-in anti-collision interlock (docs/anticollision.md): it keeps the machine's collision
shapes clear of the pile the automation knows, from what the automation knows.

Every control period it measures each shape's clearance where the encoders put it (not the true
joints) to the pile the runs know: the scanned pile where they scan (a cell never seen holds
nothing, as the automation sees it), else the true one. From the least clearance it takes the
distance the machine would still cover before it stands, its shapes' fastest speed v (the
encoders' speeds on the levers of bwr_twin.collision.monitor) held for the reaction time, then
braked at the deceleration: v t + v^2 / 2a. Within `warn` m of predicted clearance it warns,
within `slow` m it slows the path's reference to `slow_share` of its speed, within `stop` m it
stops the reference where it is, in the same period, and holds it there until the run ends, as
commercial systems latch a stop until an operator resets it. A stop or slowdown acts on the
reference the controller follows: the controller brakes the drives to it.

The reference is the path's, followed at the interlock's own pace: a path time kept as whole
control periods and a fraction, so that a run the interlock never slows follows the path's rows
exactly.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from bwr_twin.collision.monitor import PileClearance
from bwr_twin.collision.shapes import CollisionShape
from bwr_twin.config.scene import InterlockSection
from bwr_twin.stockpile.surface import Surface

CLEAR, WARN, SLOW, STOP = 0, 1, 2, 3
STATES = ("clear", "warn", "slow", "stop")


class ZoneInterlock:
    """Every run's interlock state and its reference along the path.

    Attributes:
        state: (runs,) CLEAR, WARN, SLOW or STOP this period.
        predicted: (runs,) m, the least predicted clearance this period.
        interventions: per run, each change of state as {"kind", "time_s", "predicted_clearance_m", "part"}.
    """

    def __init__(self, settings: InterlockSection, shapes: Sequence[CollisionShape], surface: Surface, runs: int,
                 period: float, rows: tuple[np.ndarray, np.ndarray, np.ndarray]):
        self.settings, self.period = settings, period
        self.monitor = PileClearance(shapes, surface, runs, period)
        self._rows = rows  # the path's (samples, 3) positions, velocities, accelerations
        self.state = np.zeros(runs, dtype=np.int64)
        self.predicted = np.full(runs, np.inf)
        self.interventions: list[list[dict]] = [[] for _ in range(runs)]
        self._whole = [0] * runs  # path time: whole control periods ...
        self._fraction = [0.0] * runs  # ... and a fraction of one
        self.q, self.qd, self.qdd = (np.zeros((runs, 3)) for _ in range(3))

    def decide(self, k: int, q_measured: np.ndarray, qd_measured: np.ndarray, known: np.ndarray) -> None:
        """Period k's state of every run, from its encoders' (runs, 3) readings and the pile it
        knows, (runs, ny, nx) m (NaN: never seen); then its reference for the period."""
        s = self.settings
        monitor = self.monitor
        monitor.step(k, q_measured, qd_measured, known, None)
        speed = np.abs(qd_measured) @ monitor.levers  # m/s, the shapes' fastest
        stopping = speed * s.reaction + speed**2 / (2.0 * s.deceleration)
        least = monitor.now.argmin(axis=1)
        self.predicted = monitor.now[np.arange(len(least)), least] - stopping
        zone = np.where(self.predicted <= s.stop, STOP, np.where(self.predicted <= s.slow, SLOW,
                                                                 np.where(self.predicted <= s.warn, WARN, CLEAR)))
        edges = np.array([np.inf, s.warn, s.slow, s.stop])  # the edge of each state's zone
        leaving = (zone < self.state) & (self.predicted <= edges[self.state] + s.hysteresis)
        zone = np.where(leaving | (self.state == STOP), self.state, zone)  # a stop holds; the rest with hysteresis
        for run in np.flatnonzero(zone != self.state):
            self.interventions[run].append({"kind": STATES[zone[run]], "time_s": round(k * self.period, 9),
                                            "predicted_clearance_m": float(self.predicted[run]),
                                            "part": monitor.parts[least[run]]})
        self.state = zone
        self._reference()

    def _reference(self) -> None:
        """Each run's reference at its path time: the rows between which it lies, interpolated;
        at rest while stopped, the velocity and acceleration scaled while slowed."""
        positions, velocities, accelerations = self._rows
        last = len(positions) - 1
        share = self.settings.slow_share
        for run, state in enumerate(self.state.tolist()):
            i, f = min(self._whole[run], last), self._fraction[run]
            if f == 0.0 or i == last:
                q, qd, qdd = positions[i], velocities[i], accelerations[i]
            else:
                q = positions[i] + (positions[i + 1] - positions[i]) * f
                qd = velocities[i] + (velocities[i + 1] - velocities[i]) * f
                qdd = accelerations[i] + (accelerations[i + 1] - accelerations[i]) * f
            pace = 0.0 if state == STOP else share if state == SLOW else 1.0
            self.q[run] = q
            self.qd[run] = qd * pace
            self.qdd[run] = qdd * pace * pace

    def advance(self) -> None:
        """On a period along each run's path, at its pace."""
        share = self.settings.slow_share
        for run, state in enumerate(self.state.tolist()):
            if state == STOP:
                continue
            if state != SLOW and self._fraction[run] == 0.0:
                self._whole[run] += 1  # the path's own rows, exactly
                continue
            fraction = self._fraction[run] + (share if state == SLOW else 1.0)
            whole = math.floor(fraction)
            self._whole[run] += whole
            self._fraction[run] = fraction - whole
