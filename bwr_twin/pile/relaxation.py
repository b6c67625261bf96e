"""Relaxation to the angle of repose: every slope between grid neighbours steeper than the
material's angle of repose slumps, the volume kept exactly.

The rule is the talus rule of thermal weathering (Musgrave, Kolb and Mace, "The synthesis and
rendering of eroded fractal terrains", SIGGRAPH 1989): material moves from a cell to its lower
neighbours wherever their height difference d exceeds the talus height T, the angle of repose's
rise over the distance between them. In the form of Olsen ("Realtime procedural terrain
generation", University of Southern Denmark, 2004) a cell moves c (d_max - T), shared among its
steep neighbours by d_i / d_total; here c = 1/2, shared by the excesses d_i - T instead, so that a
neighbour only just too low receives next to nothing. Half, so that the steepest pair is never
turned over: it is left at T or above, and the cell no lower than its lowest neighbour, so nothing
ever goes below the yard floor the pile stands on. Shared at once, not pair by pair, so that no
direction is favoured: a cone grows symmetric. Material only moves between cells, so the volume
is conserved to rounding.

Eight neighbours, not four: with T = h tan(phi) to the four axial neighbours only, the diagonal
rise could reach 2 h tan(phi) over h sqrt(2), a slope of sqrt(2) tan(phi) (47 deg for a 37 deg
material), and a cone would grow as a square pyramid with 64 % of a round cone's volume. With the
diagonals held to T = sqrt(2) h tan(phi) too, the slope along the grid lines and along the diagonals
is at most tan(phi); a plane meeting all eight bounds can be at most tan(phi) / cos(22.5 deg) =
1.082 tan(phi) steep, midway between them (39.2 deg for 37 deg), and a cone grows as a regular
octagonal pyramid with 2 sqrt(2) / pi = 90 % of a round cone's volume at the same height.

When relaxed, every pair of neighbours a, b satisfies |z_a - z_b| <= T_ab + tolerance (the
tolerance in m, DEFAULT_TOLERANCE unless asked: a slope within tolerance / h of tan(phi)).
It gets there: a cell's move lowers sum(z^2) by more than e T_axial > tolerance x T_axial, and
sum(z^2) cannot fall below (sum z)^2 / cells. That bound is loose; the practical one is
`max_rounds`: a round visits, in a fixed order, every cell a move touched (or neighboured) in the
round before, starting from all cells (or those a caller says changed, and their neighbours), so a quiet pile costs one pass and an avalanche its own
cells; a relaxation that runs out of rounds says so (Relaxed.converged). The excess decays
geometrically, so a tenfold tighter tolerance costs a few hundred rounds more on a slumping face.
The result is the same for the same heights: nothing is random and the order is fixed.

The grid's border is closed: material never leaves it, so a pile needs ground around it to
spread onto. Heights are (ny, nx) metres above the yard floor, a Surface's z[iy, ix].
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np

DEFAULT_TOLERANCE = 1e-4  # m of height a neighbour pair may stand above its talus height when relaxed
DEFAULT_MAX_ROUNDS = 100_000  # rounds; a 15 m vertical face on 0.5 m cells settles in 1,250


@dataclass(frozen=True)
class Talus:
    """The largest height difference (m) the material holds between grid neighbours."""

    spacing: float  # m, h: the grid's
    axial: float  # m, between cells a grid spacing apart: h tan(phi)
    diagonal: float  # m, between cells a diagonal apart: sqrt(2) h tan(phi)
    tolerance: float  # m a relaxed pair may stand above these

    @classmethod
    def of(cls, spacing: float, angle_of_repose: float, tolerance: float = DEFAULT_TOLERANCE) -> Talus:
        """For grid `spacing` (m) and the material's `angle_of_repose` (deg, from the scene)."""
        if not 0 < angle_of_repose < 90:
            raise ValueError(f"angle of repose must lie in (0, 90) deg, got {angle_of_repose}")
        if not spacing > 0 or not tolerance >= 0:
            raise ValueError(f"grid spacing must be > 0 and tolerance >= 0, got {spacing} and {tolerance}")
        rise = spacing * math.tan(math.radians(angle_of_repose))
        return cls(spacing, rise, rise * math.sqrt(2.0), tolerance)

    def excess(self, z: np.ndarray) -> float:
        """m: how far the steepest neighbour pair of heights z (ny, nx) stands above its talus
        height (<= tolerance once relaxed; negative if every pair is gentler)."""
        worst = -np.inf
        pairs = ((z[:, 1:] - z[:, :-1], self.axial), (z[1:, :] - z[:-1, :], self.axial),
                 (z[1:, 1:] - z[:-1, :-1], self.diagonal), (z[1:, :-1] - z[:-1, 1:], self.diagonal))
        for difference, talus in pairs:
            if difference.size:
                worst = max(worst, float(np.max(np.abs(difference))) - talus)
        return worst


@dataclass(frozen=True)
class Relaxed:
    """What one relaxation did. When recorded, its moves in the order they happened: flat cell
    indices `source` and `target` into z.ravel() and the `thickness` (m) moved."""

    rounds: int
    converged: bool  # every pair within tolerance of its talus height; False: max_rounds ran out first
    move_count: int
    moved_volume: float  # m^3 moved, over all moves (the same material may move several times)
    source: np.ndarray | None = None
    target: np.ndarray | None = None
    thickness: np.ndarray | None = None


def relax(z: np.ndarray, talus: Talus, max_rounds: int = DEFAULT_MAX_ROUNDS, record: bool = False,
          region: tuple[int, int, int, int] | None = None) -> Relaxed:
    """Relax heights z (ny, nx) m, in place, on the grid `talus` was made for, until no neighbour
    pair stands more than talus.tolerance above its talus height, or `max_rounds` rounds have run.
    `record` keeps every move, in order, for a layered pile to replay (LayeredPile.relax).
    `region` (first row, last row, first column, last column): the only cells that changed since
    the pile was last relaxed; the first round then visits them and their neighbours alone (a
    wheel's cut: a few hundred of the grid's cells), and an avalanche spreads from there."""
    if z.ndim != 2 or z.dtype != np.float64 or not z.flags.c_contiguous:
        raise ValueError(f"heights must be a C-contiguous (ny, nx) float64 array, got {z.dtype} {z.shape}")
    if max_rounds < 1:
        raise ValueError(f"max_rounds must be >= 1, got {max_rounds}")
    ny, nx = z.shape
    first_row, last_row, first_column, last_column = (0, ny - 1, 0, nx - 1) if region is None else region
    start = np.array([max(first_row - 1, 0), min(last_row + 1, ny - 1), max(first_column - 1, 0),
                      min(last_column + 1, nx - 1)], dtype=np.int64)  # a changed cell's neighbours may now be too steep
    rounds, converged, count, moved, source, target, thickness = _relax(
        z, talus.axial, talus.diagonal, talus.tolerance, max_rounds, record, start)
    kept = (source[:count], target[:count], thickness[:count]) if record else (None, None, None)
    return Relaxed(rounds, converged, count, moved * talus.spacing**2, *kept)


# The eight neighbours (row, column offsets): axial first, then diagonal.
_DY = np.array([0, 0, 1, -1, 1, -1, 1, -1])
_DX = np.array([1, -1, 0, 0, 1, -1, -1, 1])


@numba.njit(cache=True)
def _relax(z, talus_axial, talus_diagonal, tolerance, max_rounds, record, start):
    """relax's loop, its first round over the cells of the `start` rectangle (first and last row,
    first and last column): returns (rounds run, whether the last found nothing to move, moves,
    total thickness moved m, and the recorded sources, targets and thicknesses)."""
    ny, nx = z.shape
    cells = ny * nx
    flat = z.ravel()
    current = np.empty(cells, np.int64)
    size = 0
    for iy in range(start[0], start[1] + 1):
        for ix in range(start[2], start[3] + 1):
            current[size] = iy * nx + ix
            size += 1
    following = np.empty(cells, np.int64)
    queued = np.zeros(cells, np.bool_)
    excesses = np.empty(8)
    capacity = 0
    source = np.empty(0, np.int64)
    target = np.empty(0, np.int64)
    thickness = np.empty(0)
    count = 0
    moved = 0.0
    rounds = 0
    while size > 0:
        if rounds == max_rounds:
            return rounds, False, count, moved, source, target, thickness
        rounds += 1
        following_size = 0
        if record and count + 8 * size > capacity:  # a cell moves to at most 8 neighbours a round
            capacity = max(2 * capacity, count + 8 * size)
            source = _grown(source, capacity)
            target = _grown(target, capacity)
            thickness = _grown(thickness, capacity)
        for position in range(size):
            a = current[position]
            iy, ix = a // nx, a % nx
            steepest = total = 0.0
            for k in range(8):
                jy, jx = iy + _DY[k], ix + _DX[k]
                excess = -1.0
                if 0 <= jy < ny and 0 <= jx < nx:
                    excess = flat[a] - flat[jy * nx + jx] - (talus_axial if k < 4 else talus_diagonal)
                excesses[k] = excess
                if excess > 0.0:
                    total += excess
                    steepest = max(steepest, excess)
            if steepest > tolerance:  # half the steepest excess, shared by excess among the steep neighbours
                share = 0.5 * steepest / total
                for k in range(8):
                    if excesses[k] > 0.0:
                        b = (iy + _DY[k]) * nx + ix + _DX[k]
                        m = share * excesses[k]
                        flat[a] -= m
                        flat[b] += m
                        moved += m
                        if record:
                            source[count], target[count], thickness[count] = a, b, m
                        count += 1
                for k in range(-1, 8):  # a's pairs all changed: a and its neighbours are looked at again
                    jy, jx = (iy, ix) if k < 0 else (iy + _DY[k], ix + _DX[k])
                    if 0 <= jy < ny and 0 <= jx < nx and not queued[jy * nx + jx]:
                        queued[jy * nx + jx] = True
                        following[following_size] = jy * nx + jx
                        following_size += 1
        for position in range(following_size):
            queued[following[position]] = False
        current, following = following, current
        size = following_size
    return rounds, True, count, moved, source, target, thickness


@numba.njit(cache=True)
def _grown(array, capacity):
    bigger = np.empty(capacity, array.dtype)
    bigger[: len(array)] = array
    return bigger
