"""The shadow's twin: the machine's MJCF run beside the measured machine, block by block.

The estimator is windowed resynchronisation: at the start of every block (BLOCK s) the twin's
state is set to the measured one, and the twin runs through the block under the drives'
measured forces; its position and speed at the block's end against the measured ones are the
block's position and speed residuals. Within a block the twin is open loop, so a fault shows
in it before any feedback can hide it; at the next block it starts afresh, so the residuals
never build up from the disturbances of the past (a Kalman filter would need their statistics,
which a shadow does not know before it has watched the machine).

The force residual is MuJoCo's inverse dynamics (`mj_inverse`) on the measured motion less the
drive's force, per sample and averaged over the block: the force the nominal machine needs to
move as measured, less what the drive applied. The MJCF's Coulomb friction is in it as MuJoCo's
soft friction constraint gives it, as the plant's is. Its mean acceleration over a block is the
difference of the measured speeds at the block's ends over its length (the per-sample
differences telescope), so the block's mean is free of the noise of differentiating a
quantised encoder.

Beside each residual, each fault's signature: the force residual a fault of unit size would
give on the measured motion. A friction rise of share x gives -x times the nominal friction
force (viscous and Coulomb); a derate of share x, -x times the drive's force; a mass change of
m kg at the CP, -m times the inverse dynamics of a tonne there (gravity and inertia).

Where the log has the machine's anemometer, the wind's force at each measured state (MuJoCo's
fluid model, bwr_twin.model.wind) is applied to the twin as it runs through the block, and is
taken from the force the motion needs: the drives did not apply it. Without it a gust on the
boom reads as a drive fault (a 12 m/s wind raised a false slew derate within 6 s).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from bwr_twin.model.machine import Machine
from bwr_twin.model.wind import wind_forces
from bwr_twin.shadow.measured import GAP, Measured

BLOCK = 1.0  # s: the length of a block, the resynchronisation window
UNIT_MASS = 1000.0  # kg: the mass change a mass signature is of (a tonne at the CP)
# The inverse dynamics of the free motion: no contacts or joint limits. The joints' Coulomb
# friction (`frictionloss`) stays: MuJoCo's inverse of its own soft friction constraint, the
# force the plant's friction really gives near zero speed, where a sign would overstate it.
_INVERSE_OFF = mujoco.mjtDisableBit.mjDSBL_CONTACT | mujoco.mjtDisableBit.mjDSBL_LIMIT


@dataclass(frozen=True)
class _UnitPayload:
    """A payload of bwr_twin.model.spec's shape: the tonne at the CP a mass signature is of."""

    body: str
    mass: float
    pos: tuple[float, float, float]


@dataclass(frozen=True)
class Blocks:
    """The residuals and signatures of a log's blocks, (blocks, 3) per axis unless said.

    start, end: (blocks,) s; force: the force residual (N, N m); position, speed: the twin's
    prediction residuals at the block's end (m, rad; m/s, rad/s); drift: the encoder's mean
    speed over the block less the drives' speed feedback's (m/s, rad/s; 0 without feedback);
    stepped: the way the encoder's reading last changed in the block, +1 up, -1 down, 0 it read
    the same position through the block; moved: how far the axis moved over the block by the
    speed feedback (by the twin without it) (m, rad);
    friction, derate, mass: the signatures of a unit friction rise, derate and mass change;
    unseen: how far the axis moved since the reading's last change in the block (over the whole
    block if it did not change), by the speed feedback (by the twin without it) (m, rad), and
    `unseen_bounds` (blocks, 3, 2) the least and the most of that motion on the way;
    samples: (blocks,) the samples a block is made of (its length over them is the log's period);
    wind: the measured wind's mean force over the block (N, N m; None: not known, as still air).
    """

    start: np.ndarray
    end: np.ndarray
    force: np.ndarray
    position: np.ndarray
    speed: np.ndarray
    drift: np.ndarray
    stepped: np.ndarray
    moved: np.ndarray
    friction: np.ndarray
    derate: np.ndarray
    mass: np.ndarray
    unseen: np.ndarray
    unseen_bounds: np.ndarray
    samples: np.ndarray
    wind: np.ndarray | None = None

    @classmethod
    def none(cls) -> Blocks:
        """No blocks."""
        empty = np.zeros((0, 3))
        return cls(np.zeros(0), np.zeros(0), empty, empty, empty, empty, empty, empty, empty, empty, empty, empty,
                   np.zeros((0, 3, 2)), np.zeros(0, dtype=int), empty)


class ShadowTwin:
    """The machine of an MJCF as the shadow runs it: forward under measured forces, and inverse."""

    def __init__(self, mjcf: Path):
        machine = Machine(mjcf)
        self.machine = machine
        self.model_name = machine.name  # <mujoco model=...>
        self.limits = machine.drive_limits  # (3, 2) N, N m
        self._model = machine.physics_model()
        self._data = mujoco.MjData(self._model)
        self._actuators = np.array(machine.actuator_ids, dtype=np.int64)
        self._joints = machine.joint_ids
        self._gear = machine.model.actuator_gear[self._actuators, 0].copy()
        cp_body = int(machine.model.site_bodyid[machine.cp_site])
        body = mujoco.mj_id2name(machine.model, mujoco.mjtObj.mjOBJ_BODY, cp_body)
        at = tuple(float(x) for x in machine.model.site_pos[machine.cp_site])
        heavier = Machine(mjcf, payloads=(_UnitPayload(body, UNIT_MASS, at),))
        self._inverse = [self._free(machine.physics_model()), self._free(heavier.physics_model())]
        self._inverse_data = [mujoco.MjData(m) for m in self._inverse]
        self._damping = self._model.dof_damping[:3].copy()

    @staticmethod
    def _free(model: mujoco.MjModel) -> mujoco.MjModel:
        model.opt.disableflags |= int(_INVERSE_OFF)  # this copy's own option: only inverse dynamics reads it
        return model

    def blocks(self, measured: Measured) -> Blocks:
        """Every whole block of the log that no gap cuts, and its residuals."""
        per_block = max(1, round(BLOCK / measured.period))
        bounds = _whole_blocks(measured.time, measured.period, per_block)
        rows = [self._block(measured, i0, i0 + per_block) for i0 in bounds]
        if not rows:
            return Blocks.none()
        columns = list(zip(*rows))
        return Blocks(*(np.array(c) for c in columns))

    def _block(self, m: Measured, i0: int, i1: int):
        """The residuals of samples i0 .. i1 - 1, whose forces act until sample i1."""
        dt = np.diff(m.time[i0 : i1 + 1])[:, None]
        qd = m.qd if m.speed is None else m.speed  # the drives' feedback: the encoder's filtered speed lags
        qdd = (qd[i0 + 1 : i1 + 1] - qd[i0:i1]) / dt
        (nominal, coulomb), (heavier, _) = (self._inverse_of(k, m.q[i0:i1], qd[i0:i1], qdd) for k in (0, 1))
        friction_force = self._damping * qd[i0:i1] + coulomb
        wind = self._wind_on(m, i0, i1, qd)
        needed = nominal - wind
        force = m.force[i0:i1]
        weights = dt / dt.sum()
        q_end, qd_end = self._predict(m.q[i0], qd[i0], force, dt[:, 0], wind)
        span = m.time[i1] - m.time[i0]
        # The reading's last change: sample i0 + n + 1 differs from i0 + n at the last n of `change`.
        change = np.diff(m.q[i0 : i1 + 1], axis=0)
        changed = change != 0
        last = np.where(changed.any(axis=0), i1 - i0 - 1 - np.argmax(changed[::-1], axis=0), -1)
        stepped = np.sign(change[np.maximum(last, 0), np.arange(3)]) * (last >= 0)
        if m.speed is not None:
            # The motion between two samples by the trapezoid rule: at a PLC's 10 Hz the speed at
            # a step's start alone leaves half its change of speed out, a drift while it accelerates.
            steps = 0.5 * (m.speed[i0:i1] + m.speed[i0 + 1 : i1 + 1]) * dt
            moved = steps.sum(axis=0)
            drift = (m.q[i1] - m.q[i0] - moved) / span
            # The motion after the reading's last change: sample i's step ends at i + 1, so the
            # steps from the first sample with the new reading on.
            unseen_path = np.cumsum(steps * (np.arange(i1 - i0)[:, None] > last[None, :]), axis=0)
        else:
            moved, drift = q_end - m.q[i0], np.zeros(3)
            unseen_path = np.where(last >= 0, 0.0, moved)[None, :]  # the twin's motion, at the block's end only
        unseen_bounds = np.stack([np.minimum(unseen_path.min(axis=0), 0.0), np.maximum(unseen_path.max(axis=0), 0.0)],
                                 axis=-1)
        return (m.time[i0], m.time[i1], ((needed - force) * weights).sum(axis=0), m.q[i1] - q_end,
                qd[i1] - qd_end, drift, stepped, moved, -(friction_force * weights).sum(axis=0),
                -(force * weights).sum(axis=0), -((heavier - nominal) * weights).sum(axis=0), unseen_path[-1],
                unseen_bounds, i1 - i0, (wind * weights).sum(axis=0))

    def _wind_on(self, m: Measured, i0: int, i1: int, qd: np.ndarray) -> np.ndarray:
        """(i1 - i0, 3) the measured wind's force on the joints at samples i0 .. i1 - 1 (N, N m);
        zero in still air or without an anemometer."""
        if m.wind is None or m.air is None:
            return np.zeros((i1 - i0, 3))
        return wind_forces(self._model, self._joints, m.q[i0:i1], qd[i0:i1], m.wind[i0:i1], m.air.heading,
                           m.air.density)[:, :3]

    def _inverse_of(self, which: int, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(n, 3) the joint forces that move model `which` as measured (N, N m), its Coulomb
        friction's part included, and that part alone."""
        model, data = self._inverse[which], self._inverse_data[which]
        out, coulomb = np.empty_like(q), np.empty_like(q)
        for i in range(len(q)):
            data.qpos[:3], data.qvel[:3], data.qacc[:3] = q[i], qd[i], qdd[i]
            mujoco.mj_inverse(model, data)
            out[i] = data.qfrc_inverse[:3]
            coulomb[i] = -data.qfrc_constraint[:3]  # the friction constraint's force, against the motion
        return out, coulomb

    def _predict(self, q0: np.ndarray, qd0: np.ndarray, force: np.ndarray, dt: np.ndarray, wind: np.ndarray):
        """The twin from (q0, qd0) under the drive forces and the wind's held for dt each: its end
        position and speed."""
        model, data = self._model, self._data
        mujoco.mj_resetData(model, data)
        data.qpos[:3], data.qvel[:3] = q0, qd0
        step = model.opt.timestep
        for f, w, span in zip(force, wind, dt):
            data.ctrl[self._actuators] = f / self._gear
            data.qfrc_applied[:3] = w
            mujoco.mj_step(model, data, nstep=max(1, round(span / step)))
        return data.qpos[:3].copy(), data.qvel[:3].copy()


def _whole_blocks(time: np.ndarray, period: float, per_block: int) -> list[int]:
    """The first sample of every block of per_block samples (and the one after) no gap cuts."""
    cut = np.flatnonzero(np.diff(time) > GAP * period)  # a gap follows sample i
    starts, i0 = [], 0
    for c in [*cut, len(time) - 1]:
        while i0 + per_block <= c:
            starts.append(i0)
            i0 += per_block
        i0 = c + 1
    return starts
