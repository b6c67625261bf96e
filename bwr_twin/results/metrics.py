"""A run's metrics, computed online at the control period for every run of a lockstep.

metrics.json (the output contract, docs/contracts.md) holds per axis the error maxima with their
sign and time, the RMS position error, drive forces and the time spent beyond the drive limits;
error = desired - actual, and a "max" is the value of largest magnitude (sign kept; the first
one on ties). Everything is accumulated per run in a fixed order, so a run's metrics do not
depend on which runs share its lockstep.
"""

from __future__ import annotations

import numpy as np

from bwr_twin.model.machine import AXES, UNITS, to_display

UNITS_NOTE = {
    "travel": "m, m/s, m/s^2, N",
    "slew": "rad, rad/s, rad/s^2, N m",
    "luff": "rad, rad/s, rad/s^2, N m",
    "cp_error_max": "m",
    "drive_energy": "J",
    "times": "s",
}


class SignedMax:
    """The value of largest magnitude seen so far, its sign kept, and the sample it came at."""

    def __init__(self, shape: tuple[int, ...]):
        self.value = np.zeros(shape)
        self.index = np.zeros(shape, dtype=np.int64)
        self._magnitude = np.full(shape, -1.0)
        self._larger = np.zeros(shape, dtype=bool)
        self._buffer = np.zeros(shape)

    def add(self, k: int, x: np.ndarray) -> None:
        magnitude, larger = self._buffer, self._larger
        np.abs(x, out=magnitude)
        np.greater(magnitude, self._magnitude, out=larger)  # strictly: the first of equal values stays
        np.copyto(self.value, x, where=larger)
        np.copyto(self._magnitude, magnitude, where=larger)
        np.copyto(self.index, k, where=larger)


class OnlineMetrics:
    """Accumulates the metrics of every run of a lockstep, one control period at a time.

    Every metric but the CP distance sees every control period; the CP distance, a slow signal
    dominated by the travel error, is sampled at the record period.
    """

    # Columns of the (runs, 12) array `add` takes: errors (desired - actual) and applied forces.
    POSITION, VELOCITY, ACCELERATION, FORCE = slice(0, 3), slice(3, 6), slice(6, 9), slice(9, 12)

    # What a run may not do, in the order of the middle index of `_first`: (metrics key, message).
    LIMITS = (
        ("left_envelope_time", "left the operating envelope"),
        ("end_stop_time", "reached its mechanical end stop"),
        ("beyond_drive_rating_time", "was commanded beyond its drive rating"),
    )

    def __init__(self, runs: int, drive_limits: np.ndarray, envelope: np.ndarray, end_stops: np.ndarray,
                 period: float):
        self._limits = drive_limits  # (3, 2), N and N m
        self._period = period  # s, between samples
        self._power_sum = np.zeros((runs, 3))  # W, summed over the samples: motoring and braking both count
        self._power = np.zeros((runs, 3))
        self._envelope = envelope  # (3, 2), m and rad
        # An end stop is reached within 0.1 % of the joint's range of it: MuJoCo's stops are soft.
        margin = 1e-3 * np.nan_to_num(end_stops[:, 1] - end_stops[:, 0], posinf=0.0)
        self._stops = np.stack([end_stops[:, 0] + margin, end_stops[:, 1] - margin], axis=1)
        self._first = np.full((runs, len(self.LIMITS), 3), -1, dtype=np.int64)  # sample, or -1: never
        self._breach = np.zeros((runs, len(self.LIMITS), 3), dtype=bool)
        self._limited = bool(np.isfinite(drive_limits).any())
        self._maxima = SignedMax((runs, 12))
        self._cp = SignedMax((runs,))
        self._squares = np.zeros((runs, 12))
        self._square = np.zeros((runs, 12))
        self._saturated = np.zeros((runs, 3), dtype=np.int64)
        self._position_final = np.zeros((runs, 3))
        self._samples = 0

    def add(self, k: int, errors_and_forces: np.ndarray, command: np.ndarray, q: np.ndarray,
            qd_mean: np.ndarray) -> None:
        """Sample k, once its control period has ended: a (runs, 12) array of position,
        velocity and acceleration errors and applied drive forces (columns POSITION, VELOCITY,
        ACCELERATION, FORCE), the (runs, 3) commanded forces, the true joint positions and the
        mean joint velocities over the period."""
        self._maxima.add(k, errors_and_forces)
        np.multiply(errors_and_forces[:, self.FORCE], qd_mean, out=self._power)
        np.abs(self._power, out=self._power)
        self._power_sum += self._power
        np.multiply(errors_and_forces, errors_and_forces, out=self._square)
        self._squares += self._square
        breach = self._breach
        np.logical_or(q < self._envelope[:, 0], q > self._envelope[:, 1], out=breach[:, 0])
        np.logical_or(q <= self._stops[:, 0], q >= self._stops[:, 1], out=breach[:, 1])
        if self._limited:
            np.logical_or(command < self._limits[:, 0], command > self._limits[:, 1], out=breach[:, 2])
            self._saturated += breach[:, 2]
        if breach.any():
            np.copyto(self._first, k, where=breach & (self._first < 0))
        self._position_final[:] = errors_and_forces[:, self.POSITION]
        self._samples += 1

    def add_cp_error(self, k: int, cp_error: np.ndarray) -> None:
        """Sample k's (runs,) distance of the CP from its desired position, m."""
        self._cp.add(k, cp_error)

    def result(self, run: int, time: np.ndarray) -> dict:
        """metrics.json of run `run` (without its "run" block); `time` maps samples to s."""
        metrics: dict = {}
        n = self._samples
        value, index = self._maxima.value[run], self._maxima.index[run]
        rms = np.sqrt(self._squares[run] / n)
        for j, axis in enumerate(AXES):
            limit = self._limits[j]
            p, v, a, f = j, 3 + j, 6 + j, 9 + j
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
            for i, (key, _) in enumerate(self.LIMITS):
                first = self._first[run, i, j]
                metrics[axis][key] = float(time[first]) if first >= 0 else None
        metrics["limits"] = limit_flags(metrics)
        metrics["cp_error_max"] = float(self._cp.value[run])
        metrics["cp_error_max_time"] = float(time[self._cp.index[run]])
        metrics["units"] = dict(UNITS_NOTE)
        return metrics


def limit_flags(metrics: dict) -> list[str]:
    """'slew reached its mechanical end stop at 12.3 s', for every axis and limit a run broke."""
    return [f"{axis} {message} at {metrics[axis][key]:.2f} s"
            for axis in AXES for key, message in OnlineMetrics.LIMITS if metrics[axis].get(key) is not None]


def summary_table(metrics: dict) -> str:
    """The maximum errors with their times, in engineering units (m, deg)."""
    lines = [
        f"{'axis':<7} {'position error max':>24} {'velocity error max':>26} {'acceleration error max':>30} {'pos. RMS':>12}"
    ]
    for j, axis in enumerate(AXES):
        m = metrics[axis]
        lines.append(
            f"{axis:<7} {_largest(m, j, 'position', ''):>24} {_largest(m, j, 'velocity', '/s'):>26} "
            f"{_largest(m, j, 'acceleration', '/s^2'):>30} {to_display(j, m['position_error_rms']):>9.4g} {UNITS[j]}"
        )
    lines.append(f"largest CP distance from its desired position: {metrics['cp_error_max']:.4g} m @ {metrics['cp_error_max_time']:.1f} s")
    reclaim = metrics.get("reclaim")
    if reclaim is not None:
        load = reclaim["digging_force_max_N"]
        lines.append(
            f"reclaimed {reclaim['mass_t']:.1f} t ({reclaim['volume_m3']:.1f} m³): mean {reclaim['rate_mean_tph']:.0f} t/h "
            f"over {reclaim['carrying_time_s']:.0f} s of carrying, CV {reclaim['rate_cv']:.2f}, peak "
            f"{reclaim['rate_max_tph']:.0f} t/h; spilled {reclaim['spill_t']:.1f} t"
            + (f"; digging load up to {load / 1e3:.0f} kN" if load > 0 else "")
        )
        if "target_rate_tph" in reclaim:
            lines.append(plan_line(reclaim))
        if reclaim["spill_t"] > 0:
            lines.append(f"warning: the wheel dug more than its buckets hold: {reclaim['spill_t']:.1f} t spilled")
    lines += [f"warning: {flag}" for flag in metrics.get("limits", ())]
    return "\n".join(lines)


def plan_line(reclaim: dict) -> str:
    """How a bench plan was carried out: the rate in steady cutting against its target, the
    landing, the over-cut and the tonnes of each bench."""
    target, steady = reclaim["target_rate_tph"], reclaim["steady_time_s"]
    if steady > 0:
        rate = (f"steady cutting {steady:.0f} s at {reclaim['steady_rate_mean_tph']:.0f} t/h "
                f"({100 * (reclaim['steady_rate_mean_tph'] / target - 1):+.1f} % of the {target:.0f} t/h target), "
                f"CV {reclaim['steady_rate_cv']:.3f}, {100 * reclaim['steady_within_10pct']:.0f} % of it within ±10 %")
    else:
        rate = f"no steady cutting (target {target:.0f} t/h)"
    landing = reclaim["landing_error_m"]
    benches = ", ".join(f"{t:.0f}" for t in reclaim["bench_t"])
    return (f"{rate}; landing error {landing:.3f} m; over-cut up to {reclaim['overcut_max_m']:.2f} m; "
            f"bench tonnes {benches} t" if landing is not None else f"{rate}; the wheel never met the pile")


def _largest(axis_metrics: dict, j: int, kind: str, per: str) -> str:
    """'+0.01812 m @ 204.1 s': the largest error of one kind, in engineering units, and its time."""
    value, time = axis_metrics[f"{kind}_error_max"], axis_metrics[f"{kind}_error_max_time"]
    return f"{to_display(j, value):+.4g} {UNITS[j]}{per} @ {time:5.1f} s"
