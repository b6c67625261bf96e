"""The bucket in the cut and the boom conveyor, for every run of a lockstep.

What the wheel digs goes into the bucket in the cut. Every bucket interval (60 s over the
discharges a minute) that bucket discharges up to its volume onto the boom conveyor; the rest
spills and is reported, not counted as reclaimed. The reclaim rate is the conveyor's load: each
discharge spread over the next bucket interval, as a belt scale sees it. So the rate's integral
is exactly what the buckets discharged, once the last discharge has passed.

On a pile whose grade is known (a stacked one, bwr_twin.stockpile.stacked), the bucket also
carries the grade x volume of what it dug, mixed: a discharge carries its share of it and the
spill the rest (`discharged_grade`).

The conveyor only models: what the belt carried over time (its rate's statistics, each
discharge) is kept by an account that reads `discharged` and `hold` every period
(bwr_twin.stockpile.reclaim_account).
"""

from __future__ import annotations

import numpy as np

from bwr_twin.model.machine import Wheel
from bwr_twin.units import KG_PER_T, SECONDS_PER_HOUR


class Conveyor:
    """(runs,) arrays: what each bucket holds, the belt's rate and the totals.

    Attributes:
        rate: t/h on the belt this period.
        discharged: m^3 the buckets discharged onto the belt as this period ended (0: none);
            `discharged_grade` the grade they carried, on a graded pile.
        hold: the belt's load begun as this period ended (or, after the last, taken off again
            beyond it), (rate t/h (runs,), m^3 conveyed (runs,), control periods), or None.
        dug, carried, spilled: m^3 so far.
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
        self.hold: tuple[np.ndarray, np.ndarray, int] | None = None
        self.bucket_grade: np.ndarray | None = None  # grade x m^3 in the bucket in the cut, if graded
        self.discharged_grade = np.full(runs, np.nan)
        self.spilled_grade = np.zeros(runs)  # grade x m^3 spilled

    def track_grade(self) -> None:
        """Carry the grade of what is dug: `load` is then given its grade x volume."""
        self.bucket_grade = np.zeros(len(self.bucket))

    def load(self, k: int, volume: np.ndarray, grade_volume: np.ndarray | None = None) -> None:
        """Period k's cut, `volume` (runs,) m^3 (and on a graded pile its grade x m^3), goes into
        the buckets; one discharges as the period ends if its interval is up."""
        self.hold = None
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
        self.discharged[:] = self._discharge()
        self._discharging = True
        self.hold = None
        beyond = self._hold_end - k
        if beyond > 0:
            rate = self._next_rate if self._next_rate is not None else self.rate
            self.hold = (rate, -rate * beyond * self.period / (self.density * (SECONDS_PER_HOUR / KG_PER_T)), -beyond)

    def _discharge(self) -> np.ndarray:
        """Empty the bucket in the cut: up to its volume is carried, the rest spills; m^3 carried."""
        carried = np.minimum(self.bucket, self.wheel.bucket_volume)
        self.carried += carried
        self.spilled += self.bucket - carried
        if self.bucket_grade is not None:
            self.discharged_grade[:] = np.nan
            for run in np.flatnonzero(carried > 0):
                grade = self.bucket_grade[run] / self.bucket[run]  # mixed: carried and spilled alike
                self.spilled_grade[run] += grade * (self.bucket[run] - carried[run])
                self.discharged_grade[run] = grade
            self.bucket_grade[:] = 0.0
        self.bucket[:] = 0.0
        return carried

    def _discharge_onto_belt(self, k: int) -> None:
        """The bucket discharges as period k ends; the belt carries its load, evenly, over the
        periods until the next discharge. The rate is constant over them: an account adds its
        statistics for the whole hold at once (`hold`; after the last period, the part beyond the
        end is taken off again)."""
        carried = self._discharge()
        self.discharged[:] = carried
        self._discharging = True
        following = self._discharge_at + self.bucket_interval
        periods = int(np.ceil(following / self.period - 1e-9)) - (k + 1)
        rate = carried / (periods * self.period) * self.density * (SECONDS_PER_HOUR / KG_PER_T)  # t/h
        self.hold = (rate, carried, periods)
        self._next_rate, self._hold_end = rate, k + periods
        self._discharge_at = following
