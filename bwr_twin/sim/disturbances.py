"""Random forces and gusts, per run, from the run's seed alone.

Each run draws from its own generators, so a run's sequence does not depend on which runs share
its lockstep. Disturbance forces and gusts use independent streams (bwr_twin.streams), so
that turning gusts on leaves the disturbance sequence unchanged. Draws are made a block of
control periods at a time, so memory stays bounded however long the path.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from bwr_twin.sim.parameters import RunParameters
from bwr_twin.streams import Stream, stream

BLOCK = 5000  # control periods drawn at once: 50 s at 100 Hz, 15 MB of forces for 128 runs


class HeldNoise:
    """Uniform noise in [-amplitude, amplitude], redrawn every hold time and held in between,
    sampled every control period: `sample(k)` is the (runs,) + shape array of period k.

    Periods must be asked for in increasing order, without gaps of more than one block.
    """

    def __init__(
        self,
        generators: Sequence[np.random.Generator],
        amplitude: np.ndarray,
        hold: np.ndarray,
        period: float,
    ):
        """`amplitude` is (runs,) + shape, `hold` the (runs,) hold times in s."""
        self._generators = generators
        self._amplitude = np.asarray(amplitude, dtype=float)
        self._hold = np.asarray(hold, dtype=float)
        self._period = period
        self._shape = self._amplitude.shape[1:]
        self._drawn = np.zeros(len(generators), dtype=np.int64)  # draws made per run
        self._last = np.zeros(self._amplitude.shape)  # each run's latest draw
        self._block = np.zeros((0,) + self._amplitude.shape)
        self._start = 0
        self.active = bool(self._amplitude.any())  # False: every sample is zero, and need not be drawn

    def sample(self, k: int) -> np.ndarray:
        if not self._start <= k < self._start + len(self._block):
            self._draw_block(k)
        return self._block[k - self._start]

    def _draw_block(self, start: int) -> None:
        periods = np.arange(start, start + BLOCK)
        # The draw each period holds, per period and run: one per hold time (1e-9 absorbs rounding).
        held = np.floor((periods * self._period)[:, None] / self._hold + 1e-9).astype(np.int64)
        block = np.empty((BLOCK,) + self._amplitude.shape)
        for run, generator in enumerate(self._generators):
            index = held[:, run]
            first = self._drawn[run]
            new = generator.uniform(-1.0, 1.0, size=(index[-1] + 1 - first,) + self._shape)
            pool = np.concatenate([self._last[run][None], new]) if first else new
            offset = first - 1 if first else 0
            block[:, run] = pool[index - offset] * self._amplitude[run]
            self._drawn[run] = index[-1] + 1
            self._last[run] = pool[-1]
        self._block, self._start = block, start


class Disturbances:
    """The disturbance forces on the joints (N, N m) and the wind gusts (m/s) of every run."""

    def __init__(self, parameters: RunParameters, period: float):
        streams = [(stream(seed, Stream.DISTURBANCE), stream(seed, Stream.GUST)) for seed in parameters.seed]
        self.forces = HeldNoise([np.random.default_rng(force) for force, _ in streams],
                                parameters.disturbance_amplitude, parameters.disturbance_hold, period)
        self.gusts = HeldNoise([np.random.default_rng(gust) for _, gust in streams],
                               parameters.gust_amplitude, parameters.gust_hold, period)
