"""What a batch reports in DIR: summary.csv, the distribution plots and the spread it prints.

Every file appears whole or not at all: it is written under a temporary name and renamed.
"""

from __future__ import annotations

import csv
import json
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np

from bwr_twin.config.sweep import PlannedRun, Sweep, parameter_label
from bwr_twin.model.machine import AXES, UNITS, to_display
from bwr_twin.ownership import write_atomically
from bwr_twin.values import is_number

SUMMARY_FILE = "summary.csv"
PLOTS_DIR = "plots"
Status = Literal["ok", "failed", "pending", "not run"]


@dataclass(frozen=True)
class RunRecord:
    """What is known of one planned run: done or not, and its metrics.json if it succeeded."""

    status: Status
    error: str = ""  # one line, for a run that failed or did not run
    metrics: dict | None = None


def write_summary(out_dir: Path, sweep: Sweep, records: dict[str, RunRecord]) -> None:
    """DIR/summary.csv: one row per planned run, in sweep order, metrics as metrics.json names them."""
    metric_columns: dict[str, None] = {}  # ordered set
    rows = []
    for run in sweep.runs:
        record = records[run.run_id]
        metrics = _flat_metrics(record.metrics or {})
        metric_columns.update(dict.fromkeys(metrics))
        parameters = {key: json.dumps(value) if isinstance(value, (list, dict)) else value
                      for key, value in run.parameters.items()}
        limits = "; ".join((record.metrics or {}).get("limits", ()))
        rows.append({"run": run.run_id, **parameters, "seed": run.seed, "status": record.status,
                     "error": record.error, "limits": limits, **metrics})

    def write(path: Path) -> None:
        with open(path, "w", newline="") as f:
            writer = csv.DictWriter(f, ["run", *sweep.keys, "seed", "status", "error", "limits", *metric_columns])
            writer.writeheader()
            writer.writerows(rows)

    write_atomically(out_dir / SUMMARY_FILE, write, owner=out_dir)  # recorded in DIR's manifest


def _flat_metrics(metrics: dict) -> dict[str, float]:
    """The numbers of metrics.json, per axis as 'travel.position_error_max' and of the reclaim as
    'reclaim.mass_t'; with collision shapes, the least clearance to the pile over them, to a
    neighbour's, and the number of contacts; units in docs/batch.md and docs/contracts.md."""
    flat = {}
    for name, value in metrics.items():
        if name in AXES or name == "reclaim":
            flat.update({f"{name}.{key}": v for key, v in value.items() if is_number(v)})
        elif name == "collision":
            flat["collision.clearance_min_m"] = min((v["clearance_m"] for v in value["pile"].values()), default=None)
            if "machines" in value:
                flat["collision.neighbour_clearance_min_m"] = min(v["clearance_m"] for v in value["machines"].values())
            flat["collision.contacts"] = len(value["contacts"])
        elif is_number(value):
            flat[name] = value
    return flat



def write_plots(out_dir: Path, sweep: Sweep, records: dict[str, RunRecord]) -> list[Path]:
    """Error distributions over the successful runs, and heat maps when the sweep is a 2-D grid."""
    done = [run for run in sweep.runs if records[run.run_id].status == "ok"]
    if not done:
        return []
    folder = out_dir / PLOTS_DIR
    folder.mkdir(exist_ok=True)  # its files appear atomically, one by one
    paths = [_distribution_plot(folder / "error_distributions.png", sweep, done, records)]
    grid = sweep.grid_keys()
    if grid:
        paths.append(_heat_map(folder / "heat_map_position_error.png", sweep, grid, done, records))
    return paths


_QUANTITIES = (("position", "position_error_max", ""), ("velocity", "velocity_error_max", "/s"),
               ("acceleration", "acceleration_error_max", "/s²"))
_ANNOTATED_CELLS = 100  # up to this many heat map cells carry their value as text
MAX_BOXES = 60  # settings a distribution plot draws a box each; more are drawn as one


def _magnitude(record: RunRecord, axis: int, key: str) -> float:
    """|metric| of one axis in display units (m, deg)."""
    return abs(to_display(axis, record.metrics[AXES[axis]][key]))


def _distribution_plot(path: Path, sweep: Sweep, done: list[PlannedRun],
                       records: dict[str, RunRecord]) -> Path:
    """One box per setting of the varied keys, over its seeds; every run also as a dot."""
    from matplotlib.figure import Figure  # no pyplot: no global state, no display backend

    groups: dict[str, list[PlannedRun]] = {}
    for run in done:
        groups.setdefault(", ".join(run.value_labels.values()) or f"{len(done)} runs", []).append(run)
    if len(groups) > MAX_BOXES:  # drawn scenarios, each its own setting: one distribution of them all
        groups = {f"{len(done)} runs, {len(groups)} settings": done}
    width = min(24.0, 10.0 + 0.4 * len(groups))  # in: many settings need room for their labels
    fig = Figure(figsize=(width, 9), layout="constrained")
    axes = fig.subplots(3, 3, sharex=True)
    for j in range(len(AXES)):
        for column, (quantity, key, per) in enumerate(_QUANTITIES):
            ax = axes[j, column]
            values = [[_magnitude(records[run.run_id], j, key) for run in runs] for runs in groups.values()]
            ax.boxplot(values, showfliers=False)
            for x, group in enumerate(values, start=1):
                ax.plot(x + np.linspace(-0.15, 0.15, len(group)), group, ".", color="C0", alpha=0.6)
            ax.set_ylabel(f"{AXES[j]} [{UNITS[j]}{per}]")
            ax.grid(alpha=0.3)
            axes[0, column].set_title(f"|{quantity} error max|")
    for ax in axes[-1]:
        ax.set_xticks(range(1, len(groups) + 1), list(groups), rotation=30 if len(groups) > 1 else 0,
                      ha="right" if len(groups) > 1 else "center")
        ax.set_xlabel(", ".join(parameter_label(key) for key in sweep.keys) or "seeds")
    fig.suptitle(f"{sweep.path.stem}: largest errors of {len(done)} runs (box: quartiles, whiskers: 1.5 IQR)")
    write_atomically(path, lambda tmp: fig.savefig(tmp, dpi=110, format="png"), owner=path.parent.parent)
    return path


def _heat_map(path: Path, sweep: Sweep, grid: tuple[str, str], done: list[PlannedRun],
              records: dict[str, RunRecord]) -> Path:
    """|position error max| per axis over the grid, the median over seeds in each cell."""
    from matplotlib.colors import LogNorm, Normalize
    from matplotlib.figure import Figure

    x_key, y_key = grid
    xs = sorted({run.parameters[x_key] for run in sweep.runs})
    ys = sorted({run.parameters[y_key] for run in sweep.runs})
    fig = Figure(figsize=(17, 5), layout="constrained")
    axes = fig.subplots(1, 3)
    for j, ax in enumerate(axes):
        cells: dict[tuple[int, int], list[float]] = {}
        for run in done:
            cell = (ys.index(run.parameters[y_key]), xs.index(run.parameters[x_key]))
            cells.setdefault(cell, []).append(_magnitude(records[run.run_id], j, "position_error_max"))
        median = np.full((len(ys), len(xs)), np.nan)  # NaN: no successful run in that cell
        for (row, column), values in cells.items():
            median[row, column] = np.median(values)
        low, high = np.nanmin(median), np.nanmax(median)
        norm = LogNorm(low, high) if low > 0 and high > 10 * low else Normalize(low, high)  # log: decades
        mesh = ax.pcolormesh(np.ma.masked_invalid(median), norm=norm, cmap="viridis")
        if median.size <= _ANNOTATED_CELLS:
            for (row, column), value in np.ndenumerate(median):
                if np.isfinite(value):
                    ax.text(column + 0.5, row + 0.5, f"{value:.3g}", ha="center", va="center", fontsize=8,
                            color="white" if norm(value) < 0.5 else "black")
        ax.set_facecolor("0.85")
        ax.set_xticks(np.arange(len(xs)) + 0.5, [f"{x:g}" for x in xs])
        ax.set_yticks(np.arange(len(ys)) + 0.5, [f"{y:g}" for y in ys])
        ax.set_xlabel(parameter_label(x_key))
        ax.set_ylabel(parameter_label(y_key))
        ax.set_title(f"{AXES[j]}: |position error max| [{UNITS[j]}]")
        fig.colorbar(mesh, ax=ax, label=f"{AXES[j]} [{UNITS[j]}], median over seeds")
    fig.suptitle(f"{sweep.path.stem}: largest position error over the grid (grey: no successful run)")
    write_atomically(path, lambda tmp: fig.savefig(tmp, dpi=110, format="png"), owner=path.parent.parent)
    return path


def spread_table(sweep: Sweep, records: dict[str, RunRecord]) -> str:
    """Smallest, median and largest |error max| per axis over the successful runs, in m and degrees."""
    done = [records[run.run_id] for run in sweep.runs if records[run.run_id].status == "ok"]
    if not done:
        return "no successful run"
    lines = [f"|largest error| over {len(done)} successful runs: smallest / median / largest"]
    for quantity, key, per in _QUANTITIES:
        for j, axis in enumerate(AXES):
            values = np.array([_magnitude(record, j, key) for record in done])
            lines.append(f"  {axis:<6} {quantity:<12} {values.min():.4g} / {np.median(values):.4g} / "
                         f"{values.max():.4g} {UNITS[j]}{per}")
    return "\n".join(lines)
