"""The stockpile in the replay: its heights as it is dug, drawn as a mesh in tiles.

The run keeps the cells it changed every few simulated seconds (`PileHistory`). The view draws
the pile on a display grid of at most MAX_DISPLAY_VERTICES samples, split into tiles; a tile is
sent again only when a sample in it was dug, so a long reclaim stays a small export. Faces
that were dug are drawn in the colour of fresh ore, the untouched pile in weathered ore.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from bwr_twin.replay.rooted import Rooted
from bwr_twin.stockpile.history import PileHistory

if TYPE_CHECKING:  # the video renders the pile without viser
    import viser

MAX_DISPLAY_VERTICES = 20_000
TILE = 8  # display cells along a tile's side
CUT_SHOWN = 0.05  # m below the start height: a face lower than that shows as freshly cut
ORE_COLOUR = (112, 66, 44)  # weathered iron ore
CUT_COLOUR = (230, 110, 30)  # a fresh face: bright ore, seen from afar


class PileView(Rooted):
    """The pile on a viser scene at its start; once a run's history is attached, `show` poses it
    for a time of that history."""

    def __init__(self, scene: viser.SceneApi, x: np.ndarray, y: np.ndarray, z_start: np.ndarray,
                 name: str = "/pile"):
        self.dug: DugHeights | None = None
        self.x, self.y, self.z_start = x, y, z_start
        self.root = scene.add_frame(name, show_axes=False)  # the tiles' parent: shows or hides the pile
        ny, nx = z_start.shape
        step = display_step(z_start.shape)
        self._rows = samples(ny, step)
        self._cols = samples(nx, step)
        self._shown = self._display(z_start)
        self._start = self._shown.copy()
        gx, gy = np.meshgrid(x[self._cols], y[self._rows])
        self._xy = np.stack([gx, gy], axis=-1).astype(np.float32)
        self._tiles = []
        for r0 in range(0, len(self._rows) - 1, TILE):
            for c0 in range(0, len(self._cols) - 1, TILE):
                rows = slice(r0, min(r0 + TILE, len(self._rows) - 1) + 1)
                cols = slice(c0, min(c0 + TILE, len(self._cols) - 1) + 1)
                self._tiles.append(_Tile(scene, f"{name}/{r0}_{c0}", rows, cols, self._xy, self._shown, self._start))

    def attach(self, history: PileHistory) -> None:
        self.dug = DugHeights(history)

    def show(self, t: float) -> None:
        """The pile as it was at time t (s): tiles whose samples changed are sent again."""
        if self.dug is None or not self.dug.advance(t):
            return
        shown = self._display(self.dug.z)
        changed = shown != self._shown
        self._shown = shown
        for tile in self._tiles:
            if changed[tile.rows, tile.cols].any():
                tile.update(self._xy, shown, self._start)

    def _display(self, z: np.ndarray) -> np.ndarray:
        return z[np.ix_(self._rows, self._cols)].astype(np.float32)

    @property
    def corners(self) -> np.ndarray:
        """(8, 3) corners of the pile's bounding box, for framing the camera (m)."""
        top = float(self.z_start.max())
        return np.array([(x, y, z) for x in self.x[[0, -1]] for y in self.y[[0, -1]] for z in (0.0, top)])


class DugHeights:
    """A run's pile heights `z` (m) at a time of its history: the frames up to that time applied
    to its start, onwards from the time asked before (back in time: from the start again)."""

    def __init__(self, history: PileHistory):
        self.history = history
        self.z = history.z_start.copy()
        self._applied = 0  # frames applied to z

    def advance(self, t: float) -> bool:
        """Bring `z` to time t (s); whether it changed."""
        h = self.history
        frames = int(np.searchsorted(h.frame_time, t, side="right"))
        if frames == self._applied:
            return False
        if frames < self._applied:
            self.z[:] = h.z_start
            self._applied = 0
        flat = self.z.reshape(-1)
        start, end = h.offsets[self._applied], h.offsets[frames]
        flat[h.cells[start:end]] = h.heights[start:end]  # later frames overwrite earlier ones
        self._applied = frames
        return True


def display_step(shape: tuple[int, int]) -> int:
    """Every how many grid samples the pile is drawn: at most MAX_DISPLAY_VERTICES in all."""
    ny, nx = shape
    return max(1, math.ceil(math.sqrt(nx * ny / MAX_DISPLAY_VERTICES)))


def samples(count: int, step: int) -> np.ndarray:
    """Every step-th index from 0, and always the last."""
    indices = np.arange(0, count, step)
    return indices if indices[-1] == count - 1 else np.append(indices, count - 1)


class _Tile:
    """One tile of the display grid: an untouched and a freshly cut mesh over the same vertices."""

    def __init__(self, scene: viser.SceneApi, name: str, rows: slice, cols: slice, xy, shown, start):
        self.rows, self.cols = rows, cols
        ny, nx = len(range(*rows.indices(shown.shape[0]))), len(range(*cols.indices(shown.shape[1])))
        index = np.arange(ny * nx).reshape(ny, nx)
        corner = index[:-1, :-1].ravel()
        # Two triangles a display cell, counter-clockwise seen from above.
        self._faces = np.concatenate([
            np.stack([corner, corner + 1, corner + nx + 1], axis=1),
            np.stack([corner, corner + nx + 1, corner + nx], axis=1),
        ]).astype(np.uint32)
        vertices, ore, cut = self._mesh(xy, shown, start)
        self._ore = scene.add_mesh_simple(f"{name}/ore", vertices, ore, color=ORE_COLOUR, side="double")
        self._cut = scene.add_mesh_simple(f"{name}/cut", vertices, cut, color=CUT_COLOUR, side="double")

    def _mesh(self, xy, shown, start) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        z = shown[self.rows, self.cols]
        vertices = np.concatenate([xy[self.rows, self.cols], z[..., None]], axis=-1).reshape(-1, 3)
        dug = (start[self.rows, self.cols] - z > CUT_SHOWN).ravel()
        face_dug = dug[self._faces].any(axis=1)
        # An empty mesh draws nothing: one degenerate face keeps the node valid.
        empty = np.zeros((1, 3), np.uint32)
        ore, cut = self._faces[~face_dug], self._faces[face_dug]
        return vertices, ore if len(ore) else empty, cut if len(cut) else empty

    def update(self, xy, shown, start) -> None:
        vertices, ore, cut = self._mesh(xy, shown, start)
        for handle, faces in ((self._ore, ore), (self._cut, cut)):
            handle.vertices = vertices
            if not np.array_equal(handle.faces, faces):
                handle.faces = faces
