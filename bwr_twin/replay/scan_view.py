"""A run's scans on a replay's scene: the fan of the latest scan, the hits of the last second and
the scanned pile (bwr_twin.replay.scans), under the site's frame.

- `{site}/scan/fan`: a line from the scanner's origin to each hit of its latest scan at or
  before the current time; `{site}/scan/misses`: the rays that returned nothing, short and faint;
  `{site}/scan/hits`: the hits of the scans of the last second, as a point cloud of at most
  `ScanDrawing.cloud_points`.
- `{site}/scanned`: the pile the automation knew from its scans, on the true pile's display grid
  and in its tiles, one colour; cells it has not seen are not drawn.

The true pile (`{site}/pile`) and the scanned one take turns: `Site.show_pile` says which is
shown. A frame sends only what changed: the fan when the latest scan changed, the cloud when its
scans did, and the scanned pile's tiles whose samples a new frame of it changed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import viser

from bwr_twin.replay.pile import TILE, DugHeights, display_step, samples
from bwr_twin.replay.rooted import Rooted
from bwr_twin.replay.scans import KNOWN_FRAME_PERIOD, Scans
from bwr_twin.replay.style import FAN_COLOUR, HIT_COLOUR, KNOWN_COLOUR, MISS_COLOUR

FAN_WIDTH = 1.5  # px, a ray that returned
MISS_WIDTH = 1.0  # px, one that did not
HIT_SIZE = 0.5  # of the site's marker radius: a hit's point
PILE_SHOWN = ("true", "scanned")  # the GUI's choices of the pile shown


@dataclass(frozen=True)
class ScanDrawing:
    """How much of the scans a scene draws.

    Attributes:
        ray_step: draw every ray_step-th ray of a scan; 0 chooses it to draw at most `rays`.
        rays: the most rays of a scan drawn, with ray_step 0.
        cloud_points: the most hits in the cloud.
        update_period: s of the run at least between two updates of the fan and the cloud.
        most_updates: the most updates of the fan and the cloud over the whole run (0: no bound);
            a longer run has them further apart than `update_period`.
        known_period: s between the scanned pile's frames.
        both_piles: keep the hidden pile current too (an export, whose page chooses the one shown).
    """

    ray_step: int = 1
    rays: int = 0
    cloud_points: int = 3000
    update_period: float = 0.0
    most_updates: int = 0
    known_period: float = KNOWN_FRAME_PERIOD
    both_piles: bool = False

    def every(self, rays: int) -> int:
        return self.ray_step or max(1, math.ceil(rays / self.rays))


LIVE = ScanDrawing()
# The export holds every update it draws: a fan of at most 48 rays and 150 hits, once a second of the
# run and at most 2,000 times (about 1.3 kB each: heavy_scanned_reclaim's 1,933 updates are 2.5 MB
# of its 5.0 MB file), and the scanned pile in frames of 5 s, as the dug pile's
# (bwr_twin.replay.simulation).
EXPORT = ScanDrawing(ray_step=0, rays=48, cloud_points=150, update_period=1.0, most_updates=2000, known_period=5.0,
                     both_piles=True)


def scanned_note(scans: Scans | None, period: float) -> str:
    """What the scanned pile is, beside the control that shows it."""
    plan = scans.plan_time if scans is not None else None
    planned = f" The benches were planned on it at {plan:g} s." if plan is not None else ""
    return (f"the pile the automation knew from its scans, rebuilt from them every {period:g} s of the run; "
            f"cells it never saw are not drawn.{planned}")


class ScanView(Rooted):
    """A run's `scans` on `scene` under the site frame `prefix`, drawn as `drawing` says: the fan,
    the misses and the cloud under `{prefix}/scan`, its hits sized for the site's `marker_radius`
    (m), and the scanned pile under `{prefix}/scanned` on the true pile's display grid."""

    def __init__(self, scene: viser.SceneApi, prefix: str, scans: Scans, marker_radius: float,
                 drawing: ScanDrawing = LIVE):
        self.scene, self.scans, self.drawing = scene, scans, drawing
        self.every = drawing.every(scans.hits.shape[1])
        span = float(scans.time[-1] - scans.time[0])
        self.update_period = max(drawing.update_period, span / drawing.most_updates if drawing.most_updates else 0.0)
        self.root = scene.add_frame(f"{prefix}/scan", show_axes=False)
        anchor = np.array([float(np.mean(scans.x[[0, -1]])), float(np.mean(scans.y[[0, -1]])), 0.0])
        nowhere = np.zeros((1, 2, 3), dtype=np.float32)  # until the first scan: hidden anyway
        self.fan_node = scene.add_line_segments(f"{prefix}/scan/fan", nowhere, FAN_COLOUR, thickness=FAN_WIDTH,
                                                thickness_units="screen", visible=False)
        self.miss_node = scene.add_line_segments(f"{prefix}/scan/misses", nowhere, MISS_COLOUR,
                                                 thickness=MISS_WIDTH, thickness_units="screen", visible=False)
        # Hits relative to the pile's centre: float16 keeps them to a few centimetres over the pile.
        self.hit_node = scene.add_point_cloud(f"{prefix}/scan/hits", np.zeros((1, 3)), HIT_COLOUR,
                                              point_size=HIT_SIZE * marker_radius, point_shape="circle",
                                              point_shading="flat", position=anchor, visible=False)
        self._anchor = anchor
        self.known = KnownPileView(scene, f"{prefix}/scanned", scans.known(drawing.known_period))
        self.fan: tuple[int, ...] = ()  # the scans the fan draws
        self._cloud: tuple[int, int] = (0, 0)  # the scans the cloud draws, [begin, end)
        self._updated = -math.inf  # run time of the last update of fan and cloud

    def show(self, t: float, *, fan: bool = True, pile: bool = True) -> None:
        """The fan and cloud (if `fan`) and the scanned pile (if `pile`) at time t (s)."""
        if pile:
            self.known.show(t)
        if not fan:
            return
        if abs(t - self._updated) < self.update_period:
            return
        scans = self.scans
        latest = scans.latest(t)
        if latest != self.fan:
            self.fan = latest
            drawn = scans.fan(t, self.every)
            if drawn is None:
                self.fan_node.visible = self.miss_node.visible = False
            else:
                for node, lines in ((self.fan_node, drawn.hits), (self.miss_node, drawn.misses)):
                    node.visible = len(lines) > 0
                    if len(lines):
                        node.points = lines.astype(np.float32)
        window = scans.window(t)
        if window != self._cloud:
            self._cloud = window
            points = scans.cloud(t, self.drawing.cloud_points)
            self.hit_node.visible = len(points) > 0
            if len(points):
                self.hit_node.points = (points - self._anchor).astype(np.float16)
        self._updated = t


class KnownPileView(Rooted):
    """The scanned pile `history` (a PileHistory that starts unknown) on the true pile's display
    grid, in tiles of TILE display cells: a tile's mesh holds the display cells whose corners
    are all known, and is sent again when a frame changed one of its samples."""

    def __init__(self, scene: viser.SceneApi, name: str, history):
        self.dug = DugHeights(history)
        step = display_step(history.z_start.shape)
        self._rows, self._cols = samples(history.z_start.shape[0], step), samples(history.z_start.shape[1], step)
        gx, gy = np.meshgrid(history.x[self._cols], history.y[self._rows])
        self._xy = np.stack([gx, gy], axis=-1).astype(np.float32)
        self._shown = self._display(self.dug.z)
        self.root = scene.add_frame(name, show_axes=False, visible=False)
        self.tiles = []
        for r0 in range(0, len(self._rows) - 1, TILE):
            for c0 in range(0, len(self._cols) - 1, TILE):
                rows = slice(r0, min(r0 + TILE, len(self._rows) - 1) + 1)
                cols = slice(c0, min(c0 + TILE, len(self._cols) - 1) + 1)
                self.tiles.append(_KnownTile(scene, f"{name}/{r0}_{c0}", rows, cols, self._xy, self._shown))

    @property
    def z(self) -> np.ndarray:
        """The display grid's heights (m, NaN unknown) as shown."""
        return self._shown

    def show(self, t: float) -> None:
        """The scanned pile as the automation knew it at time t (s)."""
        if not self.dug.advance(t):
            return
        shown = self._display(self.dug.z)
        changed = ~((shown == self._shown) | (np.isnan(shown) & np.isnan(self._shown)))
        self._shown = shown
        for tile in self.tiles:
            if changed[tile.rows, tile.cols].any():
                tile.update(self._xy, shown)

    def _display(self, z: np.ndarray) -> np.ndarray:
        return z[np.ix_(self._rows, self._cols)].astype(np.float32)


class _KnownTile:
    """One tile of the scanned pile: the display cells whose four corners are known."""

    def __init__(self, scene: viser.SceneApi, name: str, rows: slice, cols: slice, xy, shown):
        self.rows, self.cols = rows, cols
        ny = len(range(*rows.indices(shown.shape[0])))
        nx = len(range(*cols.indices(shown.shape[1])))
        index = np.arange(ny * nx).reshape(ny, nx)
        self._corners = np.stack([index[:-1, :-1], index[:-1, 1:], index[1:, 1:], index[1:, :-1]], axis=-1).reshape(-1, 4)
        vertices, faces = self._mesh(xy, shown)
        self.node = scene.add_mesh_simple(f"{name}/known", vertices, faces, color=KNOWN_COLOUR, side="double")

    def _mesh(self, xy, shown) -> tuple[np.ndarray, np.ndarray]:
        z = shown[self.rows, self.cols]
        known = ~np.isnan(z).ravel()
        vertices = np.concatenate([xy[self.rows, self.cols], np.nan_to_num(z)[..., None]], axis=-1).reshape(-1, 3)
        cells = self._corners[known[self._corners].all(axis=1)]
        # Two triangles a display cell, counter-clockwise seen from above, as the true pile's.
        faces = np.concatenate([cells[:, [0, 1, 2]], cells[:, [0, 2, 3]]]).astype(np.uint32)
        return vertices, faces if len(faces) else np.zeros((1, 3), np.uint32)  # an empty mesh draws nothing

    def update(self, xy, shown) -> None:
        vertices, faces = self._mesh(xy, shown)
        self.node.vertices = vertices
        if not np.array_equal(self.node.faces, faces):
            self.node.faces = faces
