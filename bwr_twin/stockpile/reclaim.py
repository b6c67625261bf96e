"""The reclaim of every run of a lockstep: the cut each control period, what the buckets carry
and spill, the digging load on the joints, and each run's totals and recorded signals.

What the wheel digs goes into the bucket in the cut. Every bucket interval (60 s over the
discharges a minute) that bucket discharges up to its volume onto the boom conveyor; the rest
spills and is reported, not counted as reclaimed. The reclaim rate is the conveyor's load: each
discharge spread over the next bucket interval, as a belt scale sees it. So the rate's integral
is exactly what the buckets discharged, once the last discharge has passed.
The digging load (when the scene has [digging]) acts where the material was cut, through the
Jacobian of that point: the cutting force at the rim, P_cut / rim speed with P_cut =
cutting_energy x dug volume a second (at most the wheel drive's rating less its idle power),
lagged by one bucket interval, opposes the buckets' motion (they rise through the face),
and a lateral share of it opposes the slewing into the face.
Under a bench plan it also measures how well the plan was carried out: the rate in steady
cutting (a bucket interval after the wheel entered a full face, so that the belt carries what
it cut), the landing (where the wheel first touched the pile, against where the planner
predicted it would), the over-cut beyond the planned cut, and the tonnes of each bench.
"""

from __future__ import annotations

from collections.abc import Sequence
import numpy as np

from bwr_twin.config.scene import Scene
from bwr_twin.model.machine import Machine
from bwr_twin.planning.follower import Phase
from bwr_twin.planning.plan import BenchPlan
from bwr_twin.stockpile.cutting import Cutter
from bwr_twin.stockpile.history import PileHistory
from bwr_twin.stockpile.placement import check_placement
from bwr_twin.stockpile.surface import Surface
from bwr_twin.units import KG_PER_T, SECONDS_PER_HOUR

DUG_RATE_FLOOR = 1e-6  # m^3/s: below it the lagged dug rate is no load at all (under 1 N of force)
RATE_BAND = 0.1  # of the target: the band the steady rate is counted within


class Reclaim:
    """Owns the piles of a lockstep's runs (through its Cutter) and their reclaim accounting."""

    def __init__(self, scenes: Sequence[Scene], machine: Machine, surface: Surface, period: float,
                 frame_every: int | None = None, plan: BenchPlan | None = None):
        """`surface`: the scenes' pile; `frame_every`: keep the cells changed every that many
        control periods, for a replay; `plan`: the bench plan the runs follow, if any. Raises
        SceneError if the machine cannot dig the pile."""
        self.surface = surface
        check_placement(surface, machine, scenes[0].path)
        runs = len(scenes)
        self.machine, self.wheel, self.period = machine, machine.wheel, period
        self.cutter = Cutter(self.surface, machine.wheel, runs)
        self.density = np.array([s.stockpile.bulk_density for s in scenes])  # kg/m^3
        digging = [s.digging for s in scenes]
        self.cutting_energy = np.array([d.cutting_energy if d else 0.0 for d in digging])
        self.idle_power = np.array([d.idle_power if d else 0.0 for d in digging])
        self.lateral_ratio = np.array([d.lateral_ratio if d else 0.0 for d in digging])
        self.loaded = any(d is not None for d in digging)
        # The bucket in the cut: what it holds (m^3), and when it discharges (s).
        self.bucket_interval = 60.0 / self.wheel.discharges_per_minute
        self.bucket = np.zeros(runs)
        self._discharge_at = self.bucket_interval
        self._next_rate: np.ndarray | None = None  # t/h the belt carries from the next period on
        self._hold_end = -1  # the last period of the current belt load
        self._dug_rate = np.zeros(runs)  # m^3/s, lagged by a bucket interval
        self._lag = period / (self.bucket_interval + period)
        self._arm = np.zeros((runs, 2))  # the last cut's centre from the CP: along the boom, up (m)
        self._side = np.zeros(runs)  # and the side of the wheel's plane it lay on
        # This period's values, for the record.
        self.rate, self.depth, self.power = np.zeros(runs), np.zeros(runs), np.zeros(runs)
        self.force = np.zeros((runs, 3))
        # Totals.
        self.dug, self.carried, self.spilled = np.zeros(runs), np.zeros(runs), np.zeros(runs)  # m^3
        self.conveyed = np.zeros(runs)  # m^3, the rate's integral
        self.carrying_periods = np.zeros(runs, dtype=np.int64)
        self.rate_sum, self.rate_square_sum = np.zeros(runs), np.zeros(runs)  # t/h, over carrying periods
        self.rate_max, self.depth_max, self.force_max = np.zeros(runs), np.zeros(runs), np.zeros(runs)
        self._frame_every = frame_every
        self._frames: list[list] = [[] for _ in range(runs)]
        self._framed = self.cutter.heights.copy() if frame_every else None
        self.plan = plan
        if plan is not None:
            self.target = np.array([s.reclaim.target_rate for s in scenes])  # t/h
            # The belt carries a cut a bucket interval later, and holds it one more.
            self._settle = int(np.ceil(2 * self.bucket_interval / period))
            self._steady_for = np.zeros(runs, dtype=np.int64)  # periods in steady cutting so far
            self.steady_periods = np.zeros(runs, dtype=np.int64)
            self.steady_sum, self.steady_square_sum = np.zeros(runs), np.zeros(runs)
            self.steady_within = np.zeros(runs, dtype=np.int64)
            self.contact = np.full((runs, 3), np.nan)  # world m: the CP when the wheel first cut
            self.contact_time = np.full(runs, np.nan)
            self.overcut_max, self.overcut_time = np.zeros(runs), np.zeros(runs)  # m, s
            self.bench_carried = np.zeros((runs, plan.benches))  # m^3
            self._bench = np.zeros(runs, dtype=np.int64)

    def step(self, k: int, q: np.ndarray, runs: np.ndarray | None, phase: Phase | None = None) -> np.ndarray | None:
        """Cut period k's material with the wheels where the true joint values q (runs, 3) put
        them; returns the (runs, 3) digging load on the joints (N, N m) to hold over the period,
        or None when there is none. `phase`: where each run stands in its bench plan."""
        if self._next_rate is not None:  # a bucket discharged as the last period ended
            self.rate[:] = self._next_rate
            self._next_rate = None
        cp = self.machine.fk(q)
        cut = self.cutter.cut(cp, q[:, 1], runs)
        if phase is not None:
            self._follow(k, cp, cut, phase)
        self.dug += cut.volume
        self.bucket += cut.volume
        if (k + 1) * self.period >= self._discharge_at - 1e-9:  # the bucket discharges as the period ends
            self._discharge_onto_belt(k)
        self.depth[:] = cut.depth
        np.maximum(self.depth_max, cut.depth, out=self.depth_max)
        if self._framed is not None and k % self._frame_every == 0:
            self._keep_frame(k)
        if not self.loaded:
            return None
        # The buckets cut in chips, one a bucket interval: the load follows the dug rate (spill
        # included: it was cut all the same) through a lag of one bucket interval.
        self._dug_rate += (cut.volume / self.period - self._dug_rate) * self._lag
        self._dug_rate[self._dug_rate < DUG_RATE_FLOOR] = 0.0
        if not self._dug_rate.any():  # no wheel cuts: it turns empty
            self.power[:] = self.idle_power
            self.force[:] = 0.0
            return None
        demand = self.cutting_energy * self._dug_rate + self.idle_power
        np.minimum(demand, self.wheel.power, out=self.power)  # beyond its rating the wheel stalls
        tangential = np.maximum(self.power - self.idle_power, 0.0) / self.wheel.rim_speed
        cos, sin = np.cos(q[:, 1]), np.sin(q[:, 1])
        self._remember_cut(cut, cp, cos, sin)
        # Against the buckets' motion where they cut: the arm from the CP turned by +90 deg in
        # the boom's vertical plane (up at the front, outwards at the bottom); and against the
        # slewing into the face, along the wheel's axis (-sin, cos, 0).
        along, up = self._arm[:, 0], self._arm[:, 1]
        length = np.hypot(along, up)
        scale = np.divide(tangential, length, out=np.zeros_like(length), where=length > 0)
        lateral = self.lateral_ratio * tangential * self._side
        force = self.force
        force[:, 0] = scale * up * cos + lateral * sin
        force[:, 1] = scale * up * sin - lateral * cos
        force[:, 2] = -scale * along
        np.maximum(self.force_max, np.sqrt(np.einsum("ri,ri->r", force, force)), out=self.force_max)
        # It acts at the last cut's centre, carried with the boom.
        point = cp.copy()
        point[:, 0] += along * cos
        point[:, 1] += along * sin
        point[:, 2] += up
        return self.machine.joint_force(q, point, force)

    def _remember_cut(self, cut, cp: np.ndarray, cos: np.ndarray, sin: np.ndarray) -> None:
        """Keep where each cutting run cut, as (along the boom, up) from the CP, and its side."""
        cutting = cut.volume > 0
        if not cutting.any():
            return
        arm = cut.centroid - cp
        self._arm[cutting, 0] = (arm[:, 0] * cos + arm[:, 1] * sin)[cutting]
        self._arm[cutting, 1] = arm[cutting, 2]
        self._side[cutting] = cut.side[cutting]

    def _follow(self, k: int, cp: np.ndarray, cut, phase: Phase) -> None:
        """The bench plan's measures for period k."""
        self._bench[:] = phase.bench
        cutting = cut.volume > 0
        if not cutting.any():
            self._steady_for[:] = 0
            return
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
            rate = self.rate
            self.steady_periods += counted
            self.steady_sum += np.where(counted, rate, 0.0)
            self.steady_square_sum += np.where(counted, rate**2, 0.0)
            self.steady_within += counted & (np.abs(rate - self.target) <= RATE_BAND * self.target)

    def carried_tonnes(self) -> np.ndarray:
        """(runs,) t the buckets have discharged onto the belt so far."""
        return self.carried * self.density / KG_PER_T

    def _discharge(self) -> np.ndarray:
        """Empty the bucket in the cut: up to its volume is carried, the rest spills; m^3 carried."""
        carried = np.minimum(self.bucket, self.wheel.bucket_volume)
        self.carried += carried
        if self.plan is not None:
            np.add.at(self.bench_carried, (np.arange(len(carried)), self._bench), carried)
        self.spilled += self.bucket - carried
        self.bucket[:] = 0.0
        return carried

    def _discharge_onto_belt(self, k: int) -> None:
        """The bucket discharges as period k ends; the belt carries its load, evenly, over the
        periods until the next discharge. The rate is constant over them: its statistics are
        added for the whole hold at once (and the part beyond the path's end taken off again)."""
        carried = self._discharge()
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

    def finish(self, k: int) -> None:
        """After the path's last period k: the bucket in the cut discharges, and what the belt
        would carry after the path's end is not counted as conveyed."""
        self._discharge()
        beyond = self._hold_end - k
        if beyond > 0:
            rate = self._next_rate if self._next_rate is not None else self.rate
            self._add_hold(rate, -rate * beyond * self.period / (self.density * (SECONDS_PER_HOUR / KG_PER_T)), -beyond)

    def _keep_frame(self, k: int) -> None:
        for run in range(len(self._frames)):
            changed = np.flatnonzero(self.cutter.heights[run] != self._framed[run])
            if changed.size:
                heights = self.cutter.heights[run].ravel()[changed]
                self._framed[run].ravel()[changed] = heights
                self._frames[run].append((k * self.period, changed.astype(np.int32), heights.astype(np.float32)))

    def metrics(self, run: int) -> dict:
        """metrics.json's `reclaim` object for `run` (output contract)."""
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
            "pile_volume_lost_m3": self.surface.volume() - self.surface.volume(self.cutter.heights[run]),
            "cut_depth_max_m": float(self.depth_max[run]),
            "digging_force_max_N": float(self.force_max[run]),
            "wheel_capacity_tph": self.wheel.capacity * self.density[run] * SECONDS_PER_HOUR / KG_PER_T,
            **(self._plan_metrics(run) if self.plan is not None else {}),
        }

    def _plan_metrics(self, run: int) -> dict:
        """How the run carried out its bench plan (docs/reclaiming.md)."""
        tonnes = self.density[run] / KG_PER_T
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

    def pile(self, run: int) -> dict:
        """Run `run`'s pile: grid lines, heights before and after, and as it was dug (if kept)."""
        return dict(
            x=self.surface.x, y=self.surface.y, z_start=self.surface.z, z_end=self.cutter.heights[run].copy(),
            history=PileHistory.from_frames(self.surface.x, self.surface.y, self.surface.z, self._frames[run])
            if self._framed is not None else None,
        )
