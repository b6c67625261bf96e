"""Where the fit starts: an equation-error estimate from MuJoCo's inverse dynamics.

The output-error fit (bwr_twin.calibrate.fit) is not convex. From the MJCF's values a slow, heavy
axis (the luff) under a wrong gravity falls within every window, and Gauss-Newton's first steps
stiffen it with damping and inertia far beyond their truth, a valley it does not leave; the
other axes' parameters then absorb the misfit. The balance of forces, though, is linear in
the damping and the friction: over each log interval the drive's force equals what MuJoCo's
inverse dynamics (`mj_inverse`) needs to make the measured change of speed, plus the Coulomb
friction against the motion. One linear least-squares solve over every interval gives a start
near the truth; the output-error fit then refines it. mujoco.sysid has no such start; the
regressors come from MuJoCo's own inverse dynamics, each parameter's column from the model
compiled with that parameter changed.
"""

from __future__ import annotations

import contextlib
import io

import mujoco
import numpy as np
from mujoco import sysid

from bwr_twin.calibrate.parameters import BODY_KINDS

STICK = 0.05  # of the rated speed: slower, the Coulomb friction is anywhere within its band
STEADY = 0.05  # of the rated speed per second: an interval accelerating less is in steady motion
KINDS = ("damping", "frictionloss")  # what the start estimates
PROBE = 0.1  # of a parameter's range: the change its regressor is taken over


def equation_error_start(problem, params: sysid.ParameterDict) -> sysid.ParameterDict:
    """`params` with each axis's damping and Coulomb friction moved to their equation-error
    estimate over the log's steady motion (within their bounds); the rest held: `masses_first`
    fits the masses before, and the output-error fit the inertias after."""
    dofs = [int(problem.model.jnt_dofadr[j]) for j in problem.machine.joint_ids]
    rows = [_intervals(log, None if wind is None else wind[:, dofs])
            for log, wind in zip(problem.logs, problem.wind, strict=True)]
    q = np.vstack([r[0] for r in rows])
    qd = np.vstack([r[1] for r in rows])
    qdd = np.vstack([r[2] for r in rows])
    force = np.vstack([r[3] for r in rows])
    knobs = [k for k in problem.knobs if k.kind in KINDS and not params[k.name].frozen]
    if not knobs or not len(q):
        return params
    base = params.copy()
    needed = _inverse(problem, base, q, qd, qdd)
    columns = []
    for knob in knobs:
        if knob.kind == "frictionloss":  # MuJoCo's friction loss is a constraint: its force by hand
            column = np.zeros_like(force)
            column[:, knob.axis] = np.sign(qd[:, knob.axis])
            columns.append(column)
            continue
        trial = base.copy()
        step = PROBE * (knob.high - knob.low)
        trial[knob.name].value[:] = trial[knob.name].value + step
        columns.append((_inverse(problem, trial, q, qd, qdd) - needed) / step)
    # Rows in steady motion: friction's sign is known, and the inertias (a mass, a drive's, held
    # at their start) hardly matter. A 10 Hz log's accelerations, a difference of two speeds
    # against a mean of forces that chatter at the control rate, would not give them anyway.
    rated = _rated(problem.machine)
    moving = (np.abs(qd) > STICK * rated) & (np.abs(qdd) < STEADY * rated)
    residual = force - needed  # what the parameters' changes must explain
    regressor = np.stack(columns, axis=-1)  # (n, 3, p)
    # Each axis's equations weighted by the inverse of its force's spread: N and N m alike.
    # An axis that never moved steadily has no equations: its parameters stay where they are.
    spread = np.array([np.std(residual[moving[:, j], j]) if moving[:, j].sum() > 1 else np.inf for j in range(3)])
    weight = np.where(np.isfinite(spread), 1.0 / np.maximum(spread, 1e-300), 0.0)
    a = (regressor * (moving * weight)[..., None]).reshape(-1, len(knobs))
    b = (residual * moving * weight).reshape(-1)
    scale = np.array([k.high - k.low for k in knobs])
    delta = np.linalg.lstsq(a * scale, b, rcond=None)[0] * scale
    out = params.copy()
    for knob, d in zip(knobs, delta, strict=True):
        out[knob.name].value[:] = np.clip(base[knob.name].value + d, knob.low, knob.high)
    for p in out.values():
        p.move_off_bound(fraction=0.05)
    return out


def masses_first(problem, residual_fn, params: sysid.ParameterDict, **options) -> sysid.ParameterDict:
    """`params` with the masses and positions moved to their own output-error fit, the rest
    held. A mass off at the start leaves gravity unbalanced on a slow axis (the luff), which
    then falls within every window; fitted alone, the masses come back first."""
    bodies = {k.name for k in problem.knobs if k.kind in BODY_KINDS and not params[k.name].frozen}
    if not bodies:
        return params
    first = params.copy()
    for name, p in first.items():
        p.frozen = p.frozen or name not in bodies
    with contextlib.redirect_stdout(io.StringIO()):  # the optimizer prints each iteration
        opt, _ = sysid.optimize(first, residual_fn, optimizer="mujoco", verbose=False, **options)
    moved = params.copy()
    for name in bodies:
        moved[name].value[:] = opt[name].value
    return moved


def _rated(machine) -> np.ndarray:
    envelope = machine.envelope
    return np.where(np.isfinite(machine.rated_speed), machine.rated_speed, 0.1 * (envelope[:, 1] - envelope[:, 0]))


def _intervals(log, wind) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Per log interval (within a stretch without a gap): the mid-point joint values and speeds,
    the mean acceleration, and the mean force on the axes: the drive's (the logged forces are
    each sample's mean, so the interval's is the two ends' mean) and the wind's (`wind`, (n, 3)
    per row, or None)."""
    from bwr_twin.calibrate.windows import GAP_FACTOR

    dt = np.diff(log.time)
    keep = dt <= GAP_FACTOR * np.median(dt)
    speed = log.qd if log.qd is not None else np.array([log.velocity_at(i) for i in range(len(log.time))])
    q = 0.5 * (log.q[1:] + log.q[:-1])
    qd = 0.5 * (speed[1:] + speed[:-1])
    qdd = np.diff(speed, axis=0) / dt[:, None]
    force = 0.5 * (log.force[1:] + log.force[:-1])
    if wind is not None:
        force = force + 0.5 * (wind[1:] + wind[:-1])
    return q[keep], qd[keep], qdd[keep], force[keep]


def _inverse(problem, params: sysid.ParameterDict, q, qd, qdd) -> np.ndarray:
    """(n, 3) the axes' forces MuJoCo's inverse dynamics needs at each row, the model compiled
    with `params` (its passive damping included)."""
    model = sysid.apply_param_modifiers(params, problem.spec)
    data = mujoco.MjData(model)
    qpos = np.array([int(model.jnt_qposadr[j]) for j in problem.machine.joint_ids])
    dofs = np.array([int(model.jnt_dofadr[j]) for j in problem.machine.joint_ids])
    model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONSTRAINT  # friction by hand, no limits
    out = np.empty_like(q)
    for i in range(len(q)):
        data.qpos[:] = model.qpos0
        data.qvel[:] = 0.0
        data.qacc[:] = 0.0
        data.qpos[qpos], data.qvel[dofs], data.qacc[dofs] = q[i], qd[i], qdd[i]
        mujoco.mj_inverse(model, data)
        out[i] = data.qfrc_inverse[dofs]
    return out
