"""Calibration's targets (docs/calibration.md): machine variants of mjcf/bwr_heavy.xml with their
parameters moved 10-50 % (drawn here, seeded), each logged by the twin on a planned 10-minute test
with the imperfect plant (encoder quantisation, random disturbance forces away from the pile, wind),
sampled at 10 Hz with 1 % torque noise, and the nominal model calibrated back from the log; then
the calibrated and the nominal model predict a held-out log (another path, another seed) open
loop over 60 s windows. Prints the targets table.

    python tools/calibration_study.py [--variants 20] [--minutes 10] [--seed 1] [--out out/calibration_study]
    python tools/calibration_study.py --only 8 20   # those variants' fits alone, each with its own draw
    python tools/calibration_study.py --only 10 --torque-noise 0   # the same, its log without the torque noise
    python tools/calibration_study.py --report out/calibration_study/study.json   # its tables again

Beside each variant's held-out ratio it prints the true parameters' own: what any fit could reach
on that log, the disturbances and the noise being what no model predicts.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import mujoco
import numpy as np

from bwr_twin.calibrate.fit import Problem, fit
from bwr_twin.calibrate.log import MachineLog
from bwr_twin.calibrate.mjcf_edit import edit
from bwr_twin.calibrate.parameters import catalogue
from bwr_twin.calibrate.plan import SAMPLE_RATE, TORQUE_NOISE, scene_for, scene_text
from bwr_twin.config.scene import load_scene
from bwr_twin.model.machine import AXES, Machine
from bwr_twin.sim.lockstep import simulate

HEAVY = Path(__file__).resolve().parent.parent / "mjcf" / "bwr_heavy.xml"
# The coulomb-friction scene's plant friction (scenes/heavy_coulomb_friction.toml), the base the
# variants' friction is moved from: the MJCF has none.
FRICTION = (5.85e4, 2.5e5, 1.0e6)
ARMATURE_SHARE = 0.2  # the drives' reflected inertia as a share of each axis's own, before moving it
# The imperfect plant: a gusty wind (scenes/heavy_wind.toml's, at half its mean); the random
# disturbance forces are below (AWAY).
PLANT = """
[plant]
frictionloss = [{friction}]
wind_speed = 10.0
wind_direction = 90.0
gust_amplitude = 2.5
gust_hold_time = 5.0
air_density = 1.204
"""
PARAMS = [f"{a}_{k}" for a in AXES for k in ("damping", "frictionloss", "armature")] + ["boom_counterweight_mass"]
# A variant's luff holds its boom at every angle with at most this share of its drives' rating
# (raising and lowering): a counterweight much lighter than bwr_heavy.xml's leaves a luff whose
# drives cannot hold the boom, let alone raise it against its friction (30.5 MN m pushing against
# the 13.6 MN m of gravity on the raised boom at the file's counterweight: 22 % lighter and it
# cannot hold it).
LUFF_HOLD_SHARE = 0.8
TOLERANCE = {"damping": 0.10, "frictionloss": 0.20, "armature": 0.05, "mass": 0.05}  # the targets


# The random disturbance forces of a machine away from the pile (rail irregularities, gusts, the
# conveyor): scenes/heavy_shadow.toml's, a tenth of the heavy reclaim's digging-load fluctuation.
# A calibration test is run in a maintenance stop: the wheel does not dig.
AWAY = (2.0e3, 1.2e5, 1.1e5)  # N, N m, N m


def imperfect(text: str, share: float) -> str:
    """A test scene's text with `share` of the random disturbance forces in place of the test's
    none, recorded every control period (`log_of` resamples it)."""
    amplitude = ", ".join(f"{share * a:.6g}" for a in AWAY)
    return (text.replace("amplitude = [0.0, 0.0, 0.0]  # N, N m, N m: no digging during the test",
                         f"amplitude = [{amplitude}]  # N, N m, N m: {share:g} x scenes/heavy_shadow.toml's")
            .replace("hold_time = 1.0              # s", "hold_time = 0.6  # s")
            .replace(f"record_period = {1 / SAMPLE_RATE:g}    # s: a PLC's log", "record_period = 0.01  # s"))


def moved(rng: np.random.Generator) -> float:
    """A factor moving a value 10-50 % up or down."""
    return 1.0 + rng.choice([-1.0, 1.0]) * rng.uniform(0.1, 0.5)


def luff_holds(path: Path) -> bool:
    """The luff of the machine at `path` holds its boom at every angle of its range with at most
    LUFF_HOLD_SHARE of its drives' rating."""
    machine = Machine(path)
    model, data = machine.model, mujoco.MjData(machine.model)
    luff = machine.joint_ids[2]
    for angle in np.linspace(*machine.envelope[2], 5):
        data.qpos[:] = model.qpos0
        data.qpos[model.jnt_qposadr[luff]] = angle
        mujoco.mj_forward(model, data)
        low, high = LUFF_HOLD_SHARE * machine.drive_limits[2]
        if not low <= data.qfrc_bias[model.jnt_dofadr[luff]] <= high:
            return False
    return True


def variant(folder: Path, rng: np.random.Generator) -> tuple[Path, dict[str, float], list[float]]:
    """A variant MJCF, its true parameters by name, and its plant friction. The counterweight is
    moved 10-50 % as far as its luff still holds the boom (`luff_holds`), never less than 10 %."""
    nominal = Machine(HEAVY)
    model = nominal.model
    truth, changes = {}, []
    for axis, name in enumerate(AXES):
        dof = int(model.jnt_dofadr[nominal.joint_ids[axis]])
        damping = float(model.dof_damping[dof]) * moved(rng)
        own = catalogue(nominal, [f"{name}_armature"])[0].high  # the axis's own inertia
        armature = ARMATURE_SHARE * own * moved(rng)
        truth[f"{name}_damping"], truth[f"{name}_armature"] = damping, armature
        truth[f"{name}_frictionloss"] = FRICTION[axis] * moved(rng)
        changes += [("joint", name, "damping", 0, f"{damping:.6g}", "variant"),
                    ("joint", name, "armature", 0, f"{armature:.6g}", "variant")]
    factor = moved(rng)
    path = folder / "variant.xml"
    while True:
        mass = 330000.0 * factor
        path.write_text(edit(HEAVY.read_text(), [*changes, ("body", "boom_counterweight", "mass", 0, f"{mass:.6g}",
                                                           "variant")]))
        if abs(factor - 1) <= 0.1 or luff_holds(path):
            break
        factor = 1 + np.sign(factor - 1) * max(0.1, 0.95 * abs(factor - 1))
    truth["boom_counterweight_mass"] = mass
    return path, truth, [truth[f"{a}_frictionloss"] for a in AXES]


def log_of(scene_path: Path, rng: np.random.Generator, torque_noise: float = TORQUE_NOISE) -> MachineLog:
    """The twin's log of the scene resampled to SAMPLE_RATE, with `torque_noise` (of the drive rating, 1 sigma): the encoders, the
    speed and the wind read at each sample, the drive force its mean over the sample period
    centred on it (a historian's average; a drive fighting friction chatters at the control rate,
    and a reading of it every 0.1 s aliases that into the log); the wind's heading and air
    density from the scene, as a run directory's scene.json gives them."""
    scene = load_scene(scene_path)
    result = simulate(scene)
    machine = result.machine
    every = round(1.0 / (SAMPLE_RATE * (result.time[1] - result.time[0])))
    rows = np.arange(every, len(result.time) - every, every)
    window = rows[:, None] + np.arange(-(every // 2), every - every // 2)  # the periods centred on each row
    mean = result.drive_force[window].mean(axis=1)
    rating = np.abs(machine.drive_limits).max(axis=1)
    force = mean + rng.normal(size=mean.shape) * torque_noise * rating
    return MachineLog(path=scene_path, time=result.time[rows], q=result.q_measured[rows], force=force,
                      qd=result.qd_measured[rows], wind=result.wind_speed[rows],
                      wind_heading=np.radians(scene.plant.wind_direction), air_density=scene.plant.air_density)


def holdout_path(machine: Machine, minutes: float, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Another path: random moves within the middle of the envelope at random speeds."""
    envelope = machine.envelope
    centre, half = envelope.mean(axis=1), 0.3 * (envelope[:, 1] - envelope[:, 0]) / 2
    times, points, t = [0.0], [np.zeros(3)], 0.0
    while t < 60 * minutes:
        target = centre + rng.uniform(-1, 1, 3) * half * np.array([0.05, 1.0, 1.0])
        step = np.abs(target - points[-1]) / (0.6 * machine.rated_speed)  # at 60 % of rated on the slowest
        t += max(float(step.max()) * 1.5, 10.0)
        times.append(t)
        points.append(target)
        t += 5.0
        times.append(t)
        points.append(target)
    return np.array(times), np.array(points)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--variants", type=int, default=20)
    parser.add_argument("--minutes", type=float, default=10.0)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--disturbance", type=float, default=1.0,
                        help="share of the random disturbance forces (scenes/heavy_shadow.toml's) in the logs (default 1)")
    parser.add_argument("--out", type=Path, default=Path("out/calibration_study"))
    parser.add_argument("--torque-noise", type=float, default=TORQUE_NOISE,
                        help="of the drive rating, 1 sigma, in the fitted log (default 0.01); the held-out log keeps "
                             "the default, and every draw stays as in the full study")
    parser.add_argument("--only", type=int, nargs="+", metavar="N",
                        help="fit these variants alone (1 on); every variant up to the last is still drawn and "
                             "logged, so that each keeps the draw it has in the full study")
    parser.add_argument("--report", type=Path, metavar="STUDY_JSON",
                        help="print the tables of a finished study (its study.json) and stop")
    args = parser.parse_args()
    if args.report is not None:
        report(json.loads(args.report.read_text()))
        return
    chosen = set(range(1, args.variants + 1) if args.only is None else args.only)
    outside = sorted(chosen - set(range(1, args.variants + 1)))
    if outside:
        parser.error(f"--only: variant {outside[0]}; the variants are numbered 1 to --variants ({args.variants})")
    if not 0 <= args.torque_noise < 1:
        parser.error(f"--torque-noise: {args.torque_noise:g}; a share of the drive rating, 0 to below 1")
    rng = np.random.default_rng(args.seed)
    rows, ratios, truth_ratios, seconds, fitted = [], [], [], [], []
    for v in range(max(chosen)):
        folder = args.out / f"variant_{v + 1:02d}"
        folder.mkdir(parents=True, exist_ok=True)
        mjcf, truth, friction = variant(folder, rng)
        machine = Machine(mjcf)
        plant = PLANT.format(friction=", ".join(f"{f:.6g}" for f in friction))
        test = folder / "test.toml"
        test.write_text(imperfect(scene_text(machine, mjcf, test, args.minutes), args.disturbance) + plant)
        other = folder / "holdout.toml"
        times, points = holdout_path(machine, args.minutes, rng)
        other.write_text(imperfect(scene_for(machine, mjcf, other, times, points, ["# held out"]), args.disturbance).replace(
            "seed = 1", f"seed = {args.seed + 1000 + v}") + plant)
        log, held = log_of(test, rng, torque_noise=args.torque_noise), log_of(other, rng)
        if v + 1 not in chosen:
            continue
        fitted.append(v + 1)
        nominal = Machine(HEAVY)
        knobs = catalogue(nominal, PARAMS)
        started = time.perf_counter()
        result = fit(Problem(nominal, knobs, [log]))
        seconds.append(time.perf_counter() - started)
        check = Problem(nominal, knobs, [held], window=60.0)
        before = check.column_rms(check.params.as_nominal_vector())[:3]

        def held_out_ratio(x: np.ndarray) -> np.ndarray:
            """Per axis, the nominal model's held-out position RMS over the model at `x`'s."""
            return before / np.maximum(check.column_rms(x)[:3], 1e-300)

        exact = check.params.copy()
        for name, value in truth.items():
            exact[name].value[:] = value
        ratios.append(held_out_ratio(result.x))
        truth_ratios.append(held_out_ratio(exact.as_vector()))
        for e in result.estimates:
            true = truth[e.knob.name]
            rows.append({"variant": v + 1, "name": e.knob.name, "kind": e.knob.kind, "truth": true,
                         "fitted": e.fitted, "interval": list(e.interval), "identifiable": e.identifiable,
                         "error": (e.fitted - true) / true,
                         "covered": bool(e.identifiable and e.interval[0] <= true <= e.interval[1])})
        print(f"variant {v + 1}: fit {seconds[-1]:.0f} s; held-out RMS ratio per axis "
              f"{', '.join(f'{r:.1f}x' for r in ratios[-1])} (the truth's {', '.join(f'{r:.1f}x' for r in truth_ratios[-1])}); "
              "worst errors "
              + ", ".join(f"{r['name']} {100 * r['error']:+.0f} %" for r in rows[-len(knobs):]), flush=True)
    study = {"rows": rows, "ratios": np.array(ratios).tolist(), "truth_ratios": np.array(truth_ratios).tolist(),
             "fitted": fitted, "seconds": seconds, "variants": len(fitted), "minutes": args.minutes, "disturbance": args.disturbance,
             "torque_noise": args.torque_noise}
    name = "study.json" if args.only is None else f"study_{'_'.join(map(str, sorted(chosen)))}.json"  # a full study's stays
    (args.out / name).write_text(json.dumps(study, indent=1))
    print()
    report(study)


def report(study: dict) -> None:
    """The targets table of a study (study.json), then each parameter's errors and intervals."""
    rows, ratios, seconds = study["rows"], np.array(study["ratios"]), study["seconds"]
    print(f"{study['variants']} variants, {study['minutes']:g}-minute tests at 10 Hz, {study['disturbance']:g} x the "
          f"random disturbance forces, 10 m/s gusty wind, {study.get('torque_noise', TORQUE_NOISE):.1%} torque noise")
    print(f"{'figure':58s} {'target':14s} {'measured':22s} holds")
    for kind, tolerance in TOLERANCE.items():
        mine = [r for r in rows if r["kind"] == kind]
        within = [r for r in mine if r["identifiable"] and abs(r["error"]) <= tolerance]
        named = sum(r["identifiable"] for r in mine)
        share = len(within) / named if named else 0.0  # the target is on what the fit could identify
        figure = f"{kind} within {tolerance:.0%} (of {named} identified, {len(mine)} fitted)"
        print(f"{figure:58s} {'all':14s} {f'{len(within)} ({share:.0%})':22s} {'yes' if share == 1 else 'no'}")
    covered = [r["covered"] for r in rows if r["identifiable"]]
    share = float(np.mean(covered)) if covered else 0.0
    print(f"{'95 % interval covers the truth':58s} {'>= 90 %':14s} {share:.0%} {'':17s} {'yes' if share >= 0.9 else 'no'}")
    worst = ratios.min(axis=0)
    print(f"{'held-out 60 s RMS, nominal / calibrated, worst per axis':58s} {'>= 5x':14s} "
          f"{', '.join(f'{r:.1f}x' for r in worst):22s} {'yes' if (worst >= 5).all() else 'no'}")
    truth = np.array(study.get("truth_ratios", []))  # studies written before it was measured have none
    if truth.size:
        reach = "  the true parameters' own, worst per axis (the reach)"
        print(f"{reach:58s} {'':14s} "
              f"{', '.join(f'{r:.1f}x' for r in truth.min(axis=0))}")
    print(f"{'fit of a 10-minute log at 10 Hz, slowest':58s} {'<= 180 s':14s} {max(seconds):.0f} s {'':17s} "
          f"{'yes' if max(seconds) <= 180 else 'no'}")
    print()
    print(f"{'parameter':26s} {'within':>8s} {'covered':>8s} {'errors, %':>16s}  variants outside the target (error, %)")
    for name in dict.fromkeys(r["name"] for r in rows):
        mine = [r for r in rows if r["name"] == name]
        tolerance = TOLERANCE[mine[0]["kind"]]
        errors = [100 * r["error"] for r in mine]
        outside = [f"{r['variant']} ({100 * r['error']:+.0f})" for r in mine if abs(r["error"]) > tolerance]
        print(f"{name:26s} {sum(abs(r['error']) <= tolerance for r in mine):4d}/{len(mine):<3d} "
              f"{sum(r['covered'] for r in mine):4d}/{len(mine):<3d} {min(errors):+7.0f} {max(errors):+7.0f}  "
              + ", ".join(outside))
    print(f"{'held-out ratio per axis':26s} " + "; ".join(
        f"{axis} {ratios[:, a].min():.1f}x to {ratios[:, a].max():.1f}x" for a, axis in enumerate(AXES)))
    numbers = study.get("fitted", range(1, len(ratios) + 1))
    for a, axis in enumerate(AXES):
        short = [f"{n} ({ratios[i, a]:.1f}x" + (f", the truth's {truth[i, a]:.1f}x)" if truth.size else ")")
                 for i, n in enumerate(numbers) if ratios[i, a] < 5]
        if short:
            print(f"  {axis} below 5x on variant " + ", ".join(short))

if __name__ == "__main__":
    main()
