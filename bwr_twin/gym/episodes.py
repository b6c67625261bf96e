"""Environment slots and their episodes, each episode one run of a Lockstep.

Episodes that start in the same period share a lockstep: a vector environment's reset starts all
its slots at once, so one lockstep normally holds them all and MuJoCo steps them as one
threaded batch. A slot whose episode ends early (it left the envelope or diverged) starts its
next episode in a new lockstep, with the other slots that ended in the same period; its run in
the old lockstep is left behind at zero force and dropped with that lockstep once no slot uses
it. A run's result does not depend on which runs share its lockstep, so every episode is the
one a single environment gives for the same seed and actions.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from bwr_twin.config.scene import load_scene
from bwr_twin.errors import SceneError
from bwr_twin.gym.actions import make_drive
from bwr_twin.gym.reward import tracking_reward
from bwr_twin.gym.scales import OBSERVATION_SIZE, Scales
from bwr_twin.model.machine import AXES, describe
from bwr_twin.shipped import find_scene
from bwr_twin.sim.lockstep import Lockstep
from bwr_twin.sim.plant import mujoco_warnings


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


@dataclass
class Outcome:
    """What one period did to every slot: (slots,) arrays, zero and False for slots not stepped.

    `ended` maps a slot whose episode ended to why: "path end", "left the operating envelope:
    ..." or "diverged: ...".
    """

    reward: np.ndarray
    terminated: np.ndarray
    truncated: np.ndarray
    ended: dict[int, str]


class Episodes:
    """`count` slots, each running the episodes of one environment.

    Attributes:
        scales: the observation's scales (`bwr_twin.gym.scales`).
        period: s, the scene's control period: one step.
        observation: (count, 19) float32, each slot's latest observation.
        error: (count, 3) each slot's true position error at that observation (m, rad).
        elapsed: (count,) s since the path's start at that observation.
        seed: (count,) the scene seed of each slot's episode.
    """

    def __init__(self, scene: str | Path, count: int, *, action_mode: str, force_scale: Sequence[float] | None,
                 acceleration_scale: float, error_scale: float, reward_weights: Sequence[float],
                 overrides: Mapping[str, Any] | None, nthread: int):
        """Raises BwrError for a bad scene, path or model, ValueError for a bad argument."""
        self.scene = find_scene(scene)
        self.overrides = dict(overrides or {})
        self.nthread = nthread
        if not error_scale > 0:
            raise ValueError(f"error_scale must be > 0 m, got {error_scale!r}")
        self.weights = np.asarray(reward_weights, dtype=float)
        if self.weights.shape != (3,) or not (self.weights >= 0).all():
            raise ValueError(f"reward_weights must be 3 numbers >= 0 (travel, slew, luff), got {reward_weights!r}")
        # A lockstep of the scene as written: its machine and path set the scales and the drive.
        scene = load_scene(self.scene, self.overrides)
        if scene.reclaim is not None:
            raise SceneError(f"{scene.path}: bwr_twin/Reclaim-v0 follows a scene's [path]; this scene plans a "
                             "[reclaim], whose reference is decided as the run goes: give a scene with a [path]")
        first = Lockstep([scene], nthread=1, observe=False)
        self.scales = Scales.of(first, error_scale)
        self.period = first.period
        self.envelope = first.machine.envelope
        self.drive = make_drive(action_mode, first, count, force_scale=force_scale,
                                acceleration_scale=acceleration_scale, nthread=nthread)
        self.count = count
        self.observation = np.zeros((count, OBSERVATION_SIZE), dtype=np.float32)
        self.error = np.zeros((count, 3))
        self.elapsed = np.zeros(count)
        self.seed = np.zeros(count, dtype=np.int64)
        self._q, self._qd, self._qdd_ref = np.zeros((count, 3)), np.zeros((count, 3)), np.zeros((count, 3))
        self._groups: list[Group] = []
        self._group_of: list[Group | None] = [None] * count
        self._running = np.zeros(count, dtype=bool)

    @property
    def locksteps(self) -> list[Lockstep]:
        """The locksteps that hold a running episode."""
        return [group.loop for group in self._groups]

    def running(self) -> np.ndarray:
        """(count,) bool: the slots whose episode goes on."""
        return self._running.copy()

    def start(self, slots: Sequence[int], seeds: Sequence[int]) -> None:
        """Start new episodes in `slots`, with these scene seeds, in one new lockstep."""
        slots = np.asarray(slots, dtype=np.int64)
        scenes = [load_scene(self.scene, {**self.overrides, "simulation.seed": int(seed)}) for seed in seeds]
        group = Group(Lockstep(scenes, nthread=self.nthread, observe=False), slots)
        for slot in slots:
            self._leave(int(slot))
            self._group_of[slot] = group
        self._running[slots] = True
        self._groups.append(group)
        self.seed[slots] = seeds
        self.error[slots] = group.loop.path[0][0] - group.loop.q_true
        self._observe(group, group.runs)

    def step(self, actions: np.ndarray) -> Outcome:
        """Hold the forces of the (count, 3) actions for one control period in every running slot."""
        slots = np.flatnonzero(self._running)
        forces = np.zeros((self.count, 3))
        if len(slots):
            action = np.minimum(np.maximum(np.asarray(actions, dtype=float)[slots], -1.0), 1.0)
            forces[slots] = self.drive.forces(action, slots, self._q, self._qd, self._qdd_ref[slots])
        outcome = Outcome(np.zeros(self.count), np.zeros(self.count, dtype=bool),
                          np.zeros(self.count, dtype=bool), {})
        with mujoco_warnings():  # MuJoCo neither prints nor writes a log; a failure ends the run
            for group in list(self._groups):
                self._advance(group, forces, outcome)
        return outcome

    def _advance(self, group: Group, forces: np.ndarray, outcome: Outcome) -> None:
        """Advance one lockstep a period under the (count, 3) forces; its slots' share of `outcome`."""
        loop, runs, slots = group.loop, group.runs, group.live_slots
        command = np.zeros((loop.runs, 3))  # runs left behind get no force
        command[runs] = forces[slots]
        loop.advance(command)
        q = loop.q_true[runs]
        failed = np.zeros(len(runs), dtype=bool)
        if loop.failures or not np.isfinite(q).all():
            failed = np.isin(runs, list(loop.failures)) | ~np.isfinite(q).all(axis=1)
        outside = (q < self.envelope[:, 0]) | (q > self.envelope[:, 1])
        error = loop.path[0][min(loop.k, loop.samples - 1)] - q
        ending = failed.any() or outside.any() or loop.done
        if ending:
            error[failed] = self.error[slots[failed]]  # a diverged state has no error: keep the last
        outcome.reward[slots] = tracking_reward(error, self.scales.error, self.weights)
        self.error[slots] = error
        self._observe(group, runs[~failed] if ending else runs)
        if not ending:
            return
        terminated = np.full(len(runs), loop.done) & ~failed
        truncated = (failed | outside.any(axis=1)) & ~terminated
        outcome.terminated[slots], outcome.truncated[slots] = terminated, truncated
        for i in np.flatnonzero(terminated | truncated):
            run, slot = int(runs[i]), int(slots[i])
            if failed[i]:
                outcome.ended[slot] = f"diverged: {loop.failures.get(run, 'non-finite state')}"
            elif terminated[i]:
                outcome.ended[slot] = "path end"
            else:
                axes = ", ".join(f"{AXES[j]} = {describe(j, q[i, j])}" for j in np.flatnonzero(outside[i]))
                outcome.ended[slot] = f"left the operating envelope: {axes}"
            self._leave(slot)

    def _observe(self, group: Group, runs: np.ndarray) -> None:
        """Measure the lockstep (once a period, for all its runs) and observe `runs`."""
        loop = group.loop
        q, qd = loop.measure()
        k = min(loop.k, loop.samples - 1)  # past the path's end the reference is its end point
        q_desired, qd_desired, qdd_desired = loop.path
        slots = group.slots[runs]
        self._q[slots], self._qd[slots], self._qdd_ref[slots] = q[runs], qd[runs], qdd_desired[k]
        self.elapsed[slots] = loop.k * loop.period
        self.observation[slots] = self.scales.observe(q[runs], qd[runs], q_desired[k], qd_desired[k],
                                                      qdd_desired[k], loop.k * loop.period)

    def _leave(self, slot: int) -> None:
        """End `slot`'s episode: its run stays behind in its lockstep, dropped once none is live."""
        group = self._group_of[slot]
        if group is None:
            return
        group.leave(slot)
        self._group_of[slot] = None
        self._running[slot] = False
        if not len(group.runs):
            self._groups.remove(group)
