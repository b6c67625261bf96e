"""The fit: the machine's MJCF replayed under the logged drive forces, window by window from the
measured state, against the logged encoders (and speed feedback), with `mujoco.sysid`.

mujoco.sysid rolls the windows out (`ModelSequences`, one sequence a window), runs the
Gauss-Newton least squares (`optimize`) and gives the confidence intervals from the Jacobian
(`calculate_intervals`). Written here: the windows, the residual's weights (each signal divided
by its own residual RMS, so that the intervals come from the noise actually left), a drive's lag
an encoder's offset (signals, not model fields), the logged wind's force applied in each window
(`bwr_twin.calibrate.wind`: sysid's rollout takes controls only, so the fit's own rolls out with
`qfrc_applied` too), the floor the logged force's noise puts under each interval
(`bwr_twin.calibrate.balance`), and the identifiability rule: a parameter whose 95 % interval is
not finite or wider than its value is named, put back to its nominal value, and the rest fitted
again without it.
"""

from __future__ import annotations

import contextlib
import io
import time as clock
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import mujoco
import mujoco.rollout
import numpy as np
import scipy.special
from mujoco import sysid
from mujoco.minimize import jacobian_fd

from bwr_twin.calibrate.balance import Balance
from bwr_twin.calibrate.log import MachineLog
from bwr_twin.calibrate.parameters import Knob
from bwr_twin.calibrate.start import equation_error_start, masses_first
from bwr_twin.calibrate.wind import wind_forces
from bwr_twin.calibrate.windows import cut
from bwr_twin.model.machine import AXES, Machine
from bwr_twin.model.spec import Edits, edited_spec

WINDOW = 5.0  # s: the default window: long enough to see friction and inertia, short enough that
# the unknown loads (digging, wind) do not carry the prediction away
MAX_ITERATIONS = 30
# The relative finite-difference step (of max(1, |value|)) of every Jacobian, the solver's and
# the intervals'. The residual is not smooth below about 1e-3 of a parameter (the constraint
# solver's tolerance, stick and slip): on a ten-parameter fit of the study's, Jacobians taken
# with 1e-6 came out 50-500 times larger than with 1e-3 to 1e-2, the intervals 1,000 times too
# narrow, and Gauss-Newton's steps poor (the luff's friction 57 % off against 7 % with 1e-2).
FD_STEP = 1e-2
THREADS = 2
PASSES = 3  # fits: the first with every parameter, the next without those it could not determine
NORMAL_95 = 1.959964  # the normal's 97.5 % point: the floor's rows are thousands
TIMESTEP = 0.01  # s: the fit's physics step; the heavy machine's motion differs from 0.002 s's by < 0.1 %


@dataclass
class Problem:
    """The sysid problem of one machine and its logs."""

    machine: Machine
    knobs: list[Knob]
    logs: list[MachineLog]
    window: float = WINDOW
    timestep: float | None = TIMESTEP  # s; None: the file's
    velocity: bool = True  # compare speed feedback too
    scales: np.ndarray = field(default=None)  # per compared column: its residual's RMS, the weight's inverse
    windows: list[tuple[int, tuple[int, int]]] = field(default_factory=list)  # (log index, (first, last))

    def __post_init__(self) -> None:
        self.velocity = self.velocity and all(log.qd is not None for log in self.logs)
        names = [self.machine.model.joint(j).name for j in self.machine.joint_ids]
        self.spec = edited_spec(self.machine.path, Edits(physics_only=True, timestep=self.timestep,
                                                         joint_sensors=names, still_air=True,
                                                         velocity_sensors=names if self.velocity else ()))
        self.model = self.spec.compile()
        # Per log, the wind's generalised force at each row (None: no wind logged, still air).
        self.wind = [wind_forces(self.model, self.machine.joint_ids, log) for log in self.logs]
        self.applied: list[np.ndarray | None] = []  # per window, on its control grid
        self.columns = [f"{axis} position" for axis in AXES] + ([f"{axis} speed" for axis in AXES] if self.velocity else [])
        self.scales = np.ones(len(self.columns))
        self.params = self._parameters()
        self.sequences = self._sequences()

    # -- parameters ---------------------------------------------------------------------------

    def _parameters(self) -> sysid.ParameterDict:
        params = sysid.ParameterDict()
        for knob in self.knobs:
            params.add(sysid.Parameter(knob.name, nominal=knob.nominal, min_value=knob.low, max_value=knob.high,
                                       modifier=lambda spec, p, k=knob: k.modify(spec, p.value[0])))
        return params

    def _signal_values(self, params: sysid.ParameterDict, kind: str) -> np.ndarray:
        values = np.zeros(3)
        for knob in self.knobs:
            if knob.kind == kind:
                values[knob.axis] = params[knob.name].value[0]
        return values

    # -- the measured sequences -----------------------------------------------------------------

    def _sequences(self) -> sysid.ModelSequences:
        """One sequence a window, every window alike: the drive forces on the model's timestep
        grid (each step's mean, `MachineLog.impulse`), the measured signals on the log's median
        step (interpolated within the window, so that jitter does not change a window's shape and
        all roll out in one batch)."""
        model = self.model
        actuators = list(self.machine.actuator_ids)
        gear = self.machine.model.actuator_gear[actuators, 0]
        qpos = [int(model.jnt_qposadr[j]) for j in self.machine.joint_ids]
        qvel = [int(model.jnt_dofadr[j]) for j in self.machine.joint_ids]
        names, states, controls, sensors = [], [], [], []
        mapping = sysid.TimeSeries.compute_all_sensor_mapping(model)
        data = mujoco.MjData(model)
        dt = model.opt.timestep
        steps = max(1, round(self.window / dt))
        step = min(float(np.median(np.diff(log.time))) for log in self.logs)
        samples = max(1, int(np.floor(steps * dt / step + 1e-9)))
        control_grid, sample_grid = np.arange(steps + 1) * dt, np.arange(samples + 1) * step
        for index, log in enumerate(self.logs):
            for first, last in cut(log, self.window):
                t0 = log.time[first]
                rows = slice(first, last + 1)
                # Each physics step holds the drive force's mean over it (the last control drives nothing).
                running = log.impulse(first, last)(t0 + control_grid)
                ctrl = np.zeros((steps + 1, model.nu))
                ctrl[:-1, actuators] = np.diff(running, axis=0) / dt / gear
                ctrl[-1] = ctrl[-2]
                measured = log.q[rows] if not self.velocity else np.hstack([log.q[rows], log.qd[rows]])
                sampled = np.column_stack([np.interp(t0 + sample_grid, log.time[rows], measured[:, c])
                                           for c in range(measured.shape[1])])
                data.qpos[:] = model.qpos0
                data.qvel[:] = 0.0
                data.qpos[qpos] = log.q[first]
                data.qvel[qvel] = log.velocity_at(first)
                data.time = t0
                state = np.empty(mujoco.mj_stateSize(model, mujoco.mjtState.mjSTATE_FULLPHYSICS))
                mujoco.mj_getState(model, data, state, mujoco.mjtState.mjSTATE_FULLPHYSICS)
                wind = self.wind[index]
                self.applied.append(None if wind is None else np.column_stack(
                    [np.interp(t0 + control_grid, log.time[rows], wind[rows, d]) for d in range(model.nv)]))
                names.append(f"{log.path.name}@{t0:.1f}s")
                states.append(state)
                controls.append(sysid.TimeSeries(t0 + control_grid, ctrl))
                sensors.append(sysid.TimeSeries(t0 + sample_grid, sampled, mapping))
                self.windows.append((index, (first, last)))
        return sysid.ModelSequences(self.machine.name, self.spec, names, states, controls, sensors)

    # -- the residual ---------------------------------------------------------------------------

    def residual_fn(self, windows: Sequence[int] | None = None) -> Callable:
        """sysid's model residual over all windows (or those indexed) at once: the model compiled
        once per parameter vector, the windows rolled out in one batch on THREADS threads."""
        trajectories = self.sequences.measured_rollout
        chosen = range(len(trajectories)) if windows is None else windows
        trajectories = [trajectories[i] for i in chosen]
        applied = [self.applied[i] for i in chosen]

        def rollout(**kwargs):
            return self._rollout(applied=applied, **kwargs)

        def residual(x, params, **_):
            res, predicted, measured = sysid.model_residual(
                x, params, lambda p: sysid.apply_param_modifiers(p, self.spec), trajectories,
                modify_residual=self._compare, custom_rollout=rollout, n_threads=THREADS,
                resample_true=False)
            if x.ndim > 1:  # sysid stacks (parameter vector, window) pairs as columns: windows go down
                res = res.T.reshape(x.shape[1], -1).T
            return [res], predicted, measured

        return residual

    def _rollout(self, *, applied, models, datas, control_signal, initial_states, param_dicts,
                 rollout_signal_mapping, rollout_state_mapping, ctrl_mapping):
        """sysid's rollout, with each drive's force delayed by its lag, each window started from
        the encoders less their offsets, and the wind's force (`applied`, per window of those
        rolled out) applied."""
        controls, starts = [], []
        qpos = np.array([int(self.model.jnt_qposadr[j]) for j in self.machine.joint_ids])
        per_model = len(control_signal) // len(param_dicts)
        for i, (control, state) in enumerate(zip(control_signal, initial_states, strict=True)):
            params = param_dicts[i // per_model]
            lag, offset = self._signal_values(params, "lag"), self._signal_values(params, "offset")
            if lag.any():
                data = control.data.copy()
                for j, a in enumerate(self.machine.actuator_ids):
                    data[:, a] = np.interp(control.times - lag[j], control.times, control.data[:, a])
                control = sysid.TimeSeries(control.times, data, control.signal_mapping)
            if offset.any():
                state = state.copy()
                state[1 + qpos] -= offset  # FULLPHYSICS: time, then qpos
            controls.append(control)
            starts.append(state)
        if all(a is None for a in applied):
            return sysid.sysid_rollout(models, datas, controls, starts, rollout_signal_mapping,
                                       rollout_state_mapping, ctrl_mapping)
        still = np.zeros((len(controls[0].times), self.model.nv))
        forces = [still if a is None else a for a in applied] * (len(controls) // len(applied))
        return _rollout_applied(models, datas, controls, forces, starts, rollout_signal_mapping,
                                rollout_state_mapping, ctrl_mapping)

    def _compare(self, params, predicted, measured, model, return_pred_all, state=None, **_):
        """Measured less predicted at the samples after the window's start, each column divided
        by its scale; an encoder's offset added to the prediction."""
        times = measured.times[1:]
        got = np.column_stack([np.interp(times, predicted.times, predicted.data[:, c])
                               for c in range(predicted.data.shape[1])])
        got[:, :3] += self._signal_values(params, "offset")
        wanted = measured.data[1:]
        residual = (wanted - got) / self.scales
        mapping = measured.signal_mapping
        return residual, sysid.TimeSeries(times, got, mapping), sysid.TimeSeries(times, wanted, mapping)

    def differences(self, x: np.ndarray) -> list[np.ndarray]:
        """Measured less predicted per window (rows, columns), in SI units, at parameters `x`."""
        params = self.params.copy()
        _, predicted, measured = self.residual_fn()(x, params)
        return [m.data - p.data for p, m in zip(predicted, measured, strict=True)]

    def motion_rms(self) -> np.ndarray:
        """The RMS of each compared column's measured change from its window's start: the motion
        a model has to explain."""
        params = self.params.copy()
        _, _, measured = self.residual_fn()(params.as_vector(), params)
        moved = np.vstack([m.data - w.sensordata.data[0] for m, w in
                           zip(measured, self.sequences.measured_rollout, strict=True)])
        return np.sqrt(np.mean(moved ** 2, axis=0))

    def column_rms(self, x: np.ndarray) -> np.ndarray:
        """The RMS of each compared column over every window."""
        stacked = np.vstack(self.differences(x))
        return np.sqrt(np.mean(stacked ** 2, axis=0))


_CONTROL_AND_APPLIED = int(mujoco.mjtState.mjSTATE_CTRL | mujoco.mjtState.mjSTATE_QFRC_APPLIED)


def _rollout_applied(models, datas, controls, forces, starts, signal_mapping, state_mapping, ctrl_mapping
                     ) -> list[sysid.SystemTrajectory]:
    """sysid.sysid_rollout with a generalised force applied beside each control (`forces`, per
    rollout, on its control's grid): sysid's passes mujoco.rollout the controls alone. As there,
    a window's last control drives nothing (the last sample is reached by the one before)."""
    control = np.stack([c.data[:-1] for c in controls])
    applied = np.stack([f[:-1] for f in forces])
    state, sensordata = mujoco.rollout.rollout(list(models), datas, np.stack(starts),
                                               np.concatenate([control, applied], axis=2),
                                               control_spec=_CONTROL_AND_APPLIED)
    return [sysid.SystemTrajectory(model=m, control=sysid.TimeSeries(c.times[:-1], u, signal_mapping=ctrl_mapping),
                                   sensordata=sysid.TimeSeries(x[:, 0], y, signal_mapping),
                                   initial_state=s0, state=sysid.TimeSeries(x[:, 0], x, signal_mapping=state_mapping))
            for m, c, u, x, y, s0 in zip(models, controls, control, state, sensordata, starts, strict=True)]


@dataclass(frozen=True)
class Estimate:
    """What one parameter came to."""

    knob: Knob
    fitted: float
    standard_error: float
    interval: tuple[float, float]  # 95 %
    identifiable: bool


@dataclass(frozen=True)
class Fit:
    estimates: list[Estimate]
    rms_before: np.ndarray  # per compared column
    rms_after: np.ndarray
    columns: list[str]
    seconds: float
    evaluations: int
    x: np.ndarray = field(repr=False)
    problem: Problem = field(repr=False)
    result: object = field(repr=False)
    initial: sysid.ParameterDict = field(repr=False)
    solved: tuple[str, ...] = ()  # the parameters the last solve changed (`result` is of them)

    def value(self, name: str) -> float:
        return next(e.fitted for e in self.estimates if e.knob.name == name)


def seconds_per_evaluation(problem: Problem) -> float:
    """One rollout of every window at the nominal parameters, timed (s)."""
    started = clock.perf_counter()
    problem.differences(problem.params.as_vector())
    return clock.perf_counter() - started


def evaluations_needed(knobs: Sequence[Knob], iterations: int = MAX_ITERATIONS) -> int:
    """Rollouts of every window a fit needs at most: a Jacobian (one more than the parameters)
    an iteration and a line search's few, twice over if some parameter is dropped, and the
    intervals' Jacobian."""
    return (2 * iterations * (len(knobs) + 3)) + len(knobs) + 1


def fit(problem: Problem, *, iterations: int = MAX_ITERATIONS, progress: Callable[[int], None] | None = None) -> Fit:
    """Fit the problem's parameters: scale the residuals on the nominal model, solve, drop the
    parameters the log does not determine (back to nominal), solve again, and give each its
    interval from the residual the fit leaves."""
    started = clock.perf_counter()
    nominal = problem.params.as_nominal_vector()
    rms_before = problem.column_rms(nominal)
    problem.scales = np.where(rms_before > 0, rms_before, 1.0)
    counter = _Counter(problem.residual_fn(), progress)
    params = problem.params.copy()
    for p in params.values():  # a start on a bound (no friction in the file) stalls: start inside
        p.move_off_bound(fraction=0.05)
    params = masses_first(problem, counter, params, max_iters=iterations, eps=FD_STEP, x_scale="jac")
    params = equation_error_start(problem, params)
    problem.scales = _rescale(problem, params)  # weights of what is left at the start, not at the nominal model
    dropped: set[str] = set()
    result, solved = None, ()
    estimates = [Estimate(k, k.nominal, float("nan"), (float("nan"), float("nan")), False) for k in problem.knobs]
    for _ in range(PASSES):
        free = params.copy()
        for name in dropped:
            free[name].value[:] = free[name].nominal
            free[name].frozen = True
        if free.size == 0:
            break
        solved = tuple(k.name for k in problem.knobs if k.name not in dropped)
        with contextlib.redirect_stdout(io.StringIO()):  # the optimizer prints each iteration
            opt, result = sysid.optimize(free, counter, optimizer="mujoco", verbose=False, max_iters=iterations,
                                         eps=FD_STEP, x_scale="jac")
        problem.scales = _rescale(problem, opt)
        estimates = _intervals(problem, counter, opt, dropped)
        newly = {e.knob.name for e in estimates if not e.identifiable} - dropped
        if not newly:
            break
        dropped |= newly
        params = opt
    # What the last pass still could not determine goes back to its nominal value too.
    estimates = [e if e.identifiable else Estimate(e.knob, e.knob.nominal, e.standard_error, e.interval, False)
                 for e in estimates]
    full = problem.params.copy()
    for e in estimates:
        full[e.knob.name].value[:] = e.fitted
    x = full.as_vector()
    rms_after = problem.column_rms(x)
    return Fit(estimates, rms_before, rms_after, problem.columns, clock.perf_counter() - started, counter.calls, x,
               problem, result, problem.params, solved)


class _Counter:
    """The residual function, counting the rollouts of all windows it asks for."""

    def __init__(self, residual_fn: Callable, progress: Callable[[int], None] | None):
        self.residual_fn, self.progress, self.calls = residual_fn, progress, 0

    def __call__(self, x, params, **kwargs):
        self.calls += 1 if x.ndim == 1 else x.shape[1]
        if self.progress is not None:
            self.progress(self.calls)
        return self.residual_fn(x, params, **kwargs)


def _rescale(problem: Problem, params: sysid.ParameterDict) -> np.ndarray:
    """Each column's scale set to its RMS residual at `params`: the weights of noise left."""
    rms = problem.column_rms(params.as_vector(include_frozen=True))
    return np.where(rms > 0, rms, 1.0)


def window_intervals(r: np.ndarray, jac: np.ndarray, windows: int, alpha: float = 0.05
                     ) -> tuple[np.ndarray, np.ndarray]:
    """The parameters' covariance and the half-widths of their 1 - alpha intervals, with the
    residual correlated within a window and independent between windows (each starts from the
    measured state). sysid's calculate_intervals assumes every sample's noise independent: a
    torque noise, a gust or a disturbance force integrates into the motion, and its samples
    within a window then count many times over. Here the covariance is the sandwich
    (J'J)^-1 (sum over windows of J_w' r_w r_w' J_w) (J'J)^-1, robust to any correlation
    within a window (White 1980; the clustered form, Liang & Zeger 1986), with Student's t
    on windows - 1 degrees of freedom. calculate_intervals still names the directions the log
    does not determine (an infinite width)."""
    norms = np.linalg.norm(jac, axis=0)
    norms = np.where(norms > 0, norms, 1.0)  # columns of one size: the singular test sees the directions, not the units
    _, flagged = sysid.calculate_intervals([r], jac / norms, alpha=alpha)
    p = jac.shape[1]
    bread = np.linalg.pinv(jac.T @ jac)
    scores = np.einsum("wsp,ws->wp", jac.reshape(windows, -1, p), r.reshape(windows, -1))
    covariance = bread @ (scores.T @ scores) @ bread
    covariance *= windows / max(windows - 1, 1)  # the small-sample correction of the clustered form
    half = np.sqrt(np.maximum(np.diag(covariance), 0.0)) * scipy.special.stdtrit(max(windows - 1, 1), 1 - alpha / 2)
    return covariance, np.where(np.isfinite(flagged), half, np.inf)


def _intervals(problem: Problem, residual_fn: Callable, params: sysid.ParameterDict, dropped: set[str]
               ) -> list[Estimate]:
    """Each parameter's standard error and 95 % interval from the Jacobian at `params`
    (`window_intervals`), never narrower than the logged force's noise allows (the balance's
    floor), and whether the log determines it."""
    free = [k for k in problem.knobs if k.name not in dropped]
    trial = params.copy()
    for name in dropped:
        trial[name].frozen = True
    x = trial.as_vector()
    bounds = trial.get_bounds()

    def f(z):
        return np.concatenate(residual_fn(z, trial)[0])

    r = f(x)
    jac = np.asarray(jacobian_fd(residual=f, x=x.reshape(-1, 1), r=r.reshape(-1, 1), eps=FD_STEP, n_res=0,
                                 bounds=[bounds[0].reshape(-1, 1), bounds[1].reshape(-1, 1)])[0])
    covariance, half = window_intervals(r, jac, len(problem.windows))
    floor = Balance(problem).floor(trial, free)  # what the logged force's noise leaves unknown
    estimates = []
    index = {k.name: i for i, k in enumerate(free)}
    for knob in problem.knobs:
        if knob.name in dropped:
            estimates.append(Estimate(knob, knob.nominal, float("nan"), (float("nan"), float("nan")), False))
            continue
        i = index[knob.name]
        value = float(x[i])
        least = floor.get(knob.name, 0.0)
        width = max(float(half[i]), NORMAL_95 * least)
        stderr = max(float(np.sqrt(covariance[i, i])), least) if np.isfinite(width) else float("inf")
        identifiable = bool(np.isfinite(width) and width <= abs(value))
        estimates.append(Estimate(knob, value, stderr, (value - width, value + width), identifiable))
    return estimates
