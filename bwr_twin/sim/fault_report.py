"""What each scheduled fault did to a run, worked out from the run's record once it has ended.

Per fault: the window it acted in, the largest tracking error during it and after it (did the
machine recover?), which limits the run first broke once it had begun, and, on a reclaim, the
tonnes the belt carried while it acted against the target rate. The samples are the record's:
a fault acts on the samples with start <= t < start + duration (1e-9 s of rounding allowed, as
the loop allows on its period grid), and its "after" is from its end to the run's end.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from bwr_twin.config.faults import FAULT_AXES, FaultSection
from bwr_twin.sim.metrics import LIMITS
from bwr_twin.units import SECONDS_PER_HOUR

_TOLERANCE = 1e-9  # s: a sample this close to a window's boundary is on it
_ERROR_UNITS = ("m", "deg", "deg")  # what the per-axis errors are reported in
_TO_REPORT = np.array([1.0, math.degrees(1.0), math.degrees(1.0)])  # m; rad -> deg
_GIVEN = ("axis", "scanner", "rate", "sigma", "periods", "percent", "mass", "ramp")  # a fault's own keys, reported as the scene gives them


def fault_metrics(faults: Sequence[FaultSection], time: np.ndarray, q_desired: np.ndarray, q: np.ndarray,
                  metrics: dict, rate: np.ndarray | None = None, target_rate: float | None = None) -> list[dict]:
    """One dict per fault, in the scene's order.

    Args:
        faults: the scene's faults.
        time: (n,) s, the record's sample times, increasing.
        q_desired, q: (n, 3) desired and true joint values (m, rad, rad).
        metrics: the run's metrics.json (bwr_twin.sim.metrics `Metrics.result`): per axis the
            first time (s, or None) it left the envelope, reached an end stop or was commanded
            beyond its drive rating.
        rate: (n,) t/h the belt carried, or None without a reclaim.
        target_rate: t/h the reclaim aimed at, or None.

    Each dict holds kind, the keys the fault gives (axis, scanner, rate, sigma, periods, percent, mass, ramp), `start_s`
    and `end_s` (its end within the run: the run's end without a duration; None if it began
    after the run ended), `error_max_during` and `error_max_after` (per axis the largest
    |desired - actual|, `travel_m`, `slew_deg`, `luff_deg`; None where the window holds no
    sample), `limits_after_start` (per axis the limits first broken at or after its start, as
    `{"end_stop_s": 212.3}`), and with `rate` `tonnes_during_t` (t, the rate's integral over its
    window) and, with `target_rate` too, `shortfall_t` (t the target rate would have carried
    over the window, less those).

    metrics.json keeps only the first time of each limit, so a limit first broken before the
    fault's start is not reported, even if the run broke it again while the fault acted.
    """
    time = np.asarray(time, dtype=float)
    error = np.abs(np.asarray(q_desired, dtype=float) - np.asarray(q, dtype=float)) * _TO_REPORT
    run_start, run_end = float(time[0]), float(time[-1])
    report = []
    for fault in faults:
        stop = fault.start + fault.duration if fault.duration is not None else math.inf  # s, scheduled
        in_run = fault.start <= run_end + _TOLERANCE
        during = (time >= fault.start - _TOLERANCE) & (time < stop - _TOLERANCE)
        after = time >= stop - _TOLERANCE
        entry: dict = {"kind": fault.kind}
        entry |= {key: getattr(fault, key) for key in _GIVEN if getattr(fault, key) is not None}
        entry["start_s"] = float(fault.start)
        entry["end_s"] = min(stop, run_end) if in_run else None
        entry["error_max_during"] = _error_max(error, during)
        entry["error_max_after"] = _error_max(error, after)
        entry["limits_after_start"] = _limits_after(metrics, fault.start)
        if rate is not None:
            low, high = max(fault.start, run_start), min(stop, run_end)
            tonnes = _tonnes(time, np.asarray(rate, dtype=float), low, high) if in_run else None
            entry["tonnes_during_t"] = tonnes
            if target_rate is not None:
                entry["shortfall_t"] = (target_rate * max(high - low, 0.0) / SECONDS_PER_HOUR - tonnes
                                        if tonnes is not None else None)
        report.append(entry)
    return report


def _error_max(error: np.ndarray, window: np.ndarray) -> dict[str, float | None]:
    """Per axis the largest error over the window's samples, in the report's units."""
    largest = error[window].max(axis=0) if window.any() else (None,) * len(FAULT_AXES)
    return {f"{axis}_{unit}": None if value is None else float(value)
            for axis, unit, value in zip(FAULT_AXES, _ERROR_UNITS, largest)}


def _limits_after(metrics: dict, start: float) -> dict[str, dict[str, float]]:
    """Per axis, {"<limit>_s": time} for each limit the run first broke at or after `start`."""
    out = {}
    for axis in FAULT_AXES:
        axis_metrics = metrics.get(axis, {})
        out[axis] = {f"{key.removesuffix('_time')}_s": float(axis_metrics[key]) for key, _ in LIMITS
                     if axis_metrics.get(key) is not None and axis_metrics[key] >= start - _TOLERANCE}
    return out


def _tonnes(time: np.ndarray, rate: np.ndarray, low: float, high: float) -> float:
    """t carried between `low` and `high` s: the trapezoid rule over the samples, the rate
    interpolated linearly at the window's ends."""
    if not high > low:
        return 0.0
    inside = time[(time > low) & (time < high)]
    points = np.concatenate([[low], inside, [high]])
    return float(np.trapezoid(np.interp(points, time, rate) / SECONDS_PER_HOUR, points))
