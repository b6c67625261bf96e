"""The reclaim of every run of a lockstep, one control period at a time: the cut (its Cutter,
the one owner of the piles' heights), the bucket and belt (`Conveyor`), the digging load
(`DiggingLoad`, when the scene has [digging]), and the pile as it was dug, for a replay.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from bwr_twin.config.scene import Scene
from bwr_twin.model.machine import Machine
from bwr_twin.stockpile.conveyor import Conveyor
from bwr_twin.stockpile.cutting import Cut, Cutter
from bwr_twin.stockpile.digging import DiggingLoad
from bwr_twin.stockpile.history import PileHistory
from bwr_twin.stockpile.placement import check_placement
from bwr_twin.stockpile.surface import Surface
from bwr_twin.units import KG_PER_T, SECONDS_PER_HOUR


class Reclaim:
    """The piles of a lockstep's runs and what their wheels take from them.

    Attributes (this period's, (runs,) or (runs, 3)): `rate` t/h on the belt, `depth` m of the
    cut, `power` W of the wheel drive, `force` N of the digging load on the wheel (world frame);
    `cut` and `cp` the period's cut and the CPs that made it.
    """

    def __init__(self, scenes: Sequence[Scene], machine: Machine, surface: Surface, period: float,
                 frame_every: int | None = None):
        """`surface`: the scenes' pile; `frame_every`: keep the cells changed every that many
        control periods, for a replay. Raises SceneError if the machine cannot dig the pile."""
        self.surface = surface
        check_placement(surface, machine, scenes[0].path)
        runs = len(scenes)
        self.machine, self.wheel, self.period = machine, machine.wheel, period
        self.cutter = Cutter(self.surface, machine.wheel, runs)
        self.density = np.array([s.stockpile.bulk_density for s in scenes])  # kg/m^3
        self.conveyor = Conveyor(machine.wheel, self.density, period)
        digging = [s.digging for s in scenes]
        self.digging = None
        if any(d is not None for d in digging):
            self.digging = DiggingLoad(machine, np.array([d.cutting_energy if d else 0.0 for d in digging]),
                                       np.array([d.idle_power if d else 0.0 for d in digging]),
                                       np.array([d.lateral_ratio if d else 0.0 for d in digging]),
                                       self.conveyor.bucket_interval, period)
        zeros = np.zeros(runs)
        self.rate = self.conveyor.rate
        self.power = self.digging.power if self.digging is not None else zeros
        self.force = self.digging.force if self.digging is not None else np.zeros((runs, 3))
        self.depth = np.zeros(runs)
        self.depth_max = np.zeros(runs)
        self.cut: Cut | None = None
        self.cp = np.zeros((runs, 3))
        self._frame_every = frame_every
        self._frames: list[list] = [[] for _ in range(runs)]
        self._framed = self.cutter.heights.copy() if frame_every else None

    def step(self, k: int, q: np.ndarray, runs: np.ndarray | None) -> np.ndarray | None:
        """Cut period k's material with the wheels where the true joint values q (runs, 3) put
        them; returns the (runs, 3) digging load on the joints (N, N m) to hold over the period,
        or None when there is none."""
        self.cp = cp = self.machine.fk(q)
        self.cut = cut = self.cutter.cut(cp, q[:, 1], runs)
        self.conveyor.load(k, cut.volume)
        self.depth[:] = cut.depth
        np.maximum(self.depth_max, cut.depth, out=self.depth_max)
        if self._framed is not None and k % self._frame_every == 0:
            self._keep_frame(k)
        return self.digging.step(q, cp, cut) if self.digging is not None else None

    def carried_tonnes(self) -> np.ndarray:
        """(runs,) t the buckets have discharged onto the belt so far."""
        return self.conveyor.carried_tonnes()

    def finish(self, k: int) -> None:
        """After the last period k: the bucket in the cut discharges (bwr_twin.stockpile.conveyor)."""
        self.conveyor.finish(k)

    def _keep_frame(self, k: int) -> None:
        for run in range(len(self._frames)):
            changed = np.flatnonzero(self.cutter.heights[run] != self._framed[run])
            if changed.size:
                heights = self.cutter.heights[run].ravel()[changed]
                self._framed[run].ravel()[changed] = heights
                self._frames[run].append((k * self.period, changed.astype(np.int32), heights.astype(np.float32)))

    def metrics(self, run: int) -> dict:
        """metrics.json's `reclaim` object for `run` (output contract), but for a plan's measures."""
        return {
            **self.conveyor.metrics(run),
            "pile_volume_lost_m3": self.surface.volume() - self.surface.volume(self.cutter.heights[run]),
            "cut_depth_max_m": float(self.depth_max[run]),
            "digging_force_max_N": float(self.digging.force_max[run]) if self.digging is not None else 0.0,
            "wheel_capacity_tph": self.wheel.capacity * self.density[run] * SECONDS_PER_HOUR / KG_PER_T,
        }

    def pile(self, run: int) -> dict:
        """Run `run`'s pile: grid lines, heights before and after, and as it was dug (if kept)."""
        return dict(
            x=self.surface.x, y=self.surface.y, z_start=self.surface.z, z_end=self.cutter.heights[run].copy(),
            history=PileHistory.from_frames(self.surface.x, self.surface.y, self.surface.z, self._frames[run])
            if self._framed is not None else None,
        )
