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

The velocity and acceleration scales are twice the path's peak reference speed and acceleration
on that axis, and at least what crosses half the envelope in the path's duration (so an axis the
path leaves still gets a scale). The error scale is a distance of the bucket wheel centre (CP):
`error_scale` m on travel, `error_scale / L` rad on slew and luff, L the boom length. Every entry
is clipped to [-OBSERVATION_LIMIT, OBSERVATION_LIMIT].
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from bwr_twin.errors import ModelError
from bwr_twin.gym.kernels import observe
from bwr_twin.model.machine import AXES, Machine
from bwr_twin.sim.lockstep import Lockstep

OBSERVATION_SIZE = 19
OBSERVATION_LIMIT = 10.0  # bound of the Box; inside the envelope on the path, entries stay within about 1
POSITION, VELOCITY = slice(0, 3), slice(3, 6)
REFERENCE_POSITION, REFERENCE_VELOCITY, REFERENCE_ACCELERATION = slice(6, 9), slice(9, 12), slice(12, 15)
ERROR, TIME = slice(15, 18), 18


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
    """

    centre: np.ndarray
    half_width: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray
    error: np.ndarray
    duration: float
    # What each entry subtracts and divides by, in the layout's order.
    _offset: np.ndarray = field(init=False, repr=False)
    _divisor: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        zero = np.zeros(3)
        object.__setattr__(self, "_offset", np.concatenate([self.centre, zero, self.centre, zero, zero, zero, [0.0]]))
        object.__setattr__(self, "_divisor", np.concatenate([self.half_width, self.velocity, self.half_width,
                                                             self.velocity, self.acceleration, self.error,
                                                             [self.duration]]))

    @classmethod
    def of(cls, loop: Lockstep, error_scale: float) -> Scales:
        """The scales of a lockstep's machine and path; `error_scale` in m at the CP. Raises
        ModelError if the machine's operating envelope is not finite on every axis."""
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
                   at_cp(error_scale, loop.machine), duration)

    @property
    def offset(self) -> np.ndarray:
        """(19,) what each entry subtracts, in the layout's order."""
        return self._offset

    @property
    def divisor(self) -> np.ndarray:
        """(19,) what each entry is divided by, in the layout's order."""
        return self._divisor

    def observe(self, q: np.ndarray, qd: np.ndarray, q_ref: np.ndarray, qd_ref: np.ndarray,
                qdd_ref: np.ndarray, elapsed: float) -> np.ndarray:
        """(runs, 19) float32 observations of (runs, 3) measured and (3,) reference states,
        `elapsed` s after the path's start: (entry - offset) / divisor, clipped (bwr_twin.gym.kernels)."""
        out = np.empty((len(q), OBSERVATION_SIZE), dtype=np.float32)
        q, qd, q_ref, qd_ref, qdd_ref = (np.asarray(a, dtype=float) for a in (q, qd, q_ref, qd_ref, qdd_ref))
        observe(q, qd, q_ref, qd_ref, qdd_ref, float(elapsed), self._offset, self._divisor, OBSERVATION_LIMIT, out)
        return out

