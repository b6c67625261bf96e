"""What the shadow measures of a machine: per sample its encoders' positions and speeds and its
drives' forces, from a recorded log; and where the record has a gap.

The drive's force is the force the drive says it applies: its command, within its rating. A
derated drive delivers less than it says, which is how the shadow sees the derate; so the log's
`drive_force_command` is read, not the twin's own `drive_force` (what the actuators really
applied, which no real machine reports).

The drives' speed feedback (a motor encoder behind the gear, or the converter's speed estimate)
is a second sensor of each axis's speed, independent of the position encoder: against it an
encoder that drifts or sticks shows, which no force can (a drift shifts position and speed
alike, and the dynamics barely depend on either). A twin's log records it as `qd_actual`.

The wind, where the machine's anemometer is logged, is a force on the machine that no drive
applied: the shadow's twin applies it (bwr_twin.model.wind), or a gust would read as a fault.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from bwr_twin.errors import BwrError
from bwr_twin.results.run_files import read_scene, read_timeseries
from bwr_twin.results.rundir import SCENE_FILE

GAP = 1.5  # a step between samples longer than this many sampling periods is a gap


@dataclass(frozen=True)
class Air:
    """The air the machine's wind blows in: towards `heading` (rad from world +X towards +Y), at
    `density` kg/m^3."""

    heading: float
    density: float


@dataclass(frozen=True)
class Measured:
    """A log's samples: `time` (n,) s, increasing; `q` (n, 3) m, rad, rad; `qd` (n, 3) m/s, rad/s,
    rad/s, as the encoders read them; `force` (n, 3) N, N m, N m; `period` the sampling period in
    s (the median step); `speed` (n, 3) m/s, rad/s, rad/s the drives' speed feedback, or None;
    `wind` (n,) m/s the anemometer's reading, in `air`, or None (still air, or not measured)."""

    time: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    force: np.ndarray
    period: float
    speed: np.ndarray | None = None
    wind: np.ndarray | None = None
    air: Air | None = None

    def gaps(self) -> list[tuple[float, float]]:
        """(from, to) s of every step between samples longer than GAP periods."""
        steps = np.diff(self.time)
        return [(float(self.time[i]), float(self.time[i + 1])) for i in np.flatnonzero(steps > GAP * self.period)]

    def cut(self, keep: np.ndarray) -> Measured:
        """The samples `keep` (a boolean mask or indices)."""
        return Measured(self.time[keep], self.q[keep], self.qd[keep], self.force[keep], self.period,
                        None if self.speed is None else self.speed[keep],
                        None if self.wind is None else self.wind[keep], self.air)


def encoder_counts(measured: Measured) -> np.ndarray:
    """(3,) m, rad: each encoder's count, the smallest step its reading was seen to make; inf for
    one that never stepped (its count unknown)."""
    steps = np.abs(np.diff(measured.q, axis=0))
    return np.array([steps[steps[:, j] > 1e-12, j].min(initial=np.inf) for j in range(3)])


def read_measured(path: Path, limits: np.ndarray, *, wind: bool = True) -> Measured:
    """The log at `path` (a run directory or its timeseries.csv), its drive forces clipped to
    the (3, 2) drive `limits` (N, N m); with its wind where the run's scene.json says the plant
    had one (its heading and air density), unless `wind` is False. Raises BwrError naming the file if it holds too few
    samples to watch."""
    csv = path / "timeseries.csv" if path.is_dir() else path
    if not csv.is_file():
        raise BwrError(f"{path}: no log there: give a run directory or its timeseries.csv")
    series = read_timeseries(csv)
    time = np.asarray(series.time, dtype=float)
    if len(time) < 3:
        raise BwrError(f"{csv}: {len(time)} samples, fewer than the 3 the shadow needs")
    force = np.clip(series.signals["drive_force_command"], limits[:, 0], limits[:, 1])
    period = float(np.median(np.diff(time)))
    scene = csv.parent / SCENE_FILE
    air = None
    if wind and scene.is_file():
        plant = read_scene(scene)
        air = Air(math.radians(plant.wind_direction), plant.air_density) if plant.air_density > 0 else None
    return Measured(time, np.asarray(series.signals["q_measured"], dtype=float),
                    np.asarray(series.signals["qd_measured"], dtype=float), force, period,
                    np.asarray(series.signals["qd"], dtype=float),
                    None if air is None else np.asarray(series.wind_speed, dtype=float), air)
