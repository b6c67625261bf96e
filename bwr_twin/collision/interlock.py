"""Anti-collision interlocks (docs/anticollision.md): each control period, from what the
automation knows, each run's pace along its path: 1 its own, less to slow it, 0 to stop it.

An interlock derives from `Interlock` and is named in the scene: `[interlock] type = "zones"`, the
built-in, or `type = "my_interlock.py:MyInterlock"`, an engineer's class in a file beside the
scene. It is given numbers, not the twin: the scene's [interlock] settings, and every period the
encoders' readings and each collision shape's clearance measured where the encoders put it to the
pile the runs know (bwr_twin.collision.guard). The twin follows the path at the pace it returns,
in the period it returns it.

`ZoneInterlock` does what commercial systems do. From the least clearance it takes the distance
the machine would still cover before it stands, its shapes' fastest speed v (the encoders' speeds
on the shapes' levers) held for the reaction time, then braked at the deceleration:
v t + v^2 / 2a. Within `warn` m of predicted clearance it warns, within `slow` m it slows the path
to `slow_share` of its pace, within `stop` m it stops it and holds it there until the run ends,
as commercial systems latch a stop until an operator resets it. A warning or a slowdown ends once
the clearance predicted at the full pace it would resume is `hysteresis` m beyond its zone's edge:
slowing shortens the stopping distance, so the prediction at the slowed pace alone would leave the
zone at once and enter it again.

It also checks its encoders against the drives: over the last `encoder_window` s, each encoder's
motion against the motion its drive's own speed feedback integrates to (trapezoids of the
periods). Where they part by more than `encoder_tolerance` m at the shapes (the joint's lever),
the encoder is not to be believed, nor any clearance measured where it puts the machine: the
interlock quick-stops the drives (they brake on their own speed feedback, bwr_twin.sim.drives) and
stops the path, latched as a stop is. A stuck, dropped-out or drifting encoder is caught so,
where holding the reference cannot stop a controller that drives towards what the encoder never
shows.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from bwr_twin.model.machine import AXES

CLEAR, WARN, SLOW, STOP = 0, 1, 2, 3
STATES = ("clear", "warn", "slow", "stop")


class Interlock:
    """Never intervenes (pace 1). Subclasses decide in `pace`.

    Attributes:
        settings: the scene's [interlock] (bwr_twin.config.sections.InterlockSection).
        parts: the collision shapes' part names, in the order of `pace`'s clearance columns.
        levers: (3,) m a unit of each joint's speed moves any shape's corner at most.
        period: s between calls.
        interventions: per run, the interventions to report (metrics.json's
            `collision.interventions`): dicts with at least "kind" and "time_s".
        drive_speed: (runs, 3) the drives' own speed feedback (m/s, rad/s), which no encoder
            fault touches; the twin sets it before each `pace`.
        quick_stop: (runs,) bool, the runs whose drives the interlock quick-stops this period:
            whatever the controller commands, they brake to a stand and hold (bwr_twin.sim.drives).
    """

    def __init__(self, settings, runs: int, period: float, parts: Sequence[str], levers: np.ndarray):
        self.settings, self.period, self.parts, self.levers = settings, period, list(parts), levers
        self.interventions: list[list[dict]] = [[] for _ in range(runs)]
        self.drive_speed = np.zeros((runs, 3))
        self.quick_stop = np.zeros(runs, dtype=bool)

    def pace(self, time: float, q_measured: np.ndarray, qd_measured: np.ndarray,
             clearance: np.ndarray) -> np.ndarray:
        """(runs,) each run's pace along its path this period, in [0, 1], from the encoders'
        (runs, 3) readings and each shape's clearance to the known pile, (runs, shapes) m."""
        return np.ones(len(q_measured))


class ZoneInterlock(Interlock):
    """The built-in: warn, slow and stop zones of predicted clearance (the module's docstring).

    Attributes:
        state: (runs,) CLEAR, WARN, SLOW or STOP this period.
        predicted: (runs,) m, the least predicted clearance this period.
    """

    def __init__(self, settings, runs: int, period: float, parts: Sequence[str], levers: np.ndarray):
        super().__init__(settings, runs, period, parts, levers)
        self.state = np.zeros(runs, dtype=np.int64)
        self.predicted = np.full(runs, np.inf)
        self._edges = np.array([np.inf, settings.warn, settings.slow, settings.stop])  # each state's zone edge
        self._paces = np.array([1.0, 1.0, settings.slow_share, 0.0])
        # The encoders' readings and the drives' integrated speeds of the window's periods, a ring.
        self._window = max(round(settings.encoder_window / period), 1) + 1
        self._encoders = np.zeros((self._window, runs, 3))
        self._driven = np.zeros((self._window, runs, 3))
        self._speed = np.zeros((runs, 3))  # the drives' speed feedback of the period before
        self._calls = 0

    def pace(self, time: float, q_measured: np.ndarray, qd_measured: np.ndarray,
             clearance: np.ndarray) -> np.ndarray:
        s = self.settings
        if s.encoder_check:
            self._check_encoders(time, q_measured)
        speed = np.abs(qd_measured) @ self.levers  # m/s, the shapes' fastest
        least = clearance.argmin(axis=1)
        nearest = clearance[np.arange(len(least)), least]
        self.predicted = nearest - self._stopping(speed)
        zone = np.where(self.predicted <= s.stop, STOP, np.where(self.predicted <= s.slow, SLOW,
                                                                 np.where(self.predicted <= s.warn, WARN, CLEAR)))
        # A slowdown ends only if the machine, back at its full pace, would stay clear of the zone.
        resumed = nearest - self._stopping(speed / np.maximum(self._paces[self.state], s.slow_share))
        leaving = (zone < self.state) & (resumed <= self._edges[self.state] + s.hysteresis)
        zone = np.where(leaving | (self.state == STOP), self.state, zone)  # a stop holds; the rest with hysteresis
        zone[self.quick_stop] = STOP
        for run in np.flatnonzero((zone != self.state) & ~self.quick_stop):
            self.interventions[run].append({"kind": STATES[zone[run]], "time_s": time,
                                            "predicted_clearance_m": float(self.predicted[run]),
                                            "part": self.parts[least[run]]})
        self.state = zone
        return self._paces[zone]

    def _check_encoders(self, time: float, q_measured: np.ndarray) -> None:
        """Quick-stop the runs whose encoders have parted from their drives' speed feedback by more
        than the tolerance at the shapes over the window (from the first period, until it is full)."""
        calls, rows = self._calls, self._window
        row, oldest = calls % rows, max(calls - rows + 1, 0) % rows
        previous = self._driven[(calls - 1) % rows] if calls else 0.0
        self._driven[row] = previous + 0.5 * (self._speed + self.drive_speed) * self.period
        self._encoders[row] = q_measured
        self._speed[:] = self.drive_speed
        self._calls = calls + 1
        apart = np.abs((self._encoders[row] - self._encoders[oldest]) - (self._driven[row] - self._driven[oldest]))
        apart *= self.levers  # m at the shapes
        for run in np.flatnonzero((apart.max(axis=1) > self.settings.encoder_tolerance) & ~self.quick_stop):
            axis = int(apart[run].argmax())
            self.quick_stop[run] = True
            self.interventions[run].append({"kind": "quick_stop", "time_s": time, "axis": AXES[axis],
                                            "encoder_apart_m": float(apart[run, axis])})

    def _stopping(self, speed: np.ndarray) -> np.ndarray:
        """m the shapes cover at `speed` (m/s) before they stand: the reaction, then the braking."""
        s = self.settings
        return speed * s.reaction + speed**2 / (2.0 * s.deceleration)
