"""The cut: every control period, each run's wheel lowers the pile to its cutting envelope.

The envelope is the wheel's disc at the CP, in the vertical plane of the boom (the slew
direction), as wide as the buckets: a cell whose centre lies within half the width of that
plane and within the disc's span along the boom is lowered to the disc's lower rim. Beside the
width, the envelope's flanks rise at SIDE_SLOPE: with vertical flanks a slewing wheel would take
a whole column of cells in one period and the rate would be a train of spikes a cell apart; with
flanks a few cells wide, cells are lowered a little each period, and the same material is cut,
a little earlier. The heights only ever fall, so the volume the pile loses is exactly the sum of
the volumes cut.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bwr_twin.model.machine import Wheel
from bwr_twin.stockpile.surface import YARD_FLOOR, Surface

CELL_MARGIN = 0.5  # m the wheel may move before the cells near it are gathered again
SIDE_SLOPE = 6.0  # rise (m) per metre beside the wheel's width of the envelope's flanks (80.5 deg)


@dataclass
class Cut:
    """What each run's wheel cut in one period; (runs,) or (runs, 3) arrays, zero where it cut nothing."""

    volume: np.ndarray  # m^3 dug
    depth: np.ndarray  # m: how far inside the wheel's circle, along the boom, the material stood
    centroid: np.ndarray  # (runs, 3) world m: the volume-weighted centre of what was cut
    side: np.ndarray  # +1 or -1: which side of the wheel's plane it was cut on (0: both, or none)


class Cutter:
    """The pile heights of every run of a lockstep, (runs, ny, nx) m, and the cut that lowers them."""

    def __init__(self, surface: Surface, wheel: Wheel, runs: int):
        self.surface = surface
        self.wheel = wheel
        self.heights = np.repeat(surface.z[None], runs, axis=0)
        self._top = float(surface.z.max())  # the heights only fall: nothing above this is ever cut
        self._x0, self._y0, self._h = float(surface.x[0]), float(surface.y[0]), surface.spacing
        self._nx, self._ny = len(surface.x), len(surface.y)
        self._near: list[tuple | None] = [None] * runs  # per run: the cells near its wheel, and where it was

    def cut(self, cp: np.ndarray, slew: np.ndarray, runs: np.ndarray | None = None) -> Cut:
        """Lower every run's pile to its wheel's envelope, the wheel centred at cp (runs, 3) with
        the boom at `slew` (runs,) rad; only the `runs` given (None: all)."""
        count = len(self.heights)
        out = Cut(np.zeros(count), np.zeros(count), np.zeros((count, 3)), np.zeros(count))
        radius, half_width = self.wheel.radius, self.wheel.width / 2
        for run in range(count) if runs is None else runs:
            cx, cy, cz = cp[run]
            if cz - radius >= self._top:
                continue
            cells = self._cells_near(run, cx, cy, slew[run], half_width + (self._top - cz + radius) / SIDE_SLOPE)
            if cells is None:
                continue
            flat, x, y = cells
            cos, sin = np.cos(slew[run]), np.sin(slew[run])
            dx, dy = x - cx, y - cy
            along = dx * cos + dy * sin
            across = dy * cos - dx * sin
            envelope = np.abs(across)
            envelope -= half_width
            np.maximum(envelope, 0.0, out=envelope)
            envelope *= SIDE_SLOPE
            span = radius**2 - along * along
            outside = span < 0.0  # beyond the wheel's rim along the boom: never cut
            np.maximum(span, 0.0, out=span)
            envelope -= np.sqrt(span, out=span)
            envelope += cz
            np.maximum(envelope, YARD_FLOOR, out=envelope)  # a wheel that dips below the pile cuts no ground
            envelope[outside] = np.inf
            z = self.heights[run].reshape(-1)  # a view: the run's heights, row by row
            old = z[flat]
            cutting = np.flatnonzero(old > envelope)
            if not cutting.size:
                continue
            flat, along, across, old, new = flat[cutting], along[cutting], across[cutting], old[cutting], envelope[cutting]
            z[flat] = new
            removed = old - new
            weight = removed.sum()
            out.volume[run] = weight * self.surface.cell_area
            out.centroid[run] = (
                np.dot(removed, x[cutting]) / weight,
                np.dot(removed, y[cutting]) / weight,
                np.dot(removed, old + new) / (2 * weight),
            )
            drop = np.maximum(cz - old, 0.0)
            rim = np.sqrt(np.maximum(radius**2 - drop * drop, 0.0))
            out.depth[run] = max(float(np.max(rim - np.abs(along))), 0.0)
            out.side[run] = np.sign(np.dot(removed, across))
        return out

    def _cells_near(self, run: int, cx: float, cy: float, slew: float, half_width: float):
        """The cells that may lie under run's wheel: (flat indices, x, y of their centres), or
        None. They are gathered with a margin of CELL_MARGIN and kept while the wheel moves
        less than that margin, so most periods only compute their distances to the wheel."""
        kept = self._near[run]
        if kept is not None:
            x0, y0, slew0, width0, cells = kept
            moved = abs(cx - x0) + abs(cy - y0) + self.wheel.radius * abs(slew - slew0)
            if moved < CELL_MARGIN and half_width <= width0:
                return cells
        width = half_width + CELL_MARGIN
        flat = self._cells_under(np.array([cx, cy]), slew, width, self.wheel.radius + CELL_MARGIN)
        cells = None if flat is None else (flat, self.surface.x[flat % self._nx], self.surface.y[flat // self._nx])
        self._near[run] = (cx, cy, slew, width, cells)
        return cells

    def _cells_under(self, cp: np.ndarray, slew: float, half_width: float, radius: float) -> np.ndarray | None:
        """Flat indices of the grid cells whose centres lie within `half_width` of the wheel's
        plane and within `radius` of its centre along the boom, or None. Row by row, such cells
        form one interval of columns, so only they are visited."""
        h = self._h
        cos, sin = float(np.cos(slew)), float(np.sin(slew))
        extent = radius * abs(sin) + half_width * abs(cos)  # the rectangle's half-height in Y
        iy0 = max(int(np.ceil((cp[1] - extent - self._y0) / h)), 0)
        iy1 = min(int(np.floor((cp[1] + extent - self._y0) / h)), self._ny - 1)
        if iy0 > iy1:
            return None
        dy = self.surface.y[iy0 : iy1 + 1] - cp[1]
        low, high = -np.inf, np.inf
        # across = dy cos - dx sin and along = dx cos + dy sin: each is |centre - dx slope| <= half.
        for centre, half, slope in ((dy * cos, half_width, sin), (-dy * sin, radius, cos)):
            if abs(slope) < 1e-12:  # dx plays no part: the whole row, or none of it
                low = np.where(np.abs(centre) > half, np.inf, low)
                continue
            a, b = (centre - half) / slope, (centre + half) / slope
            low, high = np.maximum(low, np.minimum(a, b)), np.minimum(high, np.maximum(a, b))
        first = np.maximum(np.ceil((cp[0] - self._x0 + low) / h), 0.0)
        last = np.minimum(np.floor((cp[0] - self._x0 + high) / h), self._nx - 1.0)
        counts = np.maximum(last - first + 1.0, 0.0).astype(np.int64)
        total = int(counts.sum())
        if total == 0:
            return None
        row = np.repeat(np.arange(iy0, iy1 + 1), counts)
        col = np.repeat(first.astype(np.int64) - np.cumsum(counts) + counts, counts) + np.arange(total)
        return row * self._nx + col
