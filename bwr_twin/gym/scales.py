"""The observation: its layout, and the scales that bring every entry to roughly [-1, 1].

Per axis (travel in m, slew and luff in rad):

    entries  what                                      divided by (after subtracting)
    0-2      measured position (encoders)              envelope half-width (- envelope centre)
    3-5      measured velocity (encoders)              velocity scale
    6-8      reference position                        envelope half-width (- envelope centre)
    9-11     reference velocity                        velocity scale
    12-14    reference acceleration                    acceleration scale
    15-17    tracking error, reference - measured      error scale
    18       time since the path's start               path duration

With `instruments=True` (a scene with a [stockpile] on a machine that has both instruments):

    19       belt scale reading, t/h                   the wheel's capacity at the pile's bulk density
    20       wheel motor current, A                    the current at the wheel drive's rated power

the readings of the last control period (0 before the first), the spans the OPC UA server gives
as their EURange (bwr_twin.sim.ranges).

The velocity and acceleration scales are twice the path's peak reference speed and acceleration
on that axis, and at least what crosses half the envelope in the path's duration (so an axis the
path leaves still gets a scale). The error scale is a distance of the bucket wheel centre (CP):
`error_scale` m on travel, `error_scale / L` rad on slew and luff, L the boom length. Every entry
is clipped to [-OBSERVATION_LIMIT, OBSERVATION_LIMIT].
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from bwr_twin.errors import ModelError, SceneError
from bwr_twin.gym.kernels import observe
from bwr_twin.model.machine import AXES, Machine
from bwr_twin.sim.lockstep import Lockstep
from bwr_twin.sim.ranges import belt_scale_span, wheel_current_span

OBSERVATION_SIZE = 19
OBSERVATION_LIMIT = 10.0  # bound of the Box; inside the envelope on the path, entries stay within about 1
POSITION, VELOCITY = slice(0, 3), slice(3, 6)
REFERENCE_POSITION, REFERENCE_VELOCITY, REFERENCE_ACCELERATION = slice(6, 9), slice(9, 12), slice(12, 15)
ERROR, TIME = slice(15, 18), 18
INSTRUMENTS = slice(19, 21)  # with instruments=True: the belt scale, the wheel current
INSTRUMENT_SIZE = 2


def at_cp(distance: float, machine: Machine) -> np.ndarray:
    """(3,) joint quantities that move the CP by `distance`: itself on travel (m), divided by the
    boom length on slew and luff (rad). Works for speeds and accelerations alike."""
    boom = machine.geometry.boom_length
    return np.array([distance, distance / boom, distance / boom])


@dataclass(frozen=True)
class Scales:
    """What the observation subtracts and divides by, per axis (m, rad; m/s, rad/s; m/s^2, rad/s^2).

    Attributes:
        centre, half_width: (3,) of the operating envelope.
        velocity, acceleration, error: (3,) scales of velocities, accelerations and tracking errors.
        duration: s, the path's duration.
        instruments: (2,) t/h, A the belt scale and the wheel current are divided by, or None: the
            observation has no instruments.
    """

    centre: np.ndarray
    half_width: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray
    error: np.ndarray
    duration: float
    instruments: np.ndarray | None = None
    # What each entry subtracts and divides by, in the layout's order.
    _offset: np.ndarray = field(init=False, repr=False)
    _divisor: np.ndarray = field(init=False, repr=False)
    _instrument_divisor: tuple[float, float] | None = field(init=False, repr=False)

    def __post_init__(self) -> None:
        divisor = tuple(float(x) for x in self.instruments) if self.instruments is not None else None
        object.__setattr__(self, "_instrument_divisor", divisor)
        zero = np.zeros(3)
        object.__setattr__(self, "_offset", np.concatenate([self.centre, zero, self.centre, zero, zero, zero, [0.0]]))
        object.__setattr__(self, "_divisor", np.concatenate([self.half_width, self.velocity, self.half_width,
                                                             self.velocity, self.acceleration, self.error,
                                                             [self.duration]]))

    @property
    def size(self) -> int:
        """Entries of an observation: 19, and 2 with instruments."""
        return OBSERVATION_SIZE + (INSTRUMENT_SIZE if self.instruments is not None else 0)

    @classmethod
    def of(cls, loop: Lockstep, error_scale: float, instruments: bool = False) -> Scales:
        """The scales of a lockstep's machine and path; `error_scale` in m at the CP; with
        `instruments`, the belt scale's and the wheel current's. Raises ModelError if the
        machine's operating envelope is not finite on every axis, SceneError if `instruments`
        and the run lacks either instrument."""
        envelope = loop.machine.envelope
        open_axes = [axis for axis, row in zip(AXES, envelope) if not np.isfinite(row).all()]
        if open_axes:
            raise ModelError(
                f"{loop.machine.path}: the environment scales positions by the operating envelope, and "
                f"{', '.join(open_axes)} have none: give custom numerics envelope_<axis> or joint ranges"
            )
        half_width = (envelope[:, 1] - envelope[:, 0]) / 2
        _, qd_desired, qdd_desired = loop.path
        duration = loop.tracking.trajectory.duration
        velocity = np.maximum(2 * np.abs(qd_desired).max(axis=0), half_width / duration)
        acceleration = np.maximum(2 * np.abs(qdd_desired).max(axis=0), half_width / duration**2)
        return cls(envelope.mean(axis=1), half_width, velocity, acceleration,
                   at_cp(error_scale, loop.machine), duration,
                   instrument_scales(loop) if instruments else None)

    @property
    def offset(self) -> np.ndarray:
        """(19,) what each entry subtracts, in the layout's order."""
        return self._offset

    @property
    def divisor(self) -> np.ndarray:
        """(19,) what each entry is divided by, in the layout's order."""
        return self._divisor

    def observe_instruments(self, loop: Lockstep, runs: np.ndarray, out: np.ndarray) -> None:
        """The instruments' entries of `runs` of `loop` into `out` (len(runs), 2) float32: their
        readings of the last period (0 before the first) divided by `instruments`, clipped."""
        if loop.k == 0:
            out[...] = 0.0
            return
        readings = loop.instruments
        raw = np.stack([readings.belt_scale[runs], readings.wheel_current[runs]], axis=1)
        out[...] = np.clip(raw / self.instruments, -OBSERVATION_LIMIT, OBSERVATION_LIMIT)

    def observe_instruments_one(self, loop: Lockstep, out: np.ndarray) -> None:
        """`observe_instruments` of run 0 into `out` (2,), the same numbers in Python floats: a
        single environment's step, where numpy's calls would cost more than the arithmetic."""
        if loop.k == 0:
            out[0] = out[1] = 0.0
            return
        readings, (belt, current), limit = loop.instruments, self._instrument_divisor, OBSERVATION_LIMIT
        out[0] = min(max(float(readings.belt_scale[0]) / belt, -limit), limit)  # NaN passes, as np.clip lets it
        out[1] = min(max(float(readings.wheel_current[0]) / current, -limit), limit)

    def observe(self, q: np.ndarray, qd: np.ndarray, q_ref: np.ndarray, qd_ref: np.ndarray,
                qdd_ref: np.ndarray, elapsed: float) -> np.ndarray:
        """(runs, 19) float32 observations of (runs, 3) measured and (3,) reference states,
        `elapsed` s after the path's start: (entry - offset) / divisor, clipped (bwr_twin.gym.kernels)."""
        out = np.empty((len(q), OBSERVATION_SIZE), dtype=np.float32)
        q, qd, q_ref, qd_ref, qdd_ref = (np.asarray(a, dtype=float) for a in (q, qd, q_ref, qd_ref, qdd_ref))
        observe(q, qd, q_ref, qd_ref, qdd_ref, float(elapsed), self._offset, self._divisor, OBSERVATION_LIMIT, out)
        return out


def instrument_scales(loop: Lockstep) -> np.ndarray:
    """(2,) t/h, A: the belt scale's and the wheel current's scales of a lockstep's run, the tops
    of their OPC UA EURanges; SceneError naming the scene if the run lacks either instrument."""
    scene, readings = loop.scenes[0], loop.instruments
    wanted = "instruments=True observes the belt scale and the wheel current"
    if scene.stockpile is None:
        raise SceneError(f"{scene.path}: {wanted}, which a scene has only with a [stockpile] on a machine that "
                         "describes them (docs/sensing.md); this scene has no [stockpile]: give one that has, "
                         "such as heavy_dig_pile, or leave instruments out")
    missing = [f"no {what} (custom numeric '{key}')" for what, key, spec in (
        ("belt scale", "belt_scale_distance", readings and readings.scale),
        ("wheel motor", "wheel_motor", readings and readings.motor)) if spec is None]
    if missing:
        raise SceneError(f"{scene.path}: {wanted}, but its machine {scene.machine.mjcf.name} describes "
                         f"{' and '.join(missing)} (docs/sensing.md): give a machine that has both, such as "
                         "mjcf/bwr_heavy.xml, or leave instruments out")
    return np.array([belt_scale_span(loop), wheel_current_span(loop)])
