"""How well each run carried out its bench plan (docs/reclaiming.md), measured period by period:
the rate in steady cutting (two bucket intervals after the wheel entered a full face, so that
the belt carries what it cut), the landing (where the wheel first touched the pile, against
where the planner predicted it would), the over-cut beyond the planned cut, and the tonnes of
each bench.
"""

from __future__ import annotations

import numpy as np

from bwr_twin.planning.follower import Phase
from bwr_twin.planning.plan import BenchPlan
from bwr_twin.units import KG_PER_T

RATE_BAND = 0.1  # of the target: the band the steady rate is counted within


class PlanOutcome:
    """(runs,) measures of a lockstep's runs against their plan."""

    def __init__(self, plan: BenchPlan, target: np.ndarray, bucket_interval: float, period: float):
        runs = len(target)
        self.plan, self.target, self.period = plan, target, period  # target t/h
        # The belt carries a cut a bucket interval later, and holds it one more.
        self._settle = int(np.ceil(2 * bucket_interval / period))
        self._steady_for = np.zeros(runs, dtype=np.int64)  # periods in steady cutting so far
        self.steady_periods = np.zeros(runs, dtype=np.int64)
        self.steady_sum, self.steady_square_sum = np.zeros(runs), np.zeros(runs)
        self.steady_within = np.zeros(runs, dtype=np.int64)
        self.contact = np.full((runs, 3), np.nan)  # world m: the CP when the wheel first cut
        self.contact_time = np.full(runs, np.nan)
        self.overcut_max, self.overcut_time = np.zeros(runs), np.zeros(runs)  # m, s
        self.bench_carried = np.zeros((runs, plan.benches))  # m^3
        self._bench = np.zeros(runs, dtype=np.int64)
        self._runs = np.arange(runs)

    def add(self, k: int, phase: Phase, reclaim) -> None:
        """Period k, in which the runs stood at `phase` and their reclaim (bwr_twin.stockpile.
        reclaim.Reclaim) cut, carried and discharged what it did."""
        self._bench[:] = phase.bench
        cut, cp = reclaim.cut, reclaim.cp
        cutting = cut.volume > 0
        if cutting.any():
            self._cutting(k, phase, cut, cp, cutting, reclaim.rate)
        else:
            self._steady_for[:] = 0
        self.discharged(reclaim.conveyor.discharged)

    def discharged(self, volume: np.ndarray) -> None:
        """The buckets discharged `volume` (runs,) m^3 onto the belt in the current bench."""
        if volume.any():
            np.add.at(self.bench_carried, (self._runs, self._bench), volume)

    def _cutting(self, k: int, phase: Phase, cut, cp: np.ndarray, cutting: np.ndarray, rate: np.ndarray) -> None:
        first = cutting & np.isnan(self.contact_time)
        if first.any():
            self.contact[first] = cp[first]
            self.contact_time[first] = k * self.period
        if phase.steady.any():  # entering or leaving the face, the cut depth is the wheel's side
            over = np.where(phase.steady & cutting, cut.depth - phase.planned_depth, 0.0)
            larger = over > self.overcut_max
            self.overcut_max[larger] = over[larger]
            self.overcut_time[larger] = k * self.period
        self._steady_for = np.where(phase.steady, self._steady_for + 1, 0)
        counted = self._steady_for > self._settle
        if counted.any():
            self.steady_periods += counted
            self.steady_sum += np.where(counted, rate, 0.0)
            self.steady_square_sum += np.where(counted, rate**2, 0.0)
            self.steady_within += counted & (np.abs(rate - self.target) <= RATE_BAND * self.target)

    def metrics(self, run: int, density: float) -> dict:
        """The plan's share of metrics.json's `reclaim` object for `run`; `density` kg/m^3."""
        tonnes = density / KG_PER_T
        periods = int(self.steady_periods[run])
        mean = self.steady_sum[run] / periods if periods else 0.0
        variance = max(self.steady_square_sum[run] / periods - mean**2, 0.0) if periods else 0.0
        predicted = self.plan.first_contact
        landing = (float(np.linalg.norm(self.contact[run] - predicted))
                   if predicted is not None and not np.isnan(self.contact_time[run]) else None)
        return {
            "target_rate_tph": float(self.target[run]),
            "steady_time_s": periods * self.period,
            "steady_rate_mean_tph": mean,
            "steady_rate_cv": float(np.sqrt(variance) / mean) if mean > 0 else None,
            "steady_within_10pct": float(self.steady_within[run] / periods) if periods else None,
            "landing_error_m": landing,
            "first_contact_time_s": None if np.isnan(self.contact_time[run]) else float(self.contact_time[run]),
            "overcut_max_m": float(self.overcut_max[run]),
            "overcut_max_time_s": float(self.overcut_time[run]),
            "bench_t": [float(v * tonnes) for v in self.bench_carried[run]],
            "bench_planned_t": self.plan.bench_tonnes(),
        }
