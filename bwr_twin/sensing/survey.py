"""The pile each run knows only from its scans: heights on the true pile's grid, filled by hits.

Each hit sets the height of the cell it lands in (the grid point nearest to it: heights are
samples at cell centres, docs/stockpile.md). The hits of one control period that land in one
cell (a scan's neighbouring rays, or two scanners scanning together) set it to their mean: they
measure the same surface at the same moment, so their mean halves the noise of two. A later
period's hits replace the cell's height: the wheel digs the pile, and the latest scan is the pile
as it now stands. A cell no hit has reached is unknown, NaN, never 0: the ground and an unseen
crest are not the same thing. Each cell keeps the time it was last seen and how many hits it took.
"""

from __future__ import annotations

import numba
import numpy as np

from bwr_twin.pile.ground import YARD_FLOOR
from bwr_twin.pile.surface import Surface
from bwr_twin.units import KG_PER_T


class Survey:
    """The scanned piles of a lockstep's runs, on the true pile's grid.

    Attributes:
        z: (runs, ny, nx) m, NaN where unknown.
        seen: (runs, ny, nx) hits each cell has taken.
        last_seen: (runs, ny, nx) s when each cell was last hit, NaN never.
    """

    def __init__(self, surface: Surface, runs: int, most_hits: int):
        """`most_hits`: the most hits a control period may bring (the rays of every scanner)."""
        self.surface = surface
        shape = (runs,) + surface.z.shape
        self.z = np.full(shape, np.nan)
        self.seen = np.zeros(shape, dtype=np.int32)
        self.last_seen = np.full(shape, np.nan)
        self._origin = np.array([float(surface.x[0]), float(surface.y[0]), surface.spacing])
        # The period's hits, summed per cell; shared by the runs, which are added one by one.
        self._sum = np.zeros(surface.z.size)
        self._count = np.zeros(surface.z.size, dtype=np.int32)
        self._touched = np.zeros(most_hits, dtype=np.int64)

    def add(self, time: float, hits: np.ndarray, runs: np.ndarray) -> None:
        """The hits (runs, rays, 3) world m (NaN: none) of one control period at `time` s, for
        the `runs` given."""
        _add(hits, runs, self._origin, time, self.z, self.seen, self.last_seen, self._sum, self._count,
             self._touched)

    def tonnes(self, run: int, truth: np.ndarray, density: float) -> dict:
        """Run `run`'s scanned pile against its true heights `truth` (ny, nx) m (tonnes_against)."""
        return tonnes_against(self.z[run], truth, self.surface.cell_area, density)


def tonnes_against(known: np.ndarray, truth: np.ndarray, cell_area: float, density: float) -> dict:
    """A scanned pile `known` (ny, nx) m, NaN where unknown, against the true heights `truth` on
    the same grid of cells `cell_area` m^2, in tonnes at `density` kg/m^3: `scanned_t` and
    `true_t` over the cells seen, their `error_share` (scanned / true - 1, None without a true
    tonne there), the whole pile's `pile_t`, and the share of its footprint (the cells above the
    yard floor) seen, `footprint_seen_share` (None without a footprint)."""
    seen = ~np.isnan(known)
    per_metre = cell_area * density / KG_PER_T  # t a metre of height on one cell
    scanned = float(np.sum(known[seen] - YARD_FLOOR)) * per_metre
    true = float(np.sum(truth[seen] - YARD_FLOOR)) * per_metre
    footprint = truth > YARD_FLOOR
    area = int(np.count_nonzero(footprint))
    return {
        "scanned_t": scanned,
        "true_t": true,
        "error_share": scanned / true - 1.0 if true > 0 else None,
        "pile_t": float(np.sum(truth - YARD_FLOOR)) * per_metre,
        "footprint_seen_share": int(np.count_nonzero(seen & footprint)) / area if area else None,
    }


@numba.njit(cache=True)
def _add(hits, runs, origin, time, z, seen, last_seen, sums, counts, touched):  # pragma: no cover - compiled
    """Survey.add: each run's hits summed into their cells, then each touched cell set to the mean."""
    x0, y0, h = origin[0], origin[1], origin[2]
    ny, nx = z.shape[1], z.shape[2]
    for run in runs:
        n = 0
        for i in range(hits.shape[1]):
            x = hits[run, i, 0]
            if np.isnan(x):
                continue
            ix = int(np.floor((x - x0) / h + 0.5))
            iy = int(np.floor((hits[run, i, 1] - y0) / h + 0.5))
            if ix < 0 or ix >= nx or iy < 0 or iy >= ny:
                continue
            cell = iy * nx + ix
            if counts[cell] == 0:
                touched[n] = cell
                n += 1
            sums[cell] += hits[run, i, 2]
            counts[cell] += 1
        for j in range(n):
            cell = touched[j]
            iy, ix = cell // nx, cell % nx
            z[run, iy, ix] = sums[cell] / counts[cell]
            seen[run, iy, ix] += counts[cell]
            last_seen[run, iy, ix] = time
            sums[cell] = 0.0
            counts[cell] = 0
