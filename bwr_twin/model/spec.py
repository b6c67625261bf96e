"""Every edit made to a machine's MJCF before it is compiled, in one place.

The XML is the machine as its file describes it. Before compiling, a scene may add the payloads
its plant carries (point masses the file does not show) and set the physics timestep; a video
sizes the offscreen framebuffer to its pictures, adds a sky and colours the pile's cut faces
(`bwr_twin.replay.video_scene`); the simulation also strips the visual geoms: they carry no mass
and no contacts (the model contract, docs/contracts.md), so a copy without them steps to the same
state, faster. Values that may differ between the runs of one lockstep (friction loss, wind, air
density) are not edits: they are per-simulation fields of the plant's batch (`bwr_twin.sim.plant`).
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol

import mujoco
import numpy as np

from bwr_twin.errors import ModelError

_POINT_INERTIA = 1e-6  # kg m^2: a point mass, as MuJoCo needs a positive inertia


STOCKPILE = "stockpile"  # name of the pile's hfield asset and geom, and of its texture and material
SKY = "sky"  # name of the sky's texture, added for pictures of a model whose file has none
_SKY_TEXELS = 256  # a gradient's resolution: smooth on any picture


class Heights(Protocol):
    """A height grid: z[iy, ix] (m) at grid lines x[ix], y[iy] (m), evenly spaced."""

    x: np.ndarray
    y: np.ndarray
    z: np.ndarray


class Drawing(Protocol):
    """How the pile's hfield is drawn: a scene's [stockpile] section says (docs/stockpile.md)."""

    colour: tuple[float, float, float, float]  # rgba
    base_depth: float  # m of the base box below the yard floor


class Payload(Protocol):
    """A point mass (kg) at `pos` (m) in the frame of the body named `body`."""

    body: str
    mass: float
    pos: tuple[float, float, float]


class Picture(Protocol):
    """How offscreen pictures of the model are drawn."""

    width: int  # px
    height: int  # px
    samples: int  # multisamples per pixel, 0 for none
    sky: tuple[tuple[float, float, float], tuple[float, float, float]]  # rgb at the zenith and the horizon


@dataclass(frozen=True)
class Edits:
    """What to change in the file before compiling.

    Attributes:
        payloads: point masses to add, each as a child body of the body it names.
        stockpile: a pile to stand in the world as an hfield named STOCKPILE (no contacts, no
            mass: the wheel's cut is computed on the heights, `bwr_twin.stockpile`), so that
            rays (`mj_ray`) measure it as a laser scanner would.
        stockpile_drawing: how that pile is drawn; None: MuJoCo's default colour, and a base
            one grid spacing deep (a pile only for rays to measure).
        stockpile_texture: give the pile a texture of one texel per height sample, in the
            drawing's colour, for a renderer to colour it by (`set_stockpile_colours`): the
            faces the wheel cut in another colour than the untouched pile.
        timestep: the physics timestep in s; None keeps the file's.
        physics_only: delete every geom that has no contacts and meets no fluid (the visual
            ones), keeping the wind areas of MuJoCo's ellipsoid fluid model.
        rigid_body_only: switch off what M and the bias forces do not need (constraints,
            contacts, joint limits, friction loss, springs, dampers, actuation, sensors): the
            controller's belief asks for nothing else.
        picture: how MuJoCo draws the model offscreen (a video's pictures): the framebuffer's
            size and multisampling, and a sky where the file has none; None keeps the file's.
        neighbour: a second machine's MJCF, attached to the world with every name prefixed
            NEIGHBOUR: one model holds both machines, the first's joints and actuators first.
        joint_sensors: a jointpos sensor on each joint named here, `<joint>_pos`, and a
            jointvel sensor on each named in `velocity_sensors`, `<joint>_vel`: what a
            calibration compares with a machine's encoders and speed feedback.
        still_air: no wind and no air density, whatever the file gives: a calibration applies
            the logged wind's force itself, and would otherwise count it twice.
    """

    payloads: Sequence[Payload] = ()
    stockpile: Heights | None = None
    stockpile_drawing: Drawing | None = None
    stockpile_texture: bool = False
    timestep: float | None = None
    physics_only: bool = False
    rigid_body_only: bool = False
    picture: Picture | None = None
    neighbour: Path | None = None
    joint_sensors: Sequence[str] = ()
    velocity_sensors: Sequence[str] = ()
    still_air: bool = False


NEIGHBOUR = "neighbour/"  # the prefix of every name of an attached second machine

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
    spec = edited_spec(path, edits)
    try:
        return spec.compile()
    except ValueError as exc:
        raise _compile_error(path, exc) from None


def edited_spec(path: Path, edits: Edits = Edits()) -> mujoco.MjSpec:
    """The MJCF file at `path` parsed, with `edits` made, not yet compiled: for a caller that
    changes fields of it before each compile (a calibration's parameters, `set_field`). Raises
    ModelError naming the file."""
    if not path.is_file():
        raise ModelError(f"{path}: MJCF file not found")
    try:
        spec = _parse(path)
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
        if edits.neighbour is not None:
            _attach(spec, edits.neighbour)
        if edits.stockpile is not None:
            _add_stockpile(spec, edits.stockpile, edits.stockpile_drawing, textured=edits.stockpile_texture)
        if edits.timestep is not None:
            spec.option.timestep = edits.timestep
        if edits.picture is not None:
            _set_picture(spec, edits.picture)
        if edits.still_air:
            spec.option.density = 0.0
            spec.option.wind = [0.0, 0.0, 0.0]
        if edits.rigid_body_only:
            spec.option.disableflags |= int(_RIGID_BODY_ONLY)
        if edits.physics_only:
            for geom in list(spec.geoms):
                if geom.contype == 0 and geom.conaffinity == 0 and geom.fluid_ellipsoid == 0:
                    spec.delete(geom)
        for joint in edits.joint_sensors:
            spec.add_sensor(name=f"{joint}_pos", type=mujoco.mjtSensor.mjSENS_JOINTPOS,
                            objtype=mujoco.mjtObj.mjOBJ_JOINT, objname=joint)
        for joint in edits.velocity_sensors:
            spec.add_sensor(name=f"{joint}_vel", type=mujoco.mjtSensor.mjSENS_JOINTVEL,
                            objtype=mujoco.mjtObj.mjOBJ_JOINT, objname=joint)
        return spec
    except ValueError as exc:
        raise _compile_error(path, exc) from None


def _compile_error(path: Path, exc: ValueError) -> ModelError:
    first_line = str(exc).strip().splitlines()[0] if str(exc).strip() else "compile error"
    return ModelError(f"{path}: MuJoCo cannot compile it: {first_line}")


def set_field(spec: mujoco.MjSpec, kind: str, name: str, field: str, value: float | Sequence[float]) -> None:
    """Set one field of one element of `spec` before it is compiled: `kind` "joint" or "body",
    `field` an MjSpec attribute ("damping", "frictionloss", "armature"; "mass", "pos").
    Raises ModelError if the element is missing."""
    element = spec.joint(name) if kind == "joint" else spec.body(name)
    if element is None:
        raise ModelError(f"the model has no {kind} named '{name}'")
    setattr(element, field, value)


_WARNED: set[tuple[str, str]] = set()  # (file, MuJoCo's warning) already printed by this process


def _parse(path: Path) -> mujoco.MjSpec:
    """The MJCF file at `path` parsed. What MuJoCo warns of while parsing (an XML holding a NaN)
    is printed once a process as 'warning: FILE: MuJoCo: ...', not each time the file is parsed:
    a run compiles its machine more than once (the plant, the controller's model, pictures)."""
    texts: list[str] = []
    previous = mujoco.get_mju_user_warning()
    mujoco.set_mju_user_warning(texts.append)
    try:
        return mujoco.MjSpec.from_file(str(path))
    finally:
        mujoco.set_mju_user_warning(previous)
        for text in texts:
            if (str(path), text) not in _WARNED:
                _WARNED.add((str(path), text))
                print(f"warning: {path}: MuJoCo: {' '.join(text.split())}", file=sys.stderr)


def _attach(spec: mujoco.MjSpec, path: Path) -> None:
    """The machine of the MJCF at `path` on the world of `spec`, its names prefixed NEIGHBOUR."""
    if not path.is_file():
        raise ModelError(f"{path}: the neighbour's MJCF file not found")
    other = _parse(path)
    bodies = other.worldbody.bodies
    if len(bodies) != 1:
        raise ModelError(f"{path}: a neighbour's world must hold one body, its machine; it holds {len(bodies)}")
    spec.worldbody.add_frame().attach_body(bodies[0], NEIGHBOUR, "")


def _add_stockpile(spec: mujoco.MjSpec, pile: Heights, drawing: Drawing | None, *, textured: bool) -> None:
    """The pile as an hfield geom on the world body: row 0 of its data lies at the lowest Y."""
    top = max(float(pile.z.max()), 1e-3)
    base = drawing.base_depth if drawing is not None else float(pile.x[1] - pile.x[0])  # MuJoCo needs one
    spec.add_hfield(
        name=STOCKPILE,
        nrow=len(pile.y),
        ncol=len(pile.x),
        size=[(pile.x[-1] - pile.x[0]) / 2, (pile.y[-1] - pile.y[0]) / 2, top, base],
        userdata=(pile.z / top).ravel().tolist(),
    )
    geom = spec.worldbody.add_geom(
        name=STOCKPILE,
        type=mujoco.mjtGeom.mjGEOM_HFIELD,
        hfieldname=STOCKPILE,
        pos=[(pile.x[0] + pile.x[-1]) / 2, (pile.y[0] + pile.y[-1]) / 2, 0.0],
        contype=0,
        conaffinity=0,
        group=1,
    )
    if drawing is not None:
        geom.rgba = list(drawing.colour)
    if textured:  # MuJoCo stretches a 2D texture once over an hfield, its first row at the highest Y
        colour = np.asarray(geom.rgba)
        texels = np.broadcast_to(np.round(255 * colour[:3]).astype(np.uint8), (len(pile.y), len(pile.x), 3))
        texture = spec.add_texture(name=STOCKPILE, type=mujoco.mjtTexture.mjTEXTURE_2D, width=len(pile.x),
                                   height=len(pile.y), nchannel=3,
                                   colorspace=mujoco.mjtColorSpace.mjCOLORSPACE_LINEAR)  # the rgba, as is
        texture.data = texels.tobytes()
        roles = [""] * mujoco.mjtTextureRole.mjNTEXROLE
        roles[mujoco.mjtTextureRole.mjTEXROLE_RGB] = STOCKPILE
        spec.add_material(name=STOCKPILE, textures=roles)
        geom.material = STOCKPILE
        geom.rgba = [1.0, 1.0, 1.0, float(colour[3])]  # the texture holds the colour; MuJoCo multiplies


def _set_picture(spec: mujoco.MjSpec, picture: Picture) -> None:
    """An offscreen framebuffer of the picture's size and multisampling, and a gradient sky."""
    spec.visual.global_.offwidth, spec.visual.global_.offheight = picture.width, picture.height
    spec.visual.quality.offsamples = picture.samples
    if not any(texture.type == mujoco.mjtTexture.mjTEXTURE_SKYBOX for texture in spec.textures):
        spec.add_texture(name=SKY, type=mujoco.mjtTexture.mjTEXTURE_SKYBOX,
                         builtin=mujoco.mjtBuiltin.mjBUILTIN_GRADIENT, rgb1=list(picture.sky[0]),
                         rgb2=list(picture.sky[1]), width=_SKY_TEXELS, height=6 * _SKY_TEXELS)


def set_stockpile_heights(model: mujoco.MjModel, z: np.ndarray) -> None:
    """Write a run's pile heights (m, on the grid the model was compiled with) into the model's
    hfield, e.g. to scan the pile as dug with `mj_ray`. The heights only ever fall, so the
    compiled scale holds them."""
    hfield = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_HFIELD, STOCKPILE)
    nrow, ncol = model.hfield_nrow[hfield], model.hfield_ncol[hfield]
    adr, top = model.hfield_adr[hfield], model.hfield_size[hfield, 2]
    model.hfield_data[adr : adr + nrow * ncol] = (np.asarray(z) / top).ravel()


def set_stockpile_colours(model: mujoco.MjModel, rgb: np.ndarray) -> None:
    """Write colours (uint8, one per height sample, shaped as the heights with a last axis of 3)
    into the pile's texture (`Edits.stockpile_texture`); a renderer then uploads it."""
    texture = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_TEXTURE, STOCKPILE)
    adr, size = model.tex_adr[texture], model.tex_height[texture] * model.tex_width[texture] * 3
    model.tex_data[adr : adr + size] = np.asarray(rgb, dtype=np.uint8)[::-1].ravel()
