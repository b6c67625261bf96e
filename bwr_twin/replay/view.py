"""The 3D scene of a replay on a viser server, and how one instant of a recording poses it.

Meshes, the paths and the via points are sent once. An instant then costs one pose per moving
rigid body, the target's position, the tip of the CP trail and the pile's tiles dug since the
last instant (bwr_twin.replay.pile); the caller wraps it
in `server.atomic()` so that a frame arrives whole. The live replay and the HTML export share
this code, so they show the same picture.
"""

from __future__ import annotations

import numpy as np
import viser

from bwr_twin.replay.geometry import BodyPoser, visual_geoms
from bwr_twin.replay.pile import PileView
from bwr_twin.replay.recording import Plan, Recording, decimate
from bwr_twin.replay.scenery import CAMERA_FOV, frame_view, stockpile

DESIRED_COLOUR = (60, 120, 230)
ACTUAL_COLOUR = (235, 95, 20)
TARGET_COLOUR = (220, 30, 30)
VIA_COLOUR = (30, 30, 30)
ORE_COLOUR = (112, 66, 44)
GROUND_COLOUR = (205, 196, 178)
PATH_STEP = 1.0  # s between drawn points of the desired path and of the trail
TRAIL_CHUNK = 20  # trail segments per scene node; only the unfinished chunk is re-sent
LINE_WIDTH = 2.5  # px, desired path; the trail is twice as wide
MARKER_SCALE = 0.01  # marker radius as a share of the path's extent
LABEL_MERGE = 4.0  # via points closer than this many marker radii share one label
GHOST_COLOUR = (90, 110, 255)
GHOST_OPACITY = 0.35  # the second run's machine: seen through, the first stays in front


def rgb(rgba: tuple[float, ...]) -> tuple[int, int, int]:
    return tuple(round(255 * c) for c in rgba[:3])


def _segments(points: np.ndarray) -> np.ndarray:
    """A polyline (m, 3) as (m - 1, 2, 3) line segments; one degenerate segment for a single point."""
    if len(points) == 1:
        points = np.repeat(points, 2, axis=0)
    return np.stack([points[:-1], points[1:]], axis=1).astype(np.float32)


def label_groups(points: np.ndarray, distance: float) -> dict[int, list[int]]:
    """Via points that share a label, as {first point: every point labelled there}: each point
    joins the label of the first earlier point within `distance`, so every point is named once,
    and a path's coinciding ends or a bench's close via points do not print over each other."""
    groups: dict[int, list[int]] = {}
    for i, p in enumerate(points):
        near = [first for first in groups if np.linalg.norm(points[first] - p) < distance]
        groups.setdefault(near[0] if near else i, []).append(i)
    return groups


class SceneView:
    """The scene of `plan` on `server`: the machine at its start pose, ground, pile, desired
    path, via points and target. `attach` adds a recording's trail; `show` poses an instant."""

    def __init__(self, server: viser.ViserServer, plan: Plan, *, panel_share: float = 0.0):
        self.server = server
        self.plan = plan
        self.poser = BodyPoser(plan.machine)
        self.geoms = visual_geoms(plan.machine)
        self.recording: Recording | None = None
        self.ghost: Ghost | None = None
        self.pile: PileView | None = None
        scene = server.scene
        self.bodies = [scene.add_frame(f"/machine/{name}", show_axes=False) for name in self.poser.names]
        self.geom_nodes = [
            scene.add_mesh_simple(
                f"/machine/{geom.body}/{geom.name.replace('/', '_')}",
                geom.vertices,
                geom.faces,
                color=rgb(geom.rgba),
                opacity=geom.rgba[3] if geom.rgba[3] < 1.0 else None,
                flat_shading=geom.type in ("box", "plane", "mesh"),
                position=geom.position,
                wxyz=geom.wxyz,
            )
            for geom in self.geoms
        ]
        self._place(plan.q_desired[0], every_body=True)
        self._add_surroundings(panel_share)
        self._add_paths()

    def _add_surroundings(self, panel_share: float) -> None:
        """Pile, ground and an initial camera that frames machine, pile and path (in the part
        of the window that a GUI panel covering `panel_share` of its width on the right leaves)."""
        plan, scene = self.plan, self.server.scene
        rail_y = plan.machine.geometry.slew_axis_xy[1]
        moving = {name for name, moves in zip(self.poser.names, self.poser.moving) if moves}
        machine = [geom for geom in self.geoms if geom.body in moving]  # not the rail: it may run far on
        extent = [plan.cp_desired] + [
            self.poser.world_vertices(machine, q) for q in (plan.q_desired[0], plan.q_desired[len(plan.time) // 2])
        ]
        side = 1.0
        if plan.pile is not None:  # the scene's stockpile, dug as the run goes
            self.pile = PileView(scene, plan.pile.x, plan.pile.y, plan.pile.z)
            extent.append(self.pile.corners)
            side = float(np.sign(np.mean(plan.pile.y) - rail_y)) or 1.0
        else:  # scenery: a pile painted under the path, which nothing digs
            painted = stockpile(plan.via_points, rail_y=rail_y)
            if painted is not None:
                scene.add_mesh_simple("/pile", painted.vertices, painted.faces, color=ORE_COLOUR, flat_shading=True)
                extent.append(painted.vertices)
                side = painted.side
        view = frame_view(np.concatenate(extent), pile_side=side, panel_share=panel_share)
        self.caption_position = view.caption
        camera = self.server.initial_camera
        camera.position, camera.look_at, camera.up, camera.fov = (
            view.position,
            view.look_at,
            (0.0, 0.0, 1.0),
            CAMERA_FOV,
        )
        scene.add_grid(
            "/ground",
            width=view.ground_size,
            height=view.ground_size,
            cell_size=10.0,
            section_size=50.0,
            plane_color=GROUND_COLOUR,
            plane_opacity=1.0,
            position=(*view.ground_centre, -0.02),  # just below the rail foundation: no z-fighting
            fade_distance=2.0 * view.ground_size,  # the default fades out a ground this large
        )

    def _add_paths(self) -> None:
        """The whole desired CP path, the via points with labels and the current target."""
        plan, scene = self.plan, self.server.scene
        self.marker_radius = MARKER_SCALE * float(np.linalg.norm(np.ptp(plan.cp_desired, axis=0)) or 1.0)
        path = plan.cp_desired[decimate(plan.time, PATH_STEP)]
        scene.add_line_segments(
            "/path/desired", _segments(path), DESIRED_COLOUR, thickness=LINE_WIDTH, thickness_units="screen"
        )
        names = plan.names
        for i, p in enumerate(plan.via_points):
            scene.add_icosphere(f"/via/P{i + 1}", radius=self.marker_radius, color=VIA_COLOUR, position=p)
        # A path's via points are all named; a bench plan names its benches in the scene (its passes,
        # a metre apart, on the slider and in the readout).
        landmarks = {name for name, _ in plan.landmarks}
        named = [i for i, name in enumerate(names) if name in landmarks or name == "end"]
        for first, members in label_groups(plan.via_points[named], LABEL_MERGE * self.marker_radius).items():
            scene.add_label(
                f"/via/P{named[first] + 1}/label",
                "\n".join(f"{names[named[k]]}  t = {plan.via_times[named[k]]:g} s" for k in members),
                position=(0.0, 0.0, 2.0 * self.marker_radius),
                anchor="bottom-center",
            )
        self.target = scene.add_icosphere(
            "/target", radius=1.5 * self.marker_radius, color=TARGET_COLOUR, position=plan.cp_desired[0]
        )

    def _place(self, q: np.ndarray, *, every_body: bool = False) -> None:
        """Pose the rigid bodies for joint values q; static ones only when `every_body`."""
        positions, orientations = self.poser.poses(q)
        for frame, moving, position, wxyz in zip(self.bodies, self.poser.moving, positions, orientations):
            if moving or every_body:
                frame.position = position
                frame.wxyz = wxyz

    def attach(self, recording: Recording) -> None:
        """Add the actual CP trail in chunks, each sent once and then only shown or hidden."""
        self.recording = recording
        if self.pile is not None and recording.pile is not None:
            self.pile.attach(recording.pile)
        samples = decimate(recording.plan.time, PATH_STEP)
        self.trail_time = recording.plan.time[samples]
        self.trail_points = recording.cp_actual[samples]
        scene = self.server.scene
        self.trail_chunks = [
            scene.add_line_segments(
                f"/path/actual/{c}",
                _segments(self.trail_points[start : start + TRAIL_CHUNK + 1]),
                ACTUAL_COLOUR,
                thickness=2 * LINE_WIDTH,
                thickness_units="screen",
                visible=False,
            )
            for c, start in enumerate(range(0, len(samples) - 1, TRAIL_CHUNK))
        ]
        self.chunks_shown = 0
        self.trail_tip = scene.add_line_segments(
            "/path/actual/tip",
            _segments(self.trail_points[:1]),
            ACTUAL_COLOUR,
            thickness=2 * LINE_WIDTH,
            thickness_units="screen",
        )

    def add_ghost(self, recording: Recording, label: str) -> None:
        """A second run of the same path, drawn as a translucent machine that `show` poses too."""
        self.ghost = Ghost(self.server, recording, label)

    def show(self, t: float) -> None:
        """Pose machine, target and trail for time t (s) of the attached recording (and the ghost's)."""
        assert self.recording is not None, "attach a recording first"
        if self.ghost is not None:
            self.ghost.show(t)
        instant = self.recording.at(t)
        self._place(instant.q_actual)
        if self.pile is not None:
            self.pile.show(t)
        self.target.position = instant.cp_desired
        last = max(0, int(np.searchsorted(self.trail_time, t, side="right")) - 1)
        complete = last // TRAIL_CHUNK  # chunks wholly before t
        for c in range(min(complete, self.chunks_shown), max(complete, self.chunks_shown)):
            self.trail_chunks[c].visible = c < complete
        self.chunks_shown = complete
        tip = np.concatenate([self.trail_points[complete * TRAIL_CHUNK : last + 1], instant.cp_actual[None]])
        self.trail_tip.points = _segments(tip)


class Ghost:
    """Another run's machine, translucent and in one colour, posed from its own recording: two
    controllers on one path, side by side in one scene."""

    def __init__(self, server: viser.ViserServer, recording: Recording, label: str):
        self.recording = recording
        self.poser = BodyPoser(recording.plan.machine)
        moving = {name for name, moves in zip(self.poser.names, self.poser.moving) if moves}
        scene = server.scene
        self.bodies = {name: scene.add_frame(f"/ghost/{name}", show_axes=False) for name in moving}
        for geom in visual_geoms(recording.plan.machine):
            if geom.body in moving:
                scene.add_mesh_simple(f"/ghost/{geom.body}/{geom.name.replace('/', '_')}", geom.vertices,
                                      geom.faces, color=GHOST_COLOUR, opacity=GHOST_OPACITY,
                                      position=geom.position, wxyz=geom.wxyz)
        # Below the wheel: the via point labels sit above their points.
        self.label = scene.add_label("/ghost_label", f"ghost: {label}", position=recording.plan.cp_desired[0],
                                     anchor="top-center")

    def show(self, t: float) -> None:
        instant = self.recording.at(t)
        positions, orientations = self.poser.poses(instant.q_actual)
        for name, position, wxyz in zip(self.poser.names, positions, orientations):
            if name in self.bodies:
                self.bodies[name].position, self.bodies[name].wxyz = position, wxyz
        self.label.position = instant.cp_actual
