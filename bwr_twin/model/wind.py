"""The wind's generalised force on a machine at given states, from MuJoCo's fluid model.

The twin's wind is MuJoCo's ellipsoid fluid model (`opt.wind`, `opt.density`, the MJCF's wind
areas; see bwr_twin.sim.plant), and a real machine's is the same physics. A tool that replays a
logged machine (the calibration's fit, the shadow) keeps its own model in still air and applies
the logged wind as what it does: the generalised force (`qfrc_fluid`) at each logged state under
the logged wind speed, along its heading, at its air density.
"""

from __future__ import annotations

import copy
from collections.abc import Sequence

import mujoco
import numpy as np


def wind_forces(model: mujoco.MjModel, joint_ids: Sequence[int], q: np.ndarray, qd: np.ndarray,
                wind: np.ndarray, heading: float, density: float) -> np.ndarray:
    """(n, nv) the wind's generalised force (N, N m) on `model` at each of n states: the joints
    `joint_ids` at (n, 3) positions `q` (m, rad) and speeds `qd` (m/s, rad/s), the others at rest
    in their qpos0, under a wind of (n,) `wind` m/s blowing towards `heading` (rad from world +X
    towards +Y) in air of `density` kg/m^3. The model is not changed (a copy takes the air)."""
    air = copy.copy(model)
    air.opt.density = density
    direction = np.array([np.cos(heading), np.sin(heading), 0.0])
    data = mujoco.MjData(air)
    qpos = [int(air.jnt_qposadr[j]) for j in joint_ids]
    dofs = [int(air.jnt_dofadr[j]) for j in joint_ids]
    out = np.empty((len(wind), air.nv))
    for row in range(len(wind)):
        air.opt.wind[:] = wind[row] * direction
        data.qpos[:] = air.qpos0
        data.qvel[:] = 0.0
        data.qpos[qpos] = q[row]
        data.qvel[dofs] = qd[row]
        mujoco.mj_fwdPosition(air, data)
        mujoco.mj_fwdVelocity(air, data)
        out[row] = data.qfrc_fluid
    return out
