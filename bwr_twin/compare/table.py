"""The comparison table: per controller and axis, over the seeds, the figures a control engineer
compares, from the runs' metrics.json.

comparison.csv holds them in SI units (m, rad, N, N m, J; the share as a fraction), one row per
controller and axis, as metrics.json and a batch's summary.csv do; comparison.md shows one table
per axis in engineering units (mm or deg, kN or kN m, kJ, %).
"""

from __future__ import annotations

import csv
import io
from collections.abc import Sequence

import numpy as np

from bwr_twin.model.machine import AXES

# (metrics.json key, how the seeds combine, heading, display unit per axis, display scale per axis)
COLUMNS = (
    ("position_error_max", "worst", "position error max", ("mm", "deg", "deg"), (1e3, np.degrees(1), np.degrees(1))),
    ("position_error_rms", "mean", "position error RMS", ("mm", "deg", "deg"), (1e3, np.degrees(1), np.degrees(1))),
    ("velocity_error_max", "worst", "velocity error max", ("mm/s", "deg/s", "deg/s"),
     (1e3, np.degrees(1), np.degrees(1))),
    ("drive_force_max", "worst", "drive force max", ("kN", "kN m", "kN m"), (1e-3,) * 3),
    ("drive_force_rms", "mean", "drive force RMS", ("kN", "kN m", "kN m"), (1e-3,) * 3),
    ("drive_energy", "mean", "drive energy", ("kJ",) * 3, (1e-3,) * 3),
    ("saturation_fraction", "mean", "time at saturation", ("%",) * 3, (100.0,) * 3),
)


def comparison_rows(labels: Sequence[str], metrics: Sequence[Sequence[dict]]) -> list[dict]:
    """One row per controller and axis, in SI units: metrics[c][s] is controller c's metrics.json
    for seed s. 'worst' is the largest magnitude over the seeds, 'mean' the mean magnitude."""
    rows = []
    for label, runs in zip(labels, metrics):
        for axis in AXES:
            row: dict = {"controller": label, "axis": axis, "seeds": len(runs)}
            for key, combine, *_ in COLUMNS:
                values = np.abs([run[axis][key] for run in runs])
                row[key] = float(values.max() if combine == "worst" else values.mean())
            rows.append(row)
    return rows


def as_csv(rows: list[dict]) -> str:
    out = io.StringIO()
    writer = csv.DictWriter(out, list(rows[0]))
    writer.writeheader()
    writer.writerows(rows)
    return out.getvalue()


def as_markdown(rows: list[dict]) -> str:
    """One table per axis, controllers as rows, in engineering units."""
    blocks = []
    for j, axis in enumerate(AXES):
        seeds = rows[0]["seeds"]
        headings = [f"{heading} [{units[j]}]" for _, _, heading, units, _ in COLUMNS]
        lines = [f"**{axis}** ({seeds} seed{'s' if seeds > 1 else ''}: worst max, mean RMS)", "",
                 "| controller | " + " | ".join(headings) + " |", "| --- |" + " --- |" * len(headings)]
        for row in (r for r in rows if r["axis"] == axis):
            cells = [f"{row[key] * scales[j]:.4g}" for key, _, _, _, scales in COLUMNS]
            lines.append(f"| {row['controller']} | " + " | ".join(cells) + " |")
        blocks.append("\n".join(lines))
    return "\n\n".join(blocks) + "\n"
