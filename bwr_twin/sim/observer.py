"""The observer: it only watches. A full block of the loop's rows (bwr_twin.sim.block) is
reduced into the metrics and the record along time, with whole-array operations, and the loop
never waits on either.
"""

from __future__ import annotations

import numpy as np

from bwr_twin.model.machine import Machine
from bwr_twin.signals import LOOP, Signal
from bwr_twin.sim.block import Block
from bwr_twin.sim.metrics import Metrics
from bwr_twin.sim.record import Recorder


class Observer:
    """The metrics and the record of a lockstep's runs, reduced from the loop's blocks."""

    def __init__(self, runs: int, samples: int, period: float, record_every: int, machine: Machine, *,
                 path: tuple[np.ndarray, np.ndarray, np.ndarray] | None, wind_mean: np.ndarray,
                 reclaim: bool, neighbour: bool = False):
        """`path`: the shared reference's (samples, 3) position, velocity and acceleration rows,
        or None for a reference of each run's own, which the blocks hold."""
        self.runs, self.period, self.machine = runs, period, machine
        self._path = path
        self._wind_mean = wind_mean
        self.metrics = Metrics(runs, machine.drive_limits, machine.envelope, machine.joint_range, period)
        self._record_every = record_every
        self._kinds = {"reclaim": reclaim, "neighbour": neighbour}
        self.recorder = Recorder(samples, record_every, runs, reclaim=reclaim, neighbour=neighbour)

    def watch_controller(self, signals: tuple[Signal, ...], samples: int) -> None:
        """Record the controller's declared signals too; before the first period."""
        self.recorder = Recorder(samples, self._record_every, self.runs, signals, **self._kinds)

    def reduce(self, block: Block) -> None:
        """Reduce the rows `block` holds so far into the metrics and the record."""
        n, start = block.row, block.start
        if n == 0:
            return
        reference = self._reference(block, n)
        period = block.signals
        self.metrics.add_block(start, block.q[: n + 1], block.qd[: n + 1], *reference, period.command[:n],
                               period.drive_force[:n])
        self._record(block, n, reference)

    def end_at(self, samples: int) -> None:
        """The runs end after `samples` periods, sooner than the record was sized for."""
        self.recorder.end_at(samples)

    def extend_to(self, samples: int) -> None:
        """The runs go on for `samples` periods in all, longer than the record was sized for."""
        self.recorder.extend_to(samples)

    def _reference(self, block: Block, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The block's reference: (n, 1, 3) rows of the shared path, or the runs' own (n, runs, 3)."""
        if self._path is None:
            return tuple(rows[:n] for rows in block.signals.reference)
        start = block.start
        return tuple(rows[start : start + n, None, :] for rows in self._path)

    def _record(self, block: Block, n: int, reference: tuple[np.ndarray, np.ndarray, np.ndarray]) -> None:
        """Copy the block's recorded samples into the record; their CP error into the metrics."""
        recorder, start = self.recorder, block.start
        rows = recorder.row_of[start : start + n]
        picked = np.flatnonzero(rows >= 0)
        if not picked.size:
            return
        at = rows[picked]
        if at[-1] - at[0] + 1 == len(at):  # kept rows are numbered in order: a slice writes faster
            at = slice(int(at[0]), int(at[-1]) + 1)
        put, signals = recorder.put, recorder.signals
        q_desired, qd_desired, qdd_desired = (np.broadcast_to(r[picked], (len(picked), self.runs, 3))
                                              for r in reference)
        qdd = (block.qd[picked + 1] - block.qd[picked]) / self.period
        period = block.signals
        values = {"q_desired": q_desired, "q": block.q[picked], "q_measured": period.q_measured[picked],
                  "qd_desired": qd_desired, "qd": block.qd[picked], "qd_measured": period.qd_measured[picked],
                  "qdd_desired": qdd_desired, "qdd": qdd, "drive_force_command": period.command[picked],
                  "drive_force": period.drive_force[picked], "disturbance": period.disturbance[picked]}
        for signal in LOOP:  # the schema's signals, each from its rows
            put(signals[signal.name], at, values[signal.name])
        for name, values in period.controller.items():
            put(signals[name], at, values[picked])
        put(recorder.wind_speed, at, self._wind_mean + period.gust[picked])
        if period.reclaim is not None:
            for name, values in period.reclaim.items():
                put(recorder.reclaim[name], at, values[picked])
        if period.neighbour is not None:
            for name, values in period.neighbour.items():
                put(recorder.neighbour[name], at, values[picked])
        fk = self.machine.fk
        cp_error = np.linalg.norm(fk(q_desired) - fk(block.q[picked]), axis=-1)
        self.metrics.add_cp_error(start + picked, cp_error)
