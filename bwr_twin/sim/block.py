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

from dataclasses import dataclass

import numpy as np

from bwr_twin.signals import NEIGHBOUR, RECLAIM, Signal

BLOCK = 500  # control periods a block: 5 s at 100 Hz, a few MB for 128 runs
_UNREAD = ("belt_scale", "wheel_current")  # a reclaim's instrument readings: NaN on a machine without them


class Block:
    """Rows of raw signals for the periods of the current block, all (length, runs, ...) arrays.

    Attributes written at row `row` of each period:
        q, qd: (length + 1, runs, 3) the true joint state at the period's start (row + 1: its end).
        signals: the period's own rows (`PeriodRows`): what was measured, commanded and applied.
        applied: (runs, 3) the drive forces applied this period, where a drive stage overrides the command.
    """

    def __init__(self, runs: int, length: int, *, own_reference: bool, reclaim: bool, neighbour: bool,
                 controller: tuple[Signal, ...] = ()):
        self.runs, self.length = runs, length
        self.q, self.qd = np.zeros((length + 1, runs, 3)), np.zeros((length + 1, runs, 3))
        self.signals = PeriodRows.zeros(runs, length, own_reference=own_reference, reclaim=reclaim,
                                        neighbour=neighbour, controller=controller)
        self.applied = np.zeros((runs, 3))
        self.start = 0  # the block's first period
        self.row = 0  # the current period's row
        self.rows = [Row.of(self, i) for i in range(length)]  # each row's views, made once

    def with_controller(self, signals: tuple[Signal, ...]) -> Block:
        """A block like this one, before its first period, that also keeps the controller's signals."""
        rows = self.signals
        block = Block(self.runs, self.length, own_reference=rows.reference is not None,
                      reclaim=rows.reclaim is not None, neighbour=rows.neighbour is not None, controller=signals)
        block.q[0], block.qd[0] = self.q[0], self.qd[0]
        return block

    def roll(self) -> None:
        """The rows written so far are reduced: the last period's end is the next block's start."""
        n = self.row
        self.q[0], self.qd[0] = self.q[n], self.qd[n]
        self.start, self.row = self.start + n, 0


@dataclass(frozen=True)
class PeriodRows:
    """A block's rows of what each period measured, commanded and applied, (length, runs, ...),
    made once and written in place; the true state, which has a row more, is the block's own.

    q_measured, qd_measured, command, drive_force, disturbance: (length, runs, 3).
    gust: (length, runs) m/s on each run's mean wind.
    reference: a per-run reference's (q, qd, qdd desired) rows, or None for a path shared by
        every run, read from the path itself.
    controller: {name: (length, runs, width)} the controller's declared signals.
    reclaim: {name: rows} a stockpile's signals (bwr_twin.signals.RECLAIM), or None.
    neighbour: {name: (length, runs, 3)} a second machine's signals (bwr_twin.signals.NEIGHBOUR), or None.
    """

    q_measured: np.ndarray
    qd_measured: np.ndarray
    command: np.ndarray
    drive_force: np.ndarray
    disturbance: np.ndarray
    gust: np.ndarray
    reference: tuple[np.ndarray, np.ndarray, np.ndarray] | None
    controller: dict[str, np.ndarray]
    reclaim: dict[str, np.ndarray] | None
    neighbour: dict[str, np.ndarray] | None

    @classmethod
    def zeros(cls, runs: int, length: int, *, own_reference: bool, reclaim: bool, neighbour: bool,
              controller: tuple[Signal, ...]) -> PeriodRows:
        """Zero rows (NaN for a reclaim's instrument readings, which a machine without them leaves unread)."""
        q_measured, qd_measured, command, drive_force, disturbance = (np.zeros((length, runs, 3)) for _ in range(5))
        return cls(
            q_measured, qd_measured, command, drive_force, disturbance, np.zeros((length, runs)),
            tuple(np.zeros((length, runs, 3)) for _ in range(3)) if own_reference else None,
            {s.name: np.zeros((length, runs, s.width)) for s in controller},
            {name: np.full((length, runs) + ((width,) if width > 1 else ()), np.nan if name in _UNREAD else 0.0)
             for name, _, width in RECLAIM} if reclaim else None,
            {s.name: np.zeros((length, runs, 3)) for s in NEIGHBOUR} if neighbour else None,
        )


@dataclass(frozen=True, slots=True)
class Row:
    """Views of one row of a block, made once: indexing the block anew every period would cost
    more than writing the row. `q_measured_view` and `qd_measured_view` are read-only, for drivers."""

    q: np.ndarray
    qd: np.ndarray
    q_next: np.ndarray
    qd_next: np.ndarray
    q_measured: np.ndarray
    qd_measured: np.ndarray
    q_measured_view: np.ndarray
    qd_measured_view: np.ndarray
    command: np.ndarray
    drive_force: np.ndarray
    disturbance: np.ndarray
    gust: np.ndarray
    reference: tuple[np.ndarray, np.ndarray, np.ndarray] | None
    controller: tuple[tuple[str, np.ndarray], ...]
    reclaim: dict[str, np.ndarray] | None
    neighbour: tuple[np.ndarray, ...] | None  # (q_desired, q) of a neighbour's row

    @classmethod
    def of(cls, block: Block, i: int) -> Row:
        rows = block.signals
        q_measured, qd_measured = rows.q_measured[i], rows.qd_measured[i]
        return cls(
            block.q[i], block.qd[i], block.q[i + 1], block.qd[i + 1], q_measured, qd_measured,
            read_only(q_measured), read_only(qd_measured),
            rows.command[i], rows.drive_force[i], rows.disturbance[i], rows.gust[i],
            None if rows.reference is None else tuple(r[i] for r in rows.reference),
            tuple((name, r[i]) for name, r in rows.controller.items()),
            None if rows.reclaim is None else {name: r[i] for name, r in rows.reclaim.items()},
            None if rows.neighbour is None else tuple(rows.neighbour[s.name][i] for s in NEIGHBOUR),
        )


def read_only(array: np.ndarray) -> np.ndarray:
    """A view of `array` that cannot be written."""
    view = array.view()
    view.flags.writeable = False
    return view
