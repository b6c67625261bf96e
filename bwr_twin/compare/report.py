"""What a comparison leaves in DIR: the table as CSV and markdown, overlaid error and drive-force
plots, and every run's directory; all of it appears at once, when complete."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from matplotlib.figure import Figure  # no pyplot: no global state, no display backend

from bwr_twin.compare.table import as_csv, as_markdown, comparison_rows
from bwr_twin.model.machine import AXES, UNITS, to_display
from bwr_twin.sim.record import RunResult
from bwr_twin.results.rundir import staged_directory, write_run


def write_comparison(out_dir: Path, labels: Sequence[str], results: Sequence[Sequence[RunResult]], *,
                     overwrite: bool = False) -> str:
    """Write DIR for controllers `labels`, results[c][s] being controller c's run of seed s + 1;
    returns the markdown table."""
    rows = comparison_rows(labels, [[r.metrics for r in runs] for runs in results])
    markdown = as_markdown(rows)
    with staged_directory(out_dir, overwrite=overwrite, kind="comparison") as staging:
        (staging / "comparison.csv").write_text(as_csv(rows))
        (staging / "comparison.md").write_text(markdown)
        firsts = [runs[0] for runs in results]
        _overlay(staging / "errors.png", "Position error, desired - actual (seed 1)", labels, firsts,
                 lambda r, j: to_display(j, r.q_desired[:, j] - r.q[:, j]), lambda j: UNITS[j])
        _overlay(staging / "drive_forces.png", "Applied drive forces and torques (seed 1)", labels, firsts,
                 lambda r, j: r.drive_force[:, j] / 1e3, lambda j: ("kN", "kN m", "kN m")[j])
        for label, runs in zip(labels, results):
            for result in runs:
                write_run(result, staging / f"{label}-seed={result.scene.simulation.seed}", plots=False)
    return markdown


def _overlay(path: Path, title: str, labels: Sequence[str], results: Sequence[RunResult], signal, unit) -> None:
    fig = Figure(figsize=(10, 8), layout="constrained")
    axes = fig.subplots(3, 1, sharex=True)
    for j, ax in enumerate(axes):
        for k, (label, result) in enumerate(zip(labels, results)):
            ax.plot(result.time, signal(result, j), f"C{k}-", lw=0.7, label=label)
        ax.set_ylabel(f"{AXES[j]} [{unit(j)}]")
        ax.grid(alpha=0.3)
    axes[0].legend(loc="upper right")
    axes[-1].set_xlabel("time [s]")
    fig.suptitle(f"{title}\n{results[0].scene.path.name}: {', '.join(labels)}")
    fig.savefig(path, dpi=110)
