"""Rays against a pile's height grid, meeting it where MuJoCo's `mj_ray` meets the pile's hfield.

The surface is the hfield's (MuJoCo's src/engine/engine_ray.c, `mj_rayHfield`): the heights
z[r, c] stand at grid points (x[c], y[r]), and each cell (r, c) is two planar triangles split
along its diagonal from (c, r) to (c + 1, r + 1): {(c, r), (c + 1, r + 1), (c + 1, r)} and
{(c, r), (c + 1, r + 1), (c, r + 1)}. MuJoCo tests the triangles of every cell in the rectangle
the ray's segment through the hfield's top box spans; here a walk (a 2D DDA) visits only the cells
the ray's projection crosses, in order along the ray, and stops at the first cell that holds a
hit: the nearest, since a later cell's points lie farther along the ray. A cell the ray passes
above (its lowest point over the cell above the cell's highest corner) is skipped untested.
MuJoCo also meets the hfield box's sides and base, which a ray from above that hits the surface
never reaches first; the pile's grid has a border of ground (bwr_twin.pile.surface), so its
sides stand 0 m high. `tests/test_sensing.py` checks every distance against `mj_ray`.

The rays of one scan of a profile scanner whose fan stands in a vertical plane share one section
of the pile: cut along the plane, it is a polyline, and rays taken outwards from the vertical meet
it ever farther out, so one pass along it would serve the whole fan. The section is never built:
a walk begun at `begin` serves instead. A scan (bwr_twin.sensing.scanning) begins each ray's walk
where the ray below it met the pile, and so walks the section about once; a ray of a fan tilted
out of the vertical, or any other, walks from where it enters the pile's box. One kernel, checked
against MuJoCo, serves both.

MuJoCo holds hfield heights as float32 (data x size[2]); these kernels take the heights as given,
so a comparison rounds them the same way first. Distances are metres along unit directions.

The kernels are compiled with numba and cached beside this module, as the cut is.
"""

from __future__ import annotations

import math

import numba
import numpy as np

# Cell units (a fraction of the grid spacing) a hit may lie outside its triangle and still count:
# a hit on an edge shared by two triangles is found in one of them, whatever the rounding.
EDGE_TOLERANCE = 1e-10


def cast_rays(heights: np.ndarray, x: np.ndarray, y: np.ndarray, origins: np.ndarray, directions: np.ndarray,
              max_range: float = np.inf) -> np.ndarray:
    """Distances (m) from `origins` (n, 3) along unit `directions` (n, 3) to the surface of the
    heights z[iy, ix] (m) at grid lines x[ix], y[iy] (evenly spaced, m); (n,), NaN where a ray
    misses the grid's surface or meets it beyond `max_range` m."""
    heights = np.ascontiguousarray(heights, dtype=float)
    origins = np.ascontiguousarray(origins, dtype=float).reshape(-1, 3)
    directions = np.ascontiguousarray(directions, dtype=float).reshape(-1, 3)
    grid = grid_of(x, y, heights)
    out = np.empty(len(origins))
    _cast_rays(heights, grid, origins, directions, float(max_range), out)
    return out


def grid_of(x: np.ndarray, y: np.ndarray, heights: np.ndarray, low: float | None = None,
            high: float | None = None) -> np.ndarray:
    """The kernels' description of a grid: first grid lines (m), spacing (m), and the lowest and
    highest height any ray must consider (m; the heights' own unless given)."""
    low = float(np.min(heights)) if low is None else low
    high = float(np.max(heights)) if high is None else high
    return np.array([float(x[0]), float(y[0]), float(x[1] - x[0]), low, high])


@numba.njit(cache=True)
def _cast_rays(heights, grid, origins, directions, max_range, out):  # pragma: no cover - compiled
    for i in range(len(origins)):
        out[i] = ray_distance(heights, grid, origins[i, 0], origins[i, 1], origins[i, 2],
                              directions[i, 0], directions[i, 1], directions[i, 2], max_range, 0.0)


@numba.njit(cache=True, inline="always")
def ray_distance(z, grid, ox, oy, oz, dx, dy, dz, max_range, begin):  # pragma: no cover - compiled
    """Distance along the ray (o + t d, t >= 0) to the surface of heights z, or NaN (see the
    module's docstring); `grid` as `grid_of` gives it. The walk starts at t = `begin` (m), which
    the caller knows lies before the hit, if any; the cell it starts in is tested whole."""
    x0, y0, h, low, high = grid[0], grid[1], grid[2], grid[3], grid[4]
    ny, nx = z.shape
    # The ray's span within the box of the grid's surface: [x0, x_end] x [y0, y_end] x [low, high].
    t0, t1 = begin, max_range
    for origin, direction, lower, upper in ((ox, dx, x0, x0 + (nx - 1) * h), (oy, dy, y0, y0 + (ny - 1) * h),
                                            (oz, dz, low, high)):
        if direction == 0.0:
            if origin < lower or origin > upper:
                return np.nan
            continue
        ta, tb = (lower - origin) / direction, (upper - origin) / direction
        t0, t1 = max(t0, min(ta, tb)), min(t1, max(ta, tb))
    if not t0 <= t1:
        return np.nan
    # The walk, from the cell where the ray enters the box.
    c = min(max(math.floor((ox + t0 * dx - x0) / h), 0), nx - 2)
    r = min(max(math.floor((oy + t0 * dy - y0) / h), 0), ny - 2)
    step_c, step_r = (1 if dx > 0 else -1), (1 if dy > 0 else -1)
    next_c = (x0 + (c + (dx > 0)) * h - ox) / dx if dx != 0.0 else np.inf  # t at the next column line
    next_r = (y0 + (r + (dy > 0)) * h - oy) / dy if dy != 0.0 else np.inf
    delta_c = h / abs(dx) if dx != 0.0 else np.inf
    delta_r = h / abs(dy) if dy != 0.0 else np.inf
    du, dv = dx / h, dy / h
    best = np.inf
    t_in = t0
    while True:
        t_out = min(next_c, next_r, t1)
        lowest = oz + dz * (t_out if dz < 0.0 else t_in)  # the ray's lowest point over the cell
        z00, z10, z01, z11 = z[r, c], z[r, c + 1], z[r + 1, c], z[r + 1, c + 1]
        if lowest <= max(max(z00, z10), max(z01, z11)) + 1e-9:
            u0, v0 = (ox - (x0 + c * h)) / h, (oy - (y0 + r * h)) / h  # the origin in cell units
            # {(c, r), (c+1, r+1), (c+1, r)}, where v <= u: z = z00 + (z10 - z00) u + (z11 - z10) v
            best = min(best, _triangle(z00, z10 - z00, z11 - z10, u0, v0, oz, du, dv, dz, True))
            # {(c, r), (c+1, r+1), (c, r+1)}, where u <= v: z = z00 + (z11 - z01) u + (z01 - z00) v
            best = min(best, _triangle(z00, z11 - z01, z01 - z00, u0, v0, oz, du, dv, dz, False))
            if best <= t_out:
                break
        if t_out >= t1:
            break
        t_in = t_out
        if next_c < next_r:
            c += step_c
            next_c += delta_c
            if c < 0 or c > nx - 2:
                break
        else:
            r += step_r
            next_r += delta_r
            if r < 0 or r > ny - 2:
                break
    return best if best <= max_range and best < np.inf else np.nan


@numba.njit(cache=True, inline="always")
def _triangle(z00, a, b, u0, v0, oz, du, dv, dz, lower):  # pragma: no cover - compiled
    """t where the ray (u0 + t du, v0 + t dv, oz + t dz) meets the plane z00 + a u + b v within
    the cell's lower triangle (v <= u) or its upper one (u <= v), t >= 0; else infinity."""
    denominator = dz - a * du - b * dv
    if denominator == 0.0:
        return np.inf
    t = (z00 + a * u0 + b * v0 - oz) / denominator
    if not t >= 0.0:
        return np.inf
    u, v = u0 + t * du, v0 + t * dv
    e = EDGE_TOLERANCE
    if lower:
        inside = v >= -e and u <= 1.0 + e and v <= u + e
    else:
        inside = u >= -e and v <= 1.0 + e and u <= v + e
    return t if inside else np.inf
