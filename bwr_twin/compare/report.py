"""What a comparison leaves in DIR: the table as CSV and markdown, overlaid error and drive-force
plots, and every run's directory; all of it appears at once, when complete."""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from pathlib import Path

import numpy as np
from matplotlib.colors import to_rgba
from matplotlib.figure import Figure  # no pyplot: no global state, no display backend

from bwr_twin.compare.table import as_csv, as_markdown, comparison_rows
from bwr_twin.model.machine import AXES, UNITS, to_display
from bwr_twin.results.layout import DPI, fit_titles
from bwr_twin.results.rundir import staged_directory, write_run
from bwr_twin.sim.record import RunResult

FORCE_UNITS = ("kN", "kN m", "kN m")
DASHES = ("-", "--", "-.", ":")  # the mean lines', so that one laid over another still shows
BINS = 400  # time bins of the drive-force bands at most: about one per two pixels of the figure's width


def write_comparison(out_dir: Path, labels: Sequence[str], results: Sequence[Sequence[RunResult]], *,
                     overwrite: bool = False) -> str:
    """Write DIR for controllers `labels`, results[c][s] being controller c's run of seed s + 1;
    returns the markdown table."""
    rows = comparison_rows(labels, [[r.metrics for r in runs] for runs in results])
    markdown = as_markdown(rows)
    with staged_directory(out_dir, overwrite=overwrite, kind="comparison") as staging:
        (staging / "comparison.csv").write_text(as_csv(rows))
        (staging / "comparison.md").write_text(markdown)
        for name, fig in comparison_figures(labels, results):
            fig.savefig(staging / name, dpi=DPI)
        for label, runs in zip(labels, results):
            for result in runs:
                write_run(result, staging / f"{label}-seed={result.scene.simulation.seed}", plots=False)
    return markdown


def comparison_figures(labels: Sequence[str],
                       results: Sequence[Sequence[RunResult]]) -> Iterator[tuple[str, Figure]]:
    """errors.png (seed 1 of every controller overlaid) and drive_forces.png (every controller's
    band over its seeds), as (file name, figure)."""
    firsts = [runs[0] for runs in results]
    subtitle = f"{firsts[0].scene.path.name}: {', '.join(labels)}"

    def error(r: RunResult, j: int):
        return to_display(j, r.q_desired[:, j] - r.q[:, j])

    yield "errors.png", _overlay(f"Position error, desired - actual (seed 1)\n{subtitle}", labels, firsts,
                                 error, lambda j: UNITS[j])
    yield "drive_forces.png", _bands(labels, results, subtitle)


def _overlay(title: str, labels: Sequence[str], results: Sequence[RunResult], signal, unit) -> Figure:
    fig = Figure(figsize=(10, 8), layout="constrained")
    axes = fig.subplots(3, 1, sharex=True)
    for j, ax in enumerate(axes):
        for k, (label, result) in enumerate(zip(labels, results)):
            ax.plot(result.time, signal(result, j), f"C{k}-", lw=0.7, label=label)
        ax.set_ylabel(f"{AXES[j]} [{unit(j)}]")
        ax.grid(alpha=0.3)
    axes[0].legend(loc="upper right")
    axes[-1].set_xlabel("time [s]")
    fig.suptitle(title)
    fit_titles(fig)
    return fig


def _bands(labels: Sequence[str], results: Sequence[Sequence[RunResult]], subtitle: str) -> Figure:
    """Per controller and axis, the applied drive force's smallest and largest value in each time
    bin over all its seeds, as a translucent band, and its mean there as a line: the force swings
    every control period, and drawn as lines the runs' swings cover each other."""
    end = max(float(r.time[-1]) for runs in results for r in runs)
    bins = max(1, min(BINS, min(len(r.time) for runs in results for r in runs) // 2))  # no bin left empty
    edges = np.linspace(0.0, end, bins + 1)
    middle = (edges[:-1] + edges[1:]) / 2
    fig = Figure(figsize=(10, 8), layout="constrained")
    axes = fig.subplots(3, 1, sharex=True)
    for j, ax in enumerate(axes):
        handles = []
        for k, (label, runs) in enumerate(zip(labels, results)):
            low, high, mean = binned([r.time for r in runs], [r.drive_force[:, j] / 1e3 for r in runs], edges)
            # Edged in the full colour: where the bands overlap, each one's bounds still show.
            band = ax.fill_between(middle, low, high, facecolor=to_rgba(f"C{k}", 0.2), edgecolor=f"C{k}",
                                   lw=0.6, label=label)
            (line,) = ax.plot(middle, mean, color=f"C{k}", ls=DASHES[k % len(DASHES)], lw=1.0, label=label)
            handles.append((band, line))
        ax.set_ylabel(f"{AXES[j]} [{FORCE_UNITS[j]}]")
        ax.grid(alpha=0.3)
        if j == 0:
            ax.legend(handles, labels, loc="upper right")
    axes[-1].set_xlabel("time [s]")
    seeds = len(results[0])
    over = f" over {seeds} seeds" if seeds > 1 else ""
    fig.suptitle(f"Applied drive forces and torques: range{over} (band) and mean (line) "
                 f"in every {end / bins:.3g} s\n{subtitle}")
    fit_titles(fig)
    return fig


def binned(times: Sequence[np.ndarray], values: Sequence[np.ndarray], edges: np.ndarray):
    """The smallest, largest and mean value in each bin [edges[i], edges[i + 1]) (the last one
    closed) of several runs' samples together: three (len(edges) - 1,) arrays, NaN in a bin
    no sample falls in."""
    t, v = np.concatenate(times), np.concatenate(values)
    bins = np.clip(np.searchsorted(edges, t, side="right") - 1, 0, len(edges) - 2)
    n = len(edges) - 1
    low, high = np.full(n, np.inf), np.full(n, -np.inf)
    np.minimum.at(low, bins, v)
    np.maximum.at(high, bins, v)
    count = np.bincount(bins, minlength=n)
    total = np.bincount(bins, weights=v, minlength=n)
    empty = count == 0
    low[empty] = high[empty] = np.nan
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = total / count
    return low, high, mean
