"""A run's metrics, reduced from blocks of recorded control periods for every run of a lockstep.

metrics.json (the output contract, docs/contracts.md) holds per axis the error maxima with their
sign and time, the RMS position error, drive forces and the time spent beyond the drive limits;
error = desired - actual, and a "max" is the value of largest magnitude (sign kept; the first
one on ties). The loop hands over its raw signals a block of periods at a time (`Observer`);
one compiled pass over the block updates every run's sums, maxima and first breaches, period by
period in time order, so a run's metrics are those of a period-by-period reduction and do not
depend on which runs share its lockstep.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from bwr_twin.model.machine import AXES

UNITS_NOTE = {
    "travel": "m, m/s, m/s^2, N",
    "slew": "rad, rad/s, rad/s^2, N m",
    "luff": "rad, rad/s, rad/s^2, N m",
    "cp_error_max": "m",
    "drive_energy": "J",
    "times": "s",
}

# What a run may not do, in the order of the middle index of `first`: (metrics key, message).
LIMITS = (
    ("left_envelope_time", "left the operating envelope"),
    ("end_stop_time", "reached its mechanical end stop"),
    ("beyond_drive_rating_time", "was commanded beyond its drive rating"),
)
# Columns of the signed maxima and squares: errors (desired - actual) and applied forces.
POSITION, VELOCITY, ACCELERATION, FORCE = 0, 3, 6, 9


@dataclass(frozen=True)
class Bounds:
    """What a run may not do (LIMITS), as the compiled reduction compares: (3, 2) [low, high] per
    axis of the operating envelope (m, rad), the end stops (m, rad) and the drive limits (N, N m)."""

    drive_limits: np.ndarray
    envelope: np.ndarray
    stops: np.ndarray  # the joints' range, less the margin within which a stop counts as reached
    limited: bool  # whether any drive has a finite limit

    @classmethod
    def of(cls, drive_limits: np.ndarray, envelope: np.ndarray, end_stops: np.ndarray) -> Bounds:
        # An end stop is reached within 0.1 % of the joint's range of it: MuJoCo's stops are soft.
        margin = 1e-3 * np.nan_to_num(end_stops[:, 1] - end_stops[:, 0], posinf=0.0)
        return cls(drive_limits=np.ascontiguousarray(drive_limits, dtype=float),
                   envelope=np.ascontiguousarray(envelope, dtype=float),
                   stops=np.stack([end_stops[:, 0] + margin, end_stops[:, 1] - margin], axis=1),
                   limited=bool(np.isfinite(drive_limits).any()))


class Metrics:
    """The metrics of every run of a lockstep, accumulated block by block.

    Every metric but the CP distance sees every control period; the CP distance, a slow signal
    dominated by the travel error, is sampled at the record period.
    """

    def __init__(self, runs: int, drive_limits: np.ndarray, envelope: np.ndarray, end_stops: np.ndarray,
                 period: float):
        self._bounds = Bounds.of(drive_limits, envelope, end_stops)
        self._period = period  # s, between samples
        self._value = np.zeros((runs, 12))  # signed maxima
        self._index = np.zeros((runs, 12), dtype=np.int64)  # and the sample of each
        self._magnitude = np.full((runs, 12), -1.0)
        self._squares = np.zeros((runs, 12))
        self._power_sum = np.zeros((runs, 3))  # W, summed over the samples: motoring and braking both count
        self._first = np.full((runs, len(LIMITS), 3), -1, dtype=np.int64)  # sample, or -1: never
        self._saturated = np.zeros((runs, 3), dtype=np.int64)
        self._position_final = np.zeros((runs, 3))
        self._cp_value = np.zeros(runs)
        self._cp_index = np.zeros(runs, dtype=np.int64)
        self._samples = 0

    def add_block(self, start: int, q: np.ndarray, qd: np.ndarray, q_desired: np.ndarray,
                  qd_desired: np.ndarray, qdd_desired: np.ndarray, command: np.ndarray,
                  drive_force: np.ndarray) -> None:
        """Samples start .. start + n - 1, once their periods have ended: the true positions and
        velocities (n + 1, runs, 3) at each period's start and the last one's end, the reference
        (n, runs, 3), or (n, 1, 3) shared by every run, the commanded and applied drive forces
        (n, runs, 3)."""
        bounds = self._bounds
        _reduce(start, q, qd, q_desired, qd_desired, qdd_desired, command, drive_force, self._period,
                bounds.envelope, bounds.stops, bounds.drive_limits, bounds.limited, self._value, self._index,
                self._magnitude, self._squares, self._power_sum, self._first, self._saturated,
                self._position_final)
        self._samples += len(command)

    def add_cp_error(self, samples: np.ndarray, cp_error: np.ndarray) -> None:
        """The (rows, runs) distance of the CP from its desired position (m) at these samples."""
        for row, k in enumerate(samples):  # a row per recorded sample: few per block
            larger = cp_error[row] > np.abs(self._cp_value)
            self._cp_value[larger] = cp_error[row][larger]
            self._cp_index[larger] = k

    def result(self, run: int, time: np.ndarray) -> dict:
        """metrics.json of run `run` (without its "run" block); `time` maps samples to s."""
        metrics: dict = {}
        n = self._samples
        value, index = self._value[run], self._index[run]
        rms = np.sqrt(self._squares[run] / n)
        for j, axis in enumerate(AXES):
            limit = self._bounds.drive_limits[j]
            p, v, a, f = POSITION + j, VELOCITY + j, ACCELERATION + j, FORCE + j
            metrics[axis] = {
                "position_error_max": float(value[p]),
                "position_error_max_time": float(time[index[p]]),
                "velocity_error_max": float(value[v]),
                "velocity_error_max_time": float(time[index[v]]),
                "acceleration_error_max": float(value[a]),
                "acceleration_error_max_time": float(time[index[a]]),
                "position_error_rms": float(rms[p]),
                "position_error_final": float(self._position_final[run, j]),
                "drive_force_max": float(value[f]),
                "drive_force_rms": float(rms[f]),
                "drive_energy": float(self._power_sum[run, j] * self._period),  # J
                "drive_limit": [float(limit[0]), float(limit[1])] if np.isfinite(limit).any() else None,
                "saturation_fraction": float(self._saturated[run, j] / n),
            }
            for i, (key, _) in enumerate(LIMITS):
                first = self._first[run, i, j]
                metrics[axis][key] = float(time[first]) if first >= 0 else None
        metrics["limits"] = limit_flags(metrics)
        metrics["cp_error_max"] = float(self._cp_value[run])
        metrics["cp_error_max_time"] = float(time[self._cp_index[run]])
        metrics["units"] = dict(UNITS_NOTE)
        return metrics


def limit_flags(metrics: dict) -> list[str]:
    """'slew reached its mechanical end stop at 12.3 s', for every axis and limit a run broke."""
    return [f"{axis} {message} at {metrics[axis][key]:.2f} s"
            for axis in AXES for key, message in LIMITS if metrics[axis].get(key) is not None]


@numba.njit(cache=True)
def _reduce(start, q, qd, q_desired, qd_desired, qdd_desired, command, drive_force, period, envelope, stops,
            limits, limited, value, index, magnitude, squares, power_sum, first, saturated,
            position_final):  # pragma: no cover - compiled
    """One pass over a block, period by period: the same arithmetic, in the same order, as
    reducing each period on its own (so a run's sums do not depend on the block's size)."""
    n, runs = command.shape[0], command.shape[1]
    shared = q_desired.shape[1] == 1
    x = np.empty(12)
    for t in range(n):
        k = start + t
        for r in range(runs):
            rr = 0 if shared else r
            for j in range(3):
                qdd = (qd[t + 1, r, j] - qd[t, r, j]) / period  # the mean over the period
                x[POSITION + j] = q_desired[t, rr, j] - q[t, r, j]
                x[VELOCITY + j] = qd_desired[t, rr, j] - qd[t, r, j]
                x[ACCELERATION + j] = qdd_desired[t, rr, j] - qdd
                x[FORCE + j] = drive_force[t, r, j]
                power_sum[r, j] += abs(drive_force[t, r, j] * ((qd[t, r, j] + qd[t + 1, r, j]) * 0.5))
                position = q[t, r, j]
                if first[r, 0, j] < 0 and (position < envelope[j, 0] or position > envelope[j, 1]):
                    first[r, 0, j] = k
                if first[r, 1, j] < 0 and (position <= stops[j, 0] or position >= stops[j, 1]):
                    first[r, 1, j] = k
                if limited and (command[t, r, j] < limits[j, 0] or command[t, r, j] > limits[j, 1]):
                    saturated[r, j] += 1
                    if first[r, 2, j] < 0:
                        first[r, 2, j] = k
                position_final[r, j] = x[POSITION + j]
            for c in range(12):
                size = abs(x[c])
                if size > magnitude[r, c]:  # strictly: the first of equal values stays
                    magnitude[r, c] = size
                    value[r, c] = x[c]
                    index[r, c] = k
                squares[r, c] += x[c] * x[c]
