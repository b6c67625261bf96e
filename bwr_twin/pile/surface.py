"""A stockpile's surface as heights on a regular grid, built from a scene's [stockpile].

A windrow is built from its crest, height and angle of repose; a surveyed surface is read from
a height grid (.npz) or from x, y, z points (.csv) and gridded on load. Heights are metres above
the yard floor (world Z = 0); the ground around the pile is at 0.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from bwr_twin.arrays import Member, check_within, first_false, load_npz, npz_keys, read_lines
from bwr_twin.config.bounds import PILE_HEIGHT, PILE_HEIGHT_SOURCE
from bwr_twin.config.sections import StockpileSection, WindrowSection
from bwr_twin.errors import SceneError
from bwr_twin.pile.ground import YARD_FLOOR
from bwr_twin.pile.stacked_file import stacked_arrays
from bwr_twin.values import reads_as_number

MAX_CELLS = 20_000_000  # 160 MB a run of float64 heights: a bigger grid is a typo in grid_spacing
STACKED_KEY = "layer_thickness"  # the array that makes a pile.npz a stacked pile's (bwr_twin.stockpile.stacked)
# The fewest grid cells across a pile's footprint, both ways. Sampled 8 cells across, a windrow of
# 37 deg flanks keeps its volume within 1.7 % (measured: within 0.9 % at 10 cells, but 6.4 % off at
# 4 and 24 % at 2), better than the 5-15 % of a manual survey; a coarser grid samples the pile to a
# few posts, or to nothing, and the reclaimed tonnage with it.
MIN_CELLS_ACROSS = 8
# The most points a .csv survey may hold: 1,000,000 points sample a 250 x 250 m yard every 0.25 m.
# Every point is parsed and triangulated (3,000,000 took 2.4 GB and minutes): thin a denser cloud.
MAX_SURVEY_POINTS = 1_000_000
MAX_SURVEY_BYTES = 100 * MAX_SURVEY_POINTS  # 100 characters a row of x,y,z
_GRID = Member(shape=(None,), max_bytes=8 * MAX_CELLS)  # a survey's grid lines, m
_HEIGHTS = Member(shape=(None, None), max_bytes=8 * MAX_CELLS)  # its heights: at most MAX_CELLS of them


@dataclass(frozen=True, eq=False)
class Surface:
    """Heights z[iy, ix] (m) at the grid lines x[ix], y[iy] (m), spaced evenly."""

    x: np.ndarray
    y: np.ndarray
    z: np.ndarray

    @property
    def spacing(self) -> float:
        return float(self.x[1] - self.x[0])

    @property
    def cell_area(self) -> float:
        """m^2 each height sample stands for."""
        return self.spacing**2

    def volume(self, z: np.ndarray | None = None) -> float:
        """m^3 of material above the floor, for these heights or for `z` on the same grid."""
        return float(np.sum(self.z if z is None else z) * self.cell_area)


def build_surface(section: StockpileSection, scene_path: Path) -> Surface:
    """The surface a scene's [stockpile] describes. Raises SceneError naming the file and key."""
    if section.windrow is not None:
        return windrow(section.windrow, section.grid_spacing, scene_path)
    return surveyed(section.surface_file, section.grid_spacing, scene_path)


def cell_count(section: StockpileSection, scene_path: Path) -> int:
    """How many heights a run's pile holds: from the section alone for a windrow, from the
    (cached) gridded file for a survey."""
    if section.windrow is None:
        return build_surface(section, scene_path).z.size
    (x_low, x_high), (y_low, y_high) = _windrow_extent(section.windrow)
    spacing = section.grid_spacing
    _check_sampling(x_high - x_low, y_high - y_low, spacing, "the windrow's footprint", scene_path)
    return _line_count(x_low, x_high, spacing) * _line_count(y_low, y_high, spacing)


def _line_count(low: float, high: float, spacing: float) -> int:
    """Grid lines from `low` to at least `high`, with one spare line of ground on each side."""
    return int(np.ceil((high - low) / spacing)) + 3


def _grid_lines(low: float, high: float, spacing: float) -> np.ndarray:
    return low - spacing + np.arange(_line_count(low, high, spacing)) * spacing


def _check_size(nx: int, ny: int, scene_path: Path) -> None:
    if nx * ny > MAX_CELLS:
        raise SceneError(
            f"{scene_path}: 'stockpile.grid_spacing' gives {nx} x {ny} = {nx * ny:.3g} height samples, "
            f"more than {MAX_CELLS:.0e}: choose a coarser grid"
        )


def _check_sampling(length: float, width: float, spacing: float, what: str, scene_path: Path) -> None:
    """SceneError unless `spacing` puts MIN_CELLS_ACROSS cells across the pile both ways."""
    narrow = min(length, width)
    if narrow < MIN_CELLS_ACROSS * spacing:
        raise SceneError(
            f"{scene_path}: 'stockpile.grid_spacing' {spacing:g} m gives {narrow / spacing:.2g} cells across "
            f"{what} of {length:.4g} x {width:.4g} m (X x Y), fewer than {MIN_CELLS_ACROSS}: too coarse to "
            f"sample the pile (its volume within 2 %); choose at most {narrow / MIN_CELLS_ACROSS:.3g} m"
        )


def _windrow_extent(w: WindrowSection) -> tuple[tuple[float, float], tuple[float, float]]:
    """(X range, Y range) of a windrow's footprint, m: the crest and a flank's run each side."""
    spread = w.height / np.tan(np.radians(w.angle_of_repose))
    cx, cy = w.centre
    half_x, half_y = w.length / 2, w.crest_width / 2
    return (cx - half_x - spread, cx + half_x + spread), (cy - half_y - spread, cy + half_y + spread)


def windrow(w: WindrowSection, spacing: float, scene_path: Path) -> Surface:
    """A windrow: z = height - tan(repose) x (distance outside the crest rectangle along X or Y,
    whichever is larger), at least 0: planar flanks, hipped ends."""
    xs, ys = _windrow_extent(w)
    _check_sampling(xs[1] - xs[0], ys[1] - ys[0], spacing, "the windrow's footprint", scene_path)
    _check_size(_line_count(*xs, spacing), _line_count(*ys, spacing), scene_path)
    x, y = _grid_lines(*xs, spacing), _grid_lines(*ys, spacing)
    cx, cy = w.centre
    outside_x = np.maximum(np.abs(x - cx) - w.length / 2, 0.0)
    outside_y = np.maximum(np.abs(y - cy) - w.crest_width / 2, 0.0)
    slope = np.tan(np.radians(w.angle_of_repose))
    z = np.clip(w.height - slope * np.maximum(outside_x[None, :], outside_y[:, None]), 0.0, None)
    return Surface(x, y, z)


def surveyed(file: Path, spacing: float, scene_path: Path) -> Surface:
    """A surveyed surface, regridded at `spacing` (bilinear from a grid, linear between points)."""
    return _surveyed(Path(file), spacing, scene_path, file.stat().st_mtime_ns)


@functools.lru_cache(maxsize=4)
def _surveyed(file: Path, spacing: float, scene_path: Path, stamp: int) -> Surface:
    from scipy.interpolate import RegularGridInterpolator, griddata  # a second to import: only for surveys

    where = f"{scene_path}: 'stockpile.surface_file' {file}"
    if file.suffix == ".npz":
        xs, ys, zs = _read_npz(file, where)
        if STACKED_KEY in npz_keys(file) and not math.isclose(xs[1] - xs[0], spacing, rel_tol=1e-9):
            raise SceneError(f"{where}: a stacked pile is reclaimed on the grid it was stacked on, its layers "
                             f"cell by cell: 'stockpile.grid_spacing' must be its {xs[1] - xs[0]:g} m, got {spacing:g} m")
    elif file.suffix == ".csv":
        xs, ys, zs = _read_points(file, where)
    else:
        raise SceneError(f"{where}: must be a .npz height grid or a .csv of x,y,z points")
    _check_sampling(*_pile_extent(xs, ys, zs, where), spacing, "the surveyed pile", scene_path)
    _check_size(_line_count(xs.min(), xs.max(), spacing), _line_count(ys.min(), ys.max(), spacing), scene_path)
    x = _grid_lines(xs.min(), xs.max(), spacing)
    y = _grid_lines(ys.min(), ys.max(), spacing)
    gx, gy = np.meshgrid(x, y)
    if zs.ndim == 2:
        interpolate = RegularGridInterpolator((ys, xs), zs, bounds_error=False, fill_value=0.0)
        z = interpolate(np.stack([gy, gx], axis=-1))
    else:
        z = griddata(np.column_stack([xs, ys]), zs, (gx, gy), method="linear", fill_value=0.0)
    return Surface(x, y, np.clip(z, YARD_FLOOR, None))


def _pile_extent(xs: np.ndarray, ys: np.ndarray, zs: np.ndarray, where: str) -> tuple[float, float]:
    """(X, Y) extent, m, of the region a survey's interpolation raises above the yard floor: from
    its grid lines and (len(ys), len(xs)) heights, the rows and columns holding a height and one
    beyond, where its flanks reach the floor; from points, the triangles with a corner above it."""
    from scipy.spatial import Delaunay  # griddata interpolates on the same triangulation

    above = zs > YARD_FLOOR
    if not above.any():
        raise SceneError(f"{where}: holds no height above the yard floor (Z = {YARD_FLOOR:g} m): "
                         "there is no pile")
    if zs.ndim == 2:
        extents = []
        for lines, held in ((xs, above.any(axis=0)), (ys, above.any(axis=1))):
            index = np.flatnonzero(held)
            low, high = max(index[0] - 1, 0), min(index[-1] + 1, len(lines) - 1)
            extents.append(float(lines[high] - lines[low]))
        return extents[0], extents[1]
    simplices = Delaunay(np.column_stack([xs, ys])).simplices
    corners = np.unique(simplices[above[simplices].any(axis=1)])
    return float(np.ptp(xs[corners])), float(np.ptp(ys[corners]))


def is_stacked_pile(file: Path | None) -> bool:
    """Whether `file` is a stacking run's pile.npz, its layers of grade in it (docs/blending.md)."""
    return file is not None and Path(file).suffix == ".npz" and STACKED_KEY in npz_keys(Path(file))


def _read_npz(file: Path, where: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    keys = npz_keys(file)
    if STACKED_KEY in keys:  # a stacked pile: its layers are checked against its heights before any use
        stacked_arrays(file, where)
    heights = "z_end" if STACKED_KEY in keys and "z" not in keys else "z"  # a stacked pile as it ended
    arrays = load_npz(file, {"x": _GRID, "y": _GRID, heights: _HEIGHTS}, what=where, error=SceneError,
                      missing=" (x, y: grid lines in m; z: heights in m)")
    x, y, z = (np.asarray(arrays[key], dtype=float) for key in ("x", "y", heights))
    if x.ndim != 1 or y.ndim != 1 or z.shape != (len(y), len(x)) or len(x) < 2 or len(y) < 2:
        raise SceneError(f"{where}: z must be a (len(y), len(x)) grid of at least 2 x 2, got z {z.shape}, "
                         f"x {x.shape}, y {y.shape}")
    if not (np.all(np.diff(x) > 0) and np.all(np.diff(y) > 0)):
        raise SceneError(f"{where}: x and y must increase")
    _check_finite(where, x, y, z)
    check_within(where, heights, z, *PILE_HEIGHT, PILE_HEIGHT_SOURCE, SceneError)
    return x, y, z


def _read_points(file: Path, where: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    lines = read_lines(file, what=where, max_rows=MAX_SURVEY_POINTS + 1, max_bytes=MAX_SURVEY_BYTES,
                       error=SceneError,
                       why=f": a survey of at most {MAX_SURVEY_POINTS:,} points and a header (thin the cloud)")
    rows = [line for line in lines if line.strip() and not line.lstrip().startswith("#")]
    if rows and not reads_as_number(rows[0].split(",")[0]):
        rows = rows[1:]  # a header line
    points = []
    for number, line in enumerate(rows, start=1):
        cells = line.split(",")
        if len(cells) != 3 or not all(reads_as_number(c) for c in cells):
            raise SceneError(f"{where}: data row {number} must be three numbers x,y,z (m), got {line.strip()!r}")
        points.append([float(c) for c in cells])
    if len(points) < 3:
        raise SceneError(f"{where}: needs at least 3 points, got {len(points)}")
    xs, ys, zs = np.array(points).T
    _check_finite(where, xs, ys, zs)
    low, high = PILE_HEIGHT
    row = first_false((zs >= low) & (zs <= high))
    if row is not None:
        raise SceneError(f"{where}: data row {row[0] + 1}: z {zs[row]:g} m lies outside [{low:g}, {high:g}] "
                         f"({PILE_HEIGHT_SOURCE})")
    if np.ptp(xs) == 0 or np.ptp(ys) == 0:
        raise SceneError(f"{where}: the points lie on a line: they span no area")
    return xs, ys, zs


def _check_finite(where: str, *arrays: np.ndarray) -> None:
    for name, array in zip("xyz", arrays):
        if not np.all(np.isfinite(array)):
            raise SceneError(f"{where}: {name} holds a value that is not a finite number")
