"""M(q) and the bias forces of the contract's travel-slew-luff chain in closed form, identified
from MuJoCo and checked against it.

For the contract's chain (a slide along the rail, then a hinge, then a hinge that rides on the
first) every entry of the mass matrix, and every gravity force, is a fixed linear combination of
the 15 functions

    {1, cos slew, sin slew} x {1, cos luff, sin luff, cos 2 luff, sin 2 luff}

whatever the bodies' masses, centres and inertias, and whatever the axes: the slide moves every
body alike, so the travel appears nowhere; the slew turns the bodies above it rigidly, so it
enters only through the direction of their first moment against the rail (first order); a
body's first moment and inertia seen from the slew are linear and quadratic in cos and sin of the
luff. The paper's Eq. (1) has this shape for its point masses. `ChainDynamics.identify` fits the
coefficients to MuJoCo's own M and qfrc_bias at sample states (least squares, exact up to
rounding), then checks the closed form against MuJoCo at other states, velocities included; a
chain of another shape (a slide that rides on the slew, say) fails the check and gets none.

The velocity terms follow from M by Lagrange's equations, bias_i = sum_jk (dM_ij/dq_k -
dM_jk/dq_i / 2) qd_j qd_k + G_i (the paper's V derived from its M, which corrects its printed
V(1,1); docs/reproduction.md).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numba
import numpy as np

BASIS = tuple(f"{a}{b}" for a in ("", "cos(slew)", "sin(slew)")
              for b in ("", "cos(luff)", "sin(luff)", "cos(2 luff)", "sin(2 luff)"))
UPPER = ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))  # M's entries, row by row above the diagonal
FIT_STATES = 64  # sample states of the fit: four times the unknowns of each entry
CHECK_STATES = 64  # fresh states, with velocities, the closed form must match MuJoCo at
TOLERANCE = 1e-10  # of each matrix's and each bias vector's largest entry


@dataclass(frozen=True)
class ChainDynamics:
    """The closed form of one compiled machine's M and bias.

    Attributes:
        mass: (6, 15) coefficients of M's upper entries (`UPPER`) on `BASIS`, kg, kg m, kg m^2.
        gravity: (3, 15) coefficients of the gravity forces G(q) on `BASIS`, N and N m.
        error: the largest difference from MuJoCo at the check states, relative to the
            largest entry of M or of the bias there.
    """

    mass: np.ndarray
    gravity: np.ndarray
    error: float

    @classmethod
    def identify(cls, model: mujoco.MjModel, *, seed: int = 0) -> ChainDynamics | None:
        """The closed form of `model`'s M and bias (its rigid bodies only: qfrc_bias holds no
        friction, springs or dampers), or None if the model does not fit it to TOLERANCE."""
        if model.nv != 3 or model.nq != 3:
            return None
        rng = np.random.default_rng(seed)
        data = mujoco.MjData(model)
        dense = np.zeros((3, 3))

        def mujoco_at(q: np.ndarray, qd: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            data.qpos[:], data.qvel[:] = q, qd
            mujoco.mj_forward(model, data)
            mujoco.mj_fullM(model, data, dense)
            return dense.copy(), data.qfrc_bias.copy()

        states = _sample_states(rng, FIT_STATES)
        basis = np.array([_basis(q[1], q[2]) for q in states])
        measured = [mujoco_at(q, np.zeros(3)) for q in states]
        masses = np.array([[m[i, j] for i, j in UPPER] for m, _ in measured])
        gravities = np.array([g for _, g in measured])
        mass = np.linalg.lstsq(basis, masses, rcond=None)[0].T.copy()
        gravity = np.linalg.lstsq(basis, gravities, rcond=None)[0].T.copy()

        error = 0.0
        closed_mass, closed_bias = np.zeros((1, 3, 3)), np.zeros((1, 3))
        for q in _sample_states(rng, CHECK_STATES):
            qd = rng.uniform(-1.0, 1.0, 3) * np.array([1.0, 0.2, 0.2])  # m/s, rad/s: beyond any drive's
            true_mass, true_bias = mujoco_at(q, qd)
            evaluate(mass, gravity, q[None], qd[None], np.zeros(1, dtype=np.int64), closed_mass, closed_bias)
            error = max(error, np.abs(closed_mass[0] - true_mass).max() / np.abs(true_mass).max(),
                        np.abs(closed_bias[0] - true_bias).max() / max(np.abs(true_bias).max(), 1e-300))
        if not error <= TOLERANCE:
            return None
        return cls(mass, gravity, float(error))

    def at(self, q: np.ndarray, qd: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """M (3, 3) and bias (3,) at one state."""
        mass, bias = np.zeros((1, 3, 3)), np.zeros((1, 3))
        evaluate(self.mass, self.gravity, np.asarray(q, float)[None], np.asarray(qd, float)[None],
                 np.zeros(1, dtype=np.int64), mass, bias)
        return mass[0], bias[0]


def _sample_states(rng: np.random.Generator, count: int) -> np.ndarray:
    """Joint states over every angle: the closed form holds everywhere, not only in the envelope."""
    return rng.uniform([-10.0, -math.pi, -math.pi], [10.0, math.pi, math.pi], (count, 3))


def _basis(slew: float, luff: float) -> np.ndarray:
    out = np.empty(15)
    _basis_into(slew, luff, out, np.empty(15), np.empty(15))
    return out


@numba.njit(cache=True)
def _basis_into(slew, luff, value, d_slew, d_luff):  # pragma: no cover - compiled
    """`BASIS` at (slew, luff), and its derivatives along each."""
    cs, ss = math.cos(slew), math.sin(slew)
    cl, sl = math.cos(luff), math.sin(luff)
    c2, s2 = math.cos(2.0 * luff), math.sin(2.0 * luff)
    outer = (1.0, cs, ss)
    outer_d = (0.0, -ss, cs)
    inner = (1.0, cl, sl, c2, s2)
    inner_d = (0.0, -sl, cl, -2.0 * s2, 2.0 * c2)
    for a in range(3):
        for b in range(5):
            value[5 * a + b] = outer[a] * inner[b]
            d_slew[5 * a + b] = outer_d[a] * inner[b]
            d_luff[5 * a + b] = outer[a] * inner_d[b]


@numba.njit(cache=True)
def evaluate(mass_coefficients, gravity_coefficients, q, qd, ids, mass, bias):  # pragma: no cover - compiled
    """M (runs, 3, 3) and bias (runs, 3) at each (runs, 3) state, for the runs `ids`."""
    value, d_slew, d_luff = np.empty(15), np.empty(15), np.empty(15)
    m = np.empty((3, 3))
    dm = np.zeros((3, 3, 3))  # dm[k, i, j] = dM_ij / dq_k; nothing depends on the travel (k = 0)
    for r in ids:
        _basis_into(q[r, 1], q[r, 2], value, d_slew, d_luff)
        for e in range(6):
            i, j = (0, 0, 0, 1, 1, 2)[e], (0, 1, 2, 1, 2, 2)[e]
            entry = slope_slew = slope_luff = 0.0
            for n in range(15):
                c = mass_coefficients[e, n]
                entry += c * value[n]
                slope_slew += c * d_slew[n]
                slope_luff += c * d_luff[n]
            m[i, j] = m[j, i] = entry
            dm[1, i, j] = dm[1, j, i] = slope_slew
            dm[2, i, j] = dm[2, j, i] = slope_luff
        for i in range(3):
            force = 0.0
            for n in range(15):
                force += gravity_coefficients[i, n] * value[n]
            for j in range(3):
                for k in range(3):
                    force += (dm[k, i, j] - 0.5 * dm[i, j, k]) * qd[r, j] * qd[r, k]
            bias[r, i] = force
            for j in range(3):
                mass[r, i, j] = m[i, j]
