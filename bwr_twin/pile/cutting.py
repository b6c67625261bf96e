"""The cut: every control period, each run's wheel lowers the pile to its cutting envelope.

The envelope is the wheel's disc at the CP, in the vertical plane of the boom (the slew
direction), as wide as the buckets: a cell whose centre lies within half the width of that
plane and within the disc's span along the boom is lowered to the disc's lower rim. Beside the
width, the envelope's flanks rise at the wheel's side slope (the MJCF's `wheel_side_slope`, 6 m
per m unless it says): with vertical flanks a slewing wheel would take a whole column of cells
in one period and the rate would be a train of spikes a cell apart; with flanks a few cells
wide, cells are lowered a little each period, and the same material is cut, a little earlier.
The heights only ever fall, so the volume the pile loses is exactly the sum of the volumes cut.

A Cutter given the material's angle of repose (a scene's `stockpile.angle_of_repose`) then lets
the faces it cut slump (`slump`, bwr_twin.pile.relaxation), beginning from the cells it
lowered: the slump only moves material, so the volume the pile loses is still what was cut. The slumped
material lands where the wheel is and is cut in the periods that follow, as a real face falls
into the wheel.

The cut runs every control period for every run, so it is compiled with numba: one call visits,
for each run, only the cells near its wheel. Numba caches the machine code beside this module,
or in the user's cache directory if the package is read-only (or where NUMBA_CACHE_DIR says).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np

from bwr_twin.model.machine import Wheel
from bwr_twin.pile.ground import YARD_FLOOR
from bwr_twin.pile.relaxation import Relaxed, Talus, relax
from bwr_twin.pile.surface import Surface

CELL_MARGIN = 0.5  # m the wheel may move before the cells near it are gathered again


@dataclass
class Cut:
    """What each run's wheel cut in one period; (runs,) or (runs, 3) arrays, zero where it cut nothing."""

    volume: np.ndarray  # m^3 dug
    depth: np.ndarray  # m: how far inside the wheel's circle, along the boom, the material stood
    centroid: np.ndarray  # (runs, 3) world m: the volume-weighted centre of what was cut
    side: np.ndarray  # +1 or -1: which side of the wheel's plane it was cut on (0: both, or none)
    # (runs, 4) the rectangle of cells lowered: first and last row, first and last column (-1: none)
    cells: np.ndarray | None = None


class Cutter:
    """The pile heights of every run of a lockstep, (runs, ny, nx) m, and the cut that lowers them.

    `angle_of_repose` (deg): the faces the cut leaves steeper slump to it (None: they stand);
    `record` keeps every slump's moves, for a layered pile to follow.
    """

    def __init__(self, surface: Surface, wheel: Wheel, runs: int, angle_of_repose: float | None = None,
                 record: bool = False):
        self.surface = surface
        self.wheel = wheel
        self.talus = Talus.of(surface.spacing, angle_of_repose) if angle_of_repose is not None else None
        self.record = record
        self.slumped = np.zeros(runs)  # m^3 each run's faces moved as they slumped (some more than once)
        self.unconverged = np.zeros(runs, dtype=np.int64)  # slumps that ran out of rounds
        self.heights = np.repeat(surface.z[None], runs, axis=0)
        self._x = np.ascontiguousarray(surface.x, dtype=float)
        self._y = np.ascontiguousarray(surface.y, dtype=float)
        top = float(surface.z.max())  # the heights only fall: nothing above this is ever cut
        self._shape = np.array([wheel.radius, wheel.radius**2, wheel.width / 2, wheel.side_slope, top, CELL_MARGIN,
                                float(surface.x[0]), float(surface.y[0]), surface.spacing, surface.cell_area,
                                YARD_FLOOR])
        # Per run, where its wheel was when the cells near it were gathered (NaN: never).
        self._near = np.full((runs, _NEAR), np.nan)
        self._all = np.arange(runs)
        # The period's cut, written in place each period: allocating it anew cost more than the cut.
        self._out = Cut(np.zeros(runs), np.zeros(runs), np.zeros((runs, 3)), np.zeros(runs),
                        np.full((runs, 4), -1, dtype=np.int64))

    def cut(self, cp: np.ndarray, slew: np.ndarray, runs: np.ndarray | None = None) -> Cut:
        """Lower every run's pile to its wheel's envelope, the wheel centred at cp (runs, 3) with
        the boom at `slew` (runs,) rad; only the `runs` given (None: all). The Cut is this
        Cutter's own, written again by its next cut."""
        out = self._out
        order = self._all if runs is None else np.asarray(runs, dtype=np.int64)
        _cut(self.heights, self._x, self._y, np.ascontiguousarray(cp, dtype=float),
             np.ascontiguousarray(slew, dtype=float), order, self._near, self._shape,
             out.volume, out.depth, out.centroid, out.side, out.cells)
        return out

    def slump(self, cut: Cut) -> list[Relaxed | None]:
        """Let the faces `cut` left slump, each run's from the cells its wheel lowered; per run, the
        relaxation (None where nothing was cut). Nothing moves without a talus."""
        if self.talus is None:
            return [None] * len(self.heights)
        return [self._slump(run, cut.cells[run]) if cut.volume[run] > 0 else None for run in range(len(self.heights))]

    def _slump(self, run: int, cells: np.ndarray) -> Relaxed:
        relaxed = relax(self.heights[run], self.talus, record=self.record, region=tuple(cells.tolist()))
        self.slumped[run] += relaxed.moved_volume
        self.unconverged[run] += not relaxed.converged
        return relaxed


# The columns of Cutter._near: the gathering's CP x and y, slew, half-width, and the slew's cos, sin.
_NEAR = 6


@numba.njit(cache=True, error_model="numpy")
def _cut(heights, xs, ys, cp, slews, order, near, shape, volume, depth, centroid, side, lowered):
    """Cutter.cut for the runs in `order`: lowers `heights` and writes the cut's outputs, and in
    `lowered` (runs, 4) the rectangle of the cells it lowered; every run's outputs are first
    cleared (zero, and -1 for `lowered`)."""
    volume[:], depth[:], centroid[:], side[:], lowered[:] = 0.0, 0.0, 0.0, 0.0, -1
    radius, radius2, half_width, side_slope, top, margin = shape[0], shape[1], shape[2], shape[3], shape[4], shape[5]
    x0, y0, h, cell_area, floor = shape[6], shape[7], shape[8], shape[9], shape[10]
    ny, nx = heights.shape[1], heights.shape[2]
    for run in order:
        cx, cy, cz = cp[run, 0], cp[run, 1], cp[run, 2]
        if cz - radius >= top:
            continue
        slew = slews[run]
        # The cells near the wheel: those within a rectangle gathered with a margin, kept while
        # the wheel moves less than the margin, wide enough for the flanks to rise above the top.
        reach = half_width + (top - cz + radius) / side_slope
        g = near[run]
        moved = abs(cx - g[0]) + abs(cy - g[1]) + radius * abs(slew - g[2])
        if not (moved < margin and reach <= g[3]):  # NaN (never gathered) compares False
            g[0], g[1], g[2], g[3], g[4], g[5] = cx, cy, slew, reach + margin, math.cos(slew), math.sin(slew)
        gx, gy, g_width, g_cos, g_sin, g_radius = g[0], g[1], g[3], g[4], g[5], radius + margin
        extent = g_radius * abs(g_sin) + g_width * abs(g_cos)  # the rectangle's half-height in Y
        iy0 = max(int(np.ceil((gy - extent - y0) / h)), 0)
        iy1 = min(int(np.floor((gy + extent - y0) / h)), ny - 1)
        cos, sin = math.cos(slew), math.sin(slew)
        z = heights[run]
        weight = wx = wy = wz = wa = 0.0
        deepest = -np.inf
        row0, row1, column0, column1 = ny, -1, nx, -1
        for iy in range(iy0, iy1 + 1):
            first, last = _columns(ys[iy] - gy, gx - x0, g_cos, g_sin, g_width, g_radius, h, nx)
            y = ys[iy]
            for ix in range(first, last + 1):
                x = xs[ix]
                dx, dy = x - cx, y - cy
                along = dx * cos + dy * sin
                across = dy * cos - dx * sin
                span = radius2 - along * along
                if span < 0.0:  # beyond the wheel's rim along the boom: never cut
                    continue
                envelope = max(abs(across) - half_width, 0.0) * side_slope - math.sqrt(span) + cz
                new = max(envelope, floor)  # a wheel that dips below the pile cuts no ground
                old = z[iy, ix]
                if not old > new:
                    continue
                z[iy, ix] = new
                row0, row1, column0, column1 = min(row0, iy), max(row1, iy), min(column0, ix), max(column1, ix)
                removed = old - new
                weight += removed
                wx += removed * x
                wy += removed * y
                wz += removed * (old + new)
                wa += removed * across
                drop = max(cz - old, 0.0)
                deepest = max(deepest, math.sqrt(max(radius2 - drop * drop, 0.0)) - abs(along))
        if weight == 0.0:
            continue
        volume[run] = weight * cell_area
        lowered[run, 0], lowered[run, 1], lowered[run, 2], lowered[run, 3] = row0, row1, column0, column1
        centroid[run, 0], centroid[run, 1], centroid[run, 2] = wx / weight, wy / weight, wz / (2 * weight)
        depth[run] = max(deepest, 0.0)
        side[run] = np.sign(wa)


@numba.njit(cache=True, error_model="numpy")
def _columns(dy, offset, cos, sin, half_width, radius, h, nx):
    """The first and last column of a row `dy` (m) from the gathering's CP, `offset` (m) from the
    grid's first column, whose centres lie within `half_width` of the wheel's plane and within
    `radius` of its centre along the boom (first > last: none). across = dy cos - dx sin and
    along = dx cos + dy sin: each is |centre - dx slope| <= half, an interval of dx."""
    low, high = -np.inf, np.inf
    for centre, half, slope in ((dy * cos, half_width, sin), (-dy * sin, radius, cos)):
        if abs(slope) < 1e-12:  # dx plays no part: the whole row, or none of it
            if abs(centre) > half:
                low = np.inf
            continue
        a, b = (centre - half) / slope, (centre + half) / slope
        low, high = max(low, min(a, b)), min(high, max(a, b))
    first = max(np.ceil((offset + low) / h), 0.0)
    last = min(np.floor((offset + high) / h), nx - 1.0)
    if not last >= first:
        return 0, -1
    return int(first), int(last)
