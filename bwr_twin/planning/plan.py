"""A bench plan (bwr_twin.planning.bench plans it, bwr_twin.planning.follower follows it): its
segments, the speed law of its passes, and what the planner predicts of them."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from bwr_twin.planning.trajectory import rest_to_rest
from bwr_twin.units import KG_PER_T


@dataclass(frozen=True)
class Move:
    """A smooth joint-space move, at rest at both ends: one cubic per axis."""

    start: np.ndarray  # (3,) m, rad, rad
    end: np.ndarray
    duration: float  # s, a whole number of control periods
    bench: int  # 0-based
    kind: str  # "approach", "travel step", "slew clear", "step down"

    def sample(self, tau: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Position, velocity and acceleration (3,) at `tau` s into the move."""
        return rest_to_rest(self.start, self.end, self.duration, min(max(tau / self.duration, 0.0), 1.0))


@dataclass(frozen=True)
class Pass:
    """A slew across the face at one travel and luff; its speed is decided as the run goes."""

    travel: float  # m
    luff: float  # rad
    start: float  # rad, slew
    end: float  # rad
    bench: int  # 0-based
    number: int  # 1-based within the plan
    cut: tuple[float, float]  # rad: where the predicted cut begins and ends, in the pass's direction
    steady: tuple[float, float] | None  # rad: where the face stands at its full section, or None
    face_height: float  # m, the bench's
    cut_depth: float  # m, the travel advance that made this cut
    radius: float  # m from the slew axis to the face's centre of area
    volume: float  # m^3 the planner predicts it cuts

    @property
    def direction(self) -> float:
        return 1.0 if self.end >= self.start else -1.0

    def cuts_at(self, slew: float) -> bool:
        """Whether the planner predicts that the wheel cuts at `slew` (rad)."""
        return _between(slew, self.cut)

    def steady_at(self, slew: float) -> bool:
        """Whether `slew` (rad) lies where the pass cuts a full face."""
        return self.steady is not None and _between(slew, self.steady)


@dataclass(frozen=True)
class SpeedLaw:
    """The open-loop slew speed for the target rate: rate = face height x cut x lateral speed,
    the cut across the face being cut_depth x |cos(slew)|."""

    volume_rate: float  # m^3/s, the target
    law: str  # "cosine" or "constant"
    cap: float  # rad: the cosine law holds its speed beyond it
    rated: float  # rad/s, the slew drive's rated speed

    def speed(self, p: Pass, slew: float) -> float:
        """rad/s at `slew` in pass p, before any trim; `math` on floats: it runs every period."""
        angle = slew if self.law == "cosine" else 0.5 * (p.cut[0] + p.cut[1])
        cosine = max(abs(math.cos(angle)), math.cos(self.cap))
        return self.volume_rate / (p.face_height * p.cut_depth * cosine * p.radius)


@dataclass(frozen=True)
class BenchPlan:
    """The segments of a bench reclaim and what the planner predicts of them."""

    segments: tuple[Move | Pass, ...]
    start: np.ndarray  # (3,) where the machine stands at t = 0
    law: SpeedLaw
    acceleration: np.ndarray  # (3,) m/s^2, rad/s^2, rad/s^2
    rated_speed: np.ndarray  # (3,) m/s, rad/s, rad/s
    first_contact: np.ndarray | None  # (3,) world m: where the wheel first touches the pile
    bench_volumes: tuple[float, ...]  # m^3 predicted per bench
    density: float  # kg/m^3
    nominal_duration: float  # s, open loop
    longest_duration: float  # s: the slowest any rate control may make it (trims at their low limit)

    @property
    def passes(self) -> list[Pass]:
        return [s for s in self.segments if isinstance(s, Pass)]

    @property
    def benches(self) -> int:
        return len(self.bench_volumes)

    def bench_tonnes(self) -> list[float]:
        return [v * self.density / KG_PER_T for v in self.bench_volumes]


def end_of(segment: Move | Pass) -> np.ndarray:
    """The joint values (3,) at which a segment ends."""
    if isinstance(segment, Move):
        return segment.end
    return np.array([segment.travel, segment.end, segment.luff])


def _between(value: float, interval: tuple[float, float]) -> bool:
    """Whether value lies in the interval, whichever way round it is given."""
    low, high = sorted(interval)
    return low <= value <= high
