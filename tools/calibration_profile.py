"""Where the fit's residual is least along one parameter, every other at its truth, and what moves
it there: the residual RMS per compared column with one parameter scaled, on a log of the study's
first variant (tools/calibration_study.py, `--seed`) with each noise source on or off; then the
balance of forces' own estimate of every axis's damping, friction and drive inertia.

    python tools/calibration_profile.py [--param luff_armature] [--torque-noise 0.01]
        [--disturbance 1] [--still-air] [--window 5] [--seed 1] [--factors 0.5 0.8 1 ...]

Without torque noise, disturbance forces or wind, an output-error fit's residual is least at the
truth. Noise in the logged force drives the replayed motion where the machine did not go, and a
disturbance the test's position loop answers puts the answer in the logged force but not its
cause: a heavier axis filters both, so either moves the least residual of a drive inertia above
the truth; the disturbances move the travel's damping's below it, through the position. The
columns' units: m and rad (positions), m/s and rad/s (speeds). The last line of the profile is the
fit's own objective (each column in units of its RMS at the truth, as the fit weighs them where it
stands, squared and summed): the vertex of the parabola through its least and the factors either
side.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from calibration_study import HEAVY, PARAMS, PLANT, imperfect, log_of, variant

from bwr_twin.calibrate.balance import Balance
from bwr_twin.calibrate.fit import Problem
from bwr_twin.calibrate.parameters import JOINT_KINDS, catalogue
from bwr_twin.calibrate.plan import TORQUE_NOISE, scene_text
from bwr_twin.model.machine import Machine

FACTORS = (0.5, 0.8, 1.0, 1.25, 1.6, 2.0, 2.5, 3.0)  # of the truth


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--param", default="luff_armature", choices=PARAMS)
    parser.add_argument("--torque-noise", type=float, default=TORQUE_NOISE, help="of the drive rating, 1 sigma")
    parser.add_argument("--disturbance", type=float, default=1.0, help="share of the study's random disturbance forces")
    parser.add_argument("--still-air", action="store_true", help="no wind (the study's: 10 m/s, gusting 2.5 m/s)")
    parser.add_argument("--window", type=float, default=5.0, help="s, the fit's window")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--factors", type=float, nargs="+", default=FACTORS, help="of the truth, rising")
    parser.add_argument("--out", type=Path, default=Path("out/calibration_profile"))
    args = parser.parse_args()
    if min(args.factors) <= 0:
        parser.error(f"--factors: {min(args.factors):g}; each is a positive multiple of the truth")
    rng = np.random.default_rng(args.seed)
    args.out.mkdir(parents=True, exist_ok=True)
    mjcf, truth, friction = variant(args.out, rng)
    plant = PLANT.format(friction=", ".join(f"{f:.6g}" for f in friction))
    if args.still_air:
        plant = (plant.replace("wind_speed = 10.0", "wind_speed = 0.0")
                 .replace("gust_amplitude = 2.5", "gust_amplitude = 0.0"))
    test = args.out / "test.toml"
    test.write_text(imperfect(scene_text(Machine(mjcf), mjcf, test, 10.0), args.disturbance) + plant)
    log = log_of(test, rng, torque_noise=args.torque_noise)
    knobs = catalogue(Machine(HEAVY), PARAMS)
    problem = Problem(Machine(HEAVY), knobs, [log], window=args.window)
    params = problem.params.copy()
    for knob in knobs:
        params[knob.name].value[:] = truth[knob.name]
    x = params.as_vector()
    index = [k.name for k in knobs].index(args.param)
    print(f"{args.param}: truth {truth[args.param]:.4g} {knobs[index].unit}; torque noise {args.torque_noise:g} of the "
          f"rating, {args.disturbance:g} x the disturbance forces, {'still air' if args.still_air else 'gusty wind'}, "
          f"{args.window:g} s windows")
    print("x truth  " + " ".join(f"{c:>14s}" for c in problem.columns))
    rows = []
    factors = sorted(args.factors)
    for factor in factors:
        moved = x.copy()
        moved[index] *= factor
        rows.append(problem.column_rms(moved))
        print(f"{factor:7.2f}  " + " ".join(f"{r:14.4g}" for r in rows[-1]), flush=True)
    rows = np.array(rows)
    # A column the parameter barely moves (by less than 0.1 %) has no least worth naming.
    moves = rows.max(axis=0) - rows.min(axis=0) > 1e-3 * rows.min(axis=0)
    least = [f"{factors[i]:14.2f}" if m else f"{'-':>14s}" for i, m in zip(rows.argmin(axis=0), moves, strict=True)]
    print("least at " + " ".join(least) + "  x truth")
    # The fit's own objective near its end: every column's residual in units of its RMS at the
    # truth (the fit scales each column by its RMS where it stands), squared and summed.
    objective = ((rows / problem.column_rms(x)) ** 2).sum(axis=1)
    print(f"the fit's objective least at {vertex(np.array(factors), objective):.3f} x truth")
    print_balance(problem, params, knobs, truth)


def vertex(factors: np.ndarray, values: np.ndarray) -> float:
    """Where the parabola through the least of `values` and its two neighbours is least (at an
    end of `factors`, that end)."""
    i = int(np.argmin(values))
    if i in (0, len(values) - 1):
        return float(factors[i])
    a, b, _ = np.polyfit(factors[i - 1:i + 2], values[i - 1:i + 2], 2)
    return float(-b / (2 * a))


def print_balance(problem, params, knobs, truth) -> None:
    """The balance of forces' own least squares for every axis's damping, friction and drive
    inertia (the counterweight at its truth), against the truth: an equation-error fit, which
    takes the logged force as the noisy side and so sees what the log itself holds."""
    joint = [k for k in knobs if k.kind in JOINT_KINDS]
    start = params.copy()
    for knob in joint:
        start[knob.name].value[:] = knob.nominal
    balance = Balance(problem)
    delta = balance.least_squares(start, joint, balance.moving)
    print("the balance of forces' least squares (every moving interval):")
    for knob, change in zip(joint, delta, strict=True):
        value = knob.nominal + change
        print(f"  {knob.name:20s} truth {truth[knob.name]:11.4g} {knob.unit:10s} balance {value:11.4g} "
              f"({100 * (value / truth[knob.name] - 1):+.1f} %)")


if __name__ == "__main__":
    main()
