"""The balance of forces over a log's intervals, from MuJoCo's inverse dynamics, and the floor the
logged force's noise puts under each parameter's standard error.

Over each log interval the drive's force (with the wind's) equals what `mj_inverse` needs to make
the measured change of speed, plus the Coulomb friction against the motion. This balance is
linear in the damping, the friction, a drive's inertia and a mass, each parameter's column the
change of the needed force with it (the model compiled with the parameter changed).

The floor. An output-error fit replays the logged force as if it were exact, and the Jacobian's
intervals take it so. It is not: a drive's force or current is read to some percent, while the
encoders and the speed feedback read the motion to a count. Replayed, the force's noise drives
the model where the machine did not go, and a heavier, stiffer axis, which filters it, fits
better than the true one: the fit is biased and its intervals narrow. With the motion taken as
exact, the balance's least squares has the covariance (Phi' W Phi)^-1, each axis's rows weighted
by the inverse variance of its force residual: the Cramer-Rao bound for noise of that spread in
the force. No estimator does better, so no parameter's standard error is less than its square root.
"""

from __future__ import annotations

import mujoco
import numpy as np
from mujoco import sysid

from bwr_twin.calibrate.parameters import BODY_KINDS, JOINT_KINDS
from bwr_twin.calibrate.windows import stretches

STICK = 0.05  # of the rated speed: slower, the Coulomb friction is anywhere within its band
PROBE = 0.1  # of a parameter's range: the change its column is taken over (the balance is linear in most)
MODEL_KINDS = JOINT_KINDS + BODY_KINDS  # what the balance holds: a lag or an offset is a signal's


class Balance:
    """The balance of forces over every interval of a fit problem's logs (within a stretch
    without a gap): the mid-point joint values and speeds, the mean acceleration, and the mean
    force on the axes, the drive's and the wind's."""

    def __init__(self, problem):
        self.problem = problem
        dofs = [int(problem.model.jnt_dofadr[j]) for j in problem.machine.joint_ids]
        rows = [_intervals(log, None if wind is None else wind[:, dofs])
                for log, wind in zip(problem.logs, problem.wind, strict=True)]
        self.q, self.qd, self.qdd, self.force = (np.vstack([r[i] for r in rows]) for i in range(4))
        # Each row's span (its log, and which of the fit's windows of time within it), numbered 0 on.
        spans = np.vstack([np.column_stack([np.full(len(r[4]), i), (r[4] - r[4][:1]) // problem.window])
                           for i, r in enumerate(rows)])
        self.spans = np.unique(spans, axis=0, return_inverse=True)[1].ravel()
        envelope = problem.machine.envelope
        self.rated = np.where(np.isfinite(problem.machine.rated_speed), problem.machine.rated_speed,
                              0.1 * (envelope[:, 1] - envelope[:, 0]))
        self.moving = np.abs(self.qd) > STICK * self.rated  # (n, 3): friction's sign is known

    def needed(self, params: sysid.ParameterDict) -> np.ndarray:
        """(n, 3) the axes' forces the model compiled with `params` needs at each row: MuJoCo's
        inverse dynamics (its passive damping included) and the Coulomb friction against the
        motion (a constraint in MuJoCo: by hand)."""
        problem = self.problem
        model = sysid.apply_param_modifiers(params, problem.spec)
        data = mujoco.MjData(model)
        qpos = np.array([int(model.jnt_qposadr[j]) for j in problem.machine.joint_ids])
        dofs = np.array([int(model.jnt_dofadr[j]) for j in problem.machine.joint_ids])
        model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONSTRAINT  # no friction loss, no limits
        out = np.empty_like(self.q)
        for i in range(len(self.q)):
            data.qpos[:] = model.qpos0
            data.qvel[:] = 0.0
            data.qacc[:] = 0.0
            data.qpos[qpos], data.qvel[dofs], data.qacc[dofs] = self.q[i], self.qd[i], self.qdd[i]
            mujoco.mj_inverse(model, data)
            out[i] = data.qfrc_inverse[dofs]
        return out + model.dof_frictionloss[dofs] * np.sign(self.qd)

    def columns(self, params: sysid.ParameterDict, knobs, needed: np.ndarray) -> np.ndarray:
        """(n, 3, len(knobs)) each knob's column: the change of the needed force per unit of it."""
        out = []
        for knob in knobs:
            trial = params.copy()
            step = PROBE * (knob.high - knob.low)
            value = trial[knob.name].value[0]
            step = step if value + step <= knob.high else -step  # stay within the bounds
            trial[knob.name].value[:] = value + step
            out.append((self.needed(trial) - needed) / step)
        return np.stack(out, axis=-1)

    def least_squares(self, params: sysid.ParameterDict, knobs, rows: np.ndarray) -> np.ndarray:
        """The knobs' changes from `params` that best balance the forces over `rows` (n, 3), a
        mask of the equations to take: an equation-error fit. Each axis's equations are weighted
        by the inverse of its force residual's spread (N and N m alike); an axis with fewer than
        two equations has none, and what only it sees stays where it is."""
        needed = self.needed(params)
        residual = self.force - needed  # what the knobs' changes must explain
        weight = rows * _inverse(_spread(residual, rows))
        a = (self.columns(params, knobs, needed) * weight[..., None]).reshape(-1, len(knobs))
        scale = np.array([k.high - k.low for k in knobs])  # the columns of one size
        return np.linalg.lstsq(a * scale, (residual * weight).reshape(-1), rcond=None)[0] * scale

    def floor(self, params: sysid.ParameterDict, knobs, noise: np.ndarray | None = None) -> dict[str, float]:
        """Each model knob's least standard error (by name) at `params`: the Cramer-Rao bound of
        the balance for its axes' force noise `noise` (3,) in N and N m. Where `noise` is not
        given, the force residual at `params` is the noise (the drives' noise, the disturbances
        and the misfit): its spread gives the bound, and as it is correlated in time (a
        disturbance holds for a while, the misfit for longer), the clustered sandwich over spans
        of the fit's window gives the least's own scatter; the larger of the two."""
        knobs = [k for k in knobs if k.kind in MODEL_KINDS]
        if not knobs:
            return {}
        needed = self.needed(params)
        measured = noise is None
        if measured:
            residual = self.force - needed
            noise = _spread(residual, self.moving)
        rows = self.moving * _inverse(noise)  # (n, 3): each axis's moving rows, in units of its noise
        regressor = self.columns(params, knobs, needed) * rows[..., None]  # (n, 3, p)
        flat = regressor.reshape(-1, len(knobs))
        information = flat.T @ flat
        unseen = np.diag(information) <= 0  # an axis that never moved, or a knob that changes nothing
        scale = np.sqrt(np.maximum(np.diag(information), 1e-300))  # the columns of one size before inverting
        bread = np.linalg.pinv(information / np.outer(scale, scale)) / np.outer(scale, scale)
        variance = np.diag(bread)
        if measured:
            scores = np.einsum("nap,na->np", regressor, residual * rows)  # (n, p)
            spans = np.zeros((self.spans.max() + 1, len(knobs)))
            np.add.at(spans, self.spans, scores)
            clusters = len(spans)
            sandwich = bread @ (spans.T @ spans) @ bread * clusters / max(clusters - 1, 1)
            variance = np.maximum(variance, np.diag(sandwich))
        error = np.sqrt(np.maximum(variance, 0.0))
        return {k.name: float("inf") if u else float(e) for k, e, u in zip(knobs, error, unseen, strict=True)}


def _spread(residual: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """(3,) each axis's standard deviation of `residual` (n, 3) over its `rows` (n, 3), or
    infinite for an axis with fewer than two."""
    return np.array([np.std(residual[rows[:, j], j]) if rows[:, j].sum() > 1 else np.inf for j in range(3)])


def _inverse(spread: np.ndarray) -> np.ndarray:
    """(3,) each axis's weight, the inverse of its spread: none for an axis without one."""
    return np.where(np.isfinite(spread) & (spread > 0), 1.0 / np.maximum(spread, 1e-300), 0.0)


def _intervals(log, wind) -> tuple[np.ndarray, ...]:
    """Per log interval (within a stretch without a gap): the mid-point joint values and speeds,
    the mean acceleration, the mean force on the axes (the drive's, from its running integral,
    `MachineLog.impulse`; and the wind's, `wind` (n, 3) per row, or None), and the mid-point
    time."""
    dt = np.diff(log.time)
    keep = np.zeros(len(dt), dtype=bool)  # the intervals within a stretch, not across a gap
    speed = log.qd if log.qd is not None else np.array([log.velocity_at(i) for i in range(len(log.time))])
    q = 0.5 * (log.q[1:] + log.q[:-1])
    qd = 0.5 * (speed[1:] + speed[:-1])
    qdd = np.diff(speed, axis=0) / dt[:, None]
    force = np.zeros_like(q)  # each interval's mean, from the running integral of each stretch without a gap
    for first, stop in stretches(log):
        keep[first:stop - 1] = True
        if stop - first > 1:
            running = log.impulse(first, stop - 1)(log.time[first:stop])
            force[first:stop - 1] = np.diff(running, axis=0) / dt[first:stop - 1, None]
    if wind is not None:
        force = force + 0.5 * (wind[1:] + wind[:-1])
    middle = 0.5 * (log.time[1:] + log.time[:-1])
    return q[keep], qd[keep], qdd[keep], force[keep], middle[keep]
