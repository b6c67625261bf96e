"""The relaxation's speed in docs/blending.md: a 15 m windrow on 0.5 m cells (119 x 399), relaxed
after what stacking and reclaiming do to it, as bare heights and as a layered pile.

    python tools/relaxation_speed.py [--repeats 5]

Prints a markdown table: per case, the rounds and moves, and the median wall time of `--repeats`
relaxations (after one to compile), heights alone and with the layers following.
"""

from __future__ import annotations

import argparse
import math
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from bwr_twin.config.sections import WindrowSection
from bwr_twin.model.machine import Wheel
from bwr_twin.pile.cutting import Cutter
from bwr_twin.pile.relaxation import Talus, relax
from bwr_twin.pile.surface import Surface, windrow
from bwr_twin.stockpile.deposition import footprint
from bwr_twin.stockpile.layers import LayeredPile
from bwr_twin.stockpile.material import Material

SPACING = 0.5  # m
MATERIAL = Material(bulk_density=2400.0, angle_of_repose=37.0)  # iron ore, as heavy_dig_pile's
GRADE = 62.0  # Fe % of the windrow
# bwr_heavy.xml's wheel (docs/stockpile.md): 10 m, 1.6 m wide, 14 buckets of 1 m^3, 7 rpm.
HEAVY_WHEEL = Wheel(diameter=10.0, width=1.6, buckets=14, bucket_volume=1.0, discharges_per_minute=98.0)
STACKER_RATE = 10_000.0  # t/h


def windrow_pile() -> Surface:
    section = WindrowSection(length=158.0, crest_width=18.0, height=15.0,
                             angle_of_repose=MATERIAL.angle_of_repose, centre=(100.0, 30.0))
    return windrow(section, SPACING, Path("tools/relaxation_speed.py"))


def discharged(surface: Surface, seconds: float) -> np.ndarray:
    """(ny, nx) m laid by the stacker's stream over `seconds` on the crest's centre."""
    volume = MATERIAL.volume(STACKER_RATE * seconds / 3600.0)
    return footprint(surface, 100.25, 30.25) * volume / surface.cell_area


def wheel_cut(surface: Surface) -> np.ndarray:
    """(ny, nx) m the heavy wheel leaves after slewing once across the windrow's crest near its
    end, 5 m deep: a slot as wide as the buckets, cut as the twin's Cutter cuts."""
    cutter = Cutter(surface, HEAVY_WHEEL, runs=1)
    pivot, boom = np.array([14.0, 0.0]), 30.0  # the slew axis beside the windrow's end, m
    centre_height = 15.0 - 5.0 + HEAVY_WHEEL.radius
    for slew in np.radians(np.arange(40.0, 80.0, 0.01)):  # 0.01 deg a cut: 0.1 deg/s, 10 cuts a second
        cp = np.array([[pivot[0] + boom * math.cos(slew), pivot[1] + boom * math.sin(slew), centre_height]])
        cutter.cut(cp, np.array([slew]))
    return cutter.heights[0]


def cases(surface: Surface) -> dict[str, Callable[[], np.ndarray]]:
    """Heights to relax, by what made them."""
    z = surface.z
    face = z.copy()
    face[:, : z.shape[1] // 2] = 0.0
    return {
        "the windrow at rest (one pass)": lambda: z.copy(),
        f"{STACKER_RATE:,.0f} t/h for 1 s on the crest": lambda: z + discharged(surface, 1.0),
        f"{STACKER_RATE:,.0f} t/h for 60 s on the crest": lambda: z + discharged(surface, 60.0),
        "the heavy wheel's slewing cut, 5 m deep across the crest": lambda: wheel_cut(surface),
        "the whole windrow cut off square (15 m vertical face)": lambda: face,
    }


def timed(relaxation: Callable[[], object], repeats: int) -> tuple[object, float]:
    """The last result and the median wall time (s) of `repeats` runs, after one to compile."""
    relaxation()
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        result = relaxation()
        times.append(time.perf_counter() - start)
    return result, float(np.median(times))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    surface = windrow_pile()
    talus = Talus.of(SPACING, MATERIAL.angle_of_repose)
    ny, nx = surface.z.shape
    print(f"{ny} x {nx} cells of {SPACING} m, {MATERIAL.angle_of_repose:g} deg, "
          f"tolerance {talus.tolerance:g} m\n")
    print("| relaxed after | rounds | moves | heights alone | layered pile |")
    print("| --- | --- | --- | --- | --- |")
    for name, heights in cases(surface).items():
        start = heights()

        def plain(start=start):
            return relax(start.copy(), talus)

        def layered(start=start):
            pile = LayeredPile.from_surface(Surface(surface.x, surface.y, start), GRADE)
            began = time.perf_counter()
            pile.relax(talus)
            return time.perf_counter() - began  # the relaxation alone, not building the pile

        relaxed, seconds = timed(plain, args.repeats)
        layered_seconds = float(np.median([layered() for _ in range(args.repeats + 1)][1:]))
        print(f"| {name} | {relaxed.rounds:,} | {relaxed.move_count:,} | {seconds * 1e3:,.1f} ms "
              f"| {layered_seconds * 1e3:,.1f} ms |")


if __name__ == "__main__":
    main()
