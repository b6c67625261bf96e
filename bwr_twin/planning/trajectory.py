"""The desired joint trajectory: inverse kinematics at the via points, then one cubic per
segment with zero velocity at every via point (paper Sec. 4); the same cubic moves a bench
plan's joints (bwr_twin.planning.plan)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bwr_twin.config.sections import PathSection
from bwr_twin.errors import EnvelopeError
from bwr_twin.model.machine import AXES, Machine, describe, paper_to_world


@dataclass(frozen=True)
class Trajectory:
    """Cubic segments through joint-space knots.

    Attributes:
        times: (n,) via point times in s, increasing.
        knots: (n, 3) joint values at the via points (m, rad, rad).
        points: (n, 3) via points in world coordinates (m).
    """

    times: np.ndarray
    knots: np.ndarray
    points: np.ndarray

    @classmethod
    def plan(cls, path: PathSection, machine: Machine) -> Trajectory:
        """Solve the inverse kinematics at every via point and check the whole path.

        Raises UnreachableError or EnvelopeError naming the via point (1-based, as the paper
        counts) or the segment.
        """
        times = np.array([v.t for v in path.via_points])
        points = np.array([v.p for v in path.via_points], dtype=float)
        if path.frame == "paper":
            points = paper_to_world(points)
        knots = np.array(
            [
                machine.ik(p, label=f"via point {i + 1} (t = {t:g} s)")
                for i, (t, p) in enumerate(zip(times, points))
            ]
        )
        trajectory = cls(times=times, knots=knots, points=points)
        trajectory.check_envelope(machine)
        return trajectory

    def check_envelope(self, machine: Machine, samples_per_segment: int = 200) -> None:
        """Raise EnvelopeError naming the segment, the axis and the value where the path leaves the envelope."""
        # A cubic with zero end velocities is monotone, so checking the knots would do; the path
        # is sampled anyway, so that the check holds for whatever interpolation comes next.
        for i in range(len(self.times) - 1):
            t = np.linspace(self.times[i], self.times[i + 1], samples_per_segment)
            q = self.sample(t)[0]
            for j, axis in enumerate(AXES):
                low, high = machine.envelope[j]
                worst = np.argmax(np.maximum(low - q[:, j], q[:, j] - high))
                if not low - 1e-9 <= q[worst, j] <= high + 1e-9:
                    raise EnvelopeError(
                        f"segment from via point {i + 1} to {i + 2} (t = {t[worst]:.1f} s): {axis} reaches "
                        f"{describe(j, q[worst, j])}, outside the envelope "
                        f"[{describe(j, low)}, {describe(j, high)}] of {machine.path.name}"
                    )

    @property
    def duration(self) -> float:
        return float(self.times[-1] - self.times[0])

    def sample(self, t: np.ndarray | float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Desired position, velocity and acceleration at times t: each of shape t.shape + (3,).

        Times outside the path hold the end points at rest.
        """
        t = np.clip(np.asarray(t, dtype=float), self.times[0], self.times[-1])
        seg = np.clip(np.searchsorted(self.times, t, side="right") - 1, 0, len(self.times) - 2)
        t0, t1 = self.times[seg], self.times[seg + 1]
        span = (t1 - t0)[..., None]
        return rest_to_rest(self.knots[seg], self.knots[seg + 1], span, (t - t0)[..., None] / span)


def rest_to_rest(start: np.ndarray, end: np.ndarray, span, s) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The cubic from `start` at rest to `end` at rest over `span` s, at the fraction `s` of it:
    position, velocity and acceleration. Its top speed is 1.5 x delta / span, its top
    acceleration 6 x delta / span^2, at both ends."""
    delta = end - start
    return (start + delta * (3 * s**2 - 2 * s**3), delta * (6 * s - 6 * s**2) / span,
            delta * (6 - 12 * s) / span**2)
