"""The grade through a pile: per cell, a column of layers from the yard floor up, each a
thickness (m) of one grade (a number such as Fe %).

Stacking lays material in thin layers, reclaiming cuts down through them, and slumping moves the
top of one column onto the next: the layered terrain of Beneš and Forsbach ("Layered data
representation for visual simulation of terrain erosion", SCCG 2001), one material with a grade.
Every operation moves thickness between layers, the cut and the outside, and never makes or
destroys any: the pile's volume sum(thickness) x cell area and its grade-volume
sum(thickness x grade) x cell area balance with what came in and went out, to rounding. The bulk
density is uniform (the scene's one `bulk_density`), so tonnes are volume x density and the same
balances hold in tonnes and grade-tonnes.

A column holds at most `max_layers` layers. When one more must go on a full column, the adjacent
pair whose merging loses the least grade contrast is merged first: the pair with the least
t1 t2 / (t1 + t2) (g1 - g2)^2 (Ward's criterion: the thickness-weighted grade variance the merge
removes; equal grades cost nothing, thin layers little), into one layer t1 + t2 thick of the
thickness-weighted grade. The column keeps its thickness and grade-thickness, so the balances stay
exact and a cut that takes both layers takes the same material; only a cut ending inside the
merged layer sees its mean grade instead of the two.

Heights are (ny, nx) metres above the yard floor, z[iy, ix] at x[ix], y[iy], as a Surface's, and
equal the sum of the column's thicknesses (to rounding: they are updated beside the layers).
The column kernels are compiled with numba, as the cut is.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np

from bwr_twin.pile.ground import YARD_FLOOR
from bwr_twin.pile.relaxation import DEFAULT_MAX_ROUNDS, Relaxed, Talus, relax
from bwr_twin.pile.surface import Surface

DEFAULT_MAX_LAYERS = 32  # a column's layers, 16 bytes each: 0.5 MB a thousand cells


@dataclass(frozen=True)
class Removed:
    """What a cut took, per cell (ny, nx): m^3 and grade x m^3 (a grade of Fe % gives % m^3)."""

    volume: np.ndarray
    grade_volume: np.ndarray

    @property
    def total_volume(self) -> float:
        return float(self.volume.sum())

    @property
    def grade(self) -> float:
        """The volume-weighted (so, at a uniform density, mass-weighted) grade of all that was
        cut; NaN if nothing was."""
        total = self.total_volume
        return float(self.grade_volume.sum() / total) if total > 0 else float("nan")


class LayeredPile:
    """A pile's heights z (ny, nx) m and its columns of layers.

    Attributes:
        x, y: grid lines (m), evenly spaced, as a Surface's.
        z: (ny, nx) m, the heights: the sum of each column's thicknesses.
        thickness, grade: (ny, nx, max_layers) m and grade of each layer, from the floor up;
            beyond a column's count, zero.
        count: (ny, nx) the layers each column holds.
    """

    def __init__(self, x: np.ndarray, y: np.ndarray, max_layers: int = DEFAULT_MAX_LAYERS):
        """An empty pile (the bare yard floor) on grid lines x, y (m)."""
        if max_layers < 2:
            raise ValueError(f"a column needs room for at least 2 layers, got max_layers {max_layers}")
        self.x, self.y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
        shape = (len(self.y), len(self.x))
        self.z = np.full(shape, YARD_FLOOR)
        self.thickness = np.zeros((*shape, max_layers))
        self.grade = np.zeros((*shape, max_layers))
        self.count = np.zeros(shape, dtype=np.int64)

    @classmethod
    def from_surface(cls, surface: Surface, grade: float,
                     max_layers: int = DEFAULT_MAX_LAYERS) -> LayeredPile:
        """The pile of `surface`'s heights, all of one `grade`: one layer a column."""
        pile = cls(surface.x, surface.y, max_layers)
        pile.deposit(np.clip(surface.z, YARD_FLOOR, None) - YARD_FLOOR, grade)
        return pile

    @property
    def spacing(self) -> float:
        return float(self.x[1] - self.x[0])

    @property
    def cell_area(self) -> float:
        """m^2 each column stands for."""
        return self.spacing**2

    @property
    def max_layers(self) -> int:
        return self.thickness.shape[2]

    def volume(self) -> float:
        """m^3 of material in the pile, from its layers."""
        return float(self.thickness.sum() * self.cell_area)

    def grade_volume(self) -> float:
        """grade x m^3 in the pile, from its layers: over volume(), its mean grade."""
        return float(np.sum(self.thickness * self.grade) * self.cell_area)

    def top_grade(self) -> np.ndarray:
        """(ny, nx) the grade of each column's top layer, the one exposed; NaN on bare ground."""
        return top_grade(self.grade, self.count)

    def column_heights(self) -> np.ndarray:
        """(ny, nx) m: each column's thicknesses summed, above the yard floor (equal to z, to rounding)."""
        return YARD_FLOOR + self.thickness.sum(axis=2)

    def deposit(self, thickness: np.ndarray, grade: float | np.ndarray) -> None:
        """Lay `thickness` (ny, nx) m (>= 0) of `grade` (a number, or (ny, nx)) on top of each
        column: it thickens a top layer of exactly that grade, or is a new top layer."""
        thickness = np.asarray(thickness, dtype=float)
        if thickness.shape != self.z.shape:
            raise ValueError(f"thickness must be {self.z.shape} (ny, nx), got {thickness.shape}")
        if not np.all(thickness >= 0):
            raise ValueError("a deposit's thickness must be >= 0 everywhere (a cut takes material away)")
        grades = np.broadcast_to(np.asarray(grade, dtype=float), self.z.shape)
        if not np.all(np.isfinite(grades[thickness > 0])):
            raise ValueError("a deposit's grade must be a finite number")
        _deposit(*self._columns(), np.ascontiguousarray(thickness).ravel(),
                 np.ascontiguousarray(grades).ravel())
        self.z += thickness

    def cut_to(self, heights: np.ndarray) -> Removed:
        """Lower every column above `heights` (ny, nx) m to it (never below the yard floor),
        taking its layers from the top down; returns what was taken, cell by cell."""
        heights = np.asarray(heights, dtype=float)
        if heights.shape != self.z.shape:
            raise ValueError(f"heights must be {self.z.shape} (ny, nx), got {heights.shape}")
        new = np.maximum(heights, YARD_FLOOR)
        depth = np.where(new < self.z, self.z - new, 0.0)
        volume, grade_volume = np.zeros(self.z.size), np.zeros(self.z.size)
        _take(*self._columns(), depth.ravel(), volume, grade_volume)
        np.minimum(self.z, new, out=self.z)
        area = self.cell_area
        return Removed(volume.reshape(self.z.shape) * area, grade_volume.reshape(self.z.shape) * area)

    def cut_cells(self, cells: np.ndarray, heights: np.ndarray) -> tuple[float, float]:
        """Lower the flat `cells` (k,) to `heights` (k,) m, as cut_to does, visiting those cells
        alone (a wheel's cut, a few thousand of the grid's cells); returns the m^3 and grade x m^3
        taken."""
        cells = np.asarray(cells, dtype=np.int64)
        flat = self.z.reshape(-1)
        depth = np.maximum(flat[cells] - np.maximum(heights, YARD_FLOOR), 0.0)
        volume, grade_volume = _take_cells(*self._columns(), cells, depth)
        flat[cells] -= depth
        return volume * self.cell_area, grade_volume * self.cell_area

    def relax(self, talus: Talus, max_rounds: int = DEFAULT_MAX_ROUNDS) -> Relaxed:
        """Relax the pile to the angle of repose (bwr_twin.pile.relaxation), `talus` made
        for its grid: the heights slump, and each move carries the top of the higher column,
        layers and grades, onto the lower one, in the order the heights moved."""
        if not math.isclose(talus.spacing, self.spacing, rel_tol=1e-9):
            raise ValueError(f"the talus heights are for a grid of {talus.spacing:g} m, "
                             f"the pile's is {self.spacing:g} m")
        relaxed = relax(self.z, talus, max_rounds, record=True)
        _replay(*self._columns(), relaxed.source, relaxed.target, relaxed.thickness)
        return relaxed

    def follow(self, relaxed: Relaxed, heights: np.ndarray) -> None:
        """Carry the layers along a relaxation recorded on another copy of the pile's heights (a
        Cutter's slump), and take its `heights` (ny, nx) m, which it left."""
        _replay(*self._columns(), relaxed.source, relaxed.target, relaxed.thickness)
        self.z[...] = heights

    def _columns(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(cells, max_layers) views of thickness and grade, and the (cells,) counts."""
        cells = self.z.size
        return (self.thickness.reshape(cells, -1), self.grade.reshape(cells, -1), self.count.reshape(cells))


def top_grade(grade: np.ndarray, count: np.ndarray) -> np.ndarray:
    """(ny, nx) the grade of each column's top layer, of layers `grade` (ny, nx, max_layers) and
    their `count` (ny, nx) as a LayeredPile or a stacked pile.npz holds them; NaN where a column
    is empty."""
    top = np.take_along_axis(grade, np.maximum(count - 1, 0)[..., None], axis=2)[..., 0]
    return np.where(count > 0, top, np.nan)


@numba.njit(cache=True)
def _deposit(thickness, grade, count, added, added_grade):
    for cell in range(len(added)):
        if added[cell] > 0.0:
            _push(thickness, grade, count, cell, added[cell], added_grade[cell])


@numba.njit(cache=True)
def _take(thickness, grade, count, depth, volume, grade_volume):
    """Take `depth` (cells,) m off the top of each column, adding what was taken (m, grade x m)
    to volume and grade_volume."""
    for cell in range(len(depth)):
        taken, taken_grade = _take_one(thickness, grade, count, cell, depth[cell])
        volume[cell] += taken
        grade_volume[cell] += taken_grade


@numba.njit(cache=True)
def _take_cells(thickness, grade, count, cells, depth):
    """_take for the listed cells alone, depth[i] off cells[i]; returns the totals (m, grade x m)."""
    total = total_grade = 0.0
    for i in range(len(cells)):
        taken, taken_grade = _take_one(thickness, grade, count, cells[i], depth[i])
        total += taken
        total_grade += taken_grade
    return total, total_grade


@numba.njit(cache=True)
def _take_one(thickness, grade, count, cell, depth):
    """Take `depth` m off the top of one column, layer by layer; returns what it took (m, grade
    x m). A column holding less (by rounding) gives all it holds."""
    left, taken, taken_grade = depth, 0.0, 0.0
    while left > 0.0 and count[cell] > 0:
        top = count[cell] - 1
        piece = min(left, thickness[cell, top])
        taken += piece
        taken_grade += piece * grade[cell, top]
        left -= piece
        if piece == thickness[cell, top]:
            _pop(thickness, grade, count, cell)
        else:
            thickness[cell, top] -= piece
    return taken, taken_grade


@numba.njit(cache=True)
def _replay(thickness, grade, count, source, target, moved):
    """Move moved[i] m off the top of column source[i] onto column target[i], in order. The moved
    sheet keeps its order: the part of the deepest layer it reaches lands first, its top on top."""
    for i in range(len(source)):
        a, b, left = source[i], target[i], moved[i]
        deepest = count[a] - 1
        while deepest > 0 and thickness[a, deepest] < left:  # whole layers
            left -= thickness[a, deepest]
            deepest -= 1
        if deepest < 0:
            continue
        piece = min(left, thickness[a, deepest])
        _push(thickness, grade, count, b, piece, grade[a, deepest])
        for layer in range(deepest + 1, count[a]):
            _push(thickness, grade, count, b, thickness[a, layer], grade[a, layer])
        while count[a] > deepest + 1:
            _pop(thickness, grade, count, a)
        if piece == thickness[a, deepest]:
            _pop(thickness, grade, count, a)
        else:
            thickness[a, deepest] -= piece


@numba.njit(cache=True)
def _push(thickness, grade, count, cell, added, added_grade):
    """Lay `added` m of `added_grade` on top of a column (a full one merges a pair first)."""
    if not added > 0.0:
        return
    top = count[cell] - 1
    if top >= 0 and grade[cell, top] == added_grade:
        thickness[cell, top] += added
        return
    if count[cell] == thickness.shape[1]:
        _merge_closest(thickness, grade, count, cell)
    top = count[cell]
    thickness[cell, top] = added
    grade[cell, top] = added_grade
    count[cell] = top + 1


@numba.njit(cache=True)
def _pop(thickness, grade, count, cell):
    top = count[cell] - 1
    thickness[cell, top] = 0.0
    grade[cell, top] = 0.0
    count[cell] = top


@numba.njit(cache=True)
def _merge_closest(thickness, grade, count, cell):
    """Merge the adjacent pair of a column losing the least grade contrast (the module's docstring)."""
    best, best_cost = 0, np.inf
    for lower in range(count[cell] - 1):
        t1, t2 = thickness[cell, lower], thickness[cell, lower + 1]
        contrast = grade[cell, lower] - grade[cell, lower + 1]
        cost = t1 * t2 / (t1 + t2) * contrast * contrast
        if cost < best_cost:
            best, best_cost = lower, cost
    t1, t2 = thickness[cell, best], thickness[cell, best + 1]
    grade[cell, best] = (t1 * grade[cell, best] + t2 * grade[cell, best + 1]) / (t1 + t2)
    thickness[cell, best] = t1 + t2
    for layer in range(best + 1, count[cell] - 1):
        thickness[cell, layer] = thickness[cell, layer + 1]
        grade[cell, layer] = grade[cell, layer + 1]
    _pop(thickness, grade, count, cell)
