"""Where a frame on the machine (a site, a geom) stands for given joints, from the model's
kinematics alone: its pose at q = 0 moved by the serial chain's joints (the model contract), so
that sensors and collision shapes need no MuJoCo state, and the plant stays its one owner."""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numba
import numpy as np


@dataclass(frozen=True, eq=False)
class Mount:
    """Where a site sits on the machine: its pose at q = 0 and the joints that move it.

    `position` (3,) world m and `rotation` (3, 3) (columns: the site's axes in world) at q = 0;
    the first `joints` of travel, slew, luff move it (the chain is serial), each about its
    `anchor` (3, 3) world m along its `axis` (3, 3), both at q = 0.
    """

    position: np.ndarray
    rotation: np.ndarray
    joints: int
    anchor: np.ndarray
    axis: np.ndarray

    def poses(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The site's world positions (runs, 3) and rotations (runs, 3, 3) for joints q (runs, 3)."""
        q = np.ascontiguousarray(q, dtype=float).reshape(-1, 3)
        position, rotation = np.empty((len(q), 3)), np.empty((len(q), 3, 3))
        site_poses(q, self.position, self.rotation, self.joints, self.anchor, self.axis, position, rotation)
        return position, rotation


def mount_of(model: mujoco.MjModel, data: mujoco.MjData, body: int, position: np.ndarray,
             rotation: np.ndarray) -> Mount:
    """A frame on `body` at `position` (3,) and `rotation` (3, 3) in world at q = 0 (`data` after
    mj_kinematics at q = 0), and the joints (the model contract's serial chain) that move it."""
    ancestors = set()
    while body > 0:
        ancestors.add(body)
        body = int(model.body_parentid[body])
    joints = sum(int(model.jnt_bodyid[j]) in ancestors for j in range(model.njnt))
    return Mount(position=np.array(position, dtype=float), rotation=np.array(rotation, dtype=float).reshape(3, 3),
                 joints=joints, anchor=data.xanchor[:3].copy(), axis=data.xaxis[:3].copy())


@numba.njit(cache=True)
def site_poses(q, position0, rotation0, joints, anchor, axis, position, rotation):  # pragma: no cover - compiled
    """A site's world positions (runs, 3) and rotations (runs, 3, 3) for each run's joints q (runs, 3)."""
    for run in range(q.shape[0]):
        site_pose(q[run], position0, rotation0, joints, anchor, axis, position[run], rotation[run])


@numba.njit(cache=True)
def site_pose(q, position0, rotation0, joints, anchor, axis, position, rotation):  # pragma: no cover - compiled
    """A site's world pose for joints q (3,): its pose at q = 0 moved by the luff about its pivot,
    then the slew about its axis, then the travel along the rail (the serial chain's joints in
    world at q = 0, innermost first), for the first `joints` of them; into position (3,) and
    rotation (3, 3)."""
    position[:] = position0
    rotation[:] = rotation0
    turn = np.empty((3, 3))
    for j in range(joints - 1, -1, -1):
        k = axis[j]
        if j == 0:  # travel: a slide along its axis
            for a in range(3):
                position[a] += q[0] * k[a]
            continue
        c, s = math.cos(q[j]), math.sin(q[j])
        for a in range(3):  # Rodrigues: I cos + sin [k]x + (1 - cos) k k'
            for b in range(3):
                turn[a, b] = (1.0 - c) * k[a] * k[b] + (c if a == b else 0.0)
        turn[0, 1] -= s * k[2]
        turn[0, 2] += s * k[1]
        turn[1, 0] += s * k[2]
        turn[1, 2] -= s * k[0]
        turn[2, 0] -= s * k[1]
        turn[2, 1] += s * k[0]
        arm = position - anchor[j]
        for a in range(3):
            position[a] = anchor[j, a] + turn[a, 0] * arm[0] + turn[a, 1] * arm[1] + turn[a, 2] * arm[2]
        for col in range(3):
            r0, r1, r2 = rotation[0, col], rotation[1, col], rotation[2, col]
            for a in range(3):
                rotation[a, col] = turn[a, 0] * r0 + turn[a, 1] * r1 + turn[a, 2] * r2
