"""A machine's moving bodies as viser meshes: its visual geoms, posed by MuJoCo's kinematics from
joint values, painted in their MJCF colours or in one colour, solid or seen through. The replay
draws its runs with them, the shadow the machine as measured and the twin's prediction."""

from __future__ import annotations

from typing import Literal

import numpy as np
import viser

from bwr_twin.drawing.geometry import BodyPoser, VisualGeom, body_vertices, rgb, visual_geoms
from bwr_twin.model.machine import Machine

Paint = Literal["model", "colour", "translucent"]  # MJCF colours; the machine's colour; that colour, seen through


class Meshes:
    """One machine's moving bodies as scene nodes under `prefix`, posed by MuJoCo's kinematics."""

    def __init__(self, scene: viser.SceneApi, machine: Machine, prefix: str, merged: bool,
                 colour: tuple[int, int, int], paint: tuple[Paint, float]):
        self.scene, self.prefix, self.colour = scene, prefix, colour
        self.poser = BodyPoser(machine)
        self.moving = [i for i, moves in enumerate(self.poser.moving) if moves]
        moving = {self.poser.names[i] for i in self.moving}
        self.geoms = [geom for geom in visual_geoms(machine) if geom.body in moving]
        self.bodies = [scene.add_frame(f"{prefix}/{self.poser.names[i]}", show_axes=False) for i in self.moving]
        # `merged`: a node per body and MJCF colour rather than per geom: a fraction of the nodes
        # to send and draw, for a machine that mostly shows in one colour.
        keys = [(geom.body, geom.rgba, geom.type in ("box", "plane", "mesh")) for geom in self.geoms]
        self.parts = ([[geom] for geom in self.geoms] if not merged else
                      [[g for g, key in zip(self.geoms, keys) if key == first] for first in dict.fromkeys(keys)])
        self.nodes = [self._add_part(part, paint) for part in self.parts]
        self.painted = paint

    def _add_part(self, part: list[VisualGeom], paint: tuple[Paint, float]):
        """One mesh node: a geom in its own frame, or several geoms of one body and colour merged."""
        geom = part[0]
        color, opacity = self._looks(geom, *paint)
        if len(part) == 1:
            vertices, faces, position, wxyz = geom.vertices, geom.faces, geom.position, geom.wxyz
            name = geom.name.replace("/", "_")
        else:
            offsets = np.cumsum([0] + [len(g.vertices) for g in part[:-1]])
            vertices = np.concatenate([body_vertices(g) for g in part])
            faces = np.concatenate([g.faces + offset for g, offset in zip(part, offsets)])
            position, wxyz, name = (0.0, 0.0, 0.0), (1.0, 0.0, 0.0, 0.0), f"{geom.name.replace('/', '_')}+{len(part) - 1}"
        return self.scene.add_mesh_simple(f"{self.prefix}/{geom.body}/{name}", vertices, faces, color=color,
                                          opacity=opacity, flat_shading=geom.type in ("box", "plane", "mesh"),
                                          position=position, wxyz=wxyz)

    def vertices(self, q: np.ndarray) -> np.ndarray:
        """(v, 3) the machine's vertices at joint values q, in world coordinates before any offset (m)."""
        return self.poser.world_vertices(self.geoms, q)

    def place(self, q: np.ndarray) -> None:
        """Pose the moving bodies for joint values q."""
        positions, orientations = self.poser.poses(q)
        for frame, i in zip(self.bodies, self.moving):
            frame.position = positions[i]
            frame.wxyz = orientations[i]

    def paint(self, kind: Paint, opacity: float) -> None:
        if (kind, opacity) == self.painted:
            return
        for part, node in zip(self.parts, self.nodes):
            node.color, node.opacity = self._looks(part[0], kind, opacity)
        self.painted = (kind, opacity)

    def _looks(self, geom, kind: Paint, opacity: float) -> tuple[tuple[int, int, int], float | None]:
        """A geom's colour and opacity (None: opaque) when the machine is painted `kind`."""
        if kind == "model":
            return rgb(geom.rgba), geom.rgba[3] if geom.rgba[3] < 1.0 else None
        return self.colour, opacity if kind == "translucent" else None
