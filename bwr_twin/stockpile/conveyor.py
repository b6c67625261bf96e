"""The bucket in the cut and the boom conveyor, for every run of a lockstep.

What the wheel digs goes into the bucket in the cut. Every bucket interval (60 s over the
discharges a minute) that bucket discharges up to its volume onto the boom conveyor; the rest
spills and is reported, not counted as reclaimed. The reclaim rate is the conveyor's load: each
discharge spread over the next bucket interval, as a belt scale sees it. So the rate's integral
is exactly what the buckets discharged, once the last discharge has passed.

On a pile whose grade is known (a stacked one, bwr_twin.stockpile.stacked), the bucket also
carries the grade x volume of what it dug, mixed: a discharge carries its share of it and the
spill the rest, and each discharge's time, volume and grade are kept (`discharges`).
"""

from __future__ import annotations

import numpy as np

from bwr_twin.model.machine import Wheel
from bwr_twin.units import KG_PER_T, SECONDS_PER_HOUR


class Conveyor:
    """(runs,) arrays: what each bucket holds, the belt's rate and the totals.

    Attributes:
        rate: t/h on the belt this period.
        discharged: m^3 the buckets discharged onto the belt as this period ended (0: none).
        dug, carried, spilled, conveyed: m^3 so far (conveyed: the rate's integral).
    """

    def __init__(self, wheel: Wheel, density: np.ndarray, period: float):
        runs = len(density)
        self.wheel, self.density, self.period = wheel, density, period
        self.bucket_interval = wheel.bucket_interval  # s
        self.bucket = np.zeros(runs)  # m^3 in the bucket in the cut
        self._discharge_at = self.bucket_interval  # s
        self._next_rate: np.ndarray | None = None  # t/h the belt carries from the next period on
        self._hold_end = -1  # the last period of the current belt load
        self.rate = np.zeros(runs)
        self.discharged = np.zeros(runs)
        self._discharging = False  # a bucket discharged as the last period ended
        self.dug, self.carried, self.spilled = np.zeros(runs), np.zeros(runs), np.zeros(runs)
        self.conveyed = np.zeros(runs)
        self.carrying_periods = np.zeros(runs, dtype=np.int64)
        self.rate_sum, self.rate_square_sum = np.zeros(runs), np.zeros(runs)  # t/h, over carrying periods
        self.rate_max = np.zeros(runs)
        self.bucket_grade: np.ndarray | None = None  # grade x m^3 in the bucket in the cut, if graded
        self.discharges: list[list[tuple[float, float, float]]] = [[] for _ in range(runs)]
        self.spilled_grade = np.zeros(runs)  # grade x m^3 spilled

    def track_grade(self) -> None:
        """Carry the grade of what is dug: `load` is then given its grade x volume."""
        self.bucket_grade = np.zeros(len(self.bucket))

    def load(self, k: int, volume: np.ndarray, grade_volume: np.ndarray | None = None) -> None:
        """Period k's cut, `volume` (runs,) m^3 (and on a graded pile its grade x m^3), goes into
        the buckets; one discharges as the period ends if its interval is up."""
        if self._next_rate is not None:  # a bucket discharged as the last period ended
            self.rate[:] = self._next_rate
            self._next_rate = None
        self.dug += volume
        self.bucket += volume
        if self.bucket_grade is not None:
            self.bucket_grade += grade_volume
        if self._discharging:
            self.discharged[:] = 0.0
            self._discharging = False
        if (k + 1) * self.period >= self._discharge_at - 1e-9:
            self._discharge_onto_belt(k)

    def carried_tonnes(self) -> np.ndarray:
        """(runs,) t the buckets have discharged onto the belt so far."""
        return self.carried * self.density / KG_PER_T

    def finish(self, k: int) -> None:
        """After the last period k: the bucket in the cut discharges, and what the belt would
        carry after the end is not counted as conveyed."""
        self.discharged[:] = self._discharge((k + 1) * self.period)
        self._discharging = True
        beyond = self._hold_end - k
        if beyond > 0:
            rate = self._next_rate if self._next_rate is not None else self.rate
            self._add_hold(rate, -rate * beyond * self.period / (self.density * (SECONDS_PER_HOUR / KG_PER_T)), -beyond)

    def metrics(self, run: int) -> dict:
        """The conveyor's share of metrics.json's `reclaim` object (output contract)."""
        tonnes = self.density[run] / KG_PER_T  # per m^3
        periods = max(int(self.carrying_periods[run]), 1)
        mean = self.rate_sum[run] / periods
        variance = max(self.rate_square_sum[run] / periods - mean**2, 0.0)
        return {
            "mass_t": self.carried[run] * tonnes,
            "volume_m3": float(self.carried[run]),
            "rate_mean_tph": mean,
            "rate_cv": float(np.sqrt(variance) / mean) if mean > 0 else 0.0,
            "spill_t": self.spilled[run] * tonnes,
            "rate_max_tph": float(self.rate_max[run]),
            "carrying_time_s": int(self.carrying_periods[run]) * self.period,
            "conveyed_t": self.conveyed[run] * tonnes,
            "dug_m3": float(self.dug[run]),
        }

    def _discharge(self, time: float) -> np.ndarray:
        """Empty the bucket in the cut at `time` (s): up to its volume is carried, the rest spills;
        m^3 carried."""
        carried = np.minimum(self.bucket, self.wheel.bucket_volume)
        self.carried += carried
        self.spilled += self.bucket - carried
        if self.bucket_grade is not None:
            for run in np.flatnonzero(carried > 0):
                grade = self.bucket_grade[run] / self.bucket[run]  # mixed: carried and spilled alike
                self.spilled_grade[run] += grade * (self.bucket[run] - carried[run])
                self.discharges[run].append((time, float(carried[run]), float(grade)))
            self.bucket_grade[:] = 0.0
        self.bucket[:] = 0.0
        return carried

    def _discharge_onto_belt(self, k: int) -> None:
        """The bucket discharges as period k ends; the belt carries its load, evenly, over the
        periods until the next discharge. The rate is constant over them: its statistics are
        added for the whole hold at once (and the part beyond the end taken off again)."""
        carried = self._discharge((k + 1) * self.period)
        self.discharged[:] = carried
        self._discharging = True
        following = self._discharge_at + self.bucket_interval
        periods = int(np.ceil(following / self.period - 1e-9)) - (k + 1)
        rate = carried / (periods * self.period) * self.density * (SECONDS_PER_HOUR / KG_PER_T)  # t/h
        self._add_hold(rate, carried, periods)
        self._next_rate, self._hold_end = rate, k + periods
        self._discharge_at = following

    def _add_hold(self, rate: np.ndarray, conveyed: np.ndarray, periods: int) -> None:
        """Count `periods` control periods at `rate` (t/h) that convey `conveyed` (m^3); negative
        `periods` take them off again."""
        self.conveyed += conveyed
        self.carrying_periods += periods * (rate > 0)
        self.rate_sum += periods * rate
        self.rate_square_sum += periods * rate**2
        if periods > 0:
            np.maximum(self.rate_max, rate, out=self.rate_max)
