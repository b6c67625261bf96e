"""A machine's log, as the fit reads it: per axis the encoder position, the drive's force and,
where recorded, the speed feedback; the wind speed where recorded; and the checks every log meets.
`bwr_twin.calibrate.reading` reads one from a run directory or a historian's CSV."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.interpolate import CubicSpline

from bwr_twin.errors import BwrError
from bwr_twin.model.machine import AXES


@dataclass(frozen=True)
class MachineLog:
    """One log: every array a row per sample, in SI units, per axis travel, slew, luff."""

    path: Path
    time: np.ndarray  # (n,) s, increasing
    q: np.ndarray  # (n, 3) m, rad: the encoders
    force: np.ndarray  # (n, 3) N, N m: what the drives applied
    qd: np.ndarray | None = None  # (n, 3) m/s, rad/s: the speed feedback, if recorded
    wind: np.ndarray | None = None  # (n,) m/s along wind_heading, if recorded
    wind_heading: float = 0.0  # rad from world +X towards +Y: where the wind blows to
    air_density: float = 0.0  # kg/m^3; 0: the fit leaves the wind out (still air, or no wind logged)

    @property
    def windy(self) -> bool:
        """The log carries a wind the fit applies (its speed, heading and air density)."""
        return self.wind is not None and self.air_density > 0

    @property
    def rate(self) -> float:
        """The median sample rate in Hz."""
        return float(1.0 / np.median(np.diff(self.time)))

    def impulse(self, first: int, last: int) -> CubicSpline:
        """The drive forces' running integral (N s, N m s) over rows `first` to `last` (within a
        stretch without a gap): a cubic spline through it at the bounds of the sample periods.
        Each logged force is its period's mean, stamped at the period's middle, so the spline's
        slope is a force whose mean over every period is the logged one. Straight lines between
        the means would average each change over two periods more: at 10 Hz a 1 Hz swing of the
        force comes out 5 % smaller, and the fit puts a drive inertia that much low."""
        t = self.time[first:last + 1]
        bounds = np.r_[1.5 * t[0] - 0.5 * t[1], 0.5 * (t[1:] + t[:-1]), 1.5 * t[-1] - 0.5 * t[-2]]
        impulses = self.force[first:last + 1] * np.diff(bounds)[:, None]
        return CubicSpline(bounds, np.vstack([np.zeros((1, 3)), np.cumsum(impulses, axis=0)]), axis=0)

    def velocity_at(self, row: int) -> np.ndarray:
        """The (3,) speed at `row`: the speed feedback, or where there is none the slope of a
        quadratic through the encoders within VELOCITY_SPAN (a difference of two quantised
        readings 0.1 s apart would be off by more than the slew's rated speed)."""
        if self.qd is not None:
            return self.qd[row]
        near = np.flatnonzero(np.abs(self.time - self.time[row]) <= VELOCITY_SPAN / 2)
        if len(near) < 3:
            return (self.q[near[-1]] - self.q[near[0]]) / max(self.time[near[-1]] - self.time[near[0]], 1e-12)
        return np.polyfit(self.time[near] - self.time[row], self.q[near], 2)[1]


MIN_RATE, MAX_RATE = 1.0, 1000.0  # Hz: the rates a log may have
VELOCITY_SPAN = 2.0  # s of encoder readings a speed is taken from where the log has no speed feedback


def check_log(log: MachineLog) -> None:
    """The checks every log meets, whatever its source: enough rows, a rate within MIN_RATE to
    MAX_RATE, time increasing, every value finite."""
    what = str(log.path)
    if len(log.time) < 10:
        raise BwrError(f"{what}: {len(log.time)} rows; a log to fit needs at least 10")
    steps = np.diff(log.time)
    if not (steps > 0).all():
        row = int(np.argmax(~(steps > 0))) + 2
        raise BwrError(f"{what}: row {row}: time {log.time[row - 1]:g} s does not come after the row before's "
                       f"{log.time[row - 2]:g} s (time runs backwards or repeats)")
    rate = log.rate
    if not MIN_RATE <= rate <= MAX_RATE:
        raise BwrError(f"{what}: sampled at {rate:g} Hz; a log to fit is sampled at {MIN_RATE:g} to {MAX_RATE:g} Hz")
    for name, values in (("position", log.q), ("force", log.force), ("speed", log.qd)):
        if values is None:
            continue
        bad = ~np.isfinite(values)
        if bad.any():
            row, axis = np.argwhere(bad)[0]
            raise BwrError(f"{what}: row {row + 1}: the {AXES[axis]} {name} is {values[row, axis]} (not a finite "
                           "number)")
    if log.wind is not None and not np.isfinite(log.wind).all():
        row = int(np.argmax(~np.isfinite(log.wind)))
        raise BwrError(f"{what}: row {row + 1}: the wind speed is {log.wind[row]} (not a finite number)")
