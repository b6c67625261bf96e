"""A progress line of simulated seconds on a terminal: how far, out of how much, and how long
until done (tqdm's estimate). Nothing is drawn when stderr is not a terminal. A video's line
counts the seconds of the run rendered."""

from __future__ import annotations

import contextlib
import sys
from collections.abc import Callable, Iterator


@contextlib.contextmanager
def simulated_seconds(description: str = "simulating", unit: str = "s simulated"
                      ) -> Iterator[Callable[[float, float], None]]:
    """A `progress(done, total)` callback (simulated s) that draws the line, its counts followed
    by `unit`; the total may grow."""
    from tqdm import tqdm

    bar = None

    def advance(done: float, total: float) -> None:
        nonlocal bar
        if bar is None:  # the total is known once the simulation reports
            bar = tqdm(total=round(total), desc=description, unit=f" {unit}", leave=False,
                       disable=not sys.stderr.isatty(), bar_format=f"{{desc}}: {{n}}/{{total}} {unit} "
                       "[{elapsed} elapsed, {remaining} left, {rate_fmt}]")
        if round(total) != bar.total:
            bar.total = round(total)
        bar.update(round(done) - bar.n)

    try:
        yield advance
    finally:
        if bar is not None:
            bar.close()
