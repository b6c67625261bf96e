"""The MJCF's own visual geoms as triangle meshes, and the world poses of the bodies that carry them.

Every geom in the visual group becomes one `VisualGeom`: a mesh in the geom's frame, its pose in
the frame of the rigid body that carries it, and its colour. Geoms are grouped by weld body (the
root of the group of bodies welded together), so a frame of the replay sends one pose per
moving rigid body, however many geoms and welded child bodies it has.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from bwr_twin.errors import ModelError
from bwr_twin.model.machine import Machine

VISUAL_GROUP = 2  # the model contract's group of visual geoms (docs/contracts.md)
MUJOCO_DEFAULT_RGBA = (0.5, 0.5, 0.5, 1.0)  # a geom rgba equal to this defers to its material
ROUND_SEGMENTS = 24  # facets around cylinders, capsules and spheres
INFINITE_PLANE_HALF_SIZE = 500.0  # m, drawn extent of a plane whose MJCF size is 0 (infinite)
_GEOM = mujoco.mjtGeom


@dataclass(frozen=True)
class VisualGeom:
    """One visual geom, ready to draw.

    Attributes:
        name: the geom's MJCF name, or `geom<id>` when it has none.
        body: name of the weld body whose frame `position` and `wxyz` are given in.
        type: MuJoCo geom type in lower case: box, cylinder, capsule, sphere, ellipsoid, mesh, plane.
        size: MuJoCo `geom_size` (box half-sizes; cylinder and capsule radius, half-length;
            sphere radius; ellipsoid radii), in m.
        position: (3,) geom origin in the weld body's frame, m.
        wxyz: (4,) geom orientation in the weld body's frame.
        rgba: colour and opacity in [0, 1].
        vertices: (v, 3) mesh vertices in the geom's frame, m.
        faces: (f, 3) vertex indices, counter-clockwise seen from outside.
    """

    name: str
    body: str
    type: str
    size: tuple[float, float, float]
    position: np.ndarray
    wxyz: np.ndarray
    rgba: tuple[float, float, float, float]
    vertices: np.ndarray
    faces: np.ndarray


def rgb(rgba: tuple[float, ...]) -> tuple[int, int, int]:
    """An MJCF colour (0-1) as 0-255 integers."""
    return tuple(round(255 * c) for c in rgba[:3])


def body_name(model: mujoco.MjModel, body: int) -> str:
    return mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, body) or f"body{body}"


def _type_name(kind: int) -> str:
    """'box' for mjGEOM_BOX, and so on."""
    return _GEOM(kind).name[len("mjGEOM_") :].lower()


def visual_geoms(machine: Machine) -> list[VisualGeom]:
    """Every geom of the visual group, in model order. Raises ModelError for a geom type
    that has no drawing (height fields, SDFs)."""
    model = machine.model
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)  # at qpos0: poses relative to weld bodies hold for any q
    geoms = []
    for g in range(model.ngeom):
        if model.geom_group[g] != VISUAL_GROUP:
            continue
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g) or f"geom{g}"
        weld = int(model.body_weldid[model.geom_bodyid[g]])
        body_rotation = data.xmat[weld].reshape(3, 3)
        position = body_rotation.T @ (data.geom_xpos[g] - data.xpos[weld])
        wxyz = np.empty(4)
        mujoco.mju_mat2Quat(wxyz, (body_rotation.T @ data.geom_xmat[g].reshape(3, 3)).ravel())
        vertices, faces = _mesh(model, g, f"{machine.path.name}: geom '{name}'")
        geoms.append(
            VisualGeom(
                name=name,
                body=body_name(model, weld),
                type=_type_name(model.geom_type[g]),
                size=tuple(float(s) for s in model.geom_size[g]),
                position=position,
                wxyz=wxyz,
                rgba=_rgba(model, g),
                vertices=vertices.astype(np.float32),
                faces=faces.astype(np.uint32),
            )
        )
    return geoms


def _rgba(model: mujoco.MjModel, g: int) -> tuple[float, float, float, float]:
    """MuJoCo's rule: a geom's own rgba wins unless it is the default and a material is set."""
    rgba = model.geom_rgba[g]
    material = model.geom_matid[g]
    if material >= 0 and np.allclose(rgba, MUJOCO_DEFAULT_RGBA):
        rgba = model.mat_rgba[material]
    return tuple(float(c) for c in rgba)


def _mesh(model: mujoco.MjModel, g: int, where: str) -> tuple[np.ndarray, np.ndarray]:
    kind = model.geom_type[g]
    size = model.geom_size[g]
    if kind == _GEOM.mjGEOM_BOX:
        return box(size)
    if kind == _GEOM.mjGEOM_CYLINDER:
        return cylinder(size[0], size[1])
    if kind == _GEOM.mjGEOM_CAPSULE:
        return capsule(size[0], size[1])
    if kind == _GEOM.mjGEOM_SPHERE:
        return ellipsoid((size[0],) * 3)
    if kind == _GEOM.mjGEOM_ELLIPSOID:
        return ellipsoid(size)
    if kind == _GEOM.mjGEOM_PLANE:
        half = [s if s > 0 else INFINITE_PLANE_HALF_SIZE for s in size[:2]]
        vertices, faces = box((half[0], half[1], 0.0))
        return vertices, faces[10:]  # the +Z face only: a plane is seen from above
    if kind == _GEOM.mjGEOM_MESH:
        mesh = model.geom_dataid[g]
        v0, nv = model.mesh_vertadr[mesh], model.mesh_vertnum[mesh]
        f0, nf = model.mesh_faceadr[mesh], model.mesh_facenum[mesh]
        return model.mesh_vert[v0 : v0 + nv].copy(), model.mesh_face[f0 : f0 + nf].copy()
    raise ModelError(
        f"{where}: type {_type_name(kind)} cannot be drawn; visual geoms "
        "must be boxes, cylinders, capsules, spheres, ellipsoids, meshes or planes"
    )


# -- primitive meshes, in MuJoCo's conventions (centred, long axis along local Z) -------------


def box(half_sizes) -> tuple[np.ndarray, np.ndarray]:
    """A box with the given half-sizes: 8 corners, 12 triangles (draw with flat shading)."""
    corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], dtype=float)
    # fmt: off
    faces = np.array(
        [
            [0, 1, 3], [0, 3, 2],  # -X
            [4, 6, 7], [4, 7, 5],  # +X
            [0, 4, 5], [0, 5, 1],  # -Y
            [2, 3, 7], [2, 7, 6],  # +Y
            [0, 2, 6], [0, 6, 4],  # -Z
            [1, 5, 7], [1, 7, 3],  # +Z
        ]
    )
    # fmt: on
    return corners * np.asarray(half_sizes, dtype=float), faces


def _surface_of_revolution(profile: np.ndarray, segments: int) -> tuple[np.ndarray, np.ndarray]:
    """Rotate a (m, 2) profile of (radius, z) rows, bottom to top, about Z.

    A row with radius 0 is a pole; two equal rows in a row start a new band with its own
    vertices (a sharp edge, as at a cylinder's rim).
    """
    profile = profile.copy()
    profile[np.abs(profile[:, 0]) < 1e-9 * np.abs(profile).max(), 0] = 0.0  # sin(pi) is not quite 0
    angle = np.linspace(0.0, 2.0 * np.pi, segments, endpoint=False)
    ring = np.stack([np.cos(angle), np.sin(angle)], axis=1)
    vertices = np.concatenate([np.column_stack([r * ring, np.full(segments, z)]) for r, z in profile])
    faces = []
    for i in range(len(profile) - 1):
        if np.array_equal(profile[i], profile[i + 1]):
            continue
        a = i * segments + np.arange(segments)
        b = i * segments + (np.arange(segments) + 1) % segments
        if profile[i, 0] > 0:  # a quad strip's lower triangles vanish at a bottom pole
            faces.append(np.column_stack([a, b, b + segments]))
        if profile[i + 1, 0] > 0:  # and its upper ones at a top pole
            faces.append(np.column_stack([a, b + segments, a + segments]))
    return vertices, np.concatenate(faces)


def cylinder(
    radius: float, half_length: float, segments: int = ROUND_SEGMENTS
) -> tuple[np.ndarray, np.ndarray]:
    """A closed cylinder along Z; cap rims have their own vertices so that shading keeps the edge sharp."""
    h = half_length
    profile = np.array([[0, -h], [radius, -h], [radius, -h], [radius, h], [radius, h], [0, h]], dtype=float)
    return _surface_of_revolution(profile, segments)


def capsule(
    radius: float, half_length: float, segments: int = ROUND_SEGMENTS
) -> tuple[np.ndarray, np.ndarray]:
    """A cylinder along Z with hemispherical ends."""
    polar = np.linspace(0.0, np.pi / 2, segments // 4 + 1)
    bottom = np.column_stack([radius * np.sin(polar), -half_length - radius * np.cos(polar)])
    top = np.column_stack([radius * np.cos(polar), half_length + radius * np.sin(polar)])
    return _surface_of_revolution(np.concatenate([bottom, top]), segments)


def ellipsoid(radii, segments: int = ROUND_SEGMENTS) -> tuple[np.ndarray, np.ndarray]:
    """An ellipsoid with the given semi-axes (a sphere when they are equal)."""
    polar = np.linspace(0.0, np.pi, segments // 2 + 1)
    vertices, faces = _surface_of_revolution(np.column_stack([np.sin(polar), -np.cos(polar)]), segments)
    return vertices * np.asarray(radii, dtype=float), faces


class BodyPoser:
    """World poses of the weld bodies that carry visual geoms, for joint values q, from MuJoCo's
    own kinematics. `moving` tells which of them move at all (not the world)."""

    def __init__(self, machine: Machine):
        self.model = machine.model
        self.data = mujoco.MjData(self.model)
        welds = {
            int(self.model.body_weldid[self.model.geom_bodyid[g]])
            for g in range(self.model.ngeom)
            if self.model.geom_group[g] == VISUAL_GROUP
        }
        self.bodies = sorted(welds)
        self.names = [body_name(self.model, b) for b in self.bodies]
        self.moving = [b != 0 for b in self.bodies]  # the world body never moves

    def poses(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Positions (b, 3) in m and orientations (b, 4) as wxyz of `self.bodies` at joint values q."""
        self.data.qpos[:] = q
        mujoco.mj_kinematics(self.model, self.data)  # positions only; no dynamics needed to draw
        return self.data.xpos[self.bodies].copy(), self.data.xquat[self.bodies].copy()

    def world_vertices(self, geoms: list[VisualGeom], q: np.ndarray) -> np.ndarray:
        """(v, 3) every vertex of `geoms` in world coordinates at joint values q, m."""
        positions, orientations = self.poses(q)
        index = dict(zip(self.names, range(len(self.names))))
        out = []
        for geom in geoms:
            b = index[geom.body]
            in_body = geom.vertices @ _matrix(geom.wxyz).T + geom.position
            out.append(in_body @ _matrix(orientations[b]).T + positions[b])
        return np.concatenate(out)


def body_vertices(geom: VisualGeom) -> np.ndarray:
    """(v, 3) the geom's vertices in the frame of the weld body that carries it, m."""
    return geom.vertices @ _matrix(geom.wxyz).T + geom.position


def _matrix(wxyz: np.ndarray) -> np.ndarray:
    matrix = np.empty(9)
    mujoco.mju_quat2Mat(matrix, np.asarray(wxyz, dtype=float))
    return matrix.reshape(3, 3)
