"""Every edit made to a machine's MJCF before it is compiled, in one place.

The XML is the machine as its file describes it. Before compiling, a scene may add the payloads
its plant carries (point masses the file does not show) and set the physics timestep; the
simulation also strips the visual geoms: they carry no mass and no contacts (the model contract,
docs/contracts.md), so a copy without them steps to the same state, faster. Values that may
differ between the runs of one lockstep (friction loss, wind, air density) are not edits: they
are per-simulation fields of the plant's batch (`bwr_twin.sim.plant`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol

import mujoco

from bwr_twin.errors import ModelError

_POINT_INERTIA = 1e-6  # kg m^2: a point mass, as MuJoCo needs a positive inertia


class Payload(Protocol):
    """A point mass (kg) at `pos` (m) in the frame of the body named `body`."""

    body: str
    mass: float
    pos: tuple[float, float, float]


@dataclass(frozen=True)
class Edits:
    """What to change in the file before compiling.

    Attributes:
        payloads: point masses to add, each as a child body of the body it names.
        timestep: the physics timestep in s; None keeps the file's.
        physics_only: delete every geom that has no contacts and meets no fluid (the visual
            ones), keeping the wind areas of MuJoCo's ellipsoid fluid model.
        rigid_body_only: switch off what M and the bias forces do not need (constraints,
            contacts, joint limits, friction loss, springs, dampers, actuation, sensors): the
            controller's belief asks for nothing else.
    """

    payloads: Sequence[Payload] = ()
    timestep: float | None = None
    physics_only: bool = False
    rigid_body_only: bool = False


_RIGID_BODY_ONLY = (
    mujoco.mjtDisableBit.mjDSBL_CONSTRAINT
    | mujoco.mjtDisableBit.mjDSBL_CONTACT
    | mujoco.mjtDisableBit.mjDSBL_LIMIT
    | mujoco.mjtDisableBit.mjDSBL_EQUALITY
    | mujoco.mjtDisableBit.mjDSBL_FRICTIONLOSS
    | mujoco.mjtDisableBit.mjDSBL_SPRING
    | mujoco.mjtDisableBit.mjDSBL_DAMPER
    | mujoco.mjtDisableBit.mjDSBL_ACTUATION
    | mujoco.mjtDisableBit.mjDSBL_SENSOR
)


def compile_model(path: Path, edits: Edits = Edits()) -> mujoco.MjModel:
    """Compile the MJCF file at `path` with `edits`. Raises ModelError naming the file."""
    if not path.is_file():
        raise ModelError(f"{path}: MJCF file not found")
    try:
        spec = mujoco.MjSpec.from_file(str(path))
        for i, payload in enumerate(edits.payloads):
            body = spec.body(payload.body)
            if body is None:
                raise ModelError(f"{path}: payload {i + 1} names a body '{payload.body}' that the model lacks")
            body.add_body(
                name=f"payload_{i + 1}",
                pos=list(payload.pos),
                mass=payload.mass,
                inertia=[_POINT_INERTIA] * 3,
                explicitinertial=True,
            )
        if edits.timestep is not None:
            spec.option.timestep = edits.timestep
        if edits.rigid_body_only:
            spec.option.disableflags |= int(_RIGID_BODY_ONLY)
        if edits.physics_only:
            for geom in list(spec.geoms):
                if geom.contype == 0 and geom.conaffinity == 0 and geom.fluid_ellipsoid == 0:
                    spec.delete(geom)
        return spec.compile()
    except ValueError as exc:
        first_line = str(exc).strip().splitlines()[0] if str(exc).strip() else "compile error"
        raise ModelError(f"{path}: MuJoCo cannot compile it: {first_line}") from None
