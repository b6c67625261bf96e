"""The machine's collision shapes, read from its MJCF: geoms in group COLLISION_GROUP, named
`collision_<part>`, boxes or capsules, with no mass and no contacts (the model contract). Their
poses for given joints come from the kinematics alone (bwr_twin.model.mount): the plant, which
strips them as it strips every geom without contacts, stays the one owner of MuJoCo's state.

A shape on the bucket wheel's body is the wheel's cutting envelope: the wheel cuts the pile, so
it is no collision with the pile (it is with another machine).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from bwr_twin.errors import ModelError
from bwr_twin.model.mount import Mount, mount_of

COLLISION_GROUP = 5  # the geom group of collision shapes
PREFIX = "collision_"
BOX, CAPSULE = 0, 1  # a shape's kind, as the compiled kernels read it


@dataclass(frozen=True, eq=False)
class CollisionShape:
    """One collision shape: its part's name, kind, half sizes and where it sits on the machine.

    `half` is (3,) m: a box's half extents along its axes; a capsule's radius, then 0, then half
    its axis's length (along its local z). `cuts` marks the wheel's cutting envelope."""

    part: str
    kind: int
    half: np.ndarray
    mount: Mount
    cuts: bool


def read_collision_shapes(model: mujoco.MjModel, path: Path, wheel_body: int | None) -> tuple[CollisionShape, ...]:
    """The machine's collision shapes in geom order; () if it has none. ModelError naming the file
    and the geom for one that makes contacts, is of another type or lacks its `collision_` name."""
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)  # q = 0
    shapes = []
    for g in np.flatnonzero(model.geom_group == COLLISION_GROUP):
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, int(g)) or ""
        where = f"{path}: collision geom '{name or g}' (group {COLLISION_GROUP})"
        if not name.startswith(PREFIX):
            raise ModelError(f"{where} must be named '{PREFIX}<part>'")
        if model.geom_contype[g] or model.geom_conaffinity[g]:
            raise ModelError(f"{where} must have contype=\"0\" conaffinity=\"0\": it measures clearance, it "
                             "makes no contact")
        kind = {int(mujoco.mjtGeom.mjGEOM_BOX): BOX, int(mujoco.mjtGeom.mjGEOM_CAPSULE): CAPSULE}.get(
            int(model.geom_type[g]))
        if kind is None:
            raise ModelError(f"{where} must be a box or a capsule")
        size = model.geom_size[g]
        half = size.copy() if kind == BOX else np.array([size[0], 0.0, size[1]])
        body = int(model.geom_bodyid[g])
        shapes.append(CollisionShape(name[len(PREFIX):], kind, half,
                                     mount_of(model, data, body, data.geom_xpos[g], data.geom_xmat[g]),
                                     wheel_body is not None and body == wheel_body))
    return tuple(shapes)
