"""A bounded search over one parameter, for the tunings CMA-ES cannot do: it needs two or more
dimensions, and the `cma` package has no 1-D mode.

The search has CMA-ES's ask-and-tell shape on [0, 1], so the generation loop, the state file and
resuming are the same. Each generation samples `popsize` points evenly spaced inside the bracket
(strictly inside: the bracket's ends were sampled before, or are the bounds); the bracket then
shrinks to the spacing either side of the best point so far, by 2 / (popsize + 1) a generation.
The first generation spans the whole range. It finds the minimum of a unimodal objective, as
scipy's bounded scalar minimisation does, but evaluates a whole generation at once on the
workers; it draws no random numbers, so a resumed tuning ends where an uninterrupted one ends.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

DEFAULT_POPULATION = 4  # CMA-ES's own for one dimension: 4 + 3 ln(1)
TOLERANCE = 1e-6  # of the range: a bracket this narrow has converged


class ScalarSearch:
    name = "bounded scalar search"

    def __init__(self, x0: float, popsize: int = DEFAULT_POPULATION) -> None:
        self.popsize = popsize
        self.low, self.high = 0.0, 1.0
        self.best_x, self.best_f = float(x0), math.inf

    def ask(self) -> list[list[float]]:
        step = (self.high - self.low) / (self.popsize + 1)
        return [[self.low + (k + 1) * step] for k in range(self.popsize)]

    def tell(self, points: Sequence[Sequence[float]], values: Sequence[float]) -> None:
        """The objectives of the points `ask` gave (smaller is better)."""
        step = (self.high - self.low) / (self.popsize + 1)
        for (x,), f in zip(points, values):
            if f < self.best_f:
                self.best_x, self.best_f = float(x), float(f)
        self.low, self.high = max(0.0, self.best_x - step), min(1.0, self.best_x + step)

    def stop(self) -> dict[str, float]:
        width = self.high - self.low
        return {"bracket": width} if width < TOLERANCE else {}


def search_name(dimensions: int) -> str:
    """What searches a tuning of `dimensions` parameters, for messages and best_scene.toml."""
    return "CMA-ES" if dimensions > 1 else ScalarSearch.name
