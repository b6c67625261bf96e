"""A collision shape's clearance to the pile as a run has dug it, on the pile's height grid.

The clearance is the least distance from the shape to the grid's points (x[c], y[r], z[r, c]), the
surface's vertices: never less than the distance to the surface between them, and more by at most
s^2 / (4 d) for a shape d above a surface of cells s wide (0.016 m at 1 m on 0.25 m cells;
`tests/test_collision.py` holds it against MuJoCo's own distance to the same triangles). A shape
that reaches below the surface has a negative clearance: minus the deepest its underside (sampled
along its length) lies below the surface there. Only the points within `watch` m of the shape's
box are looked at; a shape farther from the pile than `watch` has the clearance `watch`.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from bwr_twin.model.shapes import BOX

SAMPLES = 16  # points along a shape's underside at which it is checked for lying below the surface


@numba.njit(cache=True)
def shape_clearance(heights, x0, y0, spacing, kind, half, position, rotation, watch):  # pragma: no cover - compiled
    """The clearance (m) of one shape, its world `position` (3,) and `rotation` (3, 3) (columns: its
    axes), to the pile of `heights` (ny, nx) m on the grid x0 + c s, y0 + r s."""
    ny, nx = heights.shape
    # The shape's world box: its centre plus the projections of its half extents.
    reach = np.empty(3)
    for a in range(3):
        if kind == BOX:
            reach[a] = abs(rotation[a, 0]) * half[0] + abs(rotation[a, 1]) * half[1] + abs(rotation[a, 2]) * half[2]
        else:
            reach[a] = abs(rotation[a, 2]) * half[2] + half[0]
    lowest = position[2] - reach[2]
    c0 = max(math.floor((position[0] - reach[0] - watch - x0) / spacing), 0)
    c1 = min(math.ceil((position[0] + reach[0] + watch - x0) / spacing), nx - 1)
    r0 = max(math.floor((position[1] - reach[1] - watch - y0) / spacing), 0)
    r1 = min(math.ceil((position[1] + reach[1] + watch - y0) / spacing), ny - 1)
    best = watch
    for r in range(r0, r1 + 1):
        py = y0 + r * spacing - position[1]
        for c in range(c0, c1 + 1):
            z = heights[r, c]
            if lowest - z >= best:  # the shape's lowest point is farther above this point than the best
                continue
            px, pz = x0 + c * spacing - position[0], z - position[2]
            # The point in the shape's frame.
            lx = rotation[0, 0] * px + rotation[1, 0] * py + rotation[2, 0] * pz
            ly = rotation[0, 1] * px + rotation[1, 1] * py + rotation[2, 1] * pz
            lz = rotation[0, 2] * px + rotation[1, 2] * py + rotation[2, 2] * pz
            if kind == BOX:
                qx, qy, qz = abs(lx) - half[0], abs(ly) - half[1], abs(lz) - half[2]
                outside = math.sqrt(max(qx, 0.0) ** 2 + max(qy, 0.0) ** 2 + max(qz, 0.0) ** 2)
                distance = outside + min(max(qx, qy, qz), 0.0)
            else:
                t = min(max(lz, -half[2]), half[2])
                distance = math.sqrt(lx * lx + ly * ly + (lz - t) ** 2) - half[0]
            best = min(best, distance)
    # Below the surface: the underside's points along the shape's longest axis.
    axis = 2
    if kind == BOX:
        axis = 0 if half[0] >= half[1] and half[0] >= half[2] else (1 if half[1] >= half[2] else 2)
    length = half[axis]
    for i in range(SAMPLES):
        s = -length + 2.0 * length * i / (SAMPLES - 1)
        sx = position[0] + rotation[0, axis] * s
        sy = position[1] + rotation[1, axis] * s
        sz = position[2] + rotation[2, axis] * s
        if kind == BOX:  # the underside: the box's lowest point across the other two axes
            for a in range(3):
                if a != axis:
                    sz -= abs(rotation[2, a]) * half[a]
        else:
            sz -= half[0]
        c = int(round((sx - x0) / spacing))
        r = int(round((sy - y0) / spacing))
        if 0 <= r < ny and 0 <= c < nx and heights[r, c] - sz > -best and heights[r, c] > sz:
            best = min(best, sz - heights[r, c])
    return best


def clearances(heights: np.ndarray, x: np.ndarray, y: np.ndarray, kinds: np.ndarray, halves: np.ndarray,
               positions: np.ndarray, rotations: np.ndarray, watch: float) -> np.ndarray:
    """(shapes,) clearances, m, of shapes at world `positions` (shapes, 3) and `rotations`
    (shapes, 3, 3) to the pile `heights` (ny, nx) on grid lines x, y."""
    spacing = float(x[1] - x[0])
    return np.array([shape_clearance(heights, float(x[0]), float(y[0]), spacing, int(kinds[i]), halves[i],
                                     positions[i], rotations[i], watch) for i in range(len(kinds))])
