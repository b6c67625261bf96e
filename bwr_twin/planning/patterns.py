"""Which passes a stacking pattern lays (scene [stacking], docs/blending.md); bwr_twin.planning.stacking
times and samples them.

Every pattern fills the same target: the ridge along the axis at the angle of repose that holds
the scene's tonnes, its crest H high and its foot W / 2 to each side of the axis (`target_ridge`).
A pass is a straight travel along the rail at a fixed slew and luff, the discharge point at a
fixed y and head height, or a dwell where the machine stands and discharges; its weight is its
share of the tonnes. Passes follow one another serpentine: each starts where the last ended, so
the machine only turns (slews, luffs) between them.

- chevron: `layers` passes along the axis, to and fro; after pass k of N the crest stands at
  H sqrt(k / N) (every chevron layer the same section).
- windrow: `layers` = m rows in the bottom layer, m - j rows in layer j, each in a valley of the
  layer below; the section is m^2 small triangles, a bottom row one of them, a higher row two
  (it fills a valley and tops it). Layer j's crest stands at (j + 1) H / m.
- cone_shell: `layers` cones, evenly from the axis's start to its end, each a dwell, each cone
  reaching the ridge's crest against the shell of the one before.
- strata: `layers` horizontal strata of equal tonnes, stratum k topped at
  h_k = H (1 - sqrt(1 - k / N)), laid in rows `row_spacing` apart across its width at mid-height.

A row is one pass: laying a row's tonnes in r passes over the same length in the same time
moves r times as fast, so one pass is the fewest, and the slowest, that keeps within the
travel's rated speed; the planner refuses a row that one pass cannot lay within it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from bwr_twin.errors import SceneError
from bwr_twin.pile.ground import YARD_FLOOR
from bwr_twin.units import KG_PER_T

# A lone cone of the relaxation stands as a regular octagonal pyramid (docs/blending.md): its
# volume is this share of a round cone's of the same height and foot.
OCTAGON_SHARE = 2.0 * math.sqrt(2.0) / math.pi


@dataclass(frozen=True)
class Pass:
    """One pass of a pattern: the discharge point from (start, y) to (end, y) at `head`."""

    start: float  # m along the rail
    end: float  # m along the rail: `start` for a dwell, where the machine stands and discharges
    y: float  # m beside the rail
    head: float  # world m: the discharge point's height, YARD_FLOOR + the crest + `drop` or the lowest it luffs
    weight: float  # its share of the tonnes, relative to the other passes'
    layer: int  # 0-based: the layer, cone or stratum it lays

    @property
    def dwell(self) -> bool:
        return self.start == self.end


@dataclass(frozen=True)
class Layout:
    """A pattern's passes in the order they are laid.

    Attributes:
        passes: every pass, serpentine.
        crests: (layers,) m above the yard floor, the target's crest once each layer is laid:
            chevron H sqrt(k / N) after pass k; windrow (j + 1) H / m after layer j's rows; cone
            shell H after every cone (each reaches the crest); strata h_k after stratum k.
        fewer: what lengthens each pass, for a refusal to name ("fewer 'layers'").
    """

    passes: tuple[Pass, ...]
    crests: np.ndarray
    fewer: str


def lay(section, lowest: float, scene_path: Path) -> Layout:
    """The passes of a [stacking]'s pattern, the discharge point `drop` above each pass's crest
    or at `lowest` (world m, as low as the boom luffs) where that is higher.
    SceneError, naming the key, for a pattern the target cannot hold."""
    height, foot = target_ridge(section)

    def head(crest: float) -> float:
        return max(YARD_FLOOR + crest + section.drop, lowest)

    if section.pattern == "chevron":
        return _chevron(section, height, head)
    if section.pattern == "windrow":
        return _windrow(section, height, 2.0 * foot, head)
    if section.pattern == "cone_shell":
        return _cone_shell(section, height, head, scene_path)
    return _strata(section, height, 2.0 * foot, head)


def equivalent_layers(passes: tuple[Pass, ...]) -> float:
    """The N of sigma_out = sigma_in / sqrt(N) for these passes: a full-face slice holds a share of
    each pass in proportion to its weight, so it averages as many independent grades as
    (sum w)^2 / sum w^2 equal layers would (N for a chevron's N passes). NaN for a pattern with
    dwells: a cone does not run the pile's length, and a slice crosses a few cones only."""
    if any(lane.dwell for lane in passes):
        return float("nan")
    weights = np.array([lane.weight for lane in passes])
    return float(weights.sum() ** 2 / np.sum(weights**2))


def target_ridge(section) -> tuple[float, float]:
    """The target ridge of a [stacking]: its crest height H = sqrt(V tan(phi) / L) and its
    foot's distance from the axis, H / tan(phi) (m)."""
    length = abs(section.axis_x[1] - section.axis_x[0])
    volume = section.tonnes * KG_PER_T / section.bulk_density
    slope = math.tan(math.radians(section.angle_of_repose))
    height = math.sqrt(volume * slope / length)
    return height, height / slope


def extent(section) -> tuple[float, float]:
    """How far (m) the pile spreads beyond the axis's ends, and to each side of the axis: the
    ridge's foot, and half as far again along the axis for the end cones the turns lay; a
    cone shell's lone first cone, if it spreads farther."""
    _, foot = target_ridge(section)
    along, across = 1.5 * foot, foot
    if section.pattern == "cone_shell":
        cone = _lone_cone(section) / math.tan(math.radians(section.angle_of_repose))
        along, across = max(along, cone), max(across, cone)
    return along, across


def _serpentine(rows: list[tuple[float, float, float, int]], x0: float, x1: float) -> tuple[Pass, ...]:
    """Rows (y m, head m, weight, layer) along the axis, each the way back from where the last ended."""
    ends = (x0, x1)
    return tuple(Pass(ends[i % 2], ends[1 - i % 2], y, head, weight, layer)
                 for i, (y, head, weight, layer) in enumerate(rows))


def _across(y0: float, width: float, count: int, reverse: bool) -> list[float]:
    """`count` lines evenly over `width` m centred on y0 (m), in order of y, descending if `reverse`:
    each layer's rows start on the side the last layer's ended."""
    lines = [y0 - 0.5 * width + (i + 0.5) * width / count for i in range(count)]
    return lines[::-1] if reverse else lines


def _chevron(section, height: float, head) -> Layout:
    crests = height * np.sqrt(np.arange(1, section.layers + 1) / section.layers)
    rows = [(section.axis_y, head(crest), 1.0, k) for k, crest in enumerate(crests)]
    return Layout(_serpentine(rows, *section.axis_x), crests, "more tonnes a layer (fewer 'layers')")


def _windrow(section, height: float, width: float, head) -> Layout:
    m = section.layers
    crests = height * np.arange(1, m + 1) / m
    rows = []
    for j in range(m):  # layer j's m - j rows, W / m apart and centred, sit in the valleys of layer j - 1's
        lines = _across(section.axis_y, (m - j) * width / m, m - j, reverse=j % 2 == 1)
        rows += [(y, head(crests[j]), 1.0 if j == 0 else 2.0, j) for y in lines]
    return Layout(_serpentine(rows, *section.axis_x), crests, "fewer rows ('layers')")


def _cone_shell(section, height: float, head, scene_path: Path) -> Layout:
    n = section.layers
    lone = _lone_cone(section)
    if lone > height + section.drop:
        raise SceneError(f"{scene_path}: [stacking]'s first cone, {section.tonnes / n:g} t alone on the floor, would "
                         f"stand {lone:.2f} m high, above its discharge point {height + section.drop:.2f} m up "
                         f"(the ridge's {height:.2f} m crest and the {section.drop:g} m 'drop'): more cones "
                         "('stacking.layers') or a shorter axis")
    crests = np.full(n, height)
    # Each cone reaches the crest: the luff is held at the final height for the whole dwell.
    passes = tuple(Pass(float(x), float(x), section.axis_y, head(height), 1.0, k)
                   for k, x in enumerate(np.linspace(*section.axis_x, n)))
    return Layout(passes, crests, "more tonnes a cone (fewer 'layers')")


def _strata(section, height: float, width: float, head) -> Layout:
    n = section.layers
    tops = height * (1.0 - np.sqrt(1.0 - np.arange(n + 1) / n))  # equal areas of the triangle below each
    rows = []
    for k in range(1, n + 1):
        span = width * (1.0 - (tops[k - 1] + tops[k]) / (2.0 * height))  # m: the section's width at mid-stratum
        count = max(1, round(span / section.row_spacing))
        lines = _across(section.axis_y, span, count, reverse=k % 2 == 0)
        rows += [(y, head(tops[k]), 1.0 / count, k - 1) for y in lines]
    return Layout(_serpentine(rows, *section.axis_x), tops[1:],
                  "fewer strata ('layers') or rows (a wider 'row_spacing')")


def _lone_cone(section) -> float:
    """m: the height of one cone's tonnes laid alone, an octagonal pyramid at the angle of repose."""
    volume = section.tonnes / section.layers * KG_PER_T / section.bulk_density
    slope = math.tan(math.radians(section.angle_of_repose))
    return (3.0 * volume * slope**2 / (math.pi * OCTAGON_SHARE)) ** (1.0 / 3.0)
