"""The logged wind's force on the machine, for the fit to apply.

The twin's wind is MuJoCo's fluid model (`opt.wind`, `opt.density`, the MJCF's wind areas; see
bwr_twin.sim.plant), and a real machine's is the same physics. A rollout cannot vary `opt.wind`
within a window, so the wind enters the fit as what it does: the generalised force MuJoCo's
fluid model gives (`qfrc_fluid`) at each logged state (the encoders and the speeds) under the
logged wind speed, along the log's heading, at its air density. The fit's own model stays in
still air (`Edits.still_air`), so that the wind is not counted twice; the force is taken at the
model's nominal geometry (a fitted mass or position does not move the wind areas).
"""

from __future__ import annotations

import copy

import mujoco
import numpy as np

from bwr_twin.calibrate.log import MachineLog


def wind_forces(model: mujoco.MjModel, joint_ids, log: MachineLog) -> np.ndarray | None:
    """(n, nv) the wind's generalised force (N, N m) at each row of `log`, on `model` (still air:
    its wind and density are set here on a copy); None for a log without a wind to apply."""
    if not log.windy:
        return None
    air = copy.copy(model)
    air.opt.density = log.air_density
    heading = np.array([np.cos(log.wind_heading), np.sin(log.wind_heading), 0.0])
    data = mujoco.MjData(air)
    qpos = [int(air.jnt_qposadr[j]) for j in joint_ids]
    dofs = [int(air.jnt_dofadr[j]) for j in joint_ids]
    out = np.empty((len(log.time), air.nv))
    for row in range(len(log.time)):
        air.opt.wind[:] = log.wind[row] * heading
        data.qpos[:] = air.qpos0
        data.qvel[:] = 0.0
        data.qpos[qpos] = log.q[row]
        data.qvel[dofs] = log.velocity_at(row)
        mujoco.mj_fwdPosition(air, data)
        mujoco.mj_fwdVelocity(air, data)
        out[row] = data.qfrc_fluid
    return out
