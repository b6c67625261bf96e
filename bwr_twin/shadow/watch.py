"""The shadow over a recorded log: its residuals, the alarms they raise, and the gaps, as events."""

from __future__ import annotations

import csv
import json
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from bwr_twin.shadow.detect import AXES, Alarm, Thresholds, assess, learn
from bwr_twin.shadow.measured import Measured, encoder_counts, read_measured
from bwr_twin.shadow.twin import Blocks, ShadowTwin

# The residuals' columns per axis, with their units (travel's first, slew's and luff's second).
_RESIDUALS = (("force", ("N", "Nm")), ("position", ("m", "rad")), ("speed", ("m/s", "rad/s")),
              ("drift", ("m/s", "rad/s")))


@dataclass(frozen=True)
class Watched:
    """What the shadow made of a log: its samples, blocks, gaps and alarms, and the health of
    each axis and the wheel end at its end (%, bwr_twin.shadow.detect.assess)."""

    measured: Measured
    blocks: Blocks
    gaps: list[tuple[float, float]]
    alarms: list[Alarm]
    health: dict[str, float]

    def events(self) -> list[dict]:
        """The log's events in time order, as JSON lines hold them."""
        events = [{"event": "gap", "time_s": start, "from_s": start, "to_s": end,
                   "meaning": "no samples: nothing is concluded over it"} for start, end in self.gaps]
        events += [alarm.event() for alarm in self.alarms]
        return sorted(events, key=lambda e: e["time_s"])


def learn_from(twin: ShadowTwin, logs: Sequence[Path], per_hour: float, *, ignore_wind: bool = False) -> Thresholds:
    """Thresholds from the fault-free logs at `logs`, of one machine (`ignore_wind`: as a shadow
    without the logs' anemometer would learn them)."""
    measured = [read_measured(log, twin.limits, wind=not ignore_wind) for log in logs]
    counts = np.min([encoder_counts(m) for m in measured], axis=0)  # the finest step any log saw
    return learn([twin.blocks(m) for m in measured], counts, per_hour)


def watch(twin: ShadowTwin, log: Path, thresholds: Thresholds, *, ignore_wind: bool = False) -> Watched:
    """The shadow over the log at `log` (a run directory or its timeseries.csv); `ignore_wind`:
    as a shadow without the log's anemometer would watch it."""
    measured = read_measured(log, twin.limits, wind=not ignore_wind)
    blocks = twin.blocks(measured)
    alarms, health = assess(blocks, thresholds)
    return Watched(measured, blocks, measured.gaps(), alarms, health)


def write_outputs(folder: Path, watched: Watched, thresholds: Thresholds) -> None:
    """events.jsonl, residuals.csv and thresholds.json into `folder`."""
    with open(folder / "events.jsonl", "w") as f:
        f.writelines(json.dumps(event) + "\n" for event in watched.events())
    thresholds.write(folder / "thresholds.json")
    blocks = watched.blocks
    header = ["start_s", "end_s"] + [f"{name}_{axis}_{units[0 if j == 0 else 1]}" for name, units in _RESIDUALS
                                     for j, axis in enumerate(AXES)]
    columns = [blocks.start, blocks.end] + [getattr(blocks, name)[:, j] for name, _ in _RESIDUALS for j in range(3)]
    with open(folder / "residuals.csv", "w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(header)
        writer.writerows(np.column_stack(columns).tolist())
