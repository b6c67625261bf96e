"""What a tuning leaves in DIR, each file written atomically: best_scene.toml, history.csv,
convergence.png and the held-out comparison (held_out.csv, held_out.md)."""

from __future__ import annotations

import csv
import datetime
import io
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from bwr_twin.config.scene_toml import scene_toml
from bwr_twin.config.tuning import Tuning
from bwr_twin.model.machine import AXES, UNITS, to_display
from bwr_twin.ownership import write_atomically
from bwr_twin.tune.scalar import search_name

HELD_OUT_METRICS = ("position_error_max", "position_error_rms", "velocity_error_max", "drive_force_rms")


def write_best_scene(folder: Path, tuning: Tuning, values: Sequence[float], objective: float,
                     evaluations: int, stopped: str) -> None:
    scene = tuning.scene(values, tuning.base.simulation.seed)
    header = (f"Found by python -m bwr_twin.tune {tuning.path} on {datetime.date.today().isoformat()}:\n"
              f"{search_name(len(tuning.parameters))} over {', '.join(p.key for p in tuning.parameters)},\n"
              f"{evaluations} evaluations on training seeds {list(tuning.training_seeds)} ({stopped}); objective "
              f"{objective:.4g}\n(the start scores the sum of the weights; {', '.join(f'{w:g} x {m}' for m, w in tuning.objective.items())},"
              f" each normalised per axis by its value at the start).\n"
              f"Base scene: {tuning.base.path}. Runs as it is: python -m bwr_twin.run best_scene.toml --out DIR")
    text = scene_toml(scene, header)
    write_atomically(folder / "best_scene.toml", lambda partial: partial.write_text(text), owner=folder)


def write_history(folder: Path, rows: list[dict]) -> None:
    names: dict[str, None] = {}
    for row in rows:
        names.update(dict.fromkeys(row))

    def write(partial: Path) -> None:
        with open(partial, "w", newline="") as f:
            writer = csv.DictWriter(f, list(names))
            writer.writeheader()
            writer.writerows(rows)

    write_atomically(folder / "history.csv", write, owner=folder)


def write_convergence(folder: Path, tuning: Tuning, rows: list[dict]) -> None:
    """Every candidate's objective by evaluation, and the best so far (log scale)."""
    feasible = [(i, r["objective"]) for i, r in enumerate(rows) if r["feasible"]]
    fig = Figure(figsize=(9, 5), layout="constrained")
    ax = fig.subplots()
    if feasible:
        index, values = np.array(feasible).T
        ax.semilogy(index, values, "C0.", ms=4, label="candidate")
        ax.semilogy(index, np.minimum.accumulate(values), "C3-", lw=1.5, label="best so far")
    infeasible = [i for i, r in enumerate(rows) if not r["feasible"]]
    if infeasible:
        ax.plot(infeasible, [ax.get_ylim()[1]] * len(infeasible), "kx", ms=5, label="infeasible")
    ax.axhline(rows[0]["objective"], color="k", ls="--", lw=0.8, label="start")
    ax.set_xlabel("evaluation")
    ax.set_ylabel("objective (start = sum of the weights)")
    ax.grid(alpha=0.3, which="both")
    ax.legend(loc="upper right")
    fig.suptitle(f"CMA-ES on {tuning.path.name}: {len(rows)} evaluations")
    write_atomically(folder / "convergence.png", lambda partial: fig.savefig(partial, dpi=110, format="png"),
                     owner=folder)


def held_out_rows(start: Sequence[dict], tuned: Sequence[dict]) -> list[dict]:
    """Per axis and metric: the mean magnitude over the held-out seeds, start and tuned (SI)."""
    rows = []
    for axis in AXES:
        for metric in HELD_OUT_METRICS:
            before = float(np.mean([abs(m[axis][metric]) for m in start]))
            after = float(np.mean([abs(m[axis][metric]) for m in tuned]))
            rows.append({"axis": axis, "metric": metric, "start": before, "tuned": after,
                         "tuned/start": after / before if before else float("nan")})
    return rows


def write_held_out(folder: Path, rows: list[dict], seeds: Sequence[int]) -> str:
    out = io.StringIO()
    writer = csv.DictWriter(out, list(rows[0]))
    writer.writeheader()
    writer.writerows(rows)
    write_atomically(folder / "held_out.csv", lambda partial: partial.write_text(out.getvalue()), owner=folder)
    lines = [f"Held-out seeds {list(seeds)} (never seen by the tuner): mean over the seeds.", "",
             "| axis | metric | start | tuned | tuned / start |", "| --- | --- | --- | --- | --- |"]
    for row in rows:
        j = AXES.index(row["axis"])
        unit = (UNITS[j] if "error" in row["metric"] else ("N", "N m", "N m")[j]) + (
            "/s" if row["metric"].startswith("velocity") else "")
        show = (lambda v: to_display(j, v)) if "error" in row["metric"] else (lambda v: v)
        lines.append(f"| {row['axis']} | {row['metric']} [{unit}] | {show(row['start']):.4g} | "
                     f"{show(row['tuned']):.4g} | {row['tuned/start']:.3f} |")
    text = "\n".join(lines) + "\n"
    write_atomically(folder / "held_out.md", lambda partial: partial.write_text(text), owner=folder)
    return text
