"""Every run's collision shapes against its pile, once a control period: the least clearance of
each shape with its time, and each contact (clearance <= 0) as an event with its start, end and
depth (docs/anticollision.md). The wheel's cutting envelope is left out: it cuts the pile.

The pile only falls as the wheel digs, so a shape's clearance shrinks no faster than the machine
moves it: by at most |travel speed| + R_slew |slew speed| + R_luff |luff speed| a second, R the
farthest any shape's corner lies from the slew and luff axes. A run's shapes are measured again
once the machine may have moved RECHECK of the least clearance measured last, and every period
within NEAR of the pile; in between each shape's clearance is known to be at least its last
measure less that motion, which `now` holds."""

from __future__ import annotations

from collections.abc import Sequence

import numba
import numpy as np

from bwr_twin.collision.pile import shape_clearance
from bwr_twin.model.mount import site_pose
from bwr_twin.model.shapes import BOX, CollisionShape
from bwr_twin.pile.surface import Surface

WATCH = 10.0  # m: the reach of the check; a shape farther from the pile is reported this far
RECHECK = 0.02  # of the least clearance measured last: the motion after which a run's shapes are measured again
NEAR = 1.0  # m: within it of the pile, a run's shapes are measured every period


class PileClearance:
    """(runs, shapes) clearances to the piles, this period's and the least so far.

    Attributes:
        parts: the shapes' part names, in order.
        now: (runs, shapes) m this period.
        least, least_time: (runs, shapes) the least clearance so far (m) and when (s).
    """

    def __init__(self, shapes: Sequence[CollisionShape], surface: Surface, runs: int, period: float):
        checked = [s for s in shapes if not s.cuts]
        self.parts = [s.part for s in checked]
        self.period = period
        self._x0, self._y0, self._spacing = float(surface.x[0]), float(surface.y[0]), float(surface.x[1] - surface.x[0])
        n = len(checked)
        self._kinds = np.array([s.kind for s in checked], dtype=np.int64)
        self._halves = np.array([s.half for s in checked]).reshape(n, 3)
        self._positions = np.array([s.mount.position for s in checked]).reshape(n, 3)
        self._rotations = np.array([s.mount.rotation for s in checked]).reshape(n, 3, 3)
        self._joints = np.array([s.mount.joints for s in checked], dtype=np.int64)
        self._anchor = checked[0].mount.anchor if checked else np.zeros((3, 3))
        self._axis = checked[0].mount.axis if checked else np.zeros((3, 3))
        self.levers = levers_of(checked)
        self.now = np.full((runs, n), WATCH)
        self._measured = np.full((runs, n), WATCH)  # each shape's last measure
        self._moved = np.full(runs, np.inf)  # m the machine may have moved since: measure at once
        self.checks = np.zeros(runs, dtype=np.int64)  # periods in which a run's shapes were measured
        self.periods = np.zeros(runs, dtype=np.int64)  # ... of these
        self.least = np.full((runs, n), np.inf)
        self.least_time = np.zeros((runs, n))
        self._events: list[list[dict]] = [[] for _ in range(runs)]
        self._open = np.full((runs, n), -1, dtype=np.int64)  # each shape's contact under way, or -1
        self._all = np.arange(runs)

    def step(self, k: int, q: np.ndarray, qd: np.ndarray, heights: np.ndarray, runs: np.ndarray | None) -> None:
        """Period k: the shapes where the true joints q (runs, 3) put them, moving at qd, against
        the piles' heights (runs, ny, nx) as dug until now; only the `runs` given (None: all)."""
        order = self._all if runs is None else runs
        self.periods[order] += 1
        if not _clearances(heights, self._x0, self._y0, self._spacing, order, q, qd, self.period, self.levers,
                           self._kinds, self._halves, self._positions, self._rotations, self._joints, self._anchor,
                           self._axis, WATCH, RECHECK, NEAR, self._moved, self._measured, self.now, self.checks):
            return  # nothing measured: nothing nearer than before
        time = round(k * self.period, 9)
        closer = self._measured < self.least
        self.least[closer] = self._measured[closer]
        self.least_time[closer] = time
        touching = self._measured <= 0.0
        if touching.any() or (self._open >= 0).any():
            self._contacts(time, touching)

    def _contacts(self, time: float, touching: np.ndarray) -> None:
        for run, shape in zip(*np.nonzero(touching | (self._open >= 0))):
            events, index = self._events[run], self._open[run, shape]
            if touching[run, shape]:
                depth = float(-self._measured[run, shape])
                if index < 0:
                    self._open[run, shape] = len(events)
                    events.append({"time_s": time, "end_s": None, "bodies": [self.parts[shape], "pile"],
                                   "depth_m": depth, "depth_time_s": time})
                elif depth > events[index]["depth_m"]:
                    events[index]["depth_m"], events[index]["depth_time_s"] = depth, time
            else:
                events[index]["end_s"] = time
                self._open[run, shape] = -1

    def metrics(self, run: int) -> dict:
        """metrics.json's `collision` object of `run` (docs/contracts.md)."""
        least = {part: {"clearance_m": float(min(self.least[run, i], WATCH)), "time_s": float(self.least_time[run, i])}
                 for i, part in enumerate(self.parts)}
        return {"watch_m": WATCH, "pile": least, "contacts": [dict(e) for e in self._events[run]],
                "interventions": [], "periods": int(self.periods[run]), "measured_periods": int(self.checks[run])}


def levers_of(shapes: Sequence[CollisionShape]) -> np.ndarray:
    """(3,): m a unit of each joint's speed moves any shape's corner at most: 1 for the travel,
    the farthest corner's distance from the slew axis and from the luff axis (at q = 0)."""
    levers = np.array([1.0, 0.0, 0.0])
    for shape in shapes:
        m = shape.mount
        signs = np.array([[a, b, c] for a in (-1, 1) for b in (-1, 1) for c in (-1, 1)])
        extent = shape.half if shape.kind == BOX else np.array([shape.half[0], shape.half[0], shape.half[2] + shape.half[0]])
        corners = m.position + (signs * extent) @ m.rotation.T
        for j in (1, 2):
            arm = corners - m.anchor[j]
            levers[j] = max(levers[j], float(np.linalg.norm(arm - np.outer(arm @ m.axis[j], m.axis[j]), axis=1).max()))
    return levers


@numba.njit(cache=True)
def _clearances(heights, x0, y0, spacing, runs, q, qd, period, levers, kinds, halves, positions0, rotations0, joints,
                anchor, axis, watch, recheck, near, moved, measured, now, checks):  # pragma: no cover - compiled
    """Each run's shapes measured if it may have moved far enough (its module's docstring), else
    their lower bounds; whether any was measured."""
    position, rotation = np.empty(3), np.empty((3, 3))
    any_measured = False
    for run in runs:
        moved[run] += (abs(qd[run, 0]) * levers[0] + abs(qd[run, 1]) * levers[1] + abs(qd[run, 2]) * levers[2]) * period
        least = watch
        for i in range(len(kinds)):
            least = min(least, measured[run, i])
        if moved[run] < recheck * least and least > near:
            for i in range(len(kinds)):
                now[run, i] = measured[run, i] - moved[run]
            continue
        for i in range(len(kinds)):
            site_pose(q[run], positions0[i], rotations0[i], joints[i], anchor, axis, position, rotation)
            measured[run, i] = shape_clearance(heights[run], x0, y0, spacing, kinds[i], halves[i], position, rotation,
                                               watch)
            now[run, i] = measured[run, i]
        moved[run] = 0.0
        checks[run] += 1
        any_measured = True
    return any_measured
