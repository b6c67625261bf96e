"""The random numbers of each run's senses, from the run's seed alone: the scanners' per ray, and
a normal a control period for the faults and the instruments (`PeriodNormals`).

Each run draws from its own streams (bwr_twin.streams): the scanners' (Stream.SCANNER), and
within it one child per scanner. So a run's scans do not depend on which runs share its lockstep, and adding a
scanner leaves the disturbances unchanged. Every scan draws a standard normal (the range noise)
and a uniform (the dropout) for every ray, hit or not, a block of scans at a time, so that the
streams stay in step whatever the rays meet and memory stays bounded however long the run.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from bwr_twin.streams import Stream, stream

BLOCK = 64  # scans drawn at once: 2.6 s at 25 Hz
PERIOD_BLOCK = 1000  # control periods of normals drawn at once


class ScanNoise:
    """One scanner's draws for every run: `at(n)` gives scan n's (runs, rays) standard normals
    and uniforms in [0, 1). Scans must be asked for in increasing order."""

    def __init__(self, seeds: Sequence[int], scanner_index: int, rays: int):
        self._generators = [np.random.default_rng(stream(seed, Stream.SCANNER, scanner_index)) for seed in seeds]
        self._rays = rays
        self._normal = np.empty((len(seeds), BLOCK, rays))
        self._uniform = np.empty((len(seeds), BLOCK, rays))
        self._start = None  # the first scan of the block drawn

    def at(self, n: int) -> tuple[np.ndarray, np.ndarray]:
        start = n - n % BLOCK
        if start != self._start:
            for run, generator in enumerate(self._generators):
                generator.standard_normal(out=self._normal[run])
                generator.random(out=self._uniform[run])
            self._start = start
        return self._normal[:, n - start], self._uniform[:, n - start]


class PeriodNormals:
    """A standard normal a control period for every run, each run from its own stream, the
    `source` stream of its seed (`more`: a grandchild's keys; bwr_twin.streams): `at(k)` is
    period k's (runs,); periods must be asked for in increasing order. Every block is drawn, so a
    stream stays in step whichever periods are asked for."""

    def __init__(self, seeds: Sequence[int], source: Stream, *more: int):
        self._generators = [np.random.default_rng(stream(seed, source, *more)) for seed in seeds]
        self._block = np.empty((len(seeds), PERIOD_BLOCK))
        self._start = None

    def at(self, k: int) -> np.ndarray:
        start = k - k % PERIOD_BLOCK
        if self._start is not None and start < self._start:
            raise RuntimeError(f"normals asked for period {k} after period {self._start}: periods must increase")
        while self._start is None or self._start < start:
            for run, generator in enumerate(self._generators):
                generator.standard_normal(out=self._block[run])
            self._start = 0 if self._start is None else self._start + PERIOD_BLOCK
        return self._block[:, k - start]
