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
from dataclasses import dataclass

import numba
import numpy as np

from bwr_twin.collision.contacts import Contacts
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
        self._grid = (float(surface.x[0]), float(surface.y[0]), float(surface.x[1] - surface.x[0]))  # x0, y0, spacing
        self._mounted = MountedShapes.of(checked)
        self.levers = levers_of(checked)
        n = len(checked)
        self.now = np.full((runs, n), WATCH)
        self._measured = np.full((runs, n), WATCH)  # each shape's last measure
        self._moved = np.full(runs, np.inf)  # m the machine may have moved since: measure at once
        self.checks = np.zeros(runs, dtype=np.int64)  # periods in which a run's shapes were measured
        self.periods = np.zeros(runs, dtype=np.int64)  # ... of these
        self.least = np.full((runs, n), np.inf)
        self.least_time = np.zeros((runs, n))
        self._contacts = Contacts(runs, n)
        self._all = np.arange(runs)

    def step(self, k: int, q: np.ndarray, qd: np.ndarray, heights: np.ndarray, runs: np.ndarray | None) -> None:
        """Period k: the shapes where the true joints q (runs, 3) put them, moving at qd, against
        the piles' heights (runs, ny, nx) as dug until now; only the `runs` given (None: all)."""
        order = self._all if runs is None else runs
        # Most periods no run has moved far enough to be measured: a call of few arguments says so.
        if not _carried(order, qd, self.levers, self.period, WATCH, RECHECK, NEAR, self.periods, self._moved,
                        self._measured, self.now):
            return
        m, contacts, time = self._mounted, self._contacts, round(k * self.period, 9)
        if not _clearances(heights, *self._grid, order, q, m.kinds, m.halves, m.positions, m.rotations,
                           m.joints, m.anchor, m.axis, WATCH, RECHECK, NEAR, time, self._moved, self._measured,
                           self.now, self.checks, self.least, self.least_time, contacts.open):
            return  # no shape measured touches the pile, and no contact is under way
        touching = self._measured <= 0.0
        for run, shape in zip(*np.nonzero(touching | (contacts.open >= 0))):
            contacts.record(run, shape, touching[run, shape], float(-self._measured[run, shape]), time,
                            [self.parts[shape], "pile"])

    def metrics(self, run: int) -> dict:
        """metrics.json's `collision` object of `run` (docs/contracts.md)."""
        least = {part: {"clearance_m": float(min(self.least[run, i], WATCH)), "time_s": float(self.least_time[run, i])}
                 for i, part in enumerate(self.parts)}
        return {"watch_m": WATCH, "pile": least, "contacts": self._contacts.events(run),
                "interventions": [], "periods": int(self.periods[run]), "measured_periods": int(self.checks[run])}


@dataclass(frozen=True)
class MountedShapes:
    """The checked shapes as the compiled kernel poses them: each one's kind, half sizes, mount
    (position and rotation at q = 0, and which joints move it), and the joints' anchors and axes."""

    kinds: np.ndarray  # (n,) BOX or CAPSULE
    halves: np.ndarray  # (n, 3) m
    positions: np.ndarray  # (n, 3) m
    rotations: np.ndarray  # (n, 3, 3)
    joints: np.ndarray  # (n,) how many of travel, slew, luff move each (the chain is serial)
    anchor: np.ndarray  # (3, 3) m, each joint's anchor
    axis: np.ndarray  # (3, 3) each joint's axis

    @classmethod
    def of(cls, shapes: Sequence[CollisionShape]) -> MountedShapes:
        n = len(shapes)
        return cls(kinds=np.array([s.kind for s in shapes], dtype=np.int64),
                   halves=np.array([s.half for s in shapes]).reshape(n, 3),
                   positions=np.array([s.mount.position for s in shapes]).reshape(n, 3),
                   rotations=np.array([s.mount.rotation for s in shapes]).reshape(n, 3, 3),
                   joints=np.array([s.mount.joints for s in shapes], dtype=np.int64),
                   anchor=shapes[0].mount.anchor if shapes else np.zeros((3, 3)),
                   axis=shapes[0].mount.axis if shapes else np.zeros((3, 3)))


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
def _due(moved, measured, watch, recheck, near) -> bool:  # pragma: no cover - compiled
    """Whether a run that may have `moved` (m) since its shapes' last `measured` (shapes,) is to
    be measured again (its module's docstring)."""
    least = watch
    for i in range(len(measured)):
        least = min(least, measured[i])
    return not (moved < recheck * least and least > near)


@numba.njit(cache=True)
def _carried(runs, qd, levers, period, watch, recheck, near,
             periods, moved, measured, now):  # pragma: no cover - compiled
    """The period counted and each run's motion added to what it may have moved; the runs not due
    carry their lower bounds in `now`. Whether any run is due to be measured."""
    any_due = False
    for run in runs:
        periods[run] += 1
        moved[run] += (abs(qd[run, 0]) * levers[0] + abs(qd[run, 1]) * levers[1] + abs(qd[run, 2]) * levers[2]) * period
        if _due(moved[run], measured[run], watch, recheck, near):
            any_due = True
        else:
            for i in range(measured.shape[1]):
                now[run, i] = measured[run, i] - moved[run]
    return any_due


@numba.njit(cache=True)
def _clearances(heights, x0, y0, spacing, runs, q, kinds, halves, positions0, rotations0, joints, anchor, axis,
                watch, recheck, near, time, moved, measured, now, checks, least_measured, least_time,
                open_contacts):  # pragma: no cover - compiled
    """The shapes of each run `_carried` found due measured, their least measures so far and
    their `time` (s). Whether a shape measured touches the pile or has a contact open (only a
    measured run can: one that is not lies farther than `near`)."""
    position, rotation = np.empty(3), np.empty((3, 3))
    contact = False
    for run in runs:
        if not _due(moved[run], measured[run], watch, recheck, near):
            continue
        for i in range(len(kinds)):
            site_pose(q[run], positions0[i], rotations0[i], joints[i], anchor, axis, position, rotation)
            measured[run, i] = shape_clearance(heights[run], x0, y0, spacing, kinds[i], halves[i], position, rotation,
                                               watch)
            now[run, i] = measured[run, i]
            if measured[run, i] < least_measured[run, i]:
                least_measured[run, i], least_time[run, i] = measured[run, i], time
            contact = contact or measured[run, i] <= 0.0 or open_contacts[run, i] >= 0
        moved[run] = 0.0
        checks[run] += 1
    return contact
