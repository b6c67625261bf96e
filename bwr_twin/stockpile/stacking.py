"""The piles the runs of a lockstep stack (scene [stacking], docs/blending.md): the one owner of
their layers while they are built.

Every `deposit_period` the stream of that period (rate x period, the last one cut to the run's
end) lands at the discharge point where the run's true joints put it as the period starts, at
the grade the stream has then, as a new layer, and the pile relaxes to the material's angle of
repose (bwr_twin.stockpile.deposition). Each run draws its grade from its own seed (its own
stream, bwr_twin.streams) or reads the scene's recorded file. What came in is summed as
it lands, so the balances, tonnes and tonnes x grade in against what the pile holds, are checked
at the end against the layers themselves.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from bwr_twin.config.sections import GradeSection, Scene
from bwr_twin.errors import SceneError
from bwr_twin.model.machine import Machine
from bwr_twin.pile.relaxation import Talus
from bwr_twin.planning.patterns import equivalent_layers
from bwr_twin.planning.stacking import StackingPlan
from bwr_twin.stockpile.deposition import discharge, height_under
from bwr_twin.stockpile.grade import Ar1Grade, RecordedGrade, tonne_weighted
from bwr_twin.stockpile.history import PileFrames, PileHistory
from bwr_twin.stockpile.layers import LayeredPile
from bwr_twin.stockpile.material import Material
from bwr_twin.streams import Stream, stream


@dataclass
class StackingRecord:
    """One run's stacking: every deposit, and the pile it built.

    Attributes:
        t, grade, tonnes: (deposits,) s each deposit began, the grade it came at, t it laid;
        point: (deposits, 2) world x, y (m) where it landed; drop (deposits,) m it fell, from the
            discharge point down to the pile under it as it began.
        x, y: the pile's grid lines (m); z: (ny, nx) heights at the end (m);
        thickness, layer_grade: (ny, nx, max_layers) its layers from the floor up; count (ny, nx).
        grade_name: what the grade is ("Fe %"); bulk_density kg/m^3; layers what the pattern's
            `layers` counts (chevron passes, windrow bottom rows, cones, strata);
            band the grade the customer accepts, or None.
        history: the heights as they grew, frame by frame, if kept for a replay.
    """

    t: np.ndarray
    grade: np.ndarray
    tonnes: np.ndarray
    point: np.ndarray
    drop: np.ndarray
    x: np.ndarray
    y: np.ndarray
    z: np.ndarray
    thickness: np.ndarray
    layer_grade: np.ndarray
    count: np.ndarray
    grade_name: str
    bulk_density: float  # kg/m^3
    layers: int  # the scene's `layers`: chevron passes, windrow bottom rows, cones or strata
    equivalent_layers: float  # the law's N for the passes laid (bwr_twin.planning.patterns.equivalent_layers)
    pattern: str  # the scene's: "chevron", "windrow", "cone_shell" or "strata"
    band: tuple[float, float] | None  # the grade the customer accepts, or None
    history: PileHistory | None = None  # the pile as it grew, if kept for a replay

    def series(self, time: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """At each `time` (s): the grade arriving, and the tonnes laid by the deposit under way."""
        if not len(self.t):
            return np.full(len(time), np.nan), np.zeros(len(time))
        index = np.clip(np.searchsorted(self.t, time, side="right") - 1, 0, None)
        return self.grade[index], np.cumsum(self.tonnes)[index]

    def pile_arrays(self) -> dict[str, np.ndarray]:
        """pile.npz's arrays (output contract, docs/contracts.md)."""
        history = self.history.arrays() if self.history is not None else {}  # its grade's name and band are these
        return {**dict(x=self.x, y=self.y, z_start=np.zeros_like(self.z), z_end=self.z, layer_thickness=self.thickness,
                       layer_grade=self.layer_grade, layer_count=self.count, deposit_t=self.t,
                       deposit_grade=self.grade, deposit_tonnes=self.tonnes, deposit_point=self.point, deposit_drop=self.drop,
                       bulk_density=self.bulk_density, grade_name=self.grade_name, layers=self.layers,
                       equivalent_layers=self.equivalent_layers, pattern=self.pattern,
                       **({"grade_band": np.array(self.band)} if self.band is not None else {})), **history}


class Stacking:
    """Every run's pile as it is stacked."""

    def __init__(self, scenes: Sequence[Scene], machine: Machine, plan: StackingPlan, period: float, duration: float,
                 frame_every: int | None = None):
        """`duration`: s the runs discharge for, their last control period's time; `frame_every`:
        keep the cells changed every that many control periods, for a replay."""
        section = scenes[0].stacking
        self.section, self.machine, self.plan, self.period = section, machine, plan, period
        self.equivalent_layers = equivalent_layers(plan.layout)
        self.material = Material(section.bulk_density, section.angle_of_repose)
        self.piles = [LayeredPile(plan.x, plan.y, section.max_layers) for _ in scenes]
        self.talus = Talus.of(self.piles[0].spacing, section.angle_of_repose)
        self.every = round(section.deposit_period / period)  # control periods between deposits
        self.duration = duration
        self.streams = [grade_stream(section.grade, section.deposit_period, scene.simulation.seed) for scene in scenes]
        _check_record(self.streams[0], scenes[0], round(duration / period), self.every, period)
        self.deposits: list[list[tuple[float, ...]]] = [[] for _ in scenes]  # (t, grade, tonnes, x, y, drop)
        self.unconverged = np.zeros(len(scenes), dtype=np.int64)  # relaxations that ran out of rounds
        self._frame_every = frame_every
        self._frames = (PileFrames([pile.z for pile in self.piles], [pile.top_grade() for pile in self.piles])
                        if frame_every else None)

    def step(self, k: int, q: np.ndarray, runs: np.ndarray | None) -> None:
        """Period k: a deposit if one falls due, where the true joints q (runs, 3) put the
        discharge point; only the `runs` given (None: all)."""
        if k % self.every:
            return
        start = k * self.period
        span = min(self.section.deposit_period, self.duration - start)
        if span <= 0:
            return
        cp = self.machine.fk(q)
        for run in range(len(self.piles)) if runs is None else runs.tolist():
            grade = float(self.streams[run].at(start))
            x, y = float(cp[run, 0]), float(cp[run, 1])
            drop = float(cp[run, 2]) - height_under(self.piles[run], x, y)
            laid = discharge(self.piles[run], x, y, self.section.rate, span, grade, self.material,
                             self.talus.tolerance)
            self.unconverged[run] += not laid.relaxed.converged
            self.deposits[run].append((start, grade, laid.tonnes, x, y, drop))
        last = start + span >= self.duration
        if self._frames is not None and (k % self._frame_every < self.every or last):  # the last, so the replay ends on the pile
            self._frames.keep(start, [pile.z for pile in self.piles], [pile.top_grade() for pile in self.piles])

    def record(self, run: int) -> StackingRecord:
        pile = self.piles[run]
        t, grade, tonnes, x, y, drop = self._deposits(run)
        section = self.section
        history = (self._frames.history(run, pile.x, pile.y, np.zeros_like(pile.z), section.grade.name,
                                        section.grade.band) if self._frames is not None else None)
        return StackingRecord(t, grade, tonnes, np.column_stack([x, y]), drop, pile.x, pile.y, pile.z.copy(),
                              pile.thickness.copy(), pile.grade.copy(), pile.count.copy(), section.grade.name,
                              section.bulk_density, section.layers, self.equivalent_layers, section.pattern,
                              section.grade.band, history)

    def _deposits(self, run: int) -> tuple[np.ndarray, ...]:
        """(deposits,) times, grades, tonnes, x, y and drops of the run's deposits."""
        rows = np.array(self.deposits[run], dtype=float).reshape(-1, 6)
        return tuple(rows.T)

    def metrics(self, run: int) -> dict:
        """metrics.json's `stacking` object (output contract): what came in and what the pile
        holds, their balances, the grade's spread, and the pile's shape."""
        pile, material = self.piles[run], self.material
        t, grade, tonnes, _, _, drop = self._deposits(run)
        tonnes_in = float(tonnes.sum())
        grade_tonnes_in = float(np.sum(tonnes * grade))
        held = material.tonnes(pile.volume())
        grade_held = material.tonnes(pile.grade_volume())
        mean_in, sd_in = tonne_weighted(tonnes, grade)
        return {
            "pattern": self.section.pattern,
            "layers": self.section.layers,
            "equivalent_layers": self.equivalent_layers,
            "deposits": len(t),
            "tonnes_in_t": tonnes_in,
            "pile_t": held,
            "balance_t": tonnes_in - held,
            "balance_relative": (tonnes_in - held) / tonnes_in if tonnes_in else 0.0,
            "grade_balance_relative": (grade_tonnes_in - grade_held) / grade_tonnes_in if grade_tonnes_in else 0.0,
            "grade_name": self.section.grade.name,
            "grade_in_mean": mean_in,
            "grade_in_sd": sd_in,
            "pile_grade_mean": grade_held / held if held > 0 else float("nan"),
            "crest_height_m": float(pile.z.max()),
            "target_height_m": self.plan.height,
            "pass_speed_m/s": self.plan.speed,
            # m the stream fell onto the pile: the planned `drop` where the pile stands as targeted
            "drop_target_m": self.section.drop,
            **{f"drop_{name}_m": float(f(drop)) if len(drop) else float("nan")
               for name, f in (("min", np.min), ("mean", np.mean), ("max", np.max))},
            "slope_excess_m": self.talus.excess(pile.z),
            "relaxations_unconverged": int(self.unconverged[run]),
            "layers_per_column_max": int(pile.count.max()),
            "rate_tph": self.section.rate,
        }


def _check_record(stream: Ar1Grade | RecordedGrade, scene: Scene, periods: int, every: int, period: float) -> None:
    """A recorded grade must cover every deposit's time, from 0 s to the last deposit's start
    (periods: control periods the runs discharge for); else a SceneError before anything runs."""
    if not isinstance(stream, RecordedGrade) or periods < 1:
        return
    last = (periods - 1) // every * every * period  # the last deposit's start: its span is > 0
    if stream.t[0] > 0.0 or stream.t[-1] < last:
        raise SceneError(
            f"{scene.path}: 'stacking.grade.file' {stream.file} records the grade from t = {stream.t[0]:g} s to "
            f"{stream.t[-1]:g} s, {stream.t[-1] - stream.t[0]:g} s; the stacking lasts {periods * period:g} s, "
            f"its deposits from 0 s to {last:g} s: the file must cover them"
        )


def grade_stream(section: GradeSection, period: float, seed: int) -> Ar1Grade | RecordedGrade:
    """The grade of the stream arriving, one value a deposit `period` (s): an AR(1) from the
    run's `seed` or the recorded file."""
    if section.file is not None:
        return RecordedGrade(section.file, section.interpolation)
    return Ar1Grade(section.mean, section.sd, section.correlation_time, period,
                    stream(seed, Stream.GRADE))
