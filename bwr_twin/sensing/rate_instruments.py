"""The belt scale and the wheel motor's current of every run of a lockstep, as the rate loop reads
them (docs/sensing.md).

The belt scale weighs what the wheel discharged the belt's transport delay later (its distance
from the discharge over the belt's speed, a whole number of control periods, rounded), with
Gaussian noise of sigma = a + b x rate, through a first-order filter. The wheel's current is the
drive's shaft power as a three-phase motor draws it, I = P / (sqrt(3) V cos(phi) eta), with noise
of its own; the power the drive reports is that current turned back into watts. A frozen scale
(a fault) holds its last reading.

Each run draws from its own streams (bwr_twin.streams), a normal a period for each, drawn a
block at a time: a run's readings depend on its seed alone.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numba
import numpy as np

from bwr_twin.config.scene import Scene
from bwr_twin.errors import SceneError
from bwr_twin.model.instruments import BeltScaleSpec, WheelMotorSpec
from bwr_twin.sensing.noise import PeriodNormals
from bwr_twin.streams import Stream

if TYPE_CHECKING:
    from bwr_twin.model.machine import Machine


def rate_instruments(scene: Scene, machine: Machine, seeds: Sequence[int], period: float) -> RateInstruments | None:
    """The belt scale and wheel current of a scene's runs: with a stockpile and a machine whose
    MJCF describes either; else None."""
    if scene.stockpile is None or (machine.belt_scale is None and machine.wheel_motor is None):
        return None
    return RateInstruments(machine.belt_scale, machine.wheel_motor, seeds, period)


def rate_loop_reads_instruments(scene: Scene, machine: Machine) -> bool:
    """Whether a bench reclaim's rate control reads the instruments ([sensing] rate_signals;
    by default "measured" when the machine describes them) rather than the true rate and power.
    SceneError if the rate control's signal has no instrument."""
    wanted = scene.sensing.rate_signals
    scale, motor = machine.belt_scale, machine.wheel_motor
    if scene.reclaim is None or wanted == "exact" or (wanted is None and scale is None and motor is None):
        return False
    control = scene.reclaim.rate_control.type
    scale_needed, motor_needed = ("a belt scale", scale, "belt_scale_distance"), ("a wheel motor", motor, "wheel_motor")
    needs = {"belt_scale": [scale_needed], "wheel_power": [motor_needed],
             "power_and_scale": [motor_needed, scale_needed]}.get(control, [])
    for what, present, key in needs:
        if present is None:
            raise SceneError(f"{scene.path}: 'reclaim.rate_control.type' \"{control}\" reads {what}, but "
                             f"{machine.path.name} describes none (custom numeric '{key}', docs/sensing.md); "
                             "set 'sensing.rate_signals' = \"exact\" to read the true signal")
    return True


class RateInstruments:
    """(runs,) readings of this control period: `belt_scale` t/h, `wheel_current` A and the
    `wheel_power` W the drive reports from it. Either instrument may be absent (None): its
    readings are then NaN."""

    def __init__(self, scale: BeltScaleSpec | None, motor: WheelMotorSpec | None, seeds: Sequence[int],
                 period: float):
        runs = len(seeds)
        self.scale, self.motor, self.period = scale, motor, period
        self.belt_scale = np.full(runs, np.nan)
        self.wheel_current = np.full(runs, np.nan)
        self.wheel_power = np.full(runs, np.nan)
        if scale is not None:
            self.delay_periods = round(scale.delay / period)
            self._belt = np.zeros((self.delay_periods + 1, runs))  # the true rates of the periods in transit
            self._smoothing = period / (scale.filter_time + period)
            self._scale_noise = PeriodNormals(seeds, Stream.BELT_SCALE)
            self.belt_scale[:] = 0.0
        if motor is not None:
            self._current_noise = PeriodNormals(seeds, Stream.WHEEL_CURRENT)
            self.wheel_current[:] = self.wheel_power[:] = 0.0  # before the first reading

    def read(self, k: int, rate: np.ndarray, power: np.ndarray, scale_frozen: bool = False) -> None:
        """Period k's readings of the true belt rate at the discharge (t/h) and the wheel's shaft power (W)."""
        scale = self.scale
        if scale is not None:
            _weigh(k, self.delay_periods, rate, self._belt, self._scale_noise.at(k), scale.noise[0], scale.noise[1],
                   self._smoothing, scale_frozen, self.belt_scale)
        motor = self.motor
        if motor is not None:
            _draw(power, motor.amps_per_watt, self._current_noise.at(k), motor.noise[0], motor.noise[1],
                  self.wheel_current, self.wheel_power)


@numba.njit(cache=True)
def _weigh(k, delay, rate, belt, normal, constant, share, smoothing, frozen, reading):  # pragma: no cover - compiled
    """The belt scale's period k: the rates in transit (delay + 1 rows, a ring), the one that
    reaches the scale with its noise, through the filter unless frozen."""
    rows = belt.shape[0]
    belt[k % rows] = rate
    for r in range(len(rate)):
        weighed = belt[(k - delay) % rows, r] if k >= delay else 0.0
        measured = weighed + normal[r] * (constant + share * abs(weighed))
        if not frozen:
            reading[r] += (measured - reading[r]) * smoothing


@numba.njit(cache=True)
def _draw(power, amps_per_watt, normal, constant, share, current, reported):  # pragma: no cover - compiled
    """The wheel motor's current for its shaft power, with its noise, and the power the drive reports from it."""
    for r in range(len(power)):
        amps = power[r] * amps_per_watt
        current[r] = amps + normal[r] * (constant + share * abs(amps))
        reported[r] = current[r] / amps_per_watt
