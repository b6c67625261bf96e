"""The observer: it only watches. The loop writes each period's raw signals into a row of the
observer's block; a full block is reduced into the metrics and the record along time, with
whole-array operations, and the loop never waits on either.

A block holds BLOCK control periods. The true state has one row more: a period's end is the
next period's start, so the mean acceleration and power of the block's last period are known
from its extra row, which becomes the next block's first.
"""

from __future__ import annotations

import numpy as np

from bwr_twin.model.machine import Machine
from bwr_twin.signals import LOOP, NEIGHBOUR, RECLAIM, Signal
from bwr_twin.sim.metrics import Metrics
from bwr_twin.sim.record import Recorder

BLOCK = 500  # control periods a block: 5 s at 100 Hz, a few MB for 128 runs


class Observer:
    """Rows of raw signals for the periods of the current block, all (BLOCK, runs, ...) arrays.

    Attributes written by the loop at row `row` (= k - start) of each period k:
        q, qd: (BLOCK + 1, runs, 3) the true joint state at the period's start (row + 1: its end).
        q_measured, qd_measured, command, drive_force, disturbance: (BLOCK, runs, 3).
        gust: (BLOCK, runs) m/s on each run's mean wind.
        q_desired, qd_desired, qdd_desired: a per-run reference's rows (None for a path shared
            by every run, which the observer reads from `path` itself).
        controller: {name: (BLOCK, runs, width)} the controller's declared signals.
        reclaim: {name: rows} a stockpile's signals (bwr_twin.sim.signals.RECLAIM), or None.
        neighbour: {name: (BLOCK, runs, 3)} a second machine's signals (bwr_twin.signals.NEIGHBOUR), or None.
    """

    def __init__(self, runs: int, samples: int, period: float, record_every: int, machine: Machine, *,
                 path: tuple[np.ndarray, np.ndarray, np.ndarray] | None, wind_mean: np.ndarray,
                 reclaim: bool, neighbour: bool = False):
        """`path`: the shared reference's (samples, 3) position, velocity and acceleration rows,
        or None for a reference of each run's own."""
        self.runs, self.period, self.machine = runs, period, machine
        self._path = path
        self._wind_mean = wind_mean
        self.metrics = Metrics(runs, machine.drive_limits, machine.envelope, machine.joint_range, period)
        self._record_every = record_every
        self.recorder = Recorder(samples, record_every, runs, reclaim=reclaim, neighbour=neighbour)
        self.q, self.qd = np.zeros((BLOCK + 1, runs, 3)), np.zeros((BLOCK + 1, runs, 3))
        (self.q_measured, self.qd_measured, self.command, self.drive_force,
         self.disturbance) = (np.zeros((BLOCK, runs, 3)) for _ in range(5))
        self.gust = np.zeros((BLOCK, runs))
        self.q_desired = self.qd_desired = self.qdd_desired = None
        if path is None:
            self.q_desired, self.qd_desired, self.qdd_desired = (np.zeros((BLOCK, runs, 3)) for _ in range(3))
        self.controller: dict[str, np.ndarray] = {}
        self.reclaim = {name: np.zeros((BLOCK, runs) + ((width,) if width > 1 else ()))
                        for name, _, width in RECLAIM} if reclaim else None
        self.neighbour = {s.name: np.zeros((BLOCK, runs, 3)) for s in NEIGHBOUR} if neighbour else None
        self.start = 0  # the block's first sample
        self.row = 0  # the current period's row
        self.rows = [Row(self, i) for i in range(BLOCK)]  # each row's views, made once

    def watch_controller(self, signals: tuple[Signal, ...], samples: int) -> None:
        """Record the controller's declared signals too; before the first period."""
        self.recorder = Recorder(samples, self._record_every, self.runs, signals, reclaim=self.reclaim is not None,
                                 neighbour=self.neighbour is not None)
        self.controller = {s.name: np.zeros((BLOCK, self.runs, s.width)) for s in signals}
        self.rows = [Row(self, i) for i in range(BLOCK)]

    def period_done(self) -> None:
        """The current period's row is written (and its end state in the row after): on to the next."""
        self.row += 1
        if self.row == BLOCK:
            self.flush()

    def flush(self) -> None:
        """Reduce the rows written so far into the metrics and the record, and start a new block."""
        n, start = self.row, self.start
        if n == 0:
            return
        reference = self._reference(start, n)
        self.metrics.add_block(start, self.q[: n + 1], self.qd[: n + 1], *reference, self.command[:n],
                               self.drive_force[:n])
        self._record(start, n, reference)
        self.q[0], self.qd[0] = self.q[n], self.qd[n]
        self.start, self.row = start + n, 0

    def end_at(self, samples: int) -> None:
        """The runs end after `samples` periods, sooner than the record was sized for."""
        self.recorder.end_at(samples)

    def extend_to(self, samples: int) -> None:
        """The runs go on for `samples` periods in all, longer than the record was sized for."""
        self.recorder.extend_to(samples)

    def _reference(self, start: int, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The block's reference: (n, 1, 3) rows of the shared path, or the runs' own (n, runs, 3)."""
        if self._path is None:
            return self.q_desired[:n], self.qd_desired[:n], self.qdd_desired[:n]
        return tuple(rows[start : start + n, None, :] for rows in self._path)

    def _record(self, start: int, n: int, reference: tuple[np.ndarray, np.ndarray, np.ndarray]) -> None:
        """Copy the block's recorded samples into the record; their CP error into the metrics."""
        recorder = self.recorder
        rows = recorder.row_of[start : start + n]
        picked = np.flatnonzero(rows >= 0)
        if not picked.size:
            return
        at = rows[picked]
        signals = recorder.signals
        q_desired, qd_desired, qdd_desired = (np.broadcast_to(r[picked], (len(picked), self.runs, 3))
                                              for r in reference)
        qdd = (self.qd[picked + 1] - self.qd[picked]) / self.period
        values = {"q_desired": q_desired, "q": self.q[picked], "q_measured": self.q_measured[picked],
                  "qd_desired": qd_desired, "qd": self.qd[picked], "qd_measured": self.qd_measured[picked],
                  "qdd_desired": qdd_desired, "qdd": qdd, "drive_force_command": self.command[picked],
                  "drive_force": self.drive_force[picked], "disturbance": self.disturbance[picked]}
        for signal in LOOP:  # the schema's signals, each from its rows
            signals[signal.name][at] = values[signal.name]
        for name, values in self.controller.items():
            signals[name][at] = values[picked]
        recorder.wind_speed[at] = self._wind_mean + self.gust[picked]
        if self.reclaim is not None:
            for name, values in self.reclaim.items():
                recorder.reclaim[name][at] = values[picked]
        if self.neighbour is not None:
            for name, values in self.neighbour.items():
                recorder.neighbour[name][at] = values[picked]
        fk = self.machine.fk
        cp_error = np.linalg.norm(fk(q_desired) - fk(self.q[picked]), axis=-1)
        self.metrics.add_cp_error(start + picked, cp_error)


class Row:
    """Views of one row of an observer's block, made once: indexing the block anew every period
    would cost more than writing the row."""

    __slots__ = ("q", "qd", "q_next", "qd_next", "q_measured", "qd_measured", "command", "drive_force",
                 "disturbance", "gust", "reference", "controller", "reclaim", "neighbour")

    def __init__(self, observer: Observer, i: int):
        o = observer
        self.q, self.qd, self.q_next, self.qd_next = o.q[i], o.qd[i], o.q[i + 1], o.qd[i + 1]
        self.q_measured, self.qd_measured = o.q_measured[i], o.qd_measured[i]
        self.command, self.drive_force, self.disturbance, self.gust = (o.command[i], o.drive_force[i],
                                                                       o.disturbance[i], o.gust[i])
        self.reference = None if o.q_desired is None else (o.q_desired[i], o.qd_desired[i], o.qdd_desired[i])
        self.controller = tuple((name, rows[i]) for name, rows in o.controller.items())
        self.reclaim = None if o.reclaim is None else tuple(rows[i] for rows in o.reclaim.values())
        # (q_desired, q) of a neighbour's row
        self.neighbour = None if o.neighbour is None else tuple(o.neighbour[s.name][i] for s in NEIGHBOUR)
