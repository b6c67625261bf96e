"""The per-run numbers of a lockstep, read once from its scenes into arrays.

The loop's parts (plant, encoders, disturbances) receive these arrays, never a `Scene`: what
may differ between the runs of a lockstep is exactly what is here, one row per run.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from bwr_twin.config.scene import Scene


@dataclass(frozen=True)
class RunParameters:
    """(runs,) or (runs, 3) arrays, in SI units; a row per run."""

    seed: tuple[int, ...]  # the disturbance and gust streams' seeds, any size SeedSequence takes
    encoder_resolution: np.ndarray  # (runs, 3) m, rad, rad
    velocity_estimated: np.ndarray  # (runs,) bool: the velocity comes from the encoder, not the plant
    velocity_filter: np.ndarray  # (runs,) s, the estimate's low-pass time constant
    disturbance_amplitude: np.ndarray  # (runs, 3) N, N m, N m
    disturbance_hold: np.ndarray  # (runs,) s
    gust_amplitude: np.ndarray  # (runs,) m/s
    gust_hold: np.ndarray  # (runs,) s
    wind_speed: np.ndarray  # (runs,) m/s, the mean
    wind_direction: np.ndarray  # (runs,) rad from world +X towards +Y
    air_density: np.ndarray  # (runs,) kg/m^3
    frictionloss: np.ndarray  # (runs, 3) N, N m; NaN rows keep the MJCF's

    @classmethod
    def of(cls, scenes: Sequence[Scene]) -> RunParameters:
        plants = [s.plant for s in scenes]
        return cls(
            seed=tuple(int(s.simulation.seed) for s in scenes),
            encoder_resolution=np.array([s.encoders.resolution for s in scenes], dtype=float),
            velocity_estimated=np.array([s.encoders.velocity_source == "encoder" for s in scenes]),
            velocity_filter=np.array([s.encoders.velocity_filter for s in scenes], dtype=float),
            disturbance_amplitude=np.array([s.disturbance.amplitude for s in scenes], dtype=float),
            disturbance_hold=np.array([s.disturbance.hold_time for s in scenes], dtype=float),
            gust_amplitude=np.array([p.gust_amplitude for p in plants], dtype=float),
            gust_hold=np.array([p.gust_hold_time for p in plants], dtype=float),
            wind_speed=np.array([p.wind_speed for p in plants], dtype=float),
            wind_direction=np.radians([p.wind_direction for p in plants]),
            air_density=np.array([p.air_density for p in plants], dtype=float),
            frictionloss=np.array([p.frictionloss if p.frictionloss is not None else (np.nan,) * 3
                                   for p in plants], dtype=float),
        )

    @property
    def runs(self) -> int:
        return len(self.seed)

    @property
    def windy(self) -> np.ndarray:
        """(runs,) bool: the run has wind or gusts (a still run costs no drag)."""
        return (self.wind_speed != 0) | (self.gust_amplitude != 0)
