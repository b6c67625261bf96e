"""One run in the replay's scene: its machine (the visual geoms of its moving bodies, posed by
MuJoCo's kinematics from the run's joint values), a second machine on its rail if the scene has
one, and its CP trail, in the run's colour.

Everything hangs under the scene frame /runs/<k>, which carries the run's place (moved aside when
runs stand side by side) and whether it is shown. The trail is sent in chunks, each once and then
only shown or hidden; a frame re-sends the body poses and the trail's unfinished tip.
"""

from __future__ import annotations

import numpy as np
import viser

from bwr_twin.drawing.meshes import Meshes, Paint
from bwr_twin.replay.recording import Instant, Plan, Recording, decimate
from bwr_twin.replay.rooted import Rooted
from bwr_twin.replay.style import GHOST_OPACITY, LINE_WIDTH, PATH_STEP

TRAIL_CHUNK = 20  # trail segments per scene node; only the unfinished chunk is re-sent



def segments(points: np.ndarray) -> np.ndarray:
    """A polyline (m, 3) as (m - 1, 2, 3) line segments; one degenerate segment for a single point."""
    if len(points) == 1:
        points = np.repeat(points, 2, axis=0)
    return np.stack([points[:-1], points[1:]], axis=1).astype(np.float32)


class MachineView(Rooted):
    """Run k's machine at the start pose of `plan`, painted as `paint` says (`MachineView.paint`)
    with `colour`, its trail's, and the neighbour on its rail where the scene has one;
    `attach` adds the recording's trail, `show` poses a time of it."""

    def __init__(self, scene: viser.SceneApi, plan: Plan, k: int, colour: tuple[int, int, int],
                 paint: tuple[Paint, float] = ("model", 1.0)):
        self.scene, self.prefix, self.colour = scene, f"/runs/{k}", colour
        self.root = scene.add_frame(self.prefix, show_axes=False)
        # The first run has a node per geom, as MuJoCo sizes it; the others a node per body and colour.
        self.own = Meshes(scene, plan.machine, self.prefix, k > 0, colour, paint)
        self.neighbour = (None if plan.neighbour is None else
                          Meshes(scene, plan.neighbour, f"{self.prefix}/neighbour", True, colour, paint))
        self.poser, self.geoms, self.nodes = self.own.poser, self.own.geoms, self.own.nodes
        self.recording: Recording | None = None
        self.place(plan.q_desired[0], plan.neighbour_q_desired[0] if plan.neighbour is not None else None)

    def vertices(self, q: np.ndarray, neighbour_q: np.ndarray | None = None) -> np.ndarray:
        """(v, 3) the machine's vertices at joint values q, and its neighbour's at neighbour_q if
        given, in world coordinates before any offset (m)."""
        own = self.own.vertices(q)
        return own if neighbour_q is None or self.neighbour is None else np.concatenate(
            [own, self.neighbour.vertices(neighbour_q)])

    def place(self, q: np.ndarray, neighbour_q: np.ndarray | None = None) -> None:
        """Pose the moving bodies for joint values q, and the neighbour's for neighbour_q."""
        self.own.place(q)
        if self.neighbour is not None and neighbour_q is not None:
            self.neighbour.place(neighbour_q)

    def paint(self, kind: Paint, opacity: float = GHOST_OPACITY) -> None:
        """Draw the machine (and its neighbour) in its MJCF colours, or all in the run's colour,
        solid or seen through with `opacity`."""
        for meshes in (self.own, self.neighbour):
            if meshes is not None:
                meshes.paint(kind, opacity)

    def attach(self, recording: Recording) -> None:
        """Add the recording's CP trail in chunks, each sent once and then only shown or hidden."""
        self.recording = recording
        samples = decimate(recording.plan.time, PATH_STEP)
        self.trail_time = recording.plan.time[samples]
        self.trail_points = recording.cp_actual[samples]
        self.trail_chunks = [
            self.scene.add_line_segments(
                f"{self.prefix}/trail/{c}",
                segments(self.trail_points[start : start + TRAIL_CHUNK + 1]),
                self.colour,
                thickness=2 * LINE_WIDTH,
                thickness_units="screen",
                visible=False,
            )
            for c, start in enumerate(range(0, len(samples) - 1, TRAIL_CHUNK))
        ]
        self.chunks_shown = 0
        self.trail_tip = self.scene.add_line_segments(
            f"{self.prefix}/trail/tip",
            segments(self.trail_points[:1]),
            self.colour,
            thickness=2 * LINE_WIDTH,
            thickness_units="screen",
        )

    def show(self, t: float) -> Instant:
        """Pose the machine and its trail for time t (s) of the attached recording; the instant shown."""
        assert self.recording is not None, "attach a recording first"
        instant = self.recording.at(t)
        self.place(instant.q_actual, instant.neighbour_q)
        last = max(0, int(np.searchsorted(self.trail_time, t, side="right")) - 1)
        complete = last // TRAIL_CHUNK  # chunks wholly before t
        for c in range(min(complete, self.chunks_shown), max(complete, self.chunks_shown)):
            self.trail_chunks[c].visible = c < complete
        self.chunks_shown = complete
        tip = np.concatenate([self.trail_points[complete * TRAIL_CHUNK : last + 1], instant.cp_actual[None]])
        self.trail_tip.points = segments(tip)
        return instant
