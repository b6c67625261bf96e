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
        self._bucket = Bucket(wheel.bucket_volume, runs)
        self._discharge_at = self.bucket_interval  # s
        self._next_rate: np.ndarray | None = None  # t/h the belt carries from the next period on
        self._hold_end = -1  # the last period of the current belt load
        self.rate = np.zeros(runs)
        self.discharged = np.zeros(runs)
        self._discharging = False  # a bucket discharged as the last period ended
        self.hold: tuple[np.ndarray, np.ndarray, int] | None = None

    @property
    def bucket(self) -> np.ndarray:
        return self._bucket.held

    @property
    def bucket_grade(self) -> np.ndarray | None:
        return self._bucket.grade

    @property
    def dug(self) -> np.ndarray:
        return self._bucket.dug

    @property
    def carried(self) -> np.ndarray:
        return self._bucket.carried

    @property
    def spilled(self) -> np.ndarray:
        return self._bucket.spilled

    @property
    def spilled_grade(self) -> np.ndarray:
        return self._bucket.spilled_grade

    @property
    def discharged_grade(self) -> np.ndarray:
        return self._bucket.discharged_grade

    def track_grade(self) -> None:
        """Carry the grade of what is dug: `load` is then given its grade x volume."""
        self._bucket.track_grade()

    def load(self, k: int, volume: np.ndarray, grade_volume: np.ndarray | None = None) -> None:
        """Period k's cut, `volume` (runs,) m^3 (and on a graded pile its grade x m^3), goes into
        the buckets; one discharges as the period ends if its interval is up."""
        self.hold = None
        if self._next_rate is not None:  # a bucket discharged as the last period ended
            self.rate[:] = self._next_rate
            self._next_rate = None
        self._bucket.fill(volume, grade_volume)
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
        self.discharged[:] = self._bucket.empty()
        self._discharging = True
        self.hold = None
        beyond = self._hold_end - k
        if beyond > 0:
            rate = self._next_rate if self._next_rate is not None else self.rate
            self.hold = (rate, -rate * beyond * self.period / (self.density * (SECONDS_PER_HOUR / KG_PER_T)), -beyond)

    def _discharge_onto_belt(self, k: int) -> None:
        """The bucket discharges as period k ends; the belt carries its load, evenly, over the
        periods until the next discharge. The rate is constant over them: an account adds its
        statistics for the whole hold at once (`hold`; after the last period, the part beyond the
        end is taken off again)."""
        carried = self._bucket.empty()
        self.discharged[:] = carried
        self._discharging = True
        following = self._discharge_at + self.bucket_interval
        periods = int(np.ceil(following / self.period - 1e-9)) - (k + 1)
        rate = carried / (periods * self.period) * self.density * (SECONDS_PER_HOUR / KG_PER_T)  # t/h
        self.hold = (rate, carried, periods)
        self._next_rate, self._hold_end = rate, k + periods
        self._discharge_at = following


class Bucket:
    """The bucket in the cut, for every run: (runs,) arrays of what it holds and what it has
    carried onto the belt and spilled, each discharge up to the bucket's volume.

    Attributes:
        held: m^3 in the bucket in the cut; `grade` its grade x m^3, if graded (else None).
        dug, carried, spilled: m^3 so far; `spilled_grade` the grade x m^3 spilled.
        discharged_grade: the grade of the last discharge, on a graded pile (NaN: none).
    """

    def __init__(self, volume: float, runs: int):
        self._volume = volume  # m^3 a bucket carries at most
        self.held = np.zeros(runs)
        self.grade: np.ndarray | None = None
        self.dug, self.carried, self.spilled = np.zeros(runs), np.zeros(runs), np.zeros(runs)
        self.discharged_grade = np.full(runs, np.nan)
        self.spilled_grade = np.zeros(runs)

    def track_grade(self) -> None:
        self.grade = np.zeros(len(self.held))

    def fill(self, volume: np.ndarray, grade_volume: np.ndarray | None) -> None:
        """The period's cut, `volume` (runs,) m^3 (and on a graded pile its grade x m^3), goes in."""
        self.dug += volume
        self.held += volume
        if self.grade is not None:
            self.grade += grade_volume

    def empty(self) -> np.ndarray:
        """Empty the bucket: up to its volume is carried, the rest spills; m^3 carried."""
        carried = np.minimum(self.held, self._volume)
        self.carried += carried
        self.spilled += self.held - carried
        if self.grade is not None:
            self.discharged_grade[:] = np.nan
            for run in np.flatnonzero(carried > 0):
                grade = self.grade[run] / self.held[run]  # mixed: carried and spilled alike
                self.spilled_grade[run] += grade * (self.held[run] - carried[run])
                self.discharged_grade[run] = grade
            self.grade[:] = 0.0
        self.held[:] = 0.0
        return carried
