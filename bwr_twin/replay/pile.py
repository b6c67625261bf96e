"""The stockpile in the replay: its heights as it is dug, drawn as a mesh in tiles.

The run keeps the cells it changed every few simulated seconds (`PileHistory`). The view draws
the pile on a display grid of at most MAX_DISPLAY_VERTICES samples, split into tiles; a tile is
sent again only when a sample in it was dug, so a long reclaim stays a small export. Faces
that were dug are drawn in the colour of fresh ore, the untouched pile in weathered ore.

A pile of grade (a stacking's, a reclaim of a stacked pile) can be coloured instead by the grade
of the layer exposed at each cell ("grade", `PileView.colour_by`): each tile's faces are split
into the bins of a `GradeScale`, a face's grade the mean of its corners' (bare ground in ore),
one mesh per bin, made the first time the bin has faces in the tile, under `{name}/grade`. Only
the colouring shown is kept current; a switch poses every tile once in the other.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from bwr_twin.replay.rooted import Rooted
from bwr_twin.stockpile.history import PileHistory

if TYPE_CHECKING:  # the video renders the pile without viser
    import viser

    from bwr_twin.replay.grade_scale import GradeScale

MAX_DISPLAY_VERTICES = 20_000
TILE = 8  # display cells along a tile's side
CUT_SHOWN = 0.05  # m below the start height: a face lower than that shows as freshly cut
ORE_COLOUR = (112, 66, 44)  # weathered iron ore
CUT_COLOUR = (230, 110, 30)  # a fresh face: bright ore, seen from afar
PILE_COLOURS = ("ore", "grade")  # the GUI's choices of how the pile is coloured


class PileView(Rooted):
    """The pile on a viser scene at its start; once a run's history is attached, `show` poses it
    for a time of that history."""

    def __init__(self, scene: viser.SceneApi, x: np.ndarray, y: np.ndarray, z_start: np.ndarray,
                 name: str = "/pile"):
        self.dug: DugHeights | None = None
        self.x, self.y, self.z_start = x, y, z_start
        self.scene, self.name = scene, name
        self.colour = "ore"  # of PILE_COLOURS
        self._scale: GradeScale | None = None
        self._grade: np.ndarray | None = None  # the display grid's top grades as shown, in "grade"
        self._grade_root = None
        self.root = scene.add_frame(name, show_axes=False)  # the tiles' parent: shows or hides the pile
        self._grid = grid = DisplayGrid.of(x, y)
        self._shown = grid.sample(z_start)
        self._start = self._shown.copy()
        self._tiles = []
        for r0 in range(0, len(grid.rows) - 1, TILE):
            for c0 in range(0, len(grid.cols) - 1, TILE):
                rows = slice(r0, min(r0 + TILE, len(grid.rows) - 1) + 1)
                cols = slice(c0, min(c0 + TILE, len(grid.cols) - 1) + 1)
                self._tiles.append(_Tile(scene, name, f"{r0}_{c0}", rows, cols, grid.xy, self._shown, self._start))

    def attach(self, history: PileHistory) -> None:
        self.dug = DugHeights(history)

    @property
    def graded(self) -> bool:
        """Whether the attached history has grade, so that the pile can be coloured by it."""
        return self.dug is not None and self.dug.grade is not None

    def show(self, t: float) -> None:
        """The pile as it was at time t (s): tiles whose samples changed are sent again."""
        if self.dug is None or not self.dug.advance(t):
            return
        shown = self._grid.sample(self.dug.z)
        changed = shown != self._shown
        self._shown = shown
        if self.colour == "grade":
            grade = self._grid.sample(self.dug.grade)
            changed |= ~((grade == self._grade) | (np.isnan(grade) & np.isnan(self._grade)))
            self._grade = grade
        for tile in self._tiles:
            if changed[tile.rows, tile.cols].any():
                self._pose(tile)

    def colour_by(self, kind: str, scale: GradeScale | None = None) -> None:
        """Colour the pile by ore ("ore": weathered, and bright where freshly cut) or by the grade
        of its top layer on `scale` ("grade", a pile with grade only), as it stands now: every
        tile is posed once in the colouring chosen."""
        if kind not in PILE_COLOURS:
            raise ValueError(f"pile colour: {kind!r}, not one of {', '.join(PILE_COLOURS)}")
        if kind == self.colour or (kind == "grade" and (not self.graded or scale is None)):
            return
        self.colour = kind
        grading = kind == "grade"
        if grading:
            self._scale = self._scale or scale  # the meshes of the bins keep their colours
            self._grade = self._grid.sample(self.dug.grade)
            if self._grade_root is None:
                self._grade_root = self.scene.add_frame(f"{self.name}/grade", show_axes=False)
            self._grade_root.visible = True
        else:
            self._grade_root.visible = False
        for tile in self._tiles:
            tile.show_ore(not grading)
            self._pose(tile)

    def _pose(self, tile: _Tile) -> None:
        if self.colour == "grade":
            tile.update_grade(self._grid.xy, self._shown, self._grade, self._scale)
        else:
            tile.update(self._grid.xy, self._shown, self._start)

    @property
    def corners(self) -> np.ndarray:
        """(8, 3) corners of the pile's bounding box, for framing the camera (m)."""
        top = float(self.z_start.max())
        return np.array([(x, y, z) for x in self.x[[0, -1]] for y in self.y[[0, -1]] for z in (0.0, top)])


@dataclass(frozen=True)
class DisplayGrid:
    """The display grid: the pile's rows and columns it samples (at most MAX_DISPLAY_VERTICES
    samples) and their (rows, cols, 2) world x, y (m, float32, as the meshes take them)."""

    rows: np.ndarray
    cols: np.ndarray
    xy: np.ndarray

    @classmethod
    def of(cls, x: np.ndarray, y: np.ndarray) -> DisplayGrid:
        step = display_step((len(y), len(x)))
        rows, cols = samples(len(y), step), samples(len(x), step)
        gx, gy = np.meshgrid(x[cols], y[rows])
        return cls(rows, cols, np.stack([gx, gy], axis=-1).astype(np.float32))

    def sample(self, z: np.ndarray) -> np.ndarray:
        """(rows, cols) float32: the pile's (ny, nx) values on the display grid."""
        return z[np.ix_(self.rows, self.cols)].astype(np.float32)


class DugHeights:
    """A run's pile heights `z` (m) at a time of its history: the frames up to that time applied
    to its start, onwards from the time asked before (back in time: from the start again). A
    history with grade gives its top layers' `grade` too (NaN on bare ground; else None)."""

    def __init__(self, history: PileHistory):
        self.history = history
        self.z = history.z_start.copy()
        self.grade = None if history.grade_start is None else history.grade_start.astype(np.float32)
        self._applied = 0  # frames applied to z

    def advance(self, t: float) -> bool:
        """Bring `z` to time t (s); whether it changed."""
        h = self.history
        frames = int(np.searchsorted(h.frame_time, t, side="right"))
        if frames == self._applied:
            return False
        if frames < self._applied:
            self.z[:] = h.z_start
            if self.grade is not None:
                self.grade[:] = h.grade_start
            self._applied = 0
        flat = self.z.reshape(-1)
        start, end = h.offsets[self._applied], h.offsets[frames]
        flat[h.cells[start:end]] = h.heights[start:end]  # later frames overwrite earlier ones
        if self.grade is not None:
            self.grade.reshape(-1)[h.cells[start:end]] = h.grades[start:end]
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
    """One tile of the display grid: an untouched and a freshly cut mesh over the same vertices;
    and, once the pile is coloured by grade, a mesh per bin of the scale that has faces here (bare
    ground's the last), each of the vertices its faces use."""

    def __init__(self, scene: viser.SceneApi, pile: str, key: str, rows: slice, cols: slice, xy, shown, start):
        self.rows, self.cols = rows, cols
        self.scene, self.pile, self.key = scene, pile, key
        self.bins: dict[int, viser.MeshHandle] = {}  # the grade's meshes by bin, bare ground's last
        name = f"{pile}/{key}"
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

    def show_ore(self, shown: bool) -> None:
        self._ore.visible = self._cut.visible = shown

    def update_grade(self, xy, shown, grade, scale: GradeScale) -> None:
        """The faces in the bins of their grade, the mean of their corners' top grades; those
        whose corners are all bare ground in ore. A bin's mesh is sent only if it changed."""
        z = shown[self.rows, self.cols]
        vertices = np.concatenate([xy[self.rows, self.cols], z[..., None]], axis=-1).reshape(-1, 3)
        corners = grade[self.rows, self.cols].ravel()[self._faces]
        known = np.isfinite(corners).sum(axis=1)
        mean = np.where(known > 0, np.nansum(corners, axis=1) / np.maximum(known, 1), np.nan)
        index = scale.bins(mean)
        index[index < 0] = len(scale.colours)  # bare ground: the last mesh
        for k, colour in enumerate([*scale.colours, ORE_COLOUR]):
            faces, handle = self._faces[index == k], self.bins.get(k)
            if handle is None and not len(faces):
                continue  # a bin the tile never showed: no node
            used, indices = _used(vertices, faces)
            if handle is None:
                self.bins[k] = self.scene.add_mesh_simple(f"{self.pile}/grade/{self.key}/{k}", used, indices,
                                                          color=colour, side="double")
            elif not (np.array_equal(handle.faces, indices) and np.array_equal(handle.vertices, used)):
                handle.vertices, handle.faces = used, indices  # sent in the caller's atomic batch


def _used(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The vertices `faces` use, and the faces on them: a bin's mesh sends no others. No faces:
    one vertex and a degenerate face (an empty mesh draws nothing, but must be valid)."""
    if not len(faces):
        return vertices[:1], np.zeros((1, 3), np.uint32)
    used, inverse = np.unique(faces, return_inverse=True)
    return vertices[used], inverse.reshape(faces.shape).astype(np.uint32)
