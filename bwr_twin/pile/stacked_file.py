"""A stacked pile's file: the arrays a reclaim takes from a stacking run's pile.npz
(docs/blending.md), checked before they are believed. The layer kernels
(bwr_twin.stockpile.layers) index a column only below its count; these checks hold the counts
within the arrays, and the layers to the heights, as the file is read."""

from __future__ import annotations

import functools
from pathlib import Path

import numpy as np

from bwr_twin.arrays import SCALAR, TEXT, Member, check_real, check_within, first_false, load_npz
from bwr_twin.config.bounds import BULK_DENSITY, PILE_HEIGHT, PILE_HEIGHT_SOURCE
from bwr_twin.errors import SceneError
from bwr_twin.pile.ground import YARD_FLOOR

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
