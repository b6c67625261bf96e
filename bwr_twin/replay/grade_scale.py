"""The colour scale of a pile's grade in the replay: the grade of the top layer, the one exposed at
each cell, in a few bins of a perceptual colour map, and the legend that says what each colour is.

viser 1.1.1 gives a mesh one colour, so the pile is drawn as one mesh per bin (bwr_twin.replay.pile):
a handful of bins keep that cheap and make each colour a range the legend can name. The bins are
of equal width, a round number, over the 2nd to 98th percentile of the top grades the run shows
(every cell's at its start and at each frame), widened to round edges (so 7 to 10 bins, as the
round width and the edges fall): one odd layer does not stretch the scale, and a grade outside it
falls in the end bin on its side.
"""

from __future__ import annotations

import html
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from bwr_twin.replay.style import ORE_COLOUR, hex_colour
from bwr_twin.stockpile.history import PileHistory

BINS = 9  # colours, about: enough to see a layer's grade change, few enough to name each
COLOUR_MAP = "viridis"  # perceptually uniform, and readable without colour vision
PERCENTILES = (2.0, 98.0)  # of the grades shown: the range the bins cover
NICE = (1.0, 1.5, 2.0, 2.5, 3.0, 4.0, 5.0, 6.0, 8.0)  # a bin's width: one of these times a power of ten


@dataclass(frozen=True)
class GradeScale:
    """Bins of grade between `edges` (ascending, one more than the bins), each drawn in its
    `colours` (0-255 RGB); the grade is `name` ("Fe %"), and `band` the one its customer accepts,
    if given."""

    name: str
    edges: np.ndarray
    colours: tuple[tuple[int, int, int], ...]
    band: tuple[float, float] | None = None

    @classmethod
    def of(cls, histories: Sequence[PileHistory]) -> GradeScale | None:
        """The scale of the piles' top grades, over all their frames; None if none has grade."""
        graded = [h for h in histories if h.grade_start is not None]
        if not graded:
            return None
        values = np.concatenate([np.concatenate([h.grade_start.ravel(), h.grades]) for h in graded])
        values = values[np.isfinite(values)]
        band = graded[0].grade_band
        if len(values):
            low, high = np.percentile(values, PERCENTILES)
        else:  # nothing laid yet: the band, or a unit
            low, high = band if band is not None else (0.0, 1.0)
        from matplotlib import colormaps  # here: only a run with grade needs it, and it takes a second

        edges = round_edges(float(low), float(high), BINS)
        bins, colour_map = len(edges) - 1, colormaps[COLOUR_MAP]
        colours = tuple(tuple(round(255 * c) for c in colour_map((k + 0.5) / bins)[:3]) for k in range(bins))
        return cls(graded[0].grade_name, edges, colours, band)

    @property
    def step(self) -> float:
        """A bin's width, in the grade's unit."""
        return float(self.edges[1] - self.edges[0])

    def bins(self, grade: np.ndarray) -> np.ndarray:
        """Each grade's bin, from 0 (below the scale too) to the last (above it too); -1 for NaN
        (bare ground)."""
        grade = np.asarray(grade, dtype=float)
        index = np.searchsorted(self.edges[1:-1], np.nan_to_num(grade), side="right")
        return np.where(np.isnan(grade), -1, index)

    def labels(self) -> list[str]:
        """Each bin's range, as the legend writes it: the end bins open."""
        digits = _decimals(self.step)
        edge = [f"{e:.{digits}f}" for e in self.edges]
        last = len(self.colours) - 1
        return [f"< {edge[1]}" if k == 0 < last else f"≥ {edge[k]}" if k == last > 0 else f"{edge[k]} – {edge[k + 1]}"
                for k in range(len(self.colours))]

    def legend_html(self) -> str:
        """The legend for the panel: the grade's name and unit, each colour's range (highest on
        top), bare ground's colour, how the range was chosen, and the band."""
        def swatch(colour) -> str:
            return (f'<span style="display:inline-block;width:1.6em;height:0.9em;vertical-align:middle;'
                    f'background:{hex_colour(colour)}"></span>')

        name = html.escape(self.name)
        rows = [(swatch(c), f"{html.escape(label)} {name}") for c, label in zip(self.colours, self.labels())][::-1]
        rows.append((swatch(ORE_COLOUR), "bare ground"))
        table = "".join(f"<tr><td>{s}</td><td>{text}</td></tr>" for s, text in rows)
        band = (f" The customer's band: {self.band[0]:g}–{self.band[1]:g} {name}." if self.band is not None else "")
        return (f'<div style="font-size:0.85em;padding:0 0.75em"><b>Top layer\'s grade, {name}</b>'
                f'<table style="border-spacing:0.4em 0.1em">{table}</table>'
                f"<p style=\"margin:0.3em 0;color:#555\">Bins of {self.step:g} {name} from percentile "
                f"{PERCENTILES[0]:g} to {PERCENTILES[1]:g} of the run's top grades, edges rounded out; a grade "
                f"beyond them is in the end bin.{band}</p></div>")


def round_edges(low: float, high: float, bins: int) -> np.ndarray:
    """Edges a round width apart, the least at least (high - low) / `bins`, from a multiple of it
    at or below `low` to at or above `high`: about `bins` bins (one more where `low` is no
    multiple, fewer where the width rounds up)."""
    span = max(high - low, 1e-3 * max(abs(low), abs(high)), 1e-9)  # one grade alone: a narrow scale about it
    exponent = math.floor(math.log10(span / bins))
    step = next(factor * 10.0**e for e in (exponent, exponent + 1) for factor in NICE
                if factor * 10.0**e >= span / bins * (1 - 1e-9))
    start = math.floor(low / step + 1e-9) * step
    count = max(math.ceil((high - start) / step - 1e-9), 1)
    return np.round(start + step * np.arange(count + 1), _decimals(step) + 1)


def _decimals(step: float) -> int:
    """The fewest decimals that write multiples of `step` exactly."""
    return next(d for d in range(10) if abs(round(step, d) - step) <= 1e-9 * step)
