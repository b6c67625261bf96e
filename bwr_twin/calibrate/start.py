"""Where the fit starts: an equation-error estimate from MuJoCo's inverse dynamics.

The output-error fit (bwr_twin.calibrate.fit) is not convex. From the MJCF's values a slow, heavy
axis (the luff) under a wrong gravity falls within every window, and Gauss-Newton's first steps
stiffen it with damping and inertia far beyond their truth, a valley it does not leave; the
other axes' parameters then absorb the misfit. The balance of forces, though, is linear in
the damping and the friction (bwr_twin.calibrate.balance): one linear least-squares solve over
the log's steady motion gives a start near the truth; the output-error fit then refines it.
mujoco.sysid has no such start.
"""

from __future__ import annotations

import contextlib
import io

import numpy as np
from mujoco import sysid

from bwr_twin.calibrate.balance import Balance
from bwr_twin.calibrate.parameters import BODY_KINDS

STEADY = 0.05  # of the rated speed per second: an interval accelerating less is in steady motion
KINDS = ("damping", "frictionloss")  # what the start estimates


def equation_error_start(problem, params: sysid.ParameterDict) -> sysid.ParameterDict:
    """`params` with each axis's damping and Coulomb friction moved to their equation-error
    estimate over the log's steady motion (within their bounds); the rest held: `masses_first`
    fits the masses before, and the output-error fit the inertias after."""
    knobs = [k for k in problem.knobs if k.kind in KINDS and not params[k.name].frozen]
    balance = Balance(problem)
    if not knobs or not len(balance.q):
        return params
    base = params.copy()
    # Rows in steady motion: friction's sign is known, and the inertias (a mass, a drive's, held
    # at their start) hardly matter. A 10 Hz log's accelerations, a difference of two speeds
    # against a mean of forces that chatter at the control rate, would not give them anyway.
    delta = balance.least_squares(base, knobs, balance.moving & (np.abs(balance.qdd) < STEADY * balance.rated))
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
