"""The reclaim of every run of a lockstep, one control period at a time: the cut (its Cutter,
the one owner of the piles' heights), the bucket and belt (`Conveyor`) and the digging load
(`DiggingLoad`, when the scene has [digging]). What it did over the run is kept by its account
(bwr_twin.stockpile.reclaim_account), which reads it every period.

On a stacked pile (bwr_twin.stockpile.stacked) each run's layers follow its heights: the cells
the wheel lowered give up their layers from the top, and the grade of what was cut goes into the
bucket with it. With a
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
from bwr_twin.stockpile.layers import LayeredPile
from bwr_twin.stockpile.placement import check_placement
from bwr_twin.stockpile.stacked import StackedPile, read_stacked


class Reclaim:
    """The piles of a lockstep's runs and what their wheels take from them.

    Attributes (this period's, (runs,) or (runs, 3)): `rate` t/h on the belt, `depth` m of the
    cut, `power` W of the wheel drive, `force` N of the digging load on the wheel (world frame);
    `cut` and `cp` the period's cut and the CPs that made it.
    """

    def __init__(self, scenes: Sequence[Scene], machine: Machine, surface: Surface, period: float):
        """`surface`: the scenes' pile. Raises SceneError if the machine cannot dig the pile."""
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
        self._strata = None
        if stacked:
            self._strata = Strata(scenes, self.surface)
            self.conveyor.track_grade()
        zeros = np.zeros(runs)
        self.rate = self.conveyor.rate
        self.power = self.digging.power if self.digging is not None else zeros
        self.force = self.digging.force if self.digging is not None else np.zeros((runs, 3))
        self.depth = np.zeros(runs)
        self.cut: Cut | None = None
        self.cp = np.zeros((runs, 3))

    @property
    def stacked(self) -> StackedPile | None:
        """The stacked pile the runs reclaim, with its layers and grades, or None."""
        return None if self._strata is None else self._strata.stacked

    @property
    def layers(self) -> list[LayeredPile] | None:
        """On a stacked pile, each run's layers as they stand under its heights; else None."""
        return None if self._strata is None else self._strata.piles

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
        strata = self._strata
        self.conveyor.load(k, cut.volume, strata.cut(cut, self.cutter.heights) if strata is not None else None)
        slumps = self.cutter.slump(cut)
        if strata is not None:
            strata.follow(slumps, self.cutter.heights)
        self.depth[:] = cut.depth
        return self.digging.step(q, cp, cut) if self.digging is not None else None

    def top_grades(self) -> list[np.ndarray] | None:
        """On a stacked pile, each run's (ny, nx) top layer's grade, for the replay; else None."""
        return None if self._strata is None else [layers.top_grade() for layers in self._strata.piles]

    @property
    def belt_delay(self) -> float:
        """s from a discharge to where the grade out is taken: the belt scale's place on the boom
        conveyor, if the machine has one (its MJCF's), else the discharge itself."""
        scale = self.machine.belt_scale
        return scale.delay if scale is not None else 0.0

    def carried_tonnes(self) -> np.ndarray:
        """(runs,) t the buckets have discharged onto the belt so far."""
        return self.conveyor.carried_tonnes()

    def finish(self, k: int) -> None:
        """After the last period k: the bucket in the cut discharges (bwr_twin.stockpile.conveyor)."""
        self.conveyor.finish(k)


class Strata:
    """On a stacked pile, each run's layers under its heights: the cells the wheel lowers give up
    their layers from the top, and the faces that slump after the cut carry theirs along.

    Attributes:
        stacked: the stacked pile as read (bwr_twin.stockpile.stacked).
        piles: each run's LayeredPile.
    """

    def __init__(self, scenes: Sequence[Scene], surface: Surface):
        """SceneError if the pile was stacked at another bulk density than the scene's."""
        scene = scenes[0]
        self.stacked = stacked = read_stacked(scene.stockpile.surface_file, surface, scene.path)
        if not math.isclose(stacked.bulk_density, scene.stockpile.bulk_density, rel_tol=1e-9):
            raise SceneError(f"{scene.path}: 'stockpile.bulk_density' ({scene.stockpile.bulk_density:g} kg/m3) must "
                             f"be the {stacked.bulk_density:g} kg/m3 its stacked pile was laid at "
                             f"({scene.stockpile.surface_file})")
        self.piles = [copy.deepcopy(stacked.pile) for _ in scenes]

    def cut(self, cut: Cut, heights: np.ndarray) -> np.ndarray:
        """(runs,) grade x m^3 of what each run's wheel cut this period: its layers lowered to the
        cut heights (runs, ny, nx), in the cells the cut lowered."""
        grade_volume = np.zeros(len(self.piles))
        for run in np.flatnonzero(cut.volume > 0):
            layers, run_heights = self.piles[run], heights[run]
            row0, row1, column0, column1 = cut.cells[run]
            window = (slice(row0, row1 + 1), slice(column0, column1 + 1))
            rows, columns = np.nonzero(layers.z[window] > run_heights[window])
            cells = (rows + row0) * run_heights.shape[1] + columns + column0
            _, grade_volume[run] = layers.cut_cells(cells, run_heights.reshape(-1)[cells])
        return grade_volume

    def follow(self, slumps: Sequence, heights: np.ndarray) -> None:
        """Each run's layers follow the faces that slumped (None: none) to its heights (runs, ny, nx)."""
        for run, slump in enumerate(slumps):
            if slump is not None:
                self.piles[run].follow(slump, heights[run])
