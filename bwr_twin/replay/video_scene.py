"""A replay as MuJoCo draws it: each run's machine posed from its recording, the pile as dug, the
desired path, the via points, the current target and each run's CP trail, in an `MjvScene` seen
by a camera that frames them all. What is drawn, and in which colours, is what the browser draws
(bwr_twin.replay.style); the pixels come from `bwr_twin.replay.video_frames`.

The model is the run's MJCF compiled for drawing (`Edits`): the pile stands in it as an hfield,
MuJoCo's own height map, on the browser's display grid (at most 20,000 samples), with a texture
of one texel per sample that colours the faces the wheel cut. Heights and texture follow the
run's pile frames and are sent to the GPU again only when a frame changed them; a mesh would
need its normals and faces rebuilt for the same picture. A run without a stockpile gets the
browser's painted pile (bwr_twin.replay.scenery) as the hfield, dug by nothing.

Several runs of one path (one machine file) are drawn together: the first machine solid in its
MJCF colours, each other translucent in its own colour, each CP trail in its run's colour. A
neighbour on the rail is attached to the model as the plant attaches it, and posed from each
run's recording beside its machine.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass

import mujoco
import numpy as np

from bwr_twin.drawing.geometry import VISUAL_GROUP, BodyPoser, visual_geoms
from bwr_twin.errors import BwrError
from bwr_twin.model.spec import STOCKPILE, Edits, compile_model, set_stockpile_colours, set_stockpile_heights
from bwr_twin.pile.surface import Surface
from bwr_twin.replay.pile import CUT_COLOUR, CUT_SHOWN, ORE_COLOUR, DugHeights, display_step
from bwr_twin.replay.recording import Plan, Recording
from bwr_twin.replay.scenery import frame_view, painted_heights, stockpile
from bwr_twin.replay.style import (
    DESIRED_COLOUR,
    GHOST_OPACITY,
    GROUND_COLOUR,
    LINE_WIDTH,
    MARKER_SCALE,
    TARGET_COLOUR,
    VIA_COLOUR,
    run_colour,
)

FRAMING_POSES = 9  # poses of the run, evenly in time, that the camera fits in view
LINE_LINES = 720  # picture lines at which a line is the browser's LINE_WIDTH pixels wide
PATH_TOLERANCE = 0.5  # px: how far a drawn path may stray from the recorded one
GROUND_BELOW = 0.02  # m: the ground lies just below the yard floor, no z-fighting with the rail bed
GROUND_REACH = 10.0  # times the browser's ground: its edge lies beyond the horizon's haze
SKY = ((0.55, 0.7, 0.9), (0.93, 0.94, 0.95))  # rgb at the zenith and at the horizon
SUN_DIRECTION = (0.3, 0.4, -1.0)  # a light from high up, beside the camera's headlight
SUN_DIFFUSE = 0.5
_IDENTITY = np.eye(3).ravel()


@dataclass(frozen=True)
class _Drawing:
    """How the pile's hfield is drawn (bwr_twin.model.spec.Drawing)."""

    colour: tuple[float, float, float, float]
    base_depth: float  # m


@dataclass(frozen=True)
class _Picture:
    """How the model is drawn offscreen (bwr_twin.model.spec.Picture)."""

    width: int
    height: int
    samples: int = 0  # bwr_twin.replay.video_frames: multisampling costs more than it shows
    sky: tuple[tuple[float, float, float], tuple[float, float, float]] = SKY


def rgba(colour: tuple[int, int, int], alpha: float = 1.0) -> np.ndarray:
    return np.array([*(c / 255 for c in colour), alpha], dtype=np.float32)


class ReplayScene:
    """The runs' MuJoCo scene at any time: `update(t)` poses it; `scene`, `camera` and `model`
    are what `mjr_render` needs. `pile_changed` tells, after an update, that the pile's hfield
    and texture (`pile_hfield`, `pile_texture`) must be uploaded again."""

    def __init__(self, recordings: Sequence[Recording], width: int, height: int):
        self.recordings = list(recordings)
        plan = self.recordings[0].plan
        files = {r.plan.machine.path.resolve() for r in self.recordings}
        if len(files) > 1:
            raise BwrError(f"runs of different machines ({', '.join(sorted(f.name for f in files))}) cannot "
                           "be drawn in one video; give runs of one machine file")
        pile, side = _pile_at_start(plan)
        history = self.recordings[0].pile  # the solid machine's pile
        dug = history is not None and plan.pile is not None
        drawing = _Drawing(tuple(rgba(ORE_COLOUR)), float(pile.x[1] - pile.x[0])) if pile else None
        self.model = compile_model(plan.machine.path, Edits(
            stockpile=pile, stockpile_drawing=drawing, stockpile_texture=dug,
            picture=_Picture(width, height), neighbour=plan.neighbour.path if plan.neighbour is not None else None))
        self.data = [mujoco.MjData(self.model) for _ in self.recordings]
        self.pile_hfield = mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_HFIELD, STOCKPILE)
        self.pile_texture = mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_TEXTURE, STOCKPILE)
        self._pile = DugPile(history, display_step(plan.pile.z.shape), pile.z) if dug else None
        self.pile_changed = False
        self.option = mujoco.MjvOption()
        self.option.geomgroup[:] = 0
        self.option.geomgroup[VISUAL_GROUP] = 1
        if pile is not None:  # the pile's group, beside the machine's
            self.option.geomgroup[self.model.geom(STOCKPILE).group[0]] = 1
        self._perturb = mujoco.MjvPerturb()
        self.camera, ground = self._frame(plan, pile, side)
        # Paths drawn to within half a pixel at the scene's middle: dozens of segments, not thousands.
        pixel = 2 * self.camera.distance * np.tan(np.radians(self.model.vis.global_.fovy) / 2) / height
        self._markers = Markers(self.recordings, ground, pixel, height)
        self.scene = mujoco.MjvScene(self.model, maxgeom=len(self.recordings) * self.model.ngeom
                                     + self._markers.count)

    def _frame(self, plan: Plan, pile: Surface | None, side: float) -> tuple[mujoco.MjvCamera, tuple]:
        """A camera that fits the moving machine over the run, the pile and the path; the ground's
        centre and half-size."""
        poser = BodyPoser(plan.machine)
        moving = {name for name, moves in zip(poser.names, poser.moving) if moves}
        geoms = [g for g in visual_geoms(plan.machine) if g.body in moving]  # not the rail: it runs far on
        poses = self.recordings[0].q_actual[np.linspace(0, len(plan.time) - 1, FRAMING_POSES).astype(int)]
        extent = [plan.cp_desired, *(poser.world_vertices(geoms, q) for q in poses)]
        if pile is not None:
            top = float(pile.z.max())
            extent.append([(x, y, z) for x in pile.x[[0, -1]] for y in pile.y[[0, -1]] for z in (0.0, top)])
        view = frame_view(np.concatenate(extent), pile_side=side, fov=np.radians(self.model.vis.global_.fovy))
        camera = mujoco.MjvCamera()
        camera.type = mujoco.mjtCamera.mjCAMERA_FREE
        forward = view.look_at - view.position
        camera.lookat[:] = view.look_at
        camera.distance = float(np.linalg.norm(forward))
        camera.azimuth = float(np.degrees(np.arctan2(forward[1], forward[0])))
        camera.elevation = float(np.degrees(np.arctan2(forward[2], np.hypot(forward[0], forward[1]))))
        return camera, (np.array([*view.ground_centre, -GROUND_BELOW]), GROUND_REACH * view.ground_size / 2)

    def update(self, t: float) -> None:
        """Pose every run, the pile and the markers for time t (s)."""
        instants = [r.at(t) for r in self.recordings]
        for data, instant in zip(self.data, instants):
            data.qpos[:3] = instant.q_actual  # the machine's joints first, a neighbour's next
            if instant.neighbour_q is not None:
                data.qpos[3:6] = instant.neighbour_q
            mujoco.mj_kinematics(self.model, data)  # positions only; no dynamics needed to draw
        self.pile_changed = self._pile is not None and self._pile.show(t, self.model)
        scene = self.scene
        mujoco.mjv_updateScene(self.model, self.data[0], self.option, None, self.camera,
                               mujoco.mjtCatBit.mjCAT_ALL, scene)
        for k, data in enumerate(self.data[1:], start=1):
            first = scene.ngeom
            mujoco.mjv_addGeoms(self.model, data, self.option, self._perturb, mujoco.mjtCatBit.mjCAT_DYNAMIC,
                                scene)
            for geom in scene.geoms[first:scene.ngeom]:
                geom.rgba[:] = rgba(run_colour(k), GHOST_OPACITY)
                geom.transparent = 1
        self._markers.add(scene, t, instants)
        self._add_sun()

    def _add_sun(self) -> None:
        """A directional light from above: the headlight alone leaves surfaces facing up flat."""
        if self.scene.nlight >= len(self.scene.lights):
            return
        light = self.scene.lights[self.scene.nlight]
        light.type = mujoco.mjtLightType.mjLIGHT_DIRECTIONAL
        light.dir[:] = SUN_DIRECTION / np.linalg.norm(SUN_DIRECTION)
        light.pos[:] = -1e3 * light.dir
        light.diffuse[:] = SUN_DIFFUSE
        light.ambient[:] = 0.0
        light.specular[:] = 0.1
        light.castshadow = 0
        light.headlight = 0
        self.scene.nlight += 1


class DugPile:
    """The pile's hfield as the solid run dug it: its heights on the display grid, and a texture
    that colours the faces the wheel cut as the browser does."""

    def __init__(self, history, step: int, start: np.ndarray):
        """`history`: the run's pile frames; `step` the display grid's; `start` its heights on it at t = 0."""
        self._dug, self._step, self._start = DugHeights(history), step, start

    def show(self, t: float, model: mujoco.MjModel) -> bool:
        """Set the model's hfield and texture to the pile at time t (s); whether they changed."""
        if not self._dug.advance(t):
            return False
        z = self._dug.z[:: self._step, :: self._step]
        set_stockpile_heights(model, z)
        cut = (self._start - z > CUT_SHOWN)[..., None]  # as the browser marks a cut face
        set_stockpile_colours(model, np.where(cut, CUT_COLOUR, ORE_COLOUR))
        return True


class Markers:
    """What is drawn beside the machines: the ground, the desired path, the via points, the
    current target and each run's CP trail, sized for the picture.

    Attributes:
        count: the most geoms they add to a scene.
    """

    def __init__(self, recordings: Sequence[Recording], ground: tuple, pixel: float, height: int):
        """`ground`: its centre and half-size; `pixel`: m a pixel spans at the scene's middle."""
        plan = recordings[0].plan
        self._ground, self._via_points = ground, plan.via_points
        self._path = plan.cp_desired[simplified(plan.cp_desired, PATH_TOLERANCE * pixel)]
        self._trails = [(r.plan.time[kept], r.cp_actual[kept]) for r in recordings
                        for kept in [simplified(r.cp_actual, PATH_TOLERANCE * pixel)]]
        self._marker = MARKER_SCALE * float(np.linalg.norm(np.ptp(plan.cp_desired, axis=0)) or 1.0)
        self._line = max(1.0, LINE_WIDTH * height / LINE_LINES)
        self.count = 2 + len(plan.via_points) + len(self._path) + sum(len(t) + 1 for t, _ in self._trails)

    def add(self, scene: mujoco.MjvScene, t: float, instants: list) -> None:
        """Add them to `scene` as they stand at time t (s), each run's trail up to t."""
        ground, half = self._ground
        _add(scene, mujoco.mjtGeom.mjGEOM_PLANE, rgba(GROUND_COLOUR), ground, size=(half, half, 1.0))
        _polyline(scene, self._path, rgba(DESIRED_COLOUR), self._line)
        for p in self._via_points:
            _add(scene, mujoco.mjtGeom.mjGEOM_SPHERE, rgba(VIA_COLOUR), p, size=(self._marker,) * 3)
        _add(scene, mujoco.mjtGeom.mjGEOM_SPHERE, rgba(TARGET_COLOUR), instants[0].cp_desired,
             size=(1.5 * self._marker,) * 3)
        for k, ((time, points), instant) in enumerate(zip(self._trails, instants)):
            done = int(np.searchsorted(time, t, side="right"))
            _polyline(scene, np.concatenate([points[:done], instant.cp_actual[None]]), rgba(run_colour(k)),
                      2 * self._line)


def _add(scene: mujoco.MjvScene, kind: int, colour: np.ndarray, position, *,
         size=(0.0, 0.0, 0.0)) -> mujoco.MjvGeom:
    geom = scene.geoms[scene.ngeom]
    mujoco.mjv_initGeom(geom, kind, np.asarray(size, float), np.asarray(position, float), _IDENTITY, colour)
    geom.category = mujoco.mjtCatBit.mjCAT_DECOR
    scene.ngeom += 1
    return geom


def _polyline(scene: mujoco.MjvScene, points: np.ndarray, colour: np.ndarray, width: float) -> None:
    for start, end in itertools.pairwise(points):
        geom = _add(scene, mujoco.mjtGeom.mjGEOM_LINE, colour, start)
        mujoco.mjv_connector(geom, mujoco.mjtGeom.mjGEOM_LINE, width, start, end)


def _pile_at_start(plan: Plan) -> tuple[Surface | None, float]:
    """The pile to stand in the model, on its display grid, and the side of the rail it lies on."""
    rail_y = plan.machine.geometry.slew_axis_xy[1]
    if plan.pile is not None:
        step = display_step(plan.pile.z.shape)
        pile = Surface(plan.pile.x[::step], plan.pile.y[::step], plan.pile.z[::step, ::step])
        return pile, float(np.sign(np.mean(pile.y) - rail_y)) or 1.0
    painted = stockpile(plan.via_points, rail_y=rail_y)
    if painted is None:
        return None, 1.0
    return painted_heights(painted), painted.side


def simplified(points: np.ndarray, tolerance: float) -> np.ndarray:
    """Indices of the points (n, 3) that keep the polyline through them within `tolerance` (m) of
    every point (Ramer-Douglas-Peucker), the first and the last always among them."""
    keep = np.zeros(len(points), dtype=bool)
    keep[[0, -1]] = True
    spans = [(0, len(points) - 1)]
    while spans:
        first, last = spans.pop()
        if last - first < 2:
            continue
        chord = points[last] - points[first]
        offsets = points[first + 1 : last] - points[first]
        # The distance to the segment, not to its line: a path may turn back on itself.
        along = np.clip(offsets @ chord / max(float(chord @ chord), 1e-300), 0.0, 1.0)
        distance = np.linalg.norm(offsets - along[:, None] * chord, axis=1)
        farthest = int(np.argmax(distance))
        if distance[farthest] > tolerance:
            keep[first + 1 + farthest] = True
            spans += [(first, first + 1 + farthest), (first + 1 + farthest, last)]
    return np.flatnonzero(keep)
