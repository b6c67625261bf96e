"""What the runs' reclaim did, kept from the model as the periods pass: the deepest cut, the
belt's rate statistics, each graded discharge and the pile as it was dug; and from these the
reclaim's share of metrics.json (`reclaim`, `blend`) and of each run's record.

The model (bwr_twin.stockpile.reclaim: the cut, the bucket and belt, the digging load) only
models; its account reads it once a period, after its step (`observe`), and once after its end
(`finish`).
"""

from __future__ import annotations

import math

import numpy as np

from bwr_twin.stockpile.grade import lots, rms_from, tonne_weighted
from bwr_twin.stockpile.history import PileFrames
from bwr_twin.stockpile.reclaim import Reclaim
from bwr_twin.units import KG_PER_T, SECONDS_PER_HOUR


class ReclaimAccount:
    """(runs,) sums and maxima of the runs' reclaim, and each run's graded discharges.

    Attributes:
        depth_max: m, the deepest cut so far.
        conveyed: m^3 the belt has carried past its scale so far (the rate's integral).
        carrying_periods: control periods the belt carried a load; `rate_sum`, `rate_square_sum`
            (t/h, (t/h)^2) and `rate_max` (t/h) over them.
        discharges: each run's [(time s, m^3 carried, grade)] of its graded discharges.
    """

    def __init__(self, reclaim: Reclaim, frame_every: int | None = None):
        """`frame_every`: keep the cells changed every that many control periods, for a replay."""
        runs = len(reclaim.density)
        self._reclaim, self._frame_every = reclaim, frame_every
        self.depth_max = np.zeros(runs)
        self.conveyed = np.zeros(runs)
        self.carrying_periods = np.zeros(runs, dtype=np.int64)
        self.rate_sum, self.rate_square_sum = np.zeros(runs), np.zeros(runs)
        self.rate_max = np.zeros(runs)
        self.discharges: list[list[tuple[float, float, float]]] = [[] for _ in range(runs)]
        self._frames = PileFrames(reclaim.heights, reclaim.top_grades()) if frame_every else None

    def observe(self, k: int) -> None:
        """Period k's cut, discharge and belt load, after the model's step."""
        reclaim = self._reclaim
        np.maximum(self.depth_max, reclaim.depth, out=self.depth_max)
        self._belt(k)
        if self._frames is not None and k % self._frame_every == 0:
            self._frames.keep(k * reclaim.period, reclaim.heights, reclaim.top_grades())

    def finish(self, k: int) -> None:
        """After the last period k and the model's `finish`: its last discharge, and the belt's
        load beyond the end taken off."""
        self._belt(k)

    def _belt(self, k: int) -> None:
        conveyor = self._reclaim.conveyor
        if conveyor.bucket_grade is not None:  # a graded discharge as period k ended
            time = (k + 1) * conveyor.period
            for run in np.flatnonzero(conveyor.discharged > 0):
                self.discharges[run].append((time, float(conveyor.discharged[run]),
                                             float(conveyor.discharged_grade[run])))
        if conveyor.hold is not None:
            self._add_hold(*conveyor.hold)

    def _add_hold(self, rate: np.ndarray, conveyed: np.ndarray, periods: int) -> None:
        """Count `periods` control periods at `rate` (t/h) that convey `conveyed` (m^3); negative
        `periods` take them off again."""
        self.conveyed += conveyed
        self.carrying_periods += periods * (rate > 0)
        self.rate_sum += periods * rate
        self.rate_square_sum += periods * rate**2
        if periods > 0:
            np.maximum(self.rate_max, rate, out=self.rate_max)

    def metrics(self, run: int) -> dict:
        """metrics.json's `reclaim` object for `run` (output contract), but for a plan's measures."""
        reclaim = self._reclaim
        conveyor, cutter, wheel, density = reclaim.conveyor, reclaim.cutter, reclaim.wheel, reclaim.density[run]
        tonnes = density / KG_PER_T  # per m^3
        periods = max(int(self.carrying_periods[run]), 1)
        mean = self.rate_sum[run] / periods
        variance = max(self.rate_square_sum[run] / periods - mean**2, 0.0)
        return {
            "mass_t": conveyor.carried[run] * tonnes,
            "volume_m3": float(conveyor.carried[run]),
            "rate_mean_tph": mean,
            "rate_cv": float(np.sqrt(variance) / mean) if mean > 0 else 0.0,
            "spill_t": conveyor.spilled[run] * tonnes,
            "rate_max_tph": float(self.rate_max[run]),
            "carrying_time_s": int(self.carrying_periods[run]) * conveyor.period,
            "conveyed_t": self.conveyed[run] * tonnes,
            "dug_m3": float(conveyor.dug[run]),
            "pile_volume_lost_m3": reclaim.surface.volume() - reclaim.surface.volume(cutter.heights[run]),
            "cut_depth_max_m": float(self.depth_max[run]),
            "digging_force_max_N": float(reclaim.digging.force_max[run]) if reclaim.digging is not None else 0.0,
            "wheel_capacity_tph": wheel.capacity * density * SECONDS_PER_HOUR / KG_PER_T,
            **({"slumped_m3": float(cutter.slumped[run]),  # moved, some of it more than once
                "slumps_unconverged": int(cutter.unconverged[run])} if cutter.talus is not None else {}),
        }

    def discharged(self, run: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(n,) each graded discharge's time (s), volume carried (m^3) and grade."""
        rows = np.array(self.discharges[run], dtype=float).reshape(-1, 3)
        return rows[:, 0], rows[:, 1], rows[:, 2]

    def blend_metrics(self, run: int) -> dict:
        """metrics.json's `blend` object on a stacked pile (output contract): the grade of what the
        buckets carried against what was stacked, the band, and the balances."""
        reclaim = self._reclaim
        stacked, conveyor = reclaim.stacked, reclaim.conveyor
        t, volume, grade = self.discharged(run)
        density = reclaim.density[run] / KG_PER_T  # t/m^3
        tonnes = volume * density
        out = float(tonnes.sum())
        mean, sd = tonne_weighted(tonnes, grade)
        lot_tonnes, lot_grade = lots(tonnes, grade, max(round(reclaim.wheel.discharges_per_minute), 1))  # a minute's
        start = stacked.pile
        held = reclaim.layers[run]
        left = (held.volume() + conveyor.carried[run] + conveyor.spilled[run] + conveyor.bucket[run])
        left_grade = (held.grade_volume() + float(np.sum(volume * grade)) + conveyor.spilled_grade[run]
                      + conveyor.bucket_grade[run])
        return {
            "grade_name": stacked.grade_name,
            "layers": stacked.layers,
            "tonnes_out_t": out,
            "grade_in_mean": stacked.grade_in_mean,
            "grade_in_sd": stacked.grade_in_sd,
            "grade_out_mean": mean,
            "grade_out_sd": sd,
            "grade_out_sd_minute": tonne_weighted(lot_tonnes, lot_grade)[1] if len(lot_tonnes) >= 2 else float("nan"),
            "grade_out_rms_minute": rms_from(lot_tonnes, lot_grade, stacked.grade_in_mean),
            "sd_ratio": sd / stacked.grade_in_sd if stacked.grade_in_sd > 0 else float("nan"),
            "pattern": stacked.pattern,
            "equivalent_layers": stacked.equivalent_layers,
            "sqrt_n_ratio": 1.0 / math.sqrt(stacked.equivalent_layers),  # NaN for cone shells
            "variance_reduction": (stacked.grade_in_sd / sd) ** 2 if sd > 0 else float("inf"),
            "band": list(stacked.band) if stacked.band is not None else None,
            "longest_outside_band_s": _longest_outside(t, grade, stacked.band, conveyor.bucket_interval),
            "belt_delay_s": reclaim.belt_delay,
            "balance_relative": (start.volume() - left) / start.volume(),
            "grade_balance_relative": (start.grade_volume() - left_grade) / start.grade_volume(),
        }

    def grade_out(self, run: int) -> dict | None:
        """On a stacked pile, the grade that left it: each discharge's time at the belt's end of
        the delay (s), its tonnes and grade, and the grade's name; else None."""
        reclaim = self._reclaim
        if reclaim.stacked is None:
            return None
        t, volume, grade = self.discharged(run)
        return {"t": t + reclaim.belt_delay, "tonnes": volume * reclaim.density[run] / KG_PER_T, "grade": grade,
                "name": reclaim.stacked.grade_name}

    def pile(self, run: int) -> dict:
        """Run `run`'s pile: grid lines, heights before and after, and as it was dug (if kept; on a
        stacked pile with its top layers' grade)."""
        reclaim = self._reclaim
        surface, stacked = reclaim.surface, reclaim.stacked
        grade = (stacked.grade_name, stacked.band) if stacked is not None else ()
        history = (self._frames.history(run, surface.x, surface.y, surface.z, *grade)
                   if self._frames is not None else None)
        return {"x": surface.x, "y": surface.y, "z_start": surface.z, "z_end": reclaim.heights[run].copy(),
                "history": history}


def _longest_outside(t: np.ndarray, grade: np.ndarray, band: tuple[float, float] | None, interval: float) -> float | None:
    """s of the longest run of discharges outside the band, each standing for a bucket interval;
    None without a band."""
    if band is None:
        return None
    longest = current = 0.0
    for value in grade:
        current = current + interval if not band[0] <= value <= band[1] else 0.0
        longest = max(longest, current)
    return longest
