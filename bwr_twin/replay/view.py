"""The 3D scene of a replay on a viser server, and how one instant of its runs poses it.

Each place where a path is reclaimed is a `Site`: the MJCF's fixed geoms (the rail), the pile,
the desired path, the via points and the target. Each run is a `MachineView`: its machine's
moving bodies and its CP trail (bwr_twin.replay.machine_view). Runs of one path share one site;
side by side, each run has its own, in a row across the rail, spaced by what each draws.

Meshes, paths and via points are sent once. An instant then costs, per shown run, one pose per
moving rigid body and the tip of its trail, and per site the target's position and the pile's
tiles dug since the last instant (bwr_twin.replay.pile); with a run that scanned, the fan and
the cloud when a new scan came, and the scanned pile's tiles a new frame of it changed
(bwr_twin.replay.scan_view); the caller wraps it in
`server.atomic()` so that a frame arrives whole. The live replay and the HTML export share this
code, so they show the same picture.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import viser

from bwr_twin.drawing.geometry import BodyPoser, visual_geoms
from bwr_twin.replay.grade_scale import GradeScale
from bwr_twin.replay.machine_view import MachineView, Paint, segments
from bwr_twin.replay.pile import PileView
from bwr_twin.replay.recording import Plan, Recording, decimate
from bwr_twin.replay.scan_view import LIVE, ScanDrawing, ScanView
from bwr_twin.replay.scenery import ASPECT, CAMERA_FOV, frame_view, stockpile
from bwr_twin.replay.style import (  # noqa: F401  (the video draws with the same colours)
    ACTUAL_COLOUR,
    DESIRED_COLOUR,
    GHOST_COLOUR,
    GHOST_OPACITY,
    GROUND_COLOUR,
    LABEL_MERGE,
    LINE_WIDTH,
    MARKER_SCALE,
    ORE_COLOUR,
    PATH_STEP,
    TARGET_COLOUR,
    VIA_COLOUR,
    rgb,
    run_colour,
)

FRAMING_POSES = 5  # poses of each run, evenly in time, that the camera and the row of runs allow for
LANE_GAP = 0.1  # of the widest run's extent across the rail: the space between runs side by side
FAINTEST = 0.2  # opacity of a translucent machine among many


def label_groups(points: np.ndarray, distance: float) -> dict[int, list[int]]:
    """Via points that share a label, as {first point: every point labelled there}: each point
    joins the label of the first earlier point within `distance`, so every point is named once,
    and a path's coinciding ends or a bench's close via points do not print over each other."""
    groups: dict[int, list[int]] = {}
    for i, p in enumerate(points):
        near = [first for first in groups if np.linalg.norm(points[first] - p) < distance]
        groups.setdefault(near[0] if near else i, []).append(i)
    return groups


class Site:
    """Where a path is reclaimed, under the scene frame /sites/<k>: the MJCF's fixed geoms, the
    pile (the scene's, dug as the site's first run dug it; or scenery under the path, dug by
    nothing), the desired path, the via points and the target; and if the site's first run
    scanned the pile, its scans (bwr_twin.replay.scan_view), drawn as `drawing` says."""

    def __init__(self, scene: viser.SceneApi, plan: Plan, k: int, name: str | None = None,
                 drawing: ScanDrawing = LIVE):
        self.scene, self.prefix, self.drawing = scene, f"/sites/{k}", drawing
        self.scans: ScanView | None = None
        self.pile_shown, self.fan_shown = "true", True
        self.frame = scene.add_frame(self.prefix, show_axes=False)
        machine = plan.machine
        poser = BodyPoser(machine)
        fixed = {name for name, moves in zip(poser.names, poser.moving) if not moves}
        self.geoms = [geom for geom in visual_geoms(machine) if geom.body in fixed]  # the world body's
        self.nodes = [
            scene.add_mesh_simple(f"{self.prefix}/fixed/{geom.name.replace('/', '_')}", geom.vertices, geom.faces,
                                  color=rgb(geom.rgba), opacity=geom.rgba[3] if geom.rgba[3] < 1.0 else None,
                                  flat_shading=geom.type in ("box", "plane", "mesh"), position=geom.position,
                                  wxyz=geom.wxyz)
            for geom in self.geoms
        ]
        rail_y = machine.geometry.slew_axis_xy[1]
        self.pile: PileView | None = None
        self.pile_side, self.points = 1.0, [plan.cp_desired]  # what the camera must see, before any offset
        if plan.pile is not None:  # the scene's stockpile, dug as the run goes
            self.pile = PileView(scene, plan.pile.x, plan.pile.y, plan.pile.z, name=f"{self.prefix}/pile")
            self.points.append(self.pile.corners)
            self.pile_side = float(np.sign(np.mean(plan.pile.y) - rail_y)) or 1.0
        else:
            painted = stockpile(plan.via_points, rail_y=rail_y)
            if painted is not None:
                scene.add_mesh_simple(f"{self.prefix}/pile", painted.vertices, painted.faces, color=ORE_COLOUR,
                                      flat_shading=True)
                self.points.append(painted.vertices)
                self.pile_side = painted.side
        self._path_nodes: list = []
        self.marker_radius = MARKER_SCALE * float(np.linalg.norm(np.ptp(plan.cp_desired, axis=0)) or 1.0)
        self.target = scene.add_icosphere(f"{self.prefix}/target", radius=1.5 * self.marker_radius,
                                          color=TARGET_COLOUR, position=plan.cp_desired[0])
        self.draw_path(plan, planned=bool(plan.via_stages))
        if name is not None:  # side by side: say whose run this is, above its path
            top = plan.cp_desired[np.argmax(plan.cp_desired[:, 2])]
            scene.add_label(f"{self.prefix}/name", name, position=top + (0.0, 0.0, 8.0 * self.marker_radius),
                            anchor="bottom-center", font_screen_scale=1.2)

    def draw_path(self, plan: Plan, *, planned: bool = False) -> None:
        """The whole desired CP path and the via points with labels (again, for a run's own times).
        A bench plan's times before its run are the plan's, as its speed law alone would run it:
        `planned` labels them so, apart from the run's own, which replace them."""
        for node in reversed(self._path_nodes):  # labels before the via points that carry them
            node.remove()
        scene = self.scene
        path = plan.cp_desired[decimate(plan.time, PATH_STEP)]
        nodes = [scene.add_line_segments(f"{self.prefix}/path", segments(path), DESIRED_COLOUR,
                                         thickness=LINE_WIDTH, thickness_units="screen")]
        names = plan.names
        nodes += [scene.add_icosphere(f"{self.prefix}/via/P{i + 1}", radius=self.marker_radius, color=VIA_COLOUR,
                                      position=p) for i, p in enumerate(plan.via_points)]
        # A path's via points are all named; a bench plan names its benches and its end in the scene
        # (its passes, a metre apart, on the slider and in the readout).
        landmarks = {name for name, _ in plan.landmarks}
        named = [i for i, name in enumerate(names) if name in landmarks or name == "end"]
        for first, members in label_groups(plan.via_points[named], LABEL_MERGE * self.marker_radius).items():
            nodes.append(scene.add_label(
                f"{self.prefix}/via/P{named[first] + 1}/label",
                "\n".join(f"{names[named[k]]}  t = {plan.via_times[named[k]]:g} s" + (" (plan)" if planned else "")
                          for k in members),
                position=(0.0, 0.0, 2.0 * self.marker_radius),
                anchor="bottom-center",
            ))
        self._path_nodes = nodes

    def attach(self, recording: Recording) -> None:
        """The site's first run: its pile as it dug it, its scans, its path and via points at its
        own times."""
        if self.pile is not None and recording.pile is not None:
            self.pile.attach(recording.pile)
        if self.pile is not None and recording.scans is not None and self.scans is None:
            self.scans = ScanView(self.scene, self.prefix, recording.scans, self.marker_radius, self.drawing)
        self.draw_path(recording.plan)

    def show_pile(self, kind: str) -> None:
        """Show the true pile ("true") or the scanned one ("scanned"), if the site's run scanned."""
        if self.scans is None:
            return
        self.pile_shown = kind
        self.pile.visible = kind == "true"
        self.scans.known.visible = kind == "scanned"

    def show_fan(self, shown: bool) -> None:
        """Show or hide the scan fan and the hits, if the site's run scanned."""
        if self.scans is not None:
            self.fan_shown = self.scans.visible = shown

    def colour_pile(self, kind: str, scale: GradeScale | None) -> None:
        """Colour the pile by ore or by the grade of its top layer (bwr_twin.replay.pile), if it has grade."""
        if self.pile is not None and self.pile.graded:
            self.pile.colour_by(kind, scale)

    def show(self, t: float, cp_desired: np.ndarray) -> None:
        self.target.position = cp_desired
        both = self.drawing.both_piles
        if self.pile is not None and (self.pile_shown == "true" or both):
            self.pile.show(t)
        if self.scans is not None:
            self.scans.show(t, fan=self.fan_shown, pile=self.pile_shown == "scanned" or both)


class SceneView:
    """The scene of one or several runs, given by their plans (a run being simulated has no
    recording yet): sites, machines, ground and an initial camera that frames them all.
    `attach` gives run k its recording; `show` poses the shown runs at a time; `paint` and
    `set_visible` change how they look.

    Args:
        server: the viser server whose scene this draws.
        plans: one per run; runs of one site must share machine and path (`runs.check_one_world`).
        names: each run's name, written over its site when the runs stand side by side.
        side_by_side: give each run its own site, in a row across the rail.
        panel_share: the part of the window a GUI panel covers on the right; the camera leaves it.
        aspect: the picture's width over its height.
        scans: how much of a run's laser scans to draw (bwr_twin.replay.scan_view).
    """

    def __init__(self, server: viser.ViserServer, plans: Plan | Sequence[Plan], *, names: Sequence[str] = (),
                 side_by_side: bool = False, panel_share: float = 0.0, aspect: float = ASPECT,
                 scans: ScanDrawing = LIVE):
        self.server = server
        plans = [plans] if isinstance(plans, Plan) else list(plans)
        self.plan = plans[0]
        scene = server.scene
        if side_by_side:
            self.sites = [Site(scene, plan, k, names[k] if k < len(names) else None, scans)
                          for k, plan in enumerate(plans)]
            self.site_of = list(range(len(plans)))
        else:
            self.sites, self.site_of = [Site(scene, plans[0], 0, drawing=scans)], [0] * len(plans)
        paints = _paints(len(plans), len(self.sites), solid=0)
        self.machines = [MachineView(scene, plan, k, run_colour(k), paint) for k, (plan, paint) in
                         enumerate(zip(plans, paints))]
        self.recordings: list[Recording | None] = [None] * len(plans)
        self._grade_scale: GradeScale | None = None  # of the sites' piles with grade, once asked for
        # What each site's first run draws over its run (runs of one site follow its path, a few
        # centimetres apart): the row's spacing and the camera's framing.
        firsts = [self.site_of.index(s) for s in range(len(self.sites))]
        extents = [np.concatenate([*site.points, *(self.machines[k].vertices(*q) for q in _framing_poses(plans[k]))])
                   for site, k in zip(self.sites, firsts)]
        offsets = _row(extents, self.sites[0].pile_side) if side_by_side else np.zeros((1, 3))
        for site, offset in zip(self.sites, offsets):
            site.frame.position = offset
        for machine, s in zip(self.machines, self.site_of):
            machine.root.position = offsets[s]
        self._frame_camera(np.concatenate([e + o for e, o in zip(extents, offsets)]), panel_share, aspect)

    @property
    def poser(self) -> BodyPoser:
        return self.machines[0].poser

    @property
    def geoms(self) -> list:
        """The first run's visual geoms in model order: its machine's and its site's fixed ones."""
        return [geom for geom, _ in self.drawn_geoms()]

    def drawn_geoms(self, k: int = 0) -> list[tuple]:
        """(VisualGeom, scene node) of run k's machine and its site's fixed geoms, in model order."""
        site, machine = self.sites[self.site_of[k]], self.machines[k]
        pairs = {geom.name: (geom, node) for geom, node in [*zip(site.geoms, site.nodes),
                                                             *zip(machine.geoms, machine.nodes)]}
        return [pairs[geom.name] for geom in visual_geoms(self.plan.machine)]

    def _frame_camera(self, points: np.ndarray, panel_share: float, aspect: float) -> None:
        """An initial camera that frames every machine, pile and path; a ground well past them."""
        view = frame_view(points, pile_side=self.sites[0].pile_side, panel_share=panel_share, aspect=aspect)
        self.caption_position = view.caption
        camera = self.server.initial_camera
        camera.position, camera.look_at, camera.up, camera.fov = view.position, view.look_at, (0.0, 0.0, 1.0), CAMERA_FOV
        self.server.scene.add_grid(
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

    def attach(self, recording: Recording, k: int = 0) -> None:
        """Run k's recording: its trail, and its site's pile and via points if it is the site's first run."""
        self.recordings[k] = recording
        self.machines[k].attach(recording)
        if self.site_of.index(self.site_of[k]) == k:
            self.sites[self.site_of[k]].attach(recording)
            self._grade_scale = None

    def paint(self, solid: int | None) -> None:
        """Run `solid` in its MJCF colours and every other one translucent in its own colour; with
        None, every machine solid in its own colour. One run alone keeps its MJCF colours."""
        for machine, (kind, opacity) in zip(self.machines, _paints(len(self.machines), len(self.sites), solid)):
            machine.paint(kind, opacity)

    def set_visible(self, k: int, shown: bool) -> None:
        self.machines[k].visible = shown

    @property
    def scanning(self) -> bool:
        """Whether a site draws a run's scans (its first run scanned its pile)."""
        return any(site.scans is not None for site in self.sites)

    def show_pile(self, kind: str) -> None:
        """At every site whose run scanned, the true pile ("true") or the scanned one ("scanned")."""
        for site in self.sites:
            site.show_pile(kind)

    def show_fan(self, shown: bool) -> None:
        """At every site whose run scanned, show or hide the scan fan and the hits."""
        for site in self.sites:
            site.show_fan(shown)

    @property
    def grade_scale(self) -> GradeScale | None:
        """One colour scale for the top grade of every site's pile that has grade (a stacking's, a
        reclaim of a stacked pile), so that a colour is one grade at every site; None if none has."""
        if self._grade_scale is None:
            self._grade_scale = GradeScale.of([site.pile.dug.history for site in self.sites
                                               if site.pile is not None and site.pile.graded])
        return self._grade_scale

    def colour_pile(self, kind: str) -> None:
        """At every site whose pile has grade, colour it by ore ("ore") or by its top layer's grade ("grade")."""
        scale = self.grade_scale
        for site in self.sites:
            site.colour_pile(kind, scale)

    def show(self, t: float) -> None:
        """Pose every shown run's machine and trail, and every site's target and pile, for time t (s)."""
        assert all(r is not None for r in self.recordings), "attach every run's recording first"
        shown = {k: machine.show(t) for k, machine in enumerate(self.machines) if machine.visible}
        for s, site in enumerate(self.sites):
            first = self.site_of.index(s)
            instant = shown[first] if first in shown else self.recordings[first].at(t)
            site.show(t, instant.cp_desired)


def _paints(runs: int, sites: int, solid: int | None) -> list[tuple[Paint, float]]:
    """How each machine is drawn (see `SceneView.paint`). The translucent machines of one site lie
    on top of each other: together they veil the solid one about as much as one ghost does
    (GHOST_OPACITY), each no fainter than FAINTEST, so that one apart from the others still shows."""
    over = max(1, runs // sites - 1)
    opacity = max(1.0 - (1.0 - GHOST_OPACITY) ** (1.0 / over), FAINTEST)
    return [("model", 1.0) if runs == 1 or k == solid else ("colour" if solid is None else "translucent", opacity)
            for k in range(runs)]


def _framing_poses(plan: Plan) -> list[tuple[np.ndarray, np.ndarray | None]]:
    """FRAMING_POSES joint values of the plan, evenly in time, each with its neighbour's (or None)."""
    samples = np.linspace(0, len(plan.time) - 1, FRAMING_POSES).astype(int)
    neighbour = plan.neighbour_q_desired
    return [(plan.q_desired[i], None if neighbour is None else neighbour[i]) for i in samples]


def _row(extents: Sequence[np.ndarray], pile_side: float) -> np.ndarray:
    """Offsets (n, 3) that set runs side by side across the rail, away from the camera: each
    next to the one before by their drawn extents across it, with a gap."""
    lows = [float(e[:, 1].min()) if pile_side > 0 else -float(e[:, 1].max()) for e in extents]
    highs = [float(e[:, 1].max()) if pile_side > 0 else -float(e[:, 1].min()) for e in extents]
    gap = LANE_GAP * max(high - low for low, high in zip(lows, highs))
    offsets, edge = [0.0], highs[0]
    for low, high in zip(lows[1:], highs[1:]):
        shift = edge + gap - low
        offsets.append(shift)
        edge = high + shift
    return np.array([(0.0, pile_side * o, 0.0) for o in offsets])
