"""The blending figure of merit, idealised: how much an ideal chevron pile of N layers narrows the
spread of the grade, sigma_out / sigma_in, against the classic 1 / sqrt(N).

The stacker lays N full-length layers, one a pass along the pile, turning at each end, while the
grade of what it lays varies in time (an AR(1) stream, bwr_twin.stockpile.grade); the reclaimer
then takes the pile in full-face slices across it, each slice's grade the mass-weighted mean of
everything in it. A slice holds a piece of every layer, each laid at another time, so its grade
averages N grades and its spread is the input's over sqrt(N) (Gerstel, "The homogenization of
bulk material in blending piles", 1979; Kohlhaas and Labahn, 1983) when:

- the grades a slice gathers are uncorrelated: the input's correlation time is short against the
  time between passes (here independent values, correlation_time 0, unless asked otherwise),
  and the stacker lays at one rate;
- every layer puts the same mass into every slice: chevrons of equal cross-section along the whole
  length (no end cones, where the layers fold over);
- the reclaimer takes the whole face, every layer, in each slice, and nothing segregates, slumps
  between slices or sticks: the material and its density are uniform;
- sigma_in is the spread of the input over the time the stacker takes to lay one slice's length,
  the scale at which a slice samples it.

The cross-section is N nested similar triangles, the k-th of height H sqrt(k / N), so that every
chevron layer between two of them has the same area; on the grid the layers' masses differ
slightly where the first, narrow triangles span few cells, and `Blend.expected` is the ratio that
exact masses m_k give, sqrt(sum m_k^2) / sum m_k.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bwr_twin.stockpile.grade import Ar1Grade
from bwr_twin.stockpile.layers import LayeredPile


@dataclass(frozen=True)
class Blend:
    """The figure of merit of a chevron pile of `layers` layers, over `slices` slices x `repeats` piles."""

    layers: int
    slices: int
    repeats: int
    sigma_in: float  # the grades laid, their standard deviation
    sigma_out: float  # the slices' grades, their standard deviation
    expected: float  # sqrt(sum m_k^2) / sum m_k of the grid's layer masses: 1 / sqrt(N) for equal ones

    @property
    def ratio(self) -> float:
        """sigma_out / sigma_in."""
        return self.sigma_out / self.sigma_in


def chevron_thickness(layers: int, cells_across: int, height: float) -> np.ndarray:
    """(layers, cells_across) m: each chevron layer's thickness across the pile, the k-th
    between the triangles of crests H sqrt((k - 1) / N) and H sqrt(k / N) with the pile's flanks,
    on cells whose middle one is the crest; the pile is `height` m high at its crest and reaches
    the floor half a cell beyond its outermost cells."""
    slope = height / (cells_across / 2)  # m a cell: every chevron's flanks, as the pile's
    offset = np.abs(np.arange(cells_across) - (cells_across - 1) / 2)
    crests = height * np.sqrt(np.arange(layers + 1) / layers)  # similar triangles: area grows as crest^2
    tops = np.clip(crests[:, None] - slope * offset[None, :], 0.0, None)
    return np.diff(tops, axis=0)


def chevron_pile(grades: np.ndarray, cells_across: int, height: float, spacing: float,
                 max_layers: int) -> LayeredPile:
    """A chevron pile of len(grades) layers, grades[k, ix] the grade layer k got at slice ix, on a
    grid of `spacing` m, len(grades[0]) cells long and `cells_across` cells wide."""
    layers, length = grades.shape
    pile = LayeredPile(np.arange(length) * spacing, np.arange(cells_across) * spacing, max_layers)
    thickness = chevron_thickness(layers, cells_across, height)
    for layer in range(layers):
        pile.deposit(np.repeat(thickness[layer][:, None], length, axis=1), grades[layer][None, :])
    return pile


def slice_grades(pile: LayeredPile) -> np.ndarray:
    """(nx,) the grade of each full-face slice, one grid column along the pile, reclaimed in turn
    from one end to the floor: the mass-weighted grade of the column of cells across the pile."""
    grades = np.empty(len(pile.x))
    heights = pile.z.copy()
    for ix in range(len(pile.x)):
        heights[:, ix] = 0.0
        removed = pile.cut_to(heights)
        grades[ix] = removed.grade
    return grades


def stacked_grades(layers: int, slices: int, stream: Ar1Grade) -> np.ndarray:
    """(layers, slices): the grade each pass laid at each slice, one stream value a slice, the
    stacker going along the pile and back again (odd passes reversed)."""
    grades = stream.series(layers * slices).reshape(layers, slices)
    grades[1::2] = grades[1::2, ::-1]
    return grades


def blend(layers: int, slices: int = 250, repeats: int = 4, seed: int = 1, cells_across: int = 81,
          height: float = 15.0, spacing: float = 0.5, correlation_time: float = 0.0,
          max_layers: int | None = None) -> Blend:
    """sigma_out / sigma_in of `repeats` chevron piles of `layers` layers and `slices` slices, the
    r-th stacked from an AR(1) stream (mean 60, sd 1, one value a slice; `correlation_time` in
    slices) seeded seed + r; both spreads pooled over the piles."""
    laid, reclaimed = [], []
    for repeat in range(repeats):
        stream = Ar1Grade(60.0, 1.0, correlation_time, 1.0, seed + repeat)
        grades = stacked_grades(layers, slices, stream)
        pile = chevron_pile(grades, cells_across, height, spacing, max_layers or layers + 1)
        laid.append(grades.ravel())
        reclaimed.append(slice_grades(pile))
    masses = chevron_thickness(layers, cells_across, height).sum(axis=1)
    return Blend(layers, slices, repeats, float(np.std(np.concatenate(laid))),
                 float(np.std(np.concatenate(reclaimed))), float(np.sqrt(np.sum(masses**2)) / masses.sum()))
