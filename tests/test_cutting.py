"""The compiled cut against the obvious numpy one, on a real windrow: the same heights to the bit,
the same volumes, depths, centroids and sides to 1e-12 (the sums are taken in another order)."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import HEAVY_MJCF, SCENES

from bwr_twin.config.scene import load_scene
from bwr_twin.model.machine import Machine, Wheel
from bwr_twin.pile.cutting import CELL_MARGIN, Cut, Cutter
from bwr_twin.pile.ground import YARD_FLOOR
from bwr_twin.pile.surface import Surface, build_surface


class NumpyCutter:
    """The cut in numpy, run by run: slow, and obviously what cutting.py's docstring says."""

    def __init__(self, surface: Surface, wheel: Wheel, runs: int):
        self.surface, self.wheel = surface, wheel
        self.heights = np.repeat(surface.z[None], runs, axis=0)
        self._top = float(surface.z.max())
        self._x0, self._y0, self._h = float(surface.x[0]), float(surface.y[0]), surface.spacing
        self._nx, self._ny = len(surface.x), len(surface.y)
        self._near: list[tuple | None] = [None] * runs

    def cut(self, cp: np.ndarray, slew: np.ndarray, runs: np.ndarray | None = None) -> Cut:
        count = len(self.heights)
        out = Cut(np.zeros(count), np.zeros(count), np.zeros((count, 3)), np.zeros(count))
        radius, half_width = self.wheel.radius, self.wheel.width / 2
        for run in range(count) if runs is None else runs:
            cx, cy, cz = cp[run]
            if cz - radius >= self._top:
                continue
            reach = half_width + (self._top - cz + radius) / self.wheel.side_slope
            cells = self._cells_near(run, cx, cy, slew[run], reach)
            if cells is None:
                continue
            flat, x, y = cells
            cos, sin = np.cos(slew[run]), np.sin(slew[run])
            dx, dy = x - cx, y - cy
            along = dx * cos + dy * sin
            across = dy * cos - dx * sin
            envelope = np.maximum(np.abs(across) - half_width, 0.0) * self.wheel.side_slope
            span = radius**2 - along * along
            outside = span < 0.0
            envelope = np.maximum(envelope - np.sqrt(np.maximum(span, 0.0)) + cz, YARD_FLOOR)
            envelope[outside] = np.inf
            z = self.heights[run].reshape(-1)
            old = z[flat]
            cutting = np.flatnonzero(old > envelope)
            if not cutting.size:
                continue
            flat, along, across, old, new = flat[cutting], along[cutting], across[cutting], old[cutting], envelope[cutting]
            z[flat] = new
            removed = old - new
            weight = removed.sum()
            out.volume[run] = weight * self.surface.cell_area
            out.centroid[run] = (np.dot(removed, x[cutting]) / weight, np.dot(removed, y[cutting]) / weight,
                                 np.dot(removed, old + new) / (2 * weight))
            drop = np.maximum(cz - old, 0.0)
            rim = np.sqrt(np.maximum(radius**2 - drop * drop, 0.0))
            out.depth[run] = max(float(np.max(rim - np.abs(along))), 0.0)
            out.side[run] = np.sign(np.dot(removed, across))
        return out

    def _cells_near(self, run, cx, cy, slew, half_width):
        kept = self._near[run]
        if kept is not None:
            x0, y0, slew0, width0, cells = kept
            if abs(cx - x0) + abs(cy - y0) + self.wheel.radius * abs(slew - slew0) < CELL_MARGIN and half_width <= width0:
                return cells
        width = half_width + CELL_MARGIN
        flat = self._cells_under(np.array([cx, cy]), slew, width, self.wheel.radius + CELL_MARGIN)
        cells = None if flat is None else (flat, self.surface.x[flat % self._nx], self.surface.y[flat // self._nx])
        self._near[run] = (cx, cy, slew, width, cells)
        return cells

    def _cells_under(self, cp, slew, half_width, radius):
        h = self._h
        cos, sin = float(np.cos(slew)), float(np.sin(slew))
        extent = radius * abs(sin) + half_width * abs(cos)
        iy0 = max(int(np.ceil((cp[1] - extent - self._y0) / h)), 0)
        iy1 = min(int(np.floor((cp[1] + extent - self._y0) / h)), self._ny - 1)
        if iy0 > iy1:
            return None
        dy = self.surface.y[iy0 : iy1 + 1] - cp[1]
        low, high = -np.inf, np.inf
        for centre, half, slope in ((dy * cos, half_width, sin), (-dy * sin, radius, cos)):
            if abs(slope) < 1e-12:
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


@pytest.fixture(scope="module")
def windrow():
    scene = load_scene(SCENES / "heavy_bench_reclaim.toml")
    return build_surface(scene.stockpile, scene.path), Machine(HEAVY_MJCF)


def assert_same(expected: Cut, got: Cut, reference: NumpyCutter, cutter: Cutter) -> None:
    np.testing.assert_array_equal(cutter.heights, reference.heights)
    for name in ("volume", "depth"):
        np.testing.assert_allclose(getattr(got, name), getattr(expected, name), rtol=1e-12, atol=0, err_msg=name)
    # A centroid to 1e-12 of its distance from the origin: a coordinate near 0 is a sum that cancels.
    scale = np.linalg.norm(expected.centroid, axis=1, keepdims=True)
    assert np.all(np.abs(got.centroid - expected.centroid) <= 1e-12 * scale), (got.centroid, expected.centroid)
    np.testing.assert_array_equal(got.side, expected.side)


def test_the_compiled_cut_is_the_numpy_cut_on_random_wheel_positions(windrow):
    """Three runs' wheels wander over the windrow, now and then jumping: above the pile, into it,
    below the yard floor; the cells near each wheel are kept for a few periods and gathered
    again. Every period, some of the runs or all of them are cut."""
    surface, machine = windrow
    runs, rng = 3, np.random.default_rng(7)
    reference, cutter = NumpyCutter(surface, machine.wheel, runs), Cutter(surface, machine.wheel, runs)
    q = np.tile([20.0, 0.8, 0.0], (runs, 1))
    kept = gathered = above = 0
    for period in range(3000):
        if period % 50 == 0:
            q = np.column_stack([rng.uniform(-60, 120, runs), rng.uniform(0.2, 1.3, runs), rng.uniform(-0.2, 0.2, runs)])
        else:
            q += rng.normal(0.0, 1.0, (runs, 3)) * [0.05, 0.002, 0.002]
        cp = machine.fk(q)
        chosen = None if period % 3 else rng.permutation(runs)[: rng.integers(1, runs + 1)]
        before = cutter._near.copy()
        assert_same(reference.cut(cp, q[:, 1], chosen), cutter.cut(cp, q[:, 1], chosen), reference, cutter)
        for run in range(runs) if chosen is None else chosen:
            if cp[run, 2] - machine.wheel.radius >= surface.z.max():
                above += 1
            elif np.array_equal(before[run], cutter._near[run], equal_nan=True):
                kept += 1
            else:
                gathered += 1
    assert min(kept, gathered, above) > 300
    dug = surface.volume() * runs - sum(surface.volume(z) for z in cutter.heights)
    assert dug > 1e4  # m^3: the wheels really dug
    assert np.any((cutter.heights == YARD_FLOOR) & (surface.z > YARD_FLOOR))  # down to the floor, no further
    assert cutter.heights.min() == YARD_FLOOR


@pytest.mark.parametrize("slew", [0.0, np.pi / 2, np.pi, -np.pi / 2])
def test_the_compiled_cut_is_the_numpy_cut_with_the_boom_along_a_grid_axis(slew):
    """With the boom along X or Y one of the gathering's bounds is a whole row or none of it."""
    machine = Machine(HEAVY_MJCF)
    q = np.array([[0.0, slew, np.radians(-5.0)]])
    cp = machine.fk(q)[0]
    # The grid a little off the wheel's centre: a cut symmetric about the wheel's plane would
    # leave its side and a centroid coordinate to the rounding of a sum that cancels.
    xs, ys = np.arange(cp[0] - 15.1, cp[0] + 15, 0.25), np.arange(cp[1] - 15.1, cp[1] + 15, 0.25)
    surface = Surface(xs, ys, np.where((np.abs(ys[:, None] - cp[1]) < 10) & (np.abs(xs - cp[0]) < 10), 14.0, 0.0))
    reference, cutter = NumpyCutter(surface, machine.wheel, 1), Cutter(surface, machine.wheel, 1)
    for step in np.linspace(0.0, 0.3, 40):
        moved = q + [[step, 0.0, 0.0]] if abs(np.sin(slew)) < 0.5 else q + [[0.0, 0.0, -step / 30]]
        cp = machine.fk(moved)
        assert_same(reference.cut(cp, moved[:, 1]), cutter.cut(cp, moved[:, 1]), reference, cutter)
    assert cutter.heights.min() < 14.0
