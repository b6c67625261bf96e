"""Which lockstep holds each environment slot's episode, and what each slot last observed.

`Episodes` (bwr_twin.gym.episodes) steps the episodes; these two keep its books: `Slots` which
group of runs each slot's episode belongs to, `Readings` each slot's latest measurement and
observation, which the drive and the infos read.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from bwr_twin.gym import kernels
from bwr_twin.gym.scales import INSTRUMENTS
from bwr_twin.sim.lockstep import Lockstep


class Group:
    """One lockstep and the environment slot of each of its runs (-1: the slot's episode ended).

    `runs` lists the runs whose episode goes on, `live_slots` their slots.
    """

    def __init__(self, loop: Lockstep, slots: np.ndarray):
        self.loop, self.slots = loop, slots.copy()
        self.runs, self.live_slots = np.arange(len(slots)), self.slots.copy()

    def leave(self, slot: int) -> None:
        self.slots[self.slots == slot] = -1
        self.runs = np.flatnonzero(self.slots >= 0)
        self.live_slots = self.slots[self.runs]


class Slots:
    """`count` slots and the group whose lockstep runs each one's episode, if it runs.

    Attributes:
        groups: the groups that hold a running episode, oldest first.
        seed: (count,) the scene seed of each slot's episode.
    """

    def __init__(self, count: int):
        self.groups: list[Group] = []
        self.seed = np.zeros(count, dtype=np.int64)
        self._group_of: list[Group | None] = [None] * count
        self._running = np.zeros(count, dtype=bool)

    @property
    def running(self) -> np.ndarray:
        """(count,) bool, live: the slots whose episode goes on."""
        return self._running

    def join(self, group: Group, seeds: Sequence[int]) -> None:
        """Start the episodes of the group's slots, with these scene seeds, ending what they ran."""
        for slot in group.slots:
            self.leave(int(slot))
            self._group_of[slot] = group
        self._running[group.slots] = True
        self.groups.append(group)
        self.seed[group.slots] = seeds

    def leave(self, slot: int) -> None:
        """End `slot`'s episode: its run stays behind in its lockstep, dropped once none is live."""
        group = self._group_of[slot]
        if group is None:
            return
        group.leave(slot)
        self._group_of[slot] = None
        self._running[slot] = False
        if not len(group.runs):
            self.groups.remove(group)


class Readings:
    """Each slot's latest measurement and observation.

    With one slot, `step_one`'s kernel (bwr_twin.gym.kernels.finish_one) writes them in place:
    `error`, `q`, `qd`, `qdd_ref` and `elapsed` are then views of one state array, `state`.

    Attributes:
        observation: (count, size) float32, each slot's latest observation.
        error: (count, 3) each slot's true position error at that observation (m, rad).
        elapsed: (count,) s since the path's start at that observation.
        q, qd, qdd_ref: (count, 3) the measured joint state and the reference's acceleration
            that the drive reads (m, rad; m/s, rad/s; m/s^2, rad/s^2).
        state, outside, instruments_one: with one slot, the kernel's state array, which axes left
            the envelope, and a view of the observation's instruments; None with more slots.
    """

    def __init__(self, count: int, size: int):
        self.observation = np.zeros((count, size), dtype=np.float32)
        self.state = self.outside = self.instruments_one = None
        if count == 1:  # step_one's kernel writes them: views of one state array
            self.state = state = np.zeros(kernels.ELAPSED + 1)
            self.error, self.q, self.qd, self.qdd_ref = (
                state[i:i + 3].reshape(1, 3) for i in (kernels.ERROR, kernels.MEASURED_Q, kernels.MEASURED_QD,
                                                        kernels.REFERENCE_QDD))
            self.elapsed = state[kernels.ELAPSED:kernels.ELAPSED + 1]
            self.outside = np.zeros(3, dtype=bool)
            self.instruments_one = self.observation[0, INSTRUMENTS]  # a view: written in place
        else:
            self.error = np.zeros((count, 3))
            self.elapsed = np.zeros(count)
            self.q, self.qd, self.qdd_ref = (np.zeros((count, 3)) for _ in range(3))
