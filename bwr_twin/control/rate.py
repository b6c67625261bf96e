"""Reclaim rate control: the slew speed trimmed to hold the target tonnage.

The bench planner's speed law (bwr_twin.planning.bench) sets the slew speed open loop, for a
face of the bench's full height and the planned cut. Where the face is lower (the pile's
flanks, the first passes into a pile's end) or the cut deeper, the tonnage drifts from the
target; a reclaimer's rate loop trims the speed law by a factor from what it measures: the
belt scale on the boom conveyor, or the wheel drive's power, the usual proxy (power = cutting
energy x dug volume a second + the power of the wheel turning empty).

A rate control sees every run of a lockstep at once, once a control period, and returns each
run's trim. An engineer's own derives from `RateControl` and is named in the scene as
`[reclaim.rate_control] type = "my_rate.py:MyRateControl"` (bwr_twin.config.plugins). It is given
numbers, not scenes: the settings, and each run's target and wheel calibration as arrays.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

import numba
import numpy as np

from bwr_twin.errors import SceneError
from bwr_twin.units import KG_PER_T, SECONDS_PER_HOUR


class RateSettings(Protocol):
    """The scene's [reclaim.rate_control], as a rate loop reads it."""

    gain: float  # trim per unit of relative rate error
    integral_time: float  # s
    filter_time: float  # s
    trim_limits: tuple[float, float]
    calibration_time: float  # s: the memory of PowerAndScale's correction


@dataclass(frozen=True)
class WheelCalibration:
    """What the automation knows to turn its signals into a rate: every run's digging load,
    rate = (power - idle_power) / cutting_energy x bulk_density (NaN for a run without
    [digging]; the cutting energy the scene's rate control assumes, else the true one), and the
    belt scale's delay behind the wheel."""

    idle_power: np.ndarray  # (runs,) W
    cutting_energy: np.ndarray  # (runs,) J/m^3
    bulk_density: np.ndarray  # (runs,) kg/m^3
    # s from the wheel's discharge to the belt rate the loop reads: the belt scale's (the MJCF's),
    # or 0 where the loop reads the true rate ([sensing] rate_signals "exact")
    belt_delay: float = 0.0


@dataclass(frozen=True)
class RateSignals:
    """What a rate loop measures, every run's, this control period."""

    belt_rate: np.ndarray  # (runs,) t/h, the belt scale on the boom conveyor
    wheel_power: np.ndarray  # (runs,) W, the wheel drive (its idle power when there is no digging load)
    # With [sensing] rate_signals "measured", the scale's reading (late and noisy) and the power
    # the drive reports from the motor's current; else the true rate and power.
    cutting: np.ndarray  # (runs,) bool: the wheel is within the planned cut of a slew pass
    steady: np.ndarray  # (runs,) bool: ... where the face allows the target (planned steady cutting)
    wheel_current: np.ndarray | None = None  # (runs,) A of the wheel motor, where the machine reports it


class RateControl:
    """Open loop: the speed law alone (trim 1). Subclasses close the loop in `trim`.

    Attributes:
        settings: the scene's [reclaim.rate_control].
        target: (runs,) t/h.
        period: s between calls.
        wheel: each run's calibration of the wheel drive's power.
    """

    def __init__(self, settings: RateSettings, target: np.ndarray, period: float, wheel: WheelCalibration):
        self.settings, self.target, self.period, self.wheel = settings, target, period, wheel

    def trim(self, signals: RateSignals) -> np.ndarray:
        """Each run's factor on the planned slew speed, (runs,)."""
        return np.ones(len(self.target))


class RateFeedback(RateControl):
    """PI on the relative rate error e = (target - measured) / target while the wheel is in a
    pass's cut. The integral grows only in steady cutting (entering and leaving the face, the
    rate falls short for want of face, not of speed) and not further into a trim limit; each
    pass starts from the speed law (the next face is another). `measured` gives the rate the
    loop sees, in t/h."""

    def __init__(self, settings: RateSettings, target: np.ndarray, period: float, wheel: WheelCalibration):
        super().__init__(settings, target, period, wheel)
        self._integral = np.zeros(len(target))  # relative error x s
        self._filtered = np.zeros(len(target))  # t/h
        self._smoothing = period / (settings.filter_time + period)

    def measured(self, signals: RateSignals) -> np.ndarray:
        raise NotImplementedError

    def trim(self, signals: RateSignals) -> np.ndarray:
        s = self.settings
        low, high = s.trim_limits
        trim = np.empty(len(self.target))
        _pi(self.measured(signals), signals.cutting, signals.steady, self.target, float(s.gain),
            float(s.integral_time), float(low), float(high), self.period, self._smoothing, self._filtered,
            self._integral, trim)
        return trim


class BeltScale(RateFeedback):
    """Trims from the belt scale: the rate itself, a bucket interval after the cut."""

    def measured(self, signals: RateSignals) -> np.ndarray:
        return signals.belt_rate


class WheelPower(RateFeedback):
    """Trims from the wheel drive's power, calibrated to t/h by the scene's [digging]:
    rate = (power - idle power) / cutting energy x bulk density."""

    def __init__(self, settings: RateSettings, target: np.ndarray, period: float, wheel: WheelCalibration):
        super().__init__(settings, target, period, wheel)
        if np.isnan(wheel.idle_power).any() or np.isnan(wheel.cutting_energy).any():
            raise SceneError("'reclaim.rate_control.type' \"wheel_power\" needs [digging]")
        self._tonnes_per_joule = wheel.bulk_density / wheel.cutting_energy * (SECONDS_PER_HOUR / KG_PER_T)

    def measured(self, signals: RateSignals) -> np.ndarray:
        return np.maximum(signals.wheel_power - self.wheel.idle_power, 0.0) * self._tonnes_per_joule


class PowerAndScale(WheelPower):
    """Trims from the wheel drive's power, as WheelPower does, its calibration corrected by the
    belt scale: the scale's tonnes over the power's tonnes `belt_delay` earlier (the same
    material, weighed), both summed with a memory of `calibration_time` s. The power has no
    transport delay, so the loop stays quick; the scale, legal for trade, sets its mean. The
    correction starts once both have summed a tenth of the target rate over `calibration_time`."""

    def __init__(self, settings: RateSettings, target: np.ndarray, period: float, wheel: WheelCalibration):
        super().__init__(settings, target, period, wheel)
        runs = len(target)
        self._delay = round(wheel.belt_delay / period)
        self._in_transit = np.zeros((self._delay + 1, runs))  # the power's rates of the periods on the belt
        self._k = 0
        self._memory = math.exp(-period / settings.calibration_time)
        self._weighed, self._powered = np.zeros(runs), np.zeros(runs)  # t/h x s, forgetting
        self._enough = 0.1 * target * settings.calibration_time
        self.correction = np.ones(runs)  # the scale's tonnes over the power's, as the loop applies it

    def measured(self, signals: RateSignals) -> np.ndarray:
        from_power = super().measured(signals)
        ring = self._in_transit
        ring[self._k % len(ring)] = from_power
        if self._k >= self._delay:
            self._weighed = self._weighed * self._memory + signals.belt_rate * self.period
            self._powered = self._powered * self._memory + ring[(self._k - self._delay) % len(ring)] * self.period
            ready = (self._powered > self._enough) & (self._weighed > self._enough)
            self.correction = np.where(ready, self._weighed / np.maximum(self._powered, 1e-12), self.correction)
        self._k += 1
        return from_power * self.correction


@numba.njit(cache=True)
def _pi(measured, cutting, steady, target, gain, integral_time, low, high, period, smoothing, filtered, integral,
        trim):  # pragma: no cover - compiled
    """RateFeedback's law for every run, compiled: the same arithmetic as its docstring says."""
    for r in range(len(target)):
        filtered[r] += (measured[r] - filtered[r]) * smoothing
        error = (target[r] - filtered[r]) / target[r] if cutting[r] else 0.0
        unclipped = 1.0 + gain * (error + integral[r] / integral_time)
        winding = (unclipped >= high and error > 0) or (unclipped <= low and error < 0)
        integral[r] += 0.0 if (winding or not steady[r]) else error * period
        if not cutting[r]:
            integral[r] = 0.0
        trim[r] = min(max(unclipped, low), high)
