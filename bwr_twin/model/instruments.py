"""The machine's rate instruments, read from its MJCF: the belt scale on the boom conveyor and the
wheel motor's current (docs/sensing.md, the model contract in docs/contracts.md).

    belt_scale_distance   m of belt from the wheel's discharge to the scale's weigh idlers
    belt_speed            m/s: with the distance, the scale's transport delay
    belt_scale_noise      t/h and a share of the rate: the reading's noise, sigma = a + b x rate
    belt_scale_filter     s: the scale's first-order filter of the buckets' pulses
    wheel_motor           V (line), efficiency, power factor: a three-phase motor's current
                          I = P / (sqrt(3) V cos(phi) eta) for the shaft power P
    wheel_current_noise   A and a share of the current: sigma = a + b x I

A machine describes both, one or neither; a key of one without the others is a ModelError
naming the file and the key.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from bwr_twin.errors import ModelError

BELT_SCALE_KEYS = {  # key: (values, meaning)
    "belt_scale_distance": (1, "m of belt from the wheel's discharge to the scale, > 0"),
    "belt_speed": (1, "m/s, > 0"),
    "belt_scale_noise": (2, "t/h and a share of the rate, both >= 0"),
    "belt_scale_filter": (1, "s, >= 0"),
}
WHEEL_MOTOR_KEYS = {
    "wheel_motor": (3, "line voltage V > 0, efficiency and power factor in (0, 1]"),
    "wheel_current_noise": (2, "A and a share of the current, both >= 0"),
}


@dataclass(frozen=True)
class BeltScaleSpec:
    """The belt scale: where it weighs, how fast the belt runs, its noise and filter."""

    distance: float  # m
    speed: float  # m/s
    noise: tuple[float, float]  # t/h, share
    filter_time: float  # s

    @property
    def delay(self) -> float:
        """s from a discharge to the scale."""
        return self.distance / self.speed


@dataclass(frozen=True)
class WheelMotorSpec:
    """The wheel's motor as its drive reports the current."""

    voltage: float  # V, line to line
    efficiency: float
    power_factor: float
    noise: tuple[float, float]  # A, share

    @property
    def amps_per_watt(self) -> float:
        """A of line current a watt of shaft power draws."""
        return 1.0 / (math.sqrt(3.0) * self.voltage * self.power_factor * self.efficiency)


def read_instruments(model: mujoco.MjModel, path: Path) -> tuple[BeltScaleSpec | None, WheelMotorSpec | None]:
    """The machine's belt scale and wheel motor, each None if its MJCF describes none."""
    belt = _values(model, path, BELT_SCALE_KEYS, "the belt scale")
    motor = _values(model, path, WHEEL_MOTOR_KEYS, "the wheel motor")
    scale = None
    if belt is not None:
        distance, speed, noise, filter_time = (belt[k] for k in BELT_SCALE_KEYS)
        _check(path, "belt_scale_distance", distance[0] > 0, distance)
        _check(path, "belt_speed", speed[0] > 0, speed)
        _check(path, "belt_scale_noise", (noise >= 0).all(), noise)
        _check(path, "belt_scale_filter", filter_time[0] >= 0, filter_time)
        scale = BeltScaleSpec(float(distance[0]), float(speed[0]), (float(noise[0]), float(noise[1])),
                              float(filter_time[0]))
    wheel = None
    if motor is not None:
        (voltage, efficiency, factor), noise = motor["wheel_motor"], motor["wheel_current_noise"]
        _check(path, "wheel_motor", voltage > 0 and 0 < efficiency <= 1 and 0 < factor <= 1, motor["wheel_motor"])
        _check(path, "wheel_current_noise", (noise >= 0).all(), noise)
        wheel = WheelMotorSpec(float(voltage), float(efficiency), float(factor), (float(noise[0]), float(noise[1])))
    return scale, wheel


def _values(model: mujoco.MjModel, path: Path, keys: dict, what: str) -> dict[str, np.ndarray] | None:
    """The numerics of one instrument by key; None if the file has none of them."""
    found = {}
    for key, (count, meaning) in keys.items():
        n = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_NUMERIC, key)
        if n < 0:
            continue
        values = model.numeric_data[model.numeric_adr[n]: model.numeric_adr[n] + model.numeric_size[n]].astype(float)
        if len(values) != count or not np.isfinite(values).all():
            raise ModelError(f"{path}: custom numeric '{key}' must hold {count} finite value"
                             f"{'s' if count > 1 else ''} ({meaning}), got {values.tolist()}")
        found[key] = values
    if not found:
        return None
    missing = [key for key in keys if key not in found]
    if missing:
        raise ModelError(f"{path}: {what} needs custom numeric '{missing[0]}' ({keys[missing[0]][1]}) beside "
                         f"'{next(iter(found))}'")
    return found


def _check(path: Path, key: str, ok: bool, values: np.ndarray) -> None:
    if not ok:
        meaning = {**BELT_SCALE_KEYS, **WHEEL_MOTOR_KEYS}[key][1]
        raise ModelError(f"{path}: custom numeric '{key}' must be {meaning}, got {values.tolist()}")
