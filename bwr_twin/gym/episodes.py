"""Environment slots and their episodes, each episode one run of a Lockstep.

Episodes that start in the same period share a lockstep: a vector environment's reset starts all
its slots at once, so one lockstep normally holds them all and MuJoCo steps them as one
threaded batch. A slot whose episode ends early (it left the envelope or diverged) starts its
next episode in a new lockstep, with the other slots that ended in the same period; its run in
the old lockstep is left behind at zero force and dropped with that lockstep once no slot uses
it. A run's result does not depend on which runs share its lockstep, so every episode is the
one a single environment gives for the same seed and actions.

A single environment steps its one slot through `step_one`: the same arithmetic in compiled
kernels (bwr_twin.gym.kernels), without the bookkeeping of slots and groups.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from bwr_twin.config.scene import Scene, load_scene
from bwr_twin.errors import BwrError, SceneError
from bwr_twin.gym import kernels
from bwr_twin.gym.actions import checked_actions, make_drive
from bwr_twin.gym.kernels import observe
from bwr_twin.gym.reward import tracking_reward
from bwr_twin.gym.scales import INSTRUMENTS, OBSERVATION_LIMIT, Scales
from bwr_twin.gym.slots import Group, Readings, Slots
from bwr_twin.gym.spaces import ENV_ID
from bwr_twin.model.machine import AXES, describe
from bwr_twin.shipped import find_scene
from bwr_twin.sim.budget import check_estimate, estimate
from bwr_twin.sim.lockstep import Lockstep
from bwr_twin.sim.plant import mujoco_warnings

TIME_LIMIT = "time limit"  # info["ended"] of an episode cut short by `duration`


@dataclass
class Outcome:
    """What one period did to every slot: (slots,) arrays, zero and False for slots not stepped.

    `ended` maps a slot whose episode ended to why: "path end", "time limit", "left the
    operating envelope: ..." or "diverged: ...".
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
        observation: (count, 19) float32, each slot's latest observation; (count, 21) with the
            instruments (`scales.size`).
        error: (count, 3) each slot's true position error at that observation (m, rad).
        elapsed: (count,) s since the path's start at that observation.
        seed: (count,) the scene seed of each slot's episode.
        limit: control periods an episode lasts at most (`duration`), or None: the path's.
        where: the environment, as errors name it.
    """

    def __init__(self, scene: str | Path, count: int, *, action_mode: str, force_scale: Sequence[float] | None,
                 acceleration_scale: float, error_scale: float, reward_weights: Sequence[float],
                 overrides: Mapping[str, Any] | None, nthread: int, duration: float | None = None,
                 instruments: bool = False):
        """Raises BwrError for a bad scene, path or model, for episodes beyond the twin's bounds
        (bwr_twin.sim.budget) or for `instruments` on a scene without them, ValueError for a
        bad argument."""
        self.scene = find_scene(scene)
        self.where = f"{ENV_ID} ({self.scene.name})"
        self.overrides = dict(overrides or {})
        self.nthread = nthread
        if not isinstance(instruments, (bool, np.bool_)):
            raise ValueError(f"instruments must be True or False, got {instruments!r}")  # noqa: TRY004 - as every bad keyword
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
        self.limit = _limit(scene, duration)
        _check_budget(scene, count, self.limit)  # before the path is sampled: a via point at 1e9 s is refused
        first = Lockstep([scene], nthread=1, observe=False)
        self.scales = Scales.of(first, error_scale, bool(instruments))
        self.instruments = bool(instruments)
        self.period = first.period
        self.envelope = first.machine.envelope
        self.drive = make_drive(action_mode, first, count, force_scale=force_scale,
                                acceleration_scale=acceleration_scale)
        self.count = count
        self._readings = Readings(count, self.scales.size)
        if count == 1:  # what step_one's kernel compares, scales and weighs with
            self._constants = np.concatenate([self.envelope.ravel(), self.scales.error, self.weights,
                                              self.scales.offset, self.scales.divisor, [OBSERVATION_LIMIT]])
        self._slots = Slots(count)

    @property
    def observation(self) -> np.ndarray:
        """Live: see the class's attributes (kept by `Readings`)."""
        return self._readings.observation

    @property
    def error(self) -> np.ndarray:
        """Live: see the class's attributes (kept by `Readings`)."""
        return self._readings.error

    @property
    def elapsed(self) -> np.ndarray:
        """Live: see the class's attributes (kept by `Readings`)."""
        return self._readings.elapsed

    @property
    def seed(self) -> np.ndarray:
        """Live: see the class's attributes (kept by `Slots`)."""
        return self._slots.seed

    @property
    def locksteps(self) -> list[Lockstep]:
        """The locksteps that hold a running episode."""
        return [group.loop for group in self._slots.groups]

    def running(self) -> np.ndarray:
        """(count,) bool: the slots whose episode goes on."""
        return self._slots.running.copy()

    def is_running(self, slot: int) -> bool:
        return bool(self._slots.running[slot])

    def start(self, slots: Sequence[int], seeds: Sequence[int]) -> None:
        """Start new episodes in `slots`, with these scene seeds, in one new lockstep."""
        slots = np.asarray(slots, dtype=np.int64)
        scenes = [load_scene(self.scene, {**self.overrides, "simulation.seed": int(seed)}) for seed in seeds]
        group = Group(Lockstep(scenes, nthread=self.nthread, observe=False), slots)
        self._slots.join(group, seeds)
        self.error[slots] = group.loop.path[0][0] - group.loop.q_true
        self._observe(group, group.runs)

    def step(self, actions: np.ndarray) -> Outcome:
        """Hold the forces of the (count, 3) actions for one control period in every running slot."""
        slots = np.flatnonzero(self._slots.running)
        forces = np.zeros((self.count, 3))
        if len(slots):
            action = np.minimum(np.maximum(np.asarray(actions, dtype=float)[slots], -1.0), 1.0)
            readings = self._readings
            forces[slots] = self.drive.forces(action, slots, readings.q, readings.qd, readings.qdd_ref[slots])
        outcome = Outcome(np.zeros(self.count), np.zeros(self.count, dtype=bool),
                          np.zeros(self.count, dtype=bool), {})
        with mujoco_warnings():  # MuJoCo neither prints nor writes a log; a failure ends the run
            for group in list(self._slots.groups):
                self._advance(group, forces, outcome)
        return outcome

    def step_one(self, action: np.ndarray) -> tuple[float, bool, bool, str | None]:
        """`step` for one slot, running, under its (3,) float action (`as_action`): (reward,
        terminated, truncated, why it ended or None), the numbers `step` gives. ValueError naming
        the element if the action is not finite."""
        loop, readings = self._slots.groups[0].loop, self._readings
        force = self.drive.force_one(action, readings.q, readings.qd, readings.qdd_ref)
        if force is None:
            checked_actions(action, (3,), self.where)  # raises, naming the element
        with mujoco_warnings():  # MuJoCo neither prints nor writes a log; a failure ends the run
            loop.advance(force)
        k = loop.k
        q_measured, qd_measured = loop.measure()
        q_desired, qd_desired, qdd_desired = loop.path
        failed = bool(loop.failures)
        status = kernels.finish_one(loop.q_true, failed, q_desired, qd_desired, qdd_desired,
                                    min(k, loop.samples - 1), q_measured, qd_measured, k * loop.period,
                                    self._constants, readings.state, readings.outside, readings.observation)
        reward = float(readings.state[kernels.REWARD])
        if self.instruments and not (failed or status & kernels.NOT_FINITE):  # observed as finish_one observes
            self.scales.observe_instruments_one(loop, readings.instruments_one)
        if not (status or failed or loop.done or k == self.limit):
            return reward, False, False, None
        self._slots.leave(0)
        if failed or status & kernels.NOT_FINITE:
            return reward, False, True, f"diverged: {loop.failures.get(0, 'non-finite state')}"
        if loop.done:
            return reward, True, False, "path end"
        if status & kernels.OUTSIDE:
            return reward, False, True, _left(loop.q_true[0], readings.outside)
        return reward, False, True, TIME_LIMIT

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
        limited = loop.k == self.limit
        ending = failed.any() or outside.any() or loop.done or limited
        if ending:
            error[failed] = self.error[slots[failed]]  # a diverged state has no error: keep the last
        outcome.reward[slots] = tracking_reward(error, self.scales.error, self.weights)
        self.error[slots] = error
        self._observe(group, runs[~failed] if ending else runs)
        if not ending:
            return
        terminated = np.full(len(runs), loop.done) & ~failed
        truncated = (failed | outside.any(axis=1) | limited) & ~terminated
        outcome.terminated[slots], outcome.truncated[slots] = terminated, truncated
        for i in np.flatnonzero(terminated | truncated):
            run, slot = int(runs[i]), int(slots[i])
            if failed[i]:
                outcome.ended[slot] = f"diverged: {loop.failures.get(run, 'non-finite state')}"
            elif terminated[i]:
                outcome.ended[slot] = "path end"
            elif outside[i].any():
                outcome.ended[slot] = _left(q[i], outside[i])
            else:
                outcome.ended[slot] = TIME_LIMIT
            self._slots.leave(slot)

    def _observe(self, group: Group, runs: np.ndarray) -> None:
        """Measure the lockstep (once a period, for all its runs) and observe `runs`."""
        loop = group.loop
        q, qd = loop.measure()
        k = min(loop.k, loop.samples - 1)  # past the path's end the reference is its end point
        q_desired, qd_desired, qdd_desired = loop.path
        slots = group.slots[runs]
        readings = self._readings
        readings.q[slots], readings.qd[slots], readings.qdd_ref[slots] = q[runs], qd[runs], qdd_desired[k]
        readings.elapsed[slots] = loop.k * loop.period
        scales = self.scales
        observation = np.empty((len(runs), scales.size), dtype=np.float32)
        observe(q[runs], qd[runs], q_desired[k], qd_desired[k], qdd_desired[k], loop.k * loop.period,
                scales.offset, scales.divisor, OBSERVATION_LIMIT, observation)
        if self.instruments:
            scales.observe_instruments(loop, runs, observation[:, INSTRUMENTS])
        readings.observation[slots] = observation


def _left(q: np.ndarray, outside: np.ndarray) -> str:
    axes = ", ".join(f"{AXES[j]} = {describe(j, q[j])}" for j in np.flatnonzero(outside))
    return f"left the operating envelope: {axes}"


def _limit(scene: Scene, duration: float | None) -> int | None:
    """Control periods of an episode of `duration` s (None: the whole path); ValueError if it is
    not a number of s > 0 within the path."""
    if duration is None:
        return None
    via = scene.trajectory.via_points
    path = via[-1].t - via[0].t
    period = scene.simulation.control_period
    if isinstance(duration, bool) or not isinstance(duration, (int, float, np.integer, np.floating)) \
            or not math.isfinite(duration) or duration <= 0:
        raise ValueError(f"duration must be a number of s > 0, got {duration!r}")
    if duration > path + period:  # the path's last period ends at path + period
        raise ValueError(f"duration {duration:g} s: beyond the path of {scene.path.name} ({path:g} s), whose "
                         f"end terminates an episode after {round(path / period) + 1} control periods; give at "
                         f"most {path + period:g} s (or no duration: the whole path)")
    periods = round(duration / period)
    if periods < 1:
        raise ValueError(f"duration {duration:g} s: shorter than one control period ({period:g} s)")
    return periods


def _check_budget(scene: Scene, count: int, limit: int | None) -> None:
    """BwrError naming the scene and the estimate if one episode of every slot would go beyond
    the twin's bounds (more than 12 h, half of the memory), as `bwr_twin.run` refuses a run."""
    cost = estimate([scene] * count, chunk=count)
    if limit is not None:  # a shorter episode: its share of the path's periods and steps
        via = scene.trajectory.via_points
        share = min(1.0, limit * scene.simulation.control_period / max(via[-1].t - via[0].t, 1e-300))
        cost = dataclasses.replace(cost, physics_steps=cost.physics_steps * share,
                                   seconds=cost.seconds * share)
    cost = dataclasses.replace(cost, disk_bytes=0.0)  # an environment writes nothing
    try:
        check_estimate(cost, where=scene.path, out_dir=Path.cwd(), force=False)
    except BwrError as exc:
        text = str(exc).split("; check the")[0]
        raise SceneError(f"{text} for one episode of {ENV_ID}; check the timestep and the via point times, "
                         "or give a shorter duration") from None
