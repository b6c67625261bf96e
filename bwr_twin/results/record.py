"""What a run leaves in memory: its signals at the record period, and its metrics.

`Recorder` keeps every run of a lockstep at the scene's `record_period` (the control rate is
kept only by the online metrics, `bwr_twin.results.metrics`), so a thousand 700 s runs fit in a
few GB. `RunResult` is one run's share.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bwr_twin.config.scene import Scene
from bwr_twin.model.machine import Machine
from bwr_twin.planning.trajectory import Trajectory
from bwr_twin.stockpile.reclaim import ReclaimRecord

# The (runs, 3) signals recorded, as RunResult names them.
SIGNALS = (
    "q_desired",
    "q",
    "q_measured",
    "qd_desired",
    "qd",
    "qd_measured",
    "qdd_desired",
    "qdd",
    "fuzzy_output",
    "acceleration_command",
    "drive_force_command",
    "drive_force",
    "disturbance",  # the random disturbance plus the digging load, on the joints
)


@dataclass
class RunResult:
    """Every signal of one run at the record period, and its metrics at the control period.

    Arrays are (n,) or (n, 3), per axis in the order travel, slew, luff, in SI units (m, rad, s,
    N, N m). `qdd` is the mean acceleration over the control period that starts at each sample.
    """

    scene: Scene
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
    fuzzy_output: np.ndarray  # FLC output, dimensionless (the output universe)
    acceleration_command: np.ndarray  # u
    drive_force_command: np.ndarray  # tau from the controller
    drive_force: np.ndarray  # what the actuators applied (after their force limits)
    disturbance: np.ndarray
    wind_speed: np.ndarray  # (n,), m/s along the wind direction
    reclaim: ReclaimRecord | None = None  # the pile and the reclaim signals, if the scene has a stockpile

    @property
    def cp_desired(self) -> np.ndarray:
        return self.machine.fk(self.q_desired)

    @property
    def cp(self) -> np.ndarray:
        return self.machine.fk(self.q)


class Recorder:
    """The signals of every run of a lockstep at the record period: (rows, runs, 3) arrays.

    Samples are control periods 0..n-1; every `every`-th one is kept, and always the last.
    """

    def __init__(self, samples: int, every: int, runs: int):
        kept = np.arange(0, samples, every)
        if kept[-1] != samples - 1:
            kept = np.append(kept, samples - 1)
        self.samples = kept
        self._row = np.full(samples, -1)
        self._row[kept] = np.arange(len(kept))
        self.signals = {name: np.zeros((len(kept), runs, 3)) for name in SIGNALS}
        self.wind_speed = np.zeros((len(kept), runs))

    def end_at(self, samples: int) -> None:
        """The run ends after `samples` control periods, sooner than planned: its last sample is kept."""
        kept = self.samples[self.samples < samples - 1]
        self.samples = np.append(kept, samples - 1)
        self._row[samples - 1] = len(kept)

    @property
    def rows(self) -> int:
        """How many rows the record holds."""
        return len(self.samples)

    def row(self, k: int) -> int:
        """The row that keeps sample k, or -1."""
        return int(self._row[k])

    def run_result(self, run: int, *, scene: Scene, machine: Machine, trajectory: Trajectory,
                   time: np.ndarray, metrics: dict) -> RunResult:
        """Run `run`'s share, as contiguous arrays of its own."""
        rows = self.rows
        signals = {name: np.ascontiguousarray(values[:rows, run]) for name, values in self.signals.items()}
        return RunResult(scene=scene, machine=machine, trajectory=trajectory, metrics=metrics,
                         time=time[self.samples], wind_speed=self.wind_speed[:rows, run].copy(), **signals)
