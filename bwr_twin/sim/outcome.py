"""How well each run carried out its bench plan (docs/reclaiming.md), measured period by period:
the rate in steady cutting (two bucket intervals after the wheel entered a full face, so that
the belt carries what it cut), the landing (where the wheel first touched the pile, against
where the planner predicted it would), the over-cut beyond the planned cut, and the tonnes of
each bench.
"""

from __future__ import annotations

import math

import numba
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
        # The counts and measures each period adds to, two arrays for one compiled call a period.
        # Counts: periods in steady cutting in a row; periods counted steady, and of these within
        # the band; the bench. Measures: t/h summed and squared over the steady periods; s of the
        # first cut; m and s of the largest over-cut.
        self._counts = np.zeros((4, runs), dtype=np.int64)
        self._measures = np.zeros((5, runs))
        self._measures[2] = np.nan
        self.contact = np.full((runs, 3), np.nan)  # world m: the CP when the wheel first cut
        self.bench_carried = np.zeros((runs, plan.benches))  # m^3

    def add(self, k: int, phase: Phase, reclaim) -> None:
        """Period k, in which the runs stood at `phase` and their reclaim (bwr_twin.stockpile.
        reclaim.Reclaim) cut, carried and discharged what it did."""
        cut = reclaim.cut
        _add(k * self.period, self._settle, phase.bench, phase.steady, phase.planned_depth, cut.volume, cut.depth,
             reclaim.cp, reclaim.rate, self.target, self._counts, self._measures, self.contact,
             reclaim.conveyor.discharged, self.bench_carried)

    def discharged(self, volume: np.ndarray) -> None:
        """The buckets discharged `volume` (runs,) m^3 onto the belt in the current bench."""
        _discharged(volume, self._counts[3], self.bench_carried)

    def metrics(self, run: int, density: float) -> dict:
        """The plan's share of metrics.json's `reclaim` object for `run`; `density` kg/m^3."""
        tonnes = density / KG_PER_T
        _, periods, within, _ = (int(count) for count in self._counts[:, run])
        steady_sum, squares, contact_time, overcut_max, overcut_time = (float(m) for m in self._measures[:, run])
        mean = steady_sum / periods if periods else 0.0
        variance = max(squares / periods - mean**2, 0.0) if periods else 0.0
        predicted = self.plan.first_contact
        landing = (float(np.linalg.norm(self.contact[run] - predicted))
                   if predicted is not None and not math.isnan(contact_time) else None)
        return {
            "target_rate_tph": float(self.target[run]),
            "steady_time_s": periods * self.period,
            "steady_rate_mean_tph": mean,
            "steady_rate_cv": float(np.sqrt(variance) / mean) if mean > 0 else None,
            "steady_within_10pct": within / periods if periods else None,
            "landing_error_m": landing,
            "first_contact_time_s": None if math.isnan(contact_time) else contact_time,
            "overcut_max_m": overcut_max,
            "overcut_max_time_s": overcut_time,
            "bench_t": [float(v * tonnes) for v in self.bench_carried[run]],
            "bench_planned_t": self.plan.bench_tonnes(),
        }


@numba.njit(cache=True)
def _add(time, settle, bench, steady, planned_depth, volume, depth, cp, rate, target, counts, measures, contact,
         discharged, bench_carried):  # pragma: no cover - compiled
    """One period's measures for every run (PlanOutcome's counts and measures by row), and what
    its buckets `discharged` (runs,) m^3 carried to its bench."""
    steady_for, steady_periods, steady_within, run_bench = counts[0], counts[1], counts[2], counts[3]
    steady_sum, steady_square_sum, contact_time, overcut_max, overcut_time = (
        measures[0], measures[1], measures[2], measures[3], measures[4])
    run_bench[:] = bench
    _discharged(discharged, run_bench, bench_carried)
    if not (volume > 0).any():
        steady_for[:] = 0
        return
    any_steady = steady.any()
    for r in range(len(volume)):
        cutting = volume[r] > 0
        if cutting and math.isnan(contact_time[r]):
            contact[r] = cp[r]
            contact_time[r] = time
        if any_steady:  # entering or leaving the face, the cut depth is the wheel's side
            over = depth[r] - planned_depth[r] if (steady[r] and cutting) else 0.0
            if over > overcut_max[r]:
                overcut_max[r] = over
                overcut_time[r] = time
        steady_for[r] = steady_for[r] + 1 if steady[r] else 0
        if steady_for[r] > settle:
            steady_periods[r] += 1
            steady_sum[r] += rate[r]
            steady_square_sum[r] += rate[r] * rate[r]
            if abs(rate[r] - target[r]) <= RATE_BAND * target[r]:
                steady_within[r] += 1


@numba.njit(cache=True)
def _discharged(volume, bench, bench_carried):  # pragma: no cover - compiled
    for r in range(len(volume)):
        if volume[r] != 0.0:
            bench_carried[r, bench[r]] += volume[r]
