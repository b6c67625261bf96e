"""The loop's working rows: each control period's raw signals, a block of periods at a time.

The loop writes period k's signals into row `row` (= k - start) of its block; when the block is
full, whoever observes the runs reduces it (bwr_twin.sim.observer) and the block rolls over. A
driver that keeps no results (a learning agent's environment) has a block of one row, rolled
every period.

The true state has one row more than the block: a period's end is the next period's start, so
the mean acceleration and power of the block's last period are known from its extra row, which
becomes the next block's first.
"""

from __future__ import annotations

import numpy as np

from bwr_twin.signals import NEIGHBOUR, RECLAIM, Signal

BLOCK = 500  # control periods a block: 5 s at 100 Hz, a few MB for 128 runs
_UNREAD = ("belt_scale", "wheel_current")  # a reclaim's instrument readings: NaN on a machine without them


class Block:
    """Rows of raw signals for the periods of the current block, all (length, runs, ...) arrays.

    Attributes written at row `row` of each period:
        q, qd: (length + 1, runs, 3) the true joint state at the period's start (row + 1: its end).
        q_measured, qd_measured, command, drive_force, disturbance: (length, runs, 3).
        gust: (length, runs) m/s on each run's mean wind.
        q_desired, qd_desired, qdd_desired: a per-run reference's rows (None for a path shared
            by every run, read from the path itself).
        controller: {name: (length, runs, width)} the controller's declared signals.
        reclaim: {name: rows} a stockpile's signals (bwr_twin.signals.RECLAIM), or None.
        neighbour: {name: (length, runs, 3)} a second machine's signals (bwr_twin.signals.NEIGHBOUR), or None.
        applied: (runs, 3) the drive forces applied this period, where a drive stage overrides the command.
    """

    def __init__(self, runs: int, length: int, *, own_reference: bool, reclaim: bool, neighbour: bool,
                 controller: tuple[Signal, ...] = ()):
        self.runs, self.length = runs, length
        self.q, self.qd = np.zeros((length + 1, runs, 3)), np.zeros((length + 1, runs, 3))
        (self.q_measured, self.qd_measured, self.command, self.drive_force,
         self.disturbance) = (np.zeros((length, runs, 3)) for _ in range(5))
        self.gust = np.zeros((length, runs))
        self.q_desired = self.qd_desired = self.qdd_desired = None
        if own_reference:
            self.q_desired, self.qd_desired, self.qdd_desired = (np.zeros((length, runs, 3)) for _ in range(3))
        self.controller = {s.name: np.zeros((length, runs, s.width)) for s in controller}
        self.reclaim = {name: np.full((length, runs) + ((width,) if width > 1 else ()),
                                      np.nan if name in _UNREAD else 0.0)
                        for name, _, width in RECLAIM} if reclaim else None
        self.neighbour = {s.name: np.zeros((length, runs, 3)) for s in NEIGHBOUR} if neighbour else None
        self.applied = np.zeros((runs, 3))
        self.start = 0  # the block's first period
        self.row = 0  # the current period's row
        self.rows = [Row(self, i) for i in range(length)]  # each row's views, made once

    def with_controller(self, signals: tuple[Signal, ...]) -> Block:
        """A block like this one, before its first period, that also keeps the controller's signals."""
        block = Block(self.runs, self.length, own_reference=self.q_desired is not None,
                      reclaim=self.reclaim is not None, neighbour=self.neighbour is not None, controller=signals)
        block.q[0], block.qd[0] = self.q[0], self.qd[0]
        return block

    def roll(self) -> None:
        """The rows written so far are reduced: the last period's end is the next block's start."""
        n = self.row
        self.q[0], self.qd[0] = self.q[n], self.qd[n]
        self.start, self.row = self.start + n, 0


class Row:
    """Views of one row of a block, made once: indexing the block anew every period would cost
    more than writing the row. `q_measured_view` and `qd_measured_view` are read-only, for drivers."""

    __slots__ = ("q", "qd", "q_next", "qd_next", "q_measured", "qd_measured", "q_measured_view",
                 "qd_measured_view", "command", "drive_force", "disturbance", "gust", "reference", "controller",
                 "reclaim", "neighbour")

    def __init__(self, block: Block, i: int):
        b = block
        self.q, self.qd, self.q_next, self.qd_next = b.q[i], b.qd[i], b.q[i + 1], b.qd[i + 1]
        self.q_measured, self.qd_measured = b.q_measured[i], b.qd_measured[i]
        self.q_measured_view, self.qd_measured_view = read_only(self.q_measured), read_only(self.qd_measured)
        self.command, self.drive_force, self.disturbance, self.gust = (b.command[i], b.drive_force[i],
                                                                       b.disturbance[i], b.gust[i])
        self.reference = None if b.q_desired is None else (b.q_desired[i], b.qd_desired[i], b.qdd_desired[i])
        self.controller = tuple((name, rows[i]) for name, rows in b.controller.items())
        self.reclaim = None if b.reclaim is None else {name: rows[i] for name, rows in b.reclaim.items()}
        # (q_desired, q) of a neighbour's row
        self.neighbour = None if b.neighbour is None else tuple(b.neighbour[s.name][i] for s in NEIGHBOUR)


def read_only(array: np.ndarray) -> np.ndarray:
    """A view of `array` that cannot be written."""
    view = array.view()
    view.flags.writeable = False
    return view
