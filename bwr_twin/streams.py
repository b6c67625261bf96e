"""The random streams of a run: each source of randomness draws from its own child of the run's
seed's SeedSequence, numbered here once, so that a run's numbers depend on its seed alone (not on
the runs beside it in a lockstep) and adding a source leaves the others' numbers unchanged."""

from __future__ import annotations

from enum import IntEnum

import numpy as np


class Stream(IntEnum):
    """The SeedSequence child (its spawn key) of a run's seed each source draws from."""

    DISTURBANCE = 0  # the random disturbance forces on the joints (bwr_twin.sim.disturbances)
    GUST = 1  # the gusts on the mean wind (bwr_twin.sim.disturbances)
    SCANNER = 2  # the boom scanners' range noise and dropout, a grandchild per scanner (bwr_twin.sensing.noise)
    FAULT = 3  # an encoder_noise fault, a grandchild per fault (bwr_twin.sensing.faults)
    BELT_SCALE = 4  # the belt scale's noise (bwr_twin.sensing.rate_instruments)
    WHEEL_CURRENT = 5  # the wheel motor's current noise (bwr_twin.sensing.rate_instruments)
    GRADE = 6  # the stacked stream's AR(1) grade (bwr_twin.stockpile.stacking)


def stream(seed: int, source: Stream, *more: int) -> np.random.SeedSequence:
    """The SeedSequence `source` of a run of `seed` draws from (`more`: a grandchild's keys)."""
    return np.random.SeedSequence(seed, spawn_key=(int(source), *more))
