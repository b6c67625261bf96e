"""What a run leaves in memory: its signals at the record period, and its metrics.

`Recorder` keeps every run of a lockstep at the scene's `record_period` (the control rate is
kept only by the metrics, `bwr_twin.sim.metrics`), so a thousand 700 s runs fit in a few GB.
`RunResult` is one run's share. Which signals there are is `bwr_twin.sim.signals`' schema.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from bwr_twin.model.machine import Machine
from bwr_twin.planning.trajectory import Trajectory
from bwr_twin.signals import LOOP, NEIGHBOUR, RECLAIM, Signal


@dataclass
class ReclaimRecord:
    """One run's reclaim signals at the record period, and its pile."""

    rate: np.ndarray  # (n,) t/h carried away
    cut_depth: np.ndarray  # (n,) m
    digging_force: np.ndarray  # (n, 3) N on the wheel, world frame
    wheel_power: np.ndarray  # (n,) W
    belt_scale: np.ndarray  # (n,) t/h as the belt scale reads it, NaN without one (bwr_twin.sensing.rate_instruments)
    wheel_current: np.ndarray  # (n,) A of the wheel motor as its drive measures it, NaN without one
    x: np.ndarray  # grid lines, m
    y: np.ndarray
    z_start: np.ndarray  # (ny, nx) m
    z_end: np.ndarray
    history: Any  # bwr_twin.stockpile.history.PileHistory: the pile as it was dug, if kept; else None
    # On a stacked pile, the grade that left it (bwr_twin.stockpile.reclaim.Reclaim.grade_out); else None
    grade_out: dict | None = None


@dataclass
class RunResult:
    """Every signal of one run at the record period, and its metrics at the control period.

    Arrays are (n,) or (n, 3), per axis in the order travel, slew, luff, in SI units (m, rad, s,
    N, N m). `qdd` is the mean acceleration over the control period that starts at each sample.
    `controller_signals` holds the signals the controller declares (`Controller.signals`), by
    name: the fuzzy controller's `fuzzy_output` and `acceleration_command`, say.
    """

    scene: Any  # bwr_twin.config.scene.Scene
    machine: Machine  # the plant's
    trajectory: Trajectory
    metrics: dict  # as metrics.json holds them
    time: np.ndarray
    q_desired: np.ndarray
    q: np.ndarray
    q_measured: np.ndarray
    qd_desired: np.ndarray
    qd: np.ndarray
    qd_measured: np.ndarray
    qdd_desired: np.ndarray
    qdd: np.ndarray
    drive_force_command: np.ndarray  # tau from the controller
    drive_force: np.ndarray  # what the actuators applied (after their force limits)
    disturbance: np.ndarray
    wind_speed: np.ndarray  # (n,), m/s along the wind direction
    controller_signals: dict[str, np.ndarray] = field(default_factory=dict)
    signal_schema: tuple[Signal, ...] = ()  # the controller's, in its order
    reclaim: ReclaimRecord | None = None  # the pile and the reclaim signals, if the scene has a stockpile
    scan: Any = None  # bwr_twin.sensing.outputs.ScanRecord: the scans and the scanned pile, if the machine scans
    # A second machine on the rail: {"q_desired", "q"} (n, 3) its schedule and its true joints, or None
    neighbour: dict[str, np.ndarray] | None = None
    stacking: Any = None  # bwr_twin.stockpile.stacking.StackingRecord: the deposits and the pile built, if it stacks

    @property
    def cp_desired(self) -> np.ndarray:
        return self.machine.fk(self.q_desired)

    @property
    def cp(self) -> np.ndarray:
        return self.machine.fk(self.q)


class Recorder:
    """The signals of every run of a lockstep at the record period: (runs, rows, ...) arrays,
    each run's rows its own, so that a run's share is a view of them, never a copy.

    Samples are control periods 0..n-1; every `every`-th one is kept, and always the last.
    """

    def __init__(self, samples: int, every: int, runs: int, controller_signals: tuple[Signal, ...] = (),
                 reclaim: bool = False, neighbour: bool = False):
        self.every = every
        self._keep(samples)
        rows = len(self.samples)
        self.controller_schema = tuple(controller_signals)
        self.signals = {s.name: np.zeros((runs, rows, s.width)) for s in LOOP + self.controller_schema}
        self.wind_speed = np.zeros((runs, rows))
        self.reclaim = {name: np.zeros((runs, rows) + ((width,) if width > 1 else ()))
                        for name, _, width in RECLAIM} if reclaim else None
        self.neighbour = {s.name: np.zeros((runs, rows, 3)) for s in NEIGHBOUR} if neighbour else None

    def _keep(self, samples: int) -> None:
        """Which of `samples` control periods are kept: every `every`-th one, and the last."""
        kept = np.arange(0, samples, self.every)
        if kept[-1] != samples - 1:
            kept = np.append(kept, samples - 1)
        self.samples = kept
        self.row_of = np.full(samples, -1)  # the row that keeps each sample, or -1
        self.row_of[kept] = np.arange(len(kept))

    @staticmethod
    def put(table: np.ndarray, at: slice | np.ndarray, values: np.ndarray) -> None:
        """Write `values` (len(at), runs, ...), a block's rows as the loop holds them, into the
        rows `at` of `table` (runs, rows, ...)."""
        table[:, at] = np.swapaxes(values, 0, 1)

    def extend_to(self, samples: int) -> None:
        """The runs go on for `samples` control periods in all, more than the record was sized
        for; the rows kept so far stay (the old last sample, off the grid, is not yet recorded)."""
        on_grid = int(np.count_nonzero(self.samples % self.every == 0))
        self._keep(samples)
        rows = len(self.samples)

        def grown(values: np.ndarray) -> np.ndarray:
            array = np.zeros((values.shape[0], rows) + values.shape[2:])
            array[:, :on_grid] = values[:, :on_grid]
            return array

        self.signals = {name: grown(values) for name, values in self.signals.items()}
        self.wind_speed = grown(self.wind_speed)
        if self.reclaim is not None:
            self.reclaim = {name: grown(values) for name, values in self.reclaim.items()}
        if self.neighbour is not None:
            self.neighbour = {name: grown(values) for name, values in self.neighbour.items()}

    def end_at(self, samples: int) -> None:
        """The run ends after `samples` control periods, sooner than planned: its last sample is kept."""
        kept = self.samples[self.samples < samples - 1]
        self.samples = np.append(kept, samples - 1)
        self.row_of[samples - 1] = len(kept)

    @property
    def rows(self) -> int:
        """How many rows the record holds."""
        return len(self.samples)

    def run_result(self, run: int, *, scene: Any, machine: Machine, trajectory: Trajectory,
                   time: np.ndarray, metrics: dict) -> RunResult:
        """Run `run`'s share: views of its own rows."""
        rows = self.rows
        share = {name: values[run, :rows] for name, values in self.signals.items()}
        controller = {s.name: share.pop(s.name) for s in self.controller_schema}
        neighbour = (None if self.neighbour is None
                     else {name: values[run, :rows] for name, values in self.neighbour.items()})
        return RunResult(scene=scene, machine=machine, trajectory=trajectory, metrics=metrics,
                         time=time[self.samples], wind_speed=self.wind_speed[run, :rows],
                         controller_signals=controller, signal_schema=self.controller_schema, neighbour=neighbour,
                         **share)

    def reclaim_share(self, run: int) -> dict[str, np.ndarray]:
        """Run `run`'s reclaim signals (ReclaimRecord's names), over the rows kept."""
        return {name: values[run, : self.rows] for name, values in self.reclaim.items()}
