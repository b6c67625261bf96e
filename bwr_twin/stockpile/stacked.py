"""A stacked pile reclaimed: a stacking run's pile.npz (docs/blending.md) as a reclaim scene's
`stockpile.surface_file`, its layers of grade laid on the reclaim's grid, so that the wheel's cut
takes them (bwr_twin.stockpile.reclaim) and the blend leaving the pile is known.

The reclaim's grid is the stacked one (bwr_twin.stockpile.surface refuses another spacing), with
the spare line of bare ground every surveyed pile gets on each side; the layers are placed cell
for cell, and their columns' sums are the reclaim's heights.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from bwr_twin.arrays import SCALAR, TEXT, Member, check_real, check_within, first_false, load_npz
from bwr_twin.config.bounds import BULK_DENSITY, PILE_HEIGHT, PILE_HEIGHT_SOURCE
from bwr_twin.errors import SceneError
from bwr_twin.stockpile.grade import tonne_weighted
from bwr_twin.stockpile.layers import LayeredPile
from bwr_twin.stockpile.surface import YARD_FLOOR, Surface

# The layers of a stacked pile, each (ny, nx, max_layers) float64: a pile of 1e6 cells of 64
# layers takes 512 MB, and every run of a reclaim keeps a copy. 1 GiB is a stacking far beyond
# any yard's (the heavy scenes' pile: 3,751 cells).
MAX_LAYER_BYTES = 1 << 30
_LINES = Member(shape=(None,), max_bytes=MAX_LAYER_BYTES)
_GRID = Member(shape=(None, None), max_bytes=MAX_LAYER_BYTES)
_LAYERS = Member(shape=(None, None, None), max_bytes=MAX_LAYER_BYTES)
# What read_stacked takes from a pile.npz: the rest (the frames, the deposits' times and points) is
# for the replay, and never read here.
SPEC = {"x": _LINES, "y": _LINES, "z_end": _GRID, "layer_thickness": _LAYERS, "layer_grade": _LAYERS,
        "layer_count": Member("iu", (None, None), MAX_LAYER_BYTES), "deposit_grade": _LINES, "deposit_tonnes": _LINES,
        "bulk_density": SCALAR, "grade_name": TEXT, "layers": Member("iu", ()),
        "grade_band": Member(shape=(2,), required=False), "equivalent_layers": Member(shape=(), required=False),
        "pattern": Member("U", (), 4096, required=False)}
HEIGHT_TOLERANCE = 1e-6  # m: a column's layers sum to its height to rounding (1e-13 m measured)


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


def stacked_arrays(file: Path, where: str) -> dict[str, np.ndarray]:
    """The arrays of the stacked pile in `file` that a reclaim uses, checked (`check_layers`);
    `where` names the file in a SceneError."""
    return _arrays(file, file.stat().st_mtime_ns, where)


@functools.lru_cache(maxsize=2)
def _arrays(file: Path, stamp: int, where: str) -> dict[str, np.ndarray]:
    """The file's arrays, read once while it is unchanged (`stamp`: its mtime)."""
    arrays = load_npz(file, SPEC, what=where, error=SceneError,
                      missing=": a stacked pile's file holds it; stack it again with this version of the twin")
    check_layers(arrays, where)
    return arrays


def check_layers(arrays: dict[str, np.ndarray], where: str) -> None:
    """SceneError, naming the array and the limit, unless a stacked pile's arrays (as SPEC reads
    them) agree: the layers' shapes with the grid, each count within its column's room, the
    layers within a count of positive thickness and finite grade and those above it empty, the
    columns' sums the heights z_end, the deposits' tonnes and grades one a deposit. The layer
    kernels (bwr_twin.stockpile.layers) index a column only below its count: these checks hold
    them within the arrays."""
    x, y, z, thickness, grade, count = (arrays[k] for k in ("x", "y", "z_end", "layer_thickness", "layer_grade",
                                                             "layer_count"))
    for key, array in (("x", x), ("y", y), ("z_end", z), ("layer_thickness", thickness), ("layer_grade", grade)):
        check_real(where, key, array, SceneError)
    grid = (len(y), len(x))
    for key, array in (("z_end", z), ("layer_count", count)):
        if array.shape != grid:
            raise SceneError(f"{where}: array '{key}' has the shape {array.shape}; the grid lines x, y make it "
                             f"{grid}")
    if thickness.shape[:2] != grid or grade.shape != thickness.shape or thickness.shape[2] < 2:
        raise SceneError(f"{where}: arrays 'layer_thickness' {thickness.shape} and 'layer_grade' {grade.shape} "
                         f"must both be (len(y), len(x), max_layers) = ({grid[0]}, {grid[1]}, max_layers), "
                         "max_layers >= 2")
    room = thickness.shape[2]
    check_within(where, "layer_count", count, 0, room, f"a column holds 0 to the {room} layers it has room for",
                 SceneError)
    held = np.arange(room) < count[..., None]
    for key, ok, rule in (("layer_thickness", np.where(held, thickness > 0, thickness == 0),
                           "> 0 m in each of a column's 'layer_count' layers, 0 above them"),
                          ("layer_grade", held | (grade == 0), "0 above a column's 'layer_count' layers")):
        at = first_false(ok)
        if at is not None:
            raise SceneError(f"{where}: array '{key}' holds {arrays[key][at]:g} at {list(at)} with 'layer_count' "
                             f"{count[at[:2]]} there; it must be {rule}")
    check_within(where, "z_end", z, *PILE_HEIGHT, PILE_HEIGHT_SOURCE, SceneError)
    at = first_false(np.abs(YARD_FLOOR + thickness.sum(axis=2) - z) <= HEIGHT_TOLERANCE)
    if at is not None:
        raise SceneError(f"{where}: array 'z_end' holds {z[at]:g} m at {list(at)}, but the layers there sum to "
                         f"{YARD_FLOOR + thickness[at].sum():g} m: a column's height is its layers' thickness "
                         f"(to {HEIGHT_TOLERANCE:g} m)")
    tonnes, grades = arrays["deposit_tonnes"], arrays["deposit_grade"]
    if tonnes.shape != grades.shape:
        raise SceneError(f"{where}: arrays 'deposit_tonnes' {tonnes.shape} and 'deposit_grade' {grades.shape} "
                         "must hold one value a deposit each")
    check_real(where, "deposit_grade", grades, SceneError)
    check_within(where, "deposit_tonnes", tonnes, 0, np.inf, "a deposit's tonnes are >= 0", SceneError)
    check_within(where, "bulk_density", arrays["bulk_density"], *BULK_DENSITY,
                 "kg/m3, from wood chips to lead ore, CEMA's table of bulk materials", SceneError)
    check_within(where, "layers", arrays["layers"], 1, np.inf, "a stacking lays at least one layer", SceneError)
    if "equivalent_layers" in arrays and not np.isnan(arrays["equivalent_layers"]):  # NaN: cone shells
        check_within(where, "equivalent_layers", arrays["equivalent_layers"], 0, np.inf,
                     "the law's N for the passes, or NaN for cone shells", SceneError)
    if "grade_band" in arrays:
        check_real(where, "grade_band", arrays["grade_band"], SceneError)
        if not arrays["grade_band"][0] < arrays["grade_band"][1]:
            raise SceneError(f"{where}: array 'grade_band' {list(arrays['grade_band'])} must be [low, high], "
                             "low < high")
