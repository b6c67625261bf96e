"""The reclaim of every run of a lockstep, one control period at a time: the cut (its Cutter,
the one owner of the piles' heights), the bucket and belt (`Conveyor`), the digging load
(`DiggingLoad`, when the scene has [digging]), and the pile as it was dug, for a replay.

On a stacked pile (bwr_twin.stockpile.stacked) each run's layers follow its heights: the cells
the wheel lowered give up their layers from the top, and the grade of what was cut goes into the
bucket with it; `blend_metrics` says what left the pile against what was stacked. With a
`stockpile.angle_of_repose`, the faces the cut leaves slump after it (bwr_twin.pile.cutting),
the layers carried along with them.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Sequence

import numpy as np

from bwr_twin.config.scene import Scene
from bwr_twin.errors import SceneError
from bwr_twin.model.machine import Machine
from bwr_twin.pile.cutting import Cut, Cutter
from bwr_twin.pile.surface import Surface, is_stacked_pile
from bwr_twin.stockpile.conveyor import Conveyor
from bwr_twin.stockpile.digging import DiggingLoad
from bwr_twin.stockpile.grade import lots, rms_from, tonne_weighted
from bwr_twin.stockpile.history import PileFrames
from bwr_twin.stockpile.layers import LayeredPile
from bwr_twin.stockpile.placement import check_placement
from bwr_twin.stockpile.stacked import read_stacked
from bwr_twin.units import KG_PER_T, SECONDS_PER_HOUR


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
        stacked = is_stacked_pile(scenes[0].stockpile.surface_file)
        self.cutter = Cutter(self.surface, machine.wheel, runs, scenes[0].stockpile.angle_of_repose, record=stacked)
        self.density = np.array([s.stockpile.bulk_density for s in scenes])  # kg/m^3
        self.conveyor = Conveyor(machine.wheel, self.density, period)
        digging = [s.digging for s in scenes]
        self.digging = None
        if any(d is not None for d in digging):
            self.digging = DiggingLoad(machine, np.array([d.cutting_energy if d else 0.0 for d in digging]),
                                       np.array([d.idle_power if d else 0.0 for d in digging]),
                                       np.array([d.lateral_ratio if d else 0.0 for d in digging]),
                                       self.conveyor.bucket_interval, period)
        self.stacked = None
        self.layers: list[LayeredPile] | None = None
        if stacked:
            self._stack(scenes)
        zeros = np.zeros(runs)
        self.rate = self.conveyor.rate
        self.power = self.digging.power if self.digging is not None else zeros
        self.force = self.digging.force if self.digging is not None else np.zeros((runs, 3))
        self.depth = np.zeros(runs)
        self.depth_max = np.zeros(runs)
        self.cut: Cut | None = None
        self.cp = np.zeros((runs, 3))
        self._frame_every = frame_every
        self._frames = PileFrames(self.cutter.heights, self._top_grades()) if frame_every else None

    @property
    def heights(self) -> np.ndarray:
        """(runs, ny, nx) m: each run's pile as dug so far."""
        return self.cutter.heights

    @property
    def dug(self) -> np.ndarray:
        """(runs,) m^3 each run's wheel has dug so far."""
        return self.conveyor.dug

    def step(self, k: int, q: np.ndarray, runs: np.ndarray | None) -> np.ndarray | None:
        """Cut period k's material with the wheels where the true joint values q (runs, 3) put
        them; returns the (runs, 3) digging load on the joints (N, N m) to hold over the period,
        or None when there is none."""
        self.cp = cp = self.machine.fk(q)
        self.cut = cut = self.cutter.cut(cp, q[:, 1], runs)
        self.conveyor.load(k, cut.volume, self._cut_layers(cut) if self.layers is not None else None)
        slumps = self.cutter.slump(cut)
        if self.layers is not None:
            for run, slump in enumerate(slumps):
                if slump is not None:
                    self.layers[run].follow(slump, self.cutter.heights[run])
        self.depth[:] = cut.depth
        np.maximum(self.depth_max, cut.depth, out=self.depth_max)
        if self._frames is not None and k % self._frame_every == 0:
            self._frames.keep(k * self.period, self.cutter.heights, self._top_grades())
        return self.digging.step(q, cp, cut) if self.digging is not None else None

    def _stack(self, scenes: Sequence[Scene]) -> None:
        """Lay the stacked pile's layers under every run's heights; SceneError if it was stacked at
        another bulk density than the scene's."""
        scene = scenes[0]
        self.stacked = stacked = read_stacked(scene.stockpile.surface_file, self.surface, scene.path)
        if not math.isclose(stacked.bulk_density, scene.stockpile.bulk_density, rel_tol=1e-9):
            raise SceneError(f"{scene.path}: 'stockpile.bulk_density' ({scene.stockpile.bulk_density:g} kg/m3) must "
                             f"be the {stacked.bulk_density:g} kg/m3 its stacked pile was laid at "
                             f"({scene.stockpile.surface_file})")
        self.layers = [copy.deepcopy(stacked.pile) for _ in scenes]
        self.conveyor.track_grade()

    def _top_grades(self) -> list[np.ndarray] | None:
        """On a stacked pile, each run's (ny, nx) top layer's grade, for the replay; else None."""
        return None if self.layers is None else [layers.top_grade() for layers in self.layers]

    def _cut_layers(self, cut: Cut) -> np.ndarray:
        """(runs,) grade x m^3 of what each run's wheel cut this period: its layers lowered to the
        cut heights, in the cells the cut lowered."""
        grade_volume = np.zeros(len(self.layers))
        for run in np.flatnonzero(cut.volume > 0):
            layers, heights = self.layers[run], self.cutter.heights[run]
            row0, row1, column0, column1 = cut.cells[run]
            window = (slice(row0, row1 + 1), slice(column0, column1 + 1))
            rows, columns = np.nonzero(layers.z[window] > heights[window])
            cells = (rows + row0) * heights.shape[1] + columns + column0
            _, grade_volume[run] = layers.cut_cells(cells, heights.reshape(-1)[cells])
        return grade_volume

    @property
    def belt_delay(self) -> float:
        """s from a discharge to where the grade out is taken: the belt scale's place on the boom
        conveyor, if the machine has one (its MJCF's), else the discharge itself."""
        scale = self.machine.belt_scale
        return scale.delay if scale is not None else 0.0

    def blend_metrics(self, run: int) -> dict:
        """metrics.json's `blend` object on a stacked pile (output contract): the grade of what the
        buckets carried against what was stacked, the band, and the balances."""
        stacked, conveyor = self.stacked, self.conveyor
        t, volume, grade = self.discharges(run)
        density = self.density[run] / KG_PER_T  # t/m^3
        tonnes = volume * density
        out = float(tonnes.sum())
        mean, sd = tonne_weighted(tonnes, grade)
        lot_tonnes, lot_grade = lots(tonnes, grade, max(round(self.wheel.discharges_per_minute), 1))  # a minute's
        start = stacked.pile
        held = self.layers[run]
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
            "longest_outside_band_s": _longest_outside(t, grade, stacked.band, self.conveyor.bucket_interval),
            "belt_delay_s": self.belt_delay,
            "balance_relative": (start.volume() - left) / start.volume(),
            "grade_balance_relative": (start.grade_volume() - left_grade) / start.grade_volume(),
        }

    def discharges(self, run: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(n,) each discharge's time (s), volume carried (m^3) and grade, on a stacked pile."""
        rows = np.array(self.conveyor.discharges[run], dtype=float).reshape(-1, 3)
        return rows[:, 0], rows[:, 1], rows[:, 2]

    def carried_tonnes(self) -> np.ndarray:
        """(runs,) t the buckets have discharged onto the belt so far."""
        return self.conveyor.carried_tonnes()

    def finish(self, k: int) -> None:
        """After the last period k: the bucket in the cut discharges (bwr_twin.stockpile.conveyor)."""
        self.conveyor.finish(k)

    def metrics(self, run: int) -> dict:
        """metrics.json's `reclaim` object for `run` (output contract), but for a plan's measures."""
        return {
            **self.conveyor.metrics(run),
            "pile_volume_lost_m3": self.surface.volume() - self.surface.volume(self.cutter.heights[run]),
            "cut_depth_max_m": float(self.depth_max[run]),
            "digging_force_max_N": float(self.digging.force_max[run]) if self.digging is not None else 0.0,
            "wheel_capacity_tph": self.wheel.capacity * self.density[run] * SECONDS_PER_HOUR / KG_PER_T,
            **({"slumped_m3": float(self.cutter.slumped[run]),  # moved, some of it more than once
                "slumps_unconverged": int(self.cutter.unconverged[run])} if self.cutter.talus is not None else {}),
        }

    def grade_out(self, run: int) -> dict | None:
        """On a stacked pile, the grade that left it: each discharge's time at the belt's end of
        the delay (s), its tonnes and grade, and the grade's name; else None."""
        if self.stacked is None:
            return None
        t, volume, grade = self.discharges(run)
        return {"t": t + self.belt_delay, "tonnes": volume * self.density[run] / KG_PER_T, "grade": grade,
                "name": self.stacked.grade_name}

    def pile(self, run: int) -> dict:
        """Run `run`'s pile: grid lines, heights before and after, and as it was dug (if kept; on a
        stacked pile with its top layers' grade)."""
        grade = (self.stacked.grade_name, self.stacked.band) if self.stacked is not None else ()
        history = (self._frames.history(run, self.surface.x, self.surface.y, self.surface.z, *grade)
                   if self._frames is not None else None)
        return {"x": self.surface.x, "y": self.surface.y, "z_start": self.surface.z,
                "z_end": self.cutter.heights[run].copy(), "history": history}
