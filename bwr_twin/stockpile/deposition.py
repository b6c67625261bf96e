"""Deposition at a discharge point: a stream of t/h falling at (x, y) for one control period.

The period's tonnes, over the uniform bulk density, are laid on the four cells whose centres
surround the point, weighted bilinearly (the weights sum to one), as a new layer of the stream's
grade, and the pile then relaxes to the angle of repose. Bilinear, not the one cell under the
point: a discharge point moving with the stacker then lays its material continuously instead of
jumping from cell to cell, and the footprint's centroid is the point itself. Deposited long enough
at one point, the material grows a cone at the angle of repose (an octagonal one on the grid,
bwr_twin.pile.relaxation).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bwr_twin.pile.relaxation import DEFAULT_MAX_ROUNDS, DEFAULT_TOLERANCE, Relaxed, Talus
from bwr_twin.pile.surface import Surface
from bwr_twin.stockpile.layers import LayeredPile
from bwr_twin.stockpile.material import Material
from bwr_twin.units import SECONDS_PER_HOUR


@dataclass(frozen=True)
class Deposited:
    """What one discharge laid: `volume` m^3 (`tonnes` t) and the relaxation that followed."""

    tonnes: float
    volume: float
    relaxed: Relaxed


def footprint(grid: LayeredPile | Surface, x: float, y: float) -> np.ndarray:
    """(ny, nx) bilinear weights, summing to one, of the four cells of `grid` (its lines x, y)
    around the point (x, y) m. Raises ValueError if the point lies outside the grid's lines."""
    iy, ix, corners = _corners(grid, x, y)
    weights = np.zeros((len(grid.y), len(grid.x)))
    weights[iy:iy + 2, ix:ix + 2] = corners
    return weights


def height_under(grid: LayeredPile | Surface, x: float, y: float) -> float:
    """m: the pile's height at (x, y), bilinear between the four cells around it (the deposit's
    own weights). Raises ValueError if the point lies outside the grid's lines."""
    iy, ix, corners = _corners(grid, x, y)
    return float(np.sum(corners * grid.z[iy:iy + 2, ix:ix + 2]))


def discharge(pile: LayeredPile, x: float, y: float, rate: float, period: float, grade: float,
              material: Material, tolerance: float = DEFAULT_TOLERANCE,
              max_rounds: int = DEFAULT_MAX_ROUNDS) -> Deposited:
    """Lay `rate` t/h of `material` at `grade` for `period` s at the point (x, y) m, then relax
    the pile to the material's angle of repose (to `tolerance` m, in at most `max_rounds`)."""
    if not rate >= 0 or not period >= 0:
        raise ValueError(f"a discharge's rate (t/h) and period (s) must be >= 0, got {rate} and {period}")
    tonnes = rate * period / SECONDS_PER_HOUR
    volume = material.volume(tonnes)
    pile.deposit(footprint(pile, x, y) * (volume / pile.cell_area), grade)
    talus = Talus.of(pile.spacing, material.angle_of_repose, tolerance)
    return Deposited(tonnes, volume, pile.relax(talus, max_rounds))


def _corners(grid: LayeredPile | Surface, x: float, y: float) -> tuple[int, int, np.ndarray]:
    """The row and column of the cell at or below and left of (x, y) m, and the (2, 2) bilinear
    weights of it and its three neighbours above and right, summing to one."""
    ix, fx = _cell(grid.x, x, "x")
    iy, fy = _cell(grid.y, y, "y")
    return iy, ix, np.array([[(1 - fx) * (1 - fy), fx * (1 - fy)], [(1 - fx) * fy, fx * fy]])


def _cell(lines: np.ndarray, value: float, axis: str) -> tuple[int, float]:
    """The index of the grid line at or below `value` (at most the last but one) and the fraction
    of a spacing beyond it."""
    if not lines[0] <= value <= lines[-1]:
        raise ValueError(f"the discharge point's {axis} = {value:g} m lies outside the pile's grid "
                         f"({lines[0]:g} to {lines[-1]:g} m)")
    spacing = lines[1] - lines[0]
    index = min(int((value - lines[0]) // spacing), len(lines) - 2)
    return index, min(max((value - lines[index]) / spacing, 0.0), 1.0)
