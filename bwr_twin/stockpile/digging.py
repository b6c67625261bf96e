"""The digging load of every run of a lockstep (when the scene has [digging]).

It acts where the material was cut, through the Jacobian of that point: the cutting force at
the rim, P_cut / rim speed with P_cut = cutting_energy x dug volume a second (at most the wheel
drive's rating less its idle power), lagged by one bucket interval, opposes the buckets' motion
(they rise through the face), and a lateral share of it opposes the slewing into the face. The
buckets cut in chips, one a bucket interval: the load follows the dug rate (spill included: it
was cut all the same) through a lag of one bucket interval.

One compiled pass a period does it for every run (`_load`).
"""

from __future__ import annotations

import math

import numba
import numpy as np

from bwr_twin.model.machine import Machine

DUG_RATE_FLOOR = 1e-6  # m^3/s: below it the lagged dug rate is no load at all (under 1 N of force)


class DiggingLoad:
    """The load's state and this period's values, (runs,) or (runs, 3) arrays.

    Attributes:
        power: W the wheel drive draws (its idle power when it does not cut).
        force: (runs, 3) N on the wheel, world frame; `force_max` its largest magnitude so far.
        joint_force: (runs, 3) N, N m: the load on the joints, held over the period.
    """

    def __init__(self, machine: Machine, cutting_energy: np.ndarray, idle_power: np.ndarray,
                 lateral_ratio: np.ndarray, bucket_interval: float, period: float):
        """Per run: `cutting_energy` J/m^3, `idle_power` W, `lateral_ratio` (0 for a run without
        [digging], which then has no load)."""
        runs = len(cutting_energy)
        wheel, g = machine.wheel, machine.geometry
        # The machine's and each run's numbers as two arrays: a compiled call a period costs by its arguments.
        self._constants = np.array([period, period / (bucket_interval + period), wheel.power, wheel.rim_speed,
                                    g.slew_axis_xy[0], g.slew_axis_xy[1], g.pivot_reach, g.pivot_height], dtype=float)
        self._per_run = np.array([cutting_energy, idle_power, lateral_ratio], dtype=float)  # (3, runs)
        self._dug_rate = np.zeros(runs)  # m^3/s, lagged by a bucket interval
        self._arm = np.zeros((runs, 2))  # the last cut's centre from the CP: along the boom, up (m)
        self._side = np.zeros(runs)  # and the side of the wheel's plane it lay on
        self.power = np.zeros(runs)
        self.force = np.zeros((runs, 3))
        self.force_max = np.zeros(runs)
        self.joint_force = np.zeros((runs, 3))

    def step(self, q: np.ndarray, cp: np.ndarray, cut) -> np.ndarray | None:
        """The load of a period whose cut (bwr_twin.pile.cutting.Cut) the wheels at joint
        values q and CPs cp (runs, 3) made: `joint_force`, or None when no wheel digs."""
        loaded = _load(q, cp, cut.volume, cut.centroid, cut.side, self._per_run, self._constants, self._dug_rate,
                       self._arm, self._side, self.power, self.force, self.force_max, self.joint_force)
        return self.joint_force if loaded else None


@numba.njit(cache=True)
def _load(q, cp, volume, centroid, side, per_run, constants, dug_rate, arm, last_side, power, force, force_max,
          joint_force):  # pragma: no cover - compiled
    """One period's load for every run; False (and no force) when no wheel digs at all. `per_run`:
    (3, runs) each run's cutting energy, idle power and lateral ratio; `constants`: the period,
    the bucket lag's share, the wheel's power and rim speed, the slew axis's x and y, the luff
    pivot's reach and height."""
    cutting_energy, idle_power, lateral_ratio = per_run[0], per_run[1], per_run[2]
    period, lag, wheel_power, rim_speed = constants[0], constants[1], constants[2], constants[3]
    slew_x, slew_y, pivot_reach, pivot_height = constants[4], constants[5], constants[6], constants[7]
    runs = len(volume)
    digging = False
    for r in range(runs):
        dug_rate[r] += (volume[r] / period - dug_rate[r]) * lag
        if dug_rate[r] < DUG_RATE_FLOOR:
            dug_rate[r] = 0.0
        digging = digging or dug_rate[r] != 0.0
    if not digging:  # no wheel cuts: it turns empty
        for r in range(runs):
            power[r] = idle_power[r]
            force[r, :] = 0.0
        return False
    for r in range(runs):
        power[r] = min(cutting_energy[r] * dug_rate[r] + idle_power[r], wheel_power)  # beyond its rating it stalls
        tangential = max(power[r] - idle_power[r], 0.0) / rim_speed
        cos, sin = math.cos(q[r, 1]), math.sin(q[r, 1])
        if volume[r] > 0:  # where this period's cut lay, as (along the boom, up) from the CP
            arm[r, 0] = (centroid[r, 0] - cp[r, 0]) * cos + (centroid[r, 1] - cp[r, 1]) * sin
            arm[r, 1] = centroid[r, 2] - cp[r, 2]
            last_side[r] = side[r]
        # Against the buckets' motion where they cut: the arm from the CP turned by +90 deg in
        # the boom's vertical plane (up at the front, outwards at the bottom); and against the
        # slewing into the face, along the wheel's axis (-sin, cos, 0).
        along, up = arm[r, 0], arm[r, 1]
        length = math.hypot(along, up)
        scale = tangential / length if length > 0 else 0.0
        lateral = lateral_ratio[r] * tangential * last_side[r]
        fx = scale * up * cos + lateral * sin
        fy = scale * up * sin - lateral * cos
        fz = -scale * along
        force[r, 0], force[r, 1], force[r, 2] = fx, fy, fz
        force_max[r] = max(force_max[r], math.sqrt(fx * fx + fy * fy + fz * fz))
        # At the last cut's centre, carried with the boom.
        joint_force[r, 0], joint_force[r, 1], joint_force[r, 2] = jacobian_transpose(
            q[r, 0], cos, sin, cp[r, 0] + along * cos, cp[r, 1] + along * sin, cp[r, 2] + up, fx, fy, fz,
            slew_x, slew_y, pivot_reach, pivot_height)
    return True


@numba.njit(cache=True)
def jacobian_transpose(travel, cos, sin, px, py, pz, fx, fy, fz, slew_x, slew_y, pivot_reach,
                       pivot_height):  # pragma: no cover - compiled
    """J^T F: the joint forces (N, N m, N m) of a world force F (N) at a world point p (m) fixed
    to the boom, the slew at (cos, sin): travel along X, the slew about Z through the slew axis
    and the luff about the world -Y turned by the slew, through the luff pivot (the model
    contract's axes; tests/test_stockpile.py checks it against MuJoCo's own Jacobian)."""
    arm_x, arm_y = px - (travel + slew_x), py - slew_y  # from the slew axis
    rx, ry, rz = arm_x - pivot_reach * cos, arm_y - pivot_reach * sin, pz - pivot_height
    return fx, arm_x * fy - arm_y * fx, -cos * rz * fx - sin * rz * fy + (sin * ry + cos * rx) * fz
