"""A stacked pile reclaimed: a stacking run's pile.npz (docs/blending.md) as a reclaim scene's
`stockpile.surface_file`, its layers of grade laid on the reclaim's grid, so that the wheel's cut
takes them (bwr_twin.stockpile.reclaim) and the blend leaving the pile is known.

The reclaim's grid is the stacked one (bwr_twin.pile.surface refuses another spacing), with
the spare line of bare ground every surveyed pile gets on each side; the layers are placed cell
for cell, and their columns' sums are the reclaim's heights.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

from bwr_twin.errors import SceneError
from bwr_twin.pile.stacked_file import stacked_arrays
from bwr_twin.pile.surface import Surface
from bwr_twin.stockpile.grade import tonne_weighted
from bwr_twin.stockpile.layers import LayeredPile


@dataclass(frozen=True)
class StackedPile:
    """What a stacked pile brings to its reclaim.

    Attributes:
        pile: its layers on the reclaim's grid (a template: each run takes a copy).
        bulk_density: kg/m^3 it was stacked at.
        grade_name: what its grade is ("Fe %"); `band` the grade its customer accepts, or None.
        grade_in_mean, grade_in_sd: the tonne-weighted grade of what was stacked, and its spread.
        layers: the scene's `layers` it was stacked in; equivalent_layers the law's N for its
            passes (NaN for cone shells; a file from before the patterns, a chevron's: `layers`);
            pattern the scene's.
    """

    pile: LayeredPile
    bulk_density: float
    grade_name: str
    band: tuple[float, float] | None
    grade_in_mean: float
    grade_in_sd: float
    layers: int
    equivalent_layers: float
    pattern: str


def read_stacked(file: Path, surface: Surface, scene_path: Path) -> StackedPile:
    """The stacked pile in `file` on `surface`'s grid (the reclaim's, built from the same file)."""
    file = Path(file)
    where = f"{scene_path}: 'stockpile.surface_file' {file}"
    arrays = stacked_arrays(file, where)
    x, y, thickness = arrays["x"], arrays["y"], arrays["layer_thickness"]
    spacing = surface.spacing
    ix, iy = round((x[0] - surface.x[0]) / spacing), round((y[0] - surface.y[0]) / spacing)
    ny, nx = thickness.shape[:2]
    if not (0 <= ix and ix + nx <= len(surface.x) and 0 <= iy and iy + ny <= len(surface.y)
            and math.isclose(surface.x[ix], x[0], abs_tol=1e-6 * spacing)):
        raise SceneError(f"{where}: its grid does not lie on the reclaim's")
    pile = LayeredPile(surface.x, surface.y, thickness.shape[2])
    pile.thickness[iy:iy + ny, ix:ix + nx] = thickness
    pile.grade[iy:iy + ny, ix:ix + nx] = arrays["layer_grade"]
    pile.count[iy:iy + ny, ix:ix + nx] = arrays["layer_count"]
    pile.z[:] = surface.z  # the columns' sums, to rounding: the cut reads one, the layers follow
    tonnes, grades = arrays["deposit_tonnes"], arrays["deposit_grade"]
    mean, sd = tonne_weighted(tonnes, grades)
    band = tuple(float(v) for v in arrays["grade_band"]) if "grade_band" in arrays else None
    return StackedPile(pile, float(arrays["bulk_density"]), str(arrays["grade_name"]), band, mean, sd,
                       int(arrays["layers"]), float(arrays.get("equivalent_layers", arrays["layers"])),
                       str(arrays.get("pattern", "chevron")))
