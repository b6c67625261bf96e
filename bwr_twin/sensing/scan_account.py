"""What the runs' scans told them, noted as the periods pass: the scanned pile's tonnes against
the truth when each run's wheel first cut and as its benches were planned (bwr_twin.sensing.
scanning only scans); and from these the `scan` object of metrics.json and each run's record of
its scans."""

from __future__ import annotations

import math

import numpy as np

from bwr_twin.sensing.outputs import KnownPile, ScanRecord
from bwr_twin.sensing.scanning import Scanning


class ScanAccount:
    """Each run's notes of its scanned pile.

    Attributes:
        first_cut: per run, the scanned pile's tonnes against the truth when its wheel first cut.
        plan_start: ... as the benches were planned, after a survey; None before.
    """

    def __init__(self, scanning: Scanning, density: np.ndarray):
        """`density`: each run's bulk density, kg/m^3."""
        runs = len(density)
        self._scanning, self._density = scanning, np.asarray(density, dtype=float)
        self.first_cut: list[dict | None] = [None] * runs
        self.plan_start: list[dict | None] = [None] * runs
        self._known_at_plan: list[KnownPile | None] = [None] * runs

    @property
    def awaiting_first_cut(self) -> bool:
        """Whether a run's wheel has yet to cut."""
        return None in self.first_cut

    def note_first_cut(self, time: float, cut: np.ndarray, heights: np.ndarray) -> None:
        """Keep the scanned pile's tonnes against the truth (heights (runs, ny, nx) m) for the
        runs whose wheel has cut (`cut` (runs,) bool) and had not before, at `time` s."""
        survey = self._scanning.survey
        for run in np.flatnonzero(cut):
            if self.first_cut[run] is None:
                self.first_cut[run] = {"time_s": time, **survey.tonnes(run, heights[run], self._density[run])}

    def note_plan_start(self, time: float, heights: np.ndarray) -> None:
        """Keep every run's scanned pile, and its tonnes against the truth (heights (runs, ny, nx)
        m), as the survey ends and the benches are planned, at `time` s."""
        scanning = self._scanning
        for run in range(len(self.plan_start)):
            self.plan_start[run] = {"time_s": time, **scanning.survey.tonnes(run, heights[run], self._density[run])}
            self._known_at_plan[run] = scanning.known(run, time)

    def metrics(self, run: int, heights: np.ndarray) -> dict:
        """metrics.json's `scan` object of `run`, whose pile now stands at heights (ny, nx) m."""
        return {**self._scanning.metrics(run, heights, self._density[run]), "first_cut": self.first_cut[run],
                "plan_start": self.plan_start[run]}

    def record(self, run: int, time: float = math.nan) -> ScanRecord:
        """Run `run`'s scans, and its scanned pile at the end, `time` s, and at the plan's start."""
        return self._scanning.record(run, time, self._known_at_plan[run])
