"""Actions in [-1, 1]^3 to drive forces (N, N m, N m), in one of two modes.

- "force": the drive force itself, normalised by the drive ratings of the plant's MJCF: +1 is
  the upper rating, -1 the lower one, 0 no force; `force_scale` (N, N m, N m), if given,
  replaces the ratings (+-1 is +-force_scale), and a machine whose MJCF has none needs it.
- "acceleration": an acceleration added to the reference's, through the controller's belief of
  the machine (`bwr_twin.control.belief`) at the measured state:

      tau = M(q_hat) (qdd_ref + a * acceleration_scale) + bias(q_hat, qd_hat)

  so a = 0 is computed-torque feed-forward. `acceleration_scale` is a CP acceleration (m/s^2):
  itself on travel, divided by the boom length on slew and luff (rad/s^2).

Actions outside [-1, 1] are clipped; NaN, infinities, complex numbers and arrays of another
shape are refused (`checked_actions`), never reshaped or turned into forces.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from bwr_twin.control.belief import Belief
from bwr_twin.errors import ModelError
from bwr_twin.gym.kernels import clipped_acceleration, clipped_force
from bwr_twin.gym.scales import at_cp
from bwr_twin.model.machine import AXES
from bwr_twin.sim.lockstep import Lockstep, first_non_finite

ACTION_MODES = ("acceleration", "force")
DEFAULT_ACCELERATION_SCALE = 0.1  # m/s^2 at the CP: 13 x the paper path's peak reference (7.5e-3 m/s^2, travel)


class ForceDrive:
    """+-1 is the drive rating (or +-force_scale) of each axis."""

    def __init__(self, loop: Lockstep, force_scale: Sequence[float] | None):
        self._force = np.zeros((1, 3))
        if force_scale is not None:
            scale = _positive("force_scale", force_scale, 3)
            self.low, self.high = scale, scale
            return
        limits = loop.machine.drive_limits
        unrated = [axis for axis, row in zip(AXES, limits) if not np.isfinite(row).all()]
        if unrated:
            raise ModelError(
                f"{loop.machine.path}: action_mode 'force' needs drive ratings (actuator forcerange or "
                f"ctrlrange), and {', '.join(unrated)} have none: pass force_scale=(N, N m, N m)"
            )
        self.low, self.high = -limits[:, 0], limits[:, 1]

    def force_one(self, action: np.ndarray, q: np.ndarray, qd: np.ndarray,
                  qdd_ref: np.ndarray) -> np.ndarray | None:
        """One slot's (1, 3) forces of its (3,) float action, clipped, as `forces` gives them;
        None if the action is not finite."""
        return None if clipped_force(action, self.low, self.high, self._force) >= 0 else self._force

    def forces(self, action: np.ndarray, slots: np.ndarray, q: np.ndarray, qd: np.ndarray,
               qdd_ref: np.ndarray) -> np.ndarray:
        """(len(slots), 3) forces of the (len(slots), 3) actions; the states are not needed."""
        return np.where(action >= 0, action * self.high, action * self.low)


class AccelerationDrive:
    """tau = M(q_hat) (qdd_ref + a * scale) + bias(q_hat, qd_hat), from the controller's belief."""

    def __init__(self, loop: Lockstep, slots: int, acceleration_scale: float):
        (scale,) = _positive("acceleration_scale", [acceleration_scale], 1)
        self.scale = at_cp(scale, loop.machine)
        # One belief for every environment slot, reused across episodes: it holds no state.
        self.belief = Belief(loop.belief_machine, slots)
        self._u = np.zeros((1, 3))

    def force_one(self, action: np.ndarray, q: np.ndarray, qd: np.ndarray,
                  qdd_ref: np.ndarray) -> np.ndarray | None:
        """One slot's (1, 3) forces of its (3,) float action, clipped, at the (1, 3) measured
        state: the numbers `forces` gives (Belief.torque sums M u as it does); None if the action
        is not finite."""
        if clipped_acceleration(action, qdd_ref, self.scale, self._u) >= 0:
            return None
        return self.belief.torque_at(q, qd, self._u)

    def forces(self, action: np.ndarray, slots: np.ndarray, q: np.ndarray, qd: np.ndarray,
               qdd_ref: np.ndarray) -> np.ndarray:
        """(len(slots), 3) forces; `q`, `qd` the measured (all slots, 3) state, `qdd_ref` the
        (len(slots), 3) reference acceleration of `slots`."""
        u = qdd_ref + action * self.scale
        self.belief.update(q, qd, None if len(slots) == len(q) else slots)
        mass, bias = self.belief.mass_matrix[slots], self.belief.bias[slots]
        # M u row by row, summed in a fixed order, as computed_torque does.
        return (mass * u[:, None, :]).sum(axis=2) + bias


def make_drive(mode: str, loop: Lockstep, slots: int, *, force_scale: Sequence[float] | None,
               acceleration_scale: float) -> ForceDrive | AccelerationDrive:
    """The drive of `mode` for `slots` environment slots of the lockstep's scene."""
    if mode == "force":
        return ForceDrive(loop, force_scale)
    if mode == "acceleration":
        return AccelerationDrive(loop, slots, acceleration_scale)
    raise ValueError(f"action_mode must be one of {', '.join(ACTION_MODES)}, got {mode!r}")


def checked_actions(actions, shape: tuple[int, ...], where: str, rows: str | None = None) -> np.ndarray:
    """`actions` as a float64 array of `shape`; ValueError naming `where` (the environment), the
    element and the expected shape for anything else: another shape, complex numbers, NaN or
    infinity. `rows` names what a row is, when there are rows (a vector environment's
    sub-environments)."""
    array = actions if isinstance(actions, np.ndarray) else _array(actions, shape, where)
    expected = f"{shape}: one row (travel, slew, luff) per {rows}" if rows else f"{shape}: travel, slew, luff"
    if array.shape != shape:
        raise ValueError(f"{where}: an action of shape {array.shape}, expected {expected}")
    kind = array.dtype.kind
    if kind not in "biuf":
        what = "complex numbers" if kind == "c" else f"values of type {array.dtype}"
        raise ValueError(f"{where}: an action of {what}, expected real numbers of shape {expected}")
    if array.dtype not in _COMPILED:
        array = array.astype(np.float64)
    bad = first_non_finite(array)
    if bad >= 0:
        index = np.unravel_index(bad, shape)
        row = f"{rows} {index[0]}, " if rows else ""
        name = f"action{'s' if rows else ''}[{', '.join(str(i) for i in index)}] ({row}{AXES[index[-1]]})"
        raise ValueError(f"{where}: {name} is {array.flat[bad]}: actions must be finite (values beyond "
                         "[-1, 1] are clipped)")
    return array


_COMPILED = (np.dtype(np.float64), np.dtype(np.float32))  # what the kernels take as they are


def as_action(action, where: str) -> np.ndarray:
    """A single environment's action as a (3,) float array for `force_one`, which checks it is
    finite: an array of float32 or float64 as it is, anything else through `checked_actions`."""
    if type(action) is np.ndarray and action.shape == (3,) and action.dtype in _COMPILED:
        return action
    return checked_actions(action, (3,), where)


def _array(actions, shape: tuple[int, ...], where: str) -> np.ndarray:
    try:
        return np.asarray(actions)
    except (ValueError, TypeError) as exc:  # ragged nesting
        raise ValueError(f"{where}: an action that is not an array of shape {shape} ({exc})") from None


def _positive(name: str, values: Sequence[float], size: int) -> np.ndarray:
    """`values` as a (size,) array; ValueError unless they are `size` finite numbers > 0."""
    array = np.asarray(values, dtype=float)
    if array.shape != (size,) or not (np.isfinite(array) & (array > 0)).all():
        raise ValueError(f"{name} must be {size} finite number(s) > 0, got {values!r}")
    return array
