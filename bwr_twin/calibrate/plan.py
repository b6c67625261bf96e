"""A test motion to record on the machine during a stop, written as a scene of the twin, and the
standard error each parameter is expected to reach with it.

The motion stays inside the MJCF's operating envelope (with a margin) and its rated speeds; the
drives' ratings bound the force (the plant clips it). Each axis in turn moves rest to rest (the
path's cubic between via points peaks at 1.5 x its mean speed) both ways at several speeds, to
part viscous from Coulomb friction; short moves accelerate hard, for inertia; the cycles stand
the luff at several angles, for the moments of the masses (the slew's angle changes no moment:
the slew swings about the middle of its range, and a long way to another slew angle would fill
the test with one speed). No digging: the scene
has no disturbance but what its [disturbance] section, absent, leaves (none).

The expected standard errors are the sensitivity at the nominal model with the log's noise: the
twin runs the test on the nominal machine with its encoders' quantisation, the log is sampled at
SAMPLE_RATE with TORQUE_NOISE, and sysid's intervals come from the Jacobian there, never below
the floor the force's noise puts under them (bwr_twin.calibrate.balance): on the heavy machine the
luff's drive inertia, its accelerations small beside that noise, is the one it raises.
"""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np

from bwr_twin.errors import BwrError

SPEEDS = (0.3, 0.6, 0.95)  # of each axis's rated speed, peak: slow enough to show friction, fast for damping
MOVE_SECONDS = (20.0, 30.0, 30.0)  # s, a move of travel, slew, luff at the slowest speed
HOLD = 5.0  # s at rest after each move: the drives hold, friction sticks
MARGIN = 0.1  # of the envelope's half-width kept clear at either end
SAMPLE_RATE = 10.0  # Hz: a PLC's log
TORQUE_NOISE = 0.01  # of the drive rating, 1 sigma
BANDWIDTH = 1.0  # rad/s: the test scene's PID, gentle (the machine's own drives run the real test)
ENCODER_RESOLUTION = (0.00153, 0.00153, 0.00076)  # m, rad, rad: the paper's encoders (Sec. 3)
WRITER = "bwr_twin.calibrate"


def test_motion(machine, minutes: float) -> tuple[np.ndarray, np.ndarray]:
    """Via point times (s) and joint values (k, 3) of the test: cycles of moves, each axis both
    ways at each of SPEEDS, the centre of the luff's swing moving from cycle to cycle (at the top
    speed, a move of its own) so that it stands at several angles."""
    if not 1.0 <= minutes <= 120.0:
        raise BwrError(f"--minutes: {minutes:g}; a test lasts 1 to 120 minutes")
    envelope = machine.envelope
    rated = np.where(np.isfinite(machine.rated_speed), machine.rated_speed, 0.1 * (envelope[:, 1] - envelope[:, 0]))
    centre = envelope.mean(axis=1)
    half = (0.5 - MARGIN) * (envelope[:, 1] - envelope[:, 0]) / 2
    start = np.clip(np.zeros(3), envelope[:, 0], envelope[:, 1])
    q, t = start.copy(), 0.0
    times, points = [0.0], [q.copy()]
    total = 60.0 * minutes
    cycle = 0
    poses = (0.0, 0.6, -0.6)  # the swing's centre, as a share of its room either way
    def hold(target: np.ndarray, seconds: float) -> None:
        nonlocal t, q
        t += seconds
        times.append(t)
        points.append(target.copy())
        t += HOLD
        times.append(t)
        points.append(target.copy())
        q = target

    while t < total:
        pose = poses[cycle % len(poses)]
        for axis in (2, 1, 0):  # the luff first: a short test still stands it at two angles
            middle = (centre[axis] + pose * half[axis] if axis == 2 else centre[axis]) if axis else q[axis]
            if axis == 2 and abs(middle - q[axis]) > 0:  # to the cycle's luff angle, at the top speed
                target = q.copy()
                target[axis] = middle
                hold(target, 1.5 * abs(middle - q[axis]) / (SPEEDS[-1] * rated[axis]))
            for share in SPEEDS:
                for sign in (1.0, -1.0):
                    duration = MOVE_SECONDS[axis] * (SPEEDS[0] / share) ** 0.5  # faster moves are shorter
                    distance = share * rated[axis] * duration / 1.5
                    target = q.copy()
                    target[axis] = np.clip(middle + sign * distance / 2, centre[axis] - 2 * half[axis],
                                           centre[axis] + 2 * half[axis])
                    # A longer way (to the first side) too peaks at this share of the rated speed.
                    hold(target, max(duration, 1.5 * abs(target[axis] - q[axis]) / (share * rated[axis])))
                    if t >= total:
                        break
                if t >= total:
                    break
            if t >= total:
                break
        cycle += 1
    return np.array(times), np.array(points)


def scene_text(machine, mjcf: Path, out: Path, minutes: float) -> str:
    """The test as a scene TOML (`scene_for`)."""
    times, points = test_motion(machine, minutes)
    header = [
        f"# A calibration test of {machine.name} ({Path(mjcf).name}): {minutes:g} minutes during a stop, the wheel",
        "# not digging. Each axis moves rest to rest both ways at 30, 60 and 95 % of its rated speed, holding 5 s",
        "# after each move; the luff swings about several angles. Run it on the machine and log, at",
        "# 1 to 1,000 Hz, each axis's encoder, drive torque (or current) and speed feedback; then",
        "# python -m bwr_twin.calibrate fit LOG --model MJCF --out DIR. Units: SI (m, rad, s, N, N m).",
    ]
    return scene_for(machine, mjcf, out, times, points, header)


def scene_for(machine, mjcf: Path, out: Path, times: np.ndarray, points: np.ndarray, header: list[str]) -> str:
    """A scene TOML moving the machine of `mjcf` through joint values `points` (k, 3) at `times`
    (s): the path as world via points, the twin's timing, the paper's encoders, no digging, and a
    PID on the machine's own inertia and gravity at the start."""
    cps = machine.fk(points)
    inertia, gravity = _inertia_and_gravity(machine, points[0])
    w = BANDWIDTH
    kp, kd, ki = inertia * w ** 2, 2 * inertia * w, inertia * w ** 3 / 4
    try:
        mjcf_text = str(Path(mjcf).resolve().relative_to(out.resolve().parent))
    except ValueError:
        mjcf_text = str(Path(mjcf).resolve())
    lines = [
        f"# written by {WRITER}",
        *header,
        "",
        "[machine]",
        f'mjcf = "{mjcf_text}"',
        "",
        "[path]",
        'frame = "world"',
        "# Each point is the CP at the joint values in the comment (travel m, slew deg, luff deg).",
        "via_points = [",
    ]
    for t, p, q in zip(times, cps, points, strict=True):
        lines.append(f"  {{ t = {t:.1f}, p = [{p[0]:.4f}, {p[1]:.4f}, {p[2]:.4f}] }},  "
                     f"# ({q[0]:.3f}, {np.degrees(q[1]):.3f}, {np.degrees(q[2]):.3f})")
    lines += [
        "]",
        "",
        "[simulation]",
        "timestep = 0.002       # s",
        "control_period = 0.01  # s",
        f"record_period = {1 / SAMPLE_RATE:g}    # s: a PLC's log",
        "seed = 1",
        "",
        "[encoders]",
        f"resolution = [{', '.join(f'{r:g}' for r in ENCODER_RESOLUTION)}]  # m, rad, rad: the paper's encoders (Sec. 3)",
        'velocity_source = "true"',
        "",
        "[disturbance]",
        "amplitude = [0.0, 0.0, 0.0]  # N, N m, N m: no digging during the test",
        "hold_time = 1.0              # s",
        "",
        "[controller]",
        'type = "pid"',
        f"# On the machine's inertia at the start, bandwidth {w:g} rad/s: kp = M w^2, kd = 2 M w, ki = M w^3 / 4.",
        f"kp = [{', '.join(f'{v:.6g}' for v in kp)}]",
        f"kd = [{', '.join(f'{v:.6g}' for v in kd)}]",
        f"ki = [{', '.join(f'{v:.6g}' for v in ki)}]",
        "# Gravity at the start, proved before the brakes open.",
        f"holding_force = [{', '.join(f'{v:.6g}' for v in gravity)}]",
        "",
    ]
    return "\n".join(lines)


def _inertia_and_gravity(machine, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each axis's own inertia (the mass matrix's diagonal) and the gravity force on it at `q`."""
    model = machine.model
    data = mujoco.MjData(model)
    qpos = [int(model.jnt_qposadr[j]) for j in machine.joint_ids]
    dofs = [int(model.jnt_dofadr[j]) for j in machine.joint_ids]
    data.qpos[qpos] = q
    mujoco.mj_forward(model, data)
    full = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, data, full)
    return full[dofs, dofs], data.qfrc_bias[dofs].copy()


def expected_errors(scene_path: Path, seed: int = 1) -> list[tuple[object, float, bool]]:
    """(knob, expected standard error, determined) of each default parameter: the twin runs the
    test on the nominal machine, the log is sampled at SAMPLE_RATE with TORQUE_NOISE, and sysid's
    intervals come from the Jacobian at the nominal values, the balance's floor under them."""
    from mujoco import sysid
    from mujoco.minimize import jacobian_fd

    from bwr_twin.calibrate.balance import Balance
    from bwr_twin.calibrate.fit import FD_STEP, NORMAL_95, Problem
    from bwr_twin.calibrate.log import MachineLog
    from bwr_twin.calibrate.parameters import catalogue
    from bwr_twin.config.scene import load_scene
    from bwr_twin.sim.lockstep import simulate

    scene = load_scene(scene_path)
    result = simulate(scene)
    machine = result.machine
    rng = np.random.default_rng(seed)
    rating = np.where(np.isfinite(machine.drive_limits).all(axis=1), np.abs(machine.drive_limits).max(axis=1), 0.0)
    force = result.drive_force + rng.normal(0.0, 1.0, result.drive_force.shape) * TORQUE_NOISE * rating
    log = MachineLog(path=scene_path, time=result.time, q=result.q_measured, force=force, qd=result.qd_measured)
    knobs = catalogue(machine, None)
    problem = Problem(machine, knobs, [log])
    params = problem.params.copy()
    x = params.as_vector()
    problem.scales = np.maximum(problem.column_rms(x), 1e-12)
    residual_fn = problem.residual_fn()

    def f(z):
        return np.concatenate(residual_fn(z, params)[0])

    r = f(x)
    probe = np.where(x > 0, x, 0.05 * np.array([k.high for k in knobs]))  # a zero's sensitivity: at 5 % of its range
    bounds = params.get_bounds()
    jac = np.asarray(jacobian_fd(residual=f, x=probe.reshape(-1, 1), r=f(probe).reshape(-1, 1), eps=FD_STEP,
                                 n_res=0, bounds=[bounds[0].reshape(-1, 1), bounds[1].reshape(-1, 1)])[0])
    covariance, half = sysid.calculate_intervals([r], jac)
    # The Jacobian takes the logged force as exact; its noise leaves more unknown (the balance's floor).
    floor = Balance(problem).floor(params, knobs, noise=TORQUE_NOISE * rating)
    out = []
    for i, knob in enumerate(knobs):
        least = floor.get(knob.name, 0.0)
        error = max(float(np.sqrt(covariance[i, i])), least) if np.isfinite(half[i]) else float("inf")
        width = max(float(half[i]), NORMAL_95 * least)
        out.append((knob, error, bool(np.isfinite(width) and width <= max(abs(knob.nominal), probe[i]))))
    return out


def write_plan(mjcf: Path, out: Path, *, minutes: float = 10.0, overwrite: bool = False) -> None:
    """Write the test scene to `out` (a .toml the twin may replace only if it wrote it) and print
    each parameter's expected standard error."""
    from bwr_twin.model.machine import Machine
    from bwr_twin.ownership import check_recorded, write_atomically, written_by

    machine = Machine(mjcf)
    if out.suffix.lower() != ".toml":
        raise BwrError(f"{out}: --out must name a .toml scene")
    if out.exists():
        if out.is_dir():
            raise BwrError(f"{out}: is a folder; --out must name a .toml scene")
        if not written_by(out, WRITER):
            raise BwrError(f"{out}: exists and was not written by the twin; it is left alone, choose another --out")
        if not overwrite:
            raise BwrError(f"{out}: already exists; choose another --out or pass --overwrite")
        check_recorded(out, None, "--out")
    elif not out.parent.is_dir():
        raise BwrError(f"{out}: the folder {out.parent} does not exist")
    text = scene_text(machine, mjcf, out, minutes)

    def write(temporary: Path) -> None:
        temporary.write_text(text, encoding="utf-8")
        for knob, error, determined in expected_errors(temporary):
            scale = max(abs(knob.nominal), 1e-300)
            share = f" ({100 * error / scale:.2g} % of nominal)" if knob.nominal else ""
            print(f"{knob.name:22s} nominal {knob.nominal:12.5g} {knob.unit:10s} expected standard error "
                  f"{error:.3g} {knob.unit}{share}{'' if determined else ': not determined by this test'}")

    write_atomically(out, write, record=True, option="--out")
    print(f"test scene in {out}")
