"""The environment's per-period arithmetic, compiled: observations, rewards, drive forces.

A step's own work is a few dozen operations on (runs, 3) arrays; as numpy calls each costs a
microsecond of overhead, which summed to more than the physics. Each kernel does what the numpy
expressions in its docstring do, in the same order and with the same operations, so results are
the same to the bit whichever number of runs is stepped (tests/test_gym.py).
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True)
def observe(q, qd, q_ref, qd_ref, qdd_ref, elapsed, offset, divisor, limit,
            out):  # pragma: no cover - compiled
    """out[r] = clip((raw[r] - offset) / divisor, -limit, limit) as float32, raw[r] the layout of
    bwr_twin.gym.scales: q, qd, q_ref, qd_ref, qdd_ref, q_ref - q, elapsed; q, qd (runs, 3),
    the references (3,)."""
    raw = np.empty(19)
    for r in range(q.shape[0]):
        for i in range(3):
            raw[i] = q[r, i]
            raw[3 + i] = qd[r, i]
            raw[6 + i] = q_ref[i]
            raw[9 + i] = qd_ref[i]
            raw[12 + i] = qdd_ref[i]
            raw[15 + i] = q_ref[i] - q[r, i]
        raw[18] = elapsed
        for j in range(19):
            x = (raw[j] - offset[j]) / divisor[j]
            if x < -limit:  # NaN passes through, as np.maximum and np.minimum let it
                x = -limit
            if x > limit:
                x = limit
            out[r, j] = np.float32(x)


@numba.njit(cache=True)
def reward(error, scale, weights, out):  # pragma: no cover - compiled
    """out[r] = -(w0 (e0 / s0)^2 + w1 (e1 / s1)^2 + w2 (e2 / s2)^2), axis by axis in that order."""
    for r in range(error.shape[0]):
        s0 = error[r, 0] / scale[0]
        s1 = error[r, 1] / scale[1]
        s2 = error[r, 2] / scale[2]
        out[r] = -(weights[0] * (s0 * s0) + weights[1] * (s1 * s1) + weights[2] * (s2 * s2))


@numba.njit(cache=True)
def clipped_force(action, low, high, out):  # pragma: no cover - compiled
    """Force mode, one run: a = clip(action, -1, 1); out[0] = a * high where a >= 0, else a * low
    (np.where(a >= 0, a * high, a * low)). Returns the index of a non-finite action, writing
    nothing, or -1."""
    for i in range(3):
        if not np.isfinite(action[i]):
            return i
    for i in range(3):
        a = min(max(np.float64(action[i]), -1.0), 1.0)
        out[0, i] = a * high[i] if a >= 0 else a * low[i]
    return -1


@numba.njit(cache=True)
def clipped_acceleration(action, qdd_ref, scale, out):  # pragma: no cover - compiled
    """Acceleration mode, one run: out[0] = qdd_ref[0] + clip(action, -1, 1) * scale. Returns the
    index of a non-finite action, writing nothing, or -1."""
    for i in range(3):
        if not np.isfinite(action[i]):
            return i
    for i in range(3):
        out[0, i] = qdd_ref[0, i] + min(max(np.float64(action[i]), -1.0), 1.0) * scale[i]
    return -1


# Where step_one's constants and state sit in their arrays (`Episodes`).
ENVELOPE, ERROR_SCALE, WEIGHTS, OFFSET, DIVISOR, LIMIT = 0, 6, 9, 12, 31, 50
ERROR, MEASURED_Q, MEASURED_QD, REFERENCE_QDD, REWARD, ELAPSED = 0, 3, 6, 9, 12, 13
NOT_FINITE, OUTSIDE = 1, 2  # finish_one's status bits


@numba.njit(cache=True)
def finish_one(q, failed, q_desired, qd_desired, qdd_desired, row, q_measured, qd_measured, elapsed,
               constants, state, outside, observation):  # pragma: no cover - compiled
    """One run at the end of a period, read at path row `row`: the error (reference - true q,
    kept from the last period if the run `failed` or q is not finite), `outside` the axes beyond
    the envelope, the reward of the error (`reward`), and unless it failed the measured state,
    the reference acceleration, `elapsed` and the observation (`observe`). Returns the status
    bits NOT_FINITE and OUTSIDE."""
    finite = np.isfinite(q[0, 0]) and np.isfinite(q[0, 1]) and np.isfinite(q[0, 2])
    keep = finite and not failed
    status = 0 if finite else NOT_FINITE
    for i in range(3):
        if keep:
            state[ERROR + i] = q_desired[row, i] - q[0, i]
        outside[i] = q[0, i] < constants[ENVELOPE + 2 * i] or q[0, i] > constants[ENVELOPE + 2 * i + 1]
        if outside[i]:
            status |= OUTSIDE
    reward(state[ERROR:ERROR + 3].reshape(1, 3), constants[ERROR_SCALE:ERROR_SCALE + 3],
           constants[WEIGHTS:WEIGHTS + 3], state[REWARD:REWARD + 1])
    if keep:
        for i in range(3):
            state[MEASURED_Q + i] = q_measured[0, i]
            state[MEASURED_QD + i] = qd_measured[0, i]
            state[REFERENCE_QDD + i] = qdd_desired[row, i]
        state[ELAPSED] = elapsed
        observe(q_measured, qd_measured, q_desired[row], qd_desired[row], qdd_desired[row], elapsed,
                constants[OFFSET:OFFSET + 19], constants[DIVISOR:DIVISOR + 19], constants[LIMIT], observation)
    return status
