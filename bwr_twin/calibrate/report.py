"""The calibration's report in its output folder: mujoco.sysid's HTML report (`default_report`:
the parameters, the signals, the covariance) on a few of the windows, and PNG figures of the
measured, nominal and calibrated traces per axis, the residuals, and the parameters with their
95 % intervals."""

from __future__ import annotations

import contextlib
import io
from pathlib import Path

import numpy as np

from bwr_twin.model.machine import AXES

REPORT_WINDOWS = 6  # windows the HTML report and the trace figures show: spread over the logs
WRITER = "bwr_twin.calibrate"


def write_report(folder: Path, result) -> None:
    """report.html, traces.png, residuals.png and parameters.png into `folder`."""
    problem = result.problem
    count = len(problem.sequences.measured_rollout)
    shown = sorted(set(np.linspace(0, count - 1, min(REPORT_WINDOWS, count)).round().astype(int).tolist()))
    nominal = problem.params.as_nominal_vector()
    _, before, measured = problem.residual_fn(shown)(nominal, problem.params.copy())
    _, after, _ = problem.residual_fn(shown)(result.x, problem.params.copy())
    _traces(folder / "traces.png", problem, measured, before, after)
    _residuals(folder / "residuals.png", problem, measured, before, after)
    _parameters(folder / "parameters.png", result)
    if result.result is not None:
        _html(folder / "report.html", problem, result, shown)


def _figure():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _save(fig, path: Path) -> None:
    from bwr_twin.ownership import picture_metadata

    fig.savefig(path, dpi=110, metadata=picture_metadata(WRITER, ".png"))
    _figure().close(fig)


def _traces(path: Path, problem, measured, before, after) -> None:
    plt = _figure()
    fig, axes = plt.subplots(3, 1, figsize=(10, 8), sharex=False)
    for j, ax in enumerate(axes):
        for k, (m, b, a) in enumerate(zip(measured, before, after, strict=True)):
            scale = 1.0 if j == 0 else 180 / np.pi
            ax.plot(m.times, m.data[:, j] * scale, "k.", ms=2, label="measured" if k == 0 else None)
            ax.plot(b.times, b.data[:, j] * scale, "r-", lw=1, label="nominal" if k == 0 else None)
            ax.plot(a.times, a.data[:, j] * scale, "b-", lw=1, label="calibrated" if k == 0 else None)
        ax.set_ylabel(f"{AXES[j]} ({'m' if j == 0 else 'deg'})")
        ax.grid(alpha=0.3)
    axes[0].legend(loc="best", fontsize=8)
    axes[-1].set_xlabel("time (s): windows, each from the measured state")
    fig.suptitle("Encoders: measured, nominal and calibrated model")
    fig.tight_layout()
    _save(fig, path)


def _residuals(path: Path, problem, measured, before, after) -> None:
    plt = _figure()
    fig, axes = plt.subplots(3, 1, figsize=(10, 8))
    for j, ax in enumerate(axes):
        scale = 1.0 if j == 0 else 180 / np.pi
        for k, (m, b, a) in enumerate(zip(measured, before, after, strict=True)):
            ax.plot(m.times, (m.data[:, j] - b.data[:, j]) * scale, "r-", lw=1, label="nominal" if k == 0 else None)
            ax.plot(m.times, (m.data[:, j] - a.data[:, j]) * scale, "b-", lw=1, label="calibrated" if k == 0 else None)
        ax.axhline(0, color="k", lw=0.5)
        ax.set_ylabel(f"{AXES[j]} ({'m' if j == 0 else 'deg'})")
        ax.grid(alpha=0.3)
    axes[0].legend(loc="best", fontsize=8)
    axes[-1].set_xlabel("time (s)")
    fig.suptitle("Residuals: measured less predicted")
    fig.tight_layout()
    _save(fig, path)


def _parameters(path: Path, result) -> None:
    plt = _figure()
    estimates = result.estimates
    fig, ax = plt.subplots(figsize=(8, 0.45 * len(estimates) + 1.5))
    for i, e in enumerate(estimates):
        reference = abs(e.knob.nominal) if e.knob.nominal else max(abs(e.fitted), 1e-300)
        if e.identifiable:
            low, high = (v / reference for v in e.interval)
            ax.errorbar(e.fitted / reference, i, xerr=[[e.fitted / reference - low], [high - e.fitted / reference]],
                        fmt="bo", capsize=3)
        else:
            ax.plot(e.fitted / reference, i, "x", color="grey")
        ax.plot(e.knob.nominal / reference, i, "r|", ms=12)
    ax.set_yticks(range(len(estimates)), [e.knob.name + ("" if e.identifiable else " (not determined)")
                                           for e in estimates])
    ax.set_xlabel("value / nominal (a zero nominal: / fitted); red: nominal, blue: fitted with its 95 % interval")
    ax.grid(alpha=0.3)
    fig.tight_layout()
    _save(fig, path)


def _html(path: Path, problem, result, shown) -> None:
    """mujoco.sysid's own report on the windows shown."""
    from mujoco import sysid

    residual = problem.residual_fn(shown)

    def per_sequence(x, params, **_):  # sysid's report reads one list of predictions per sequence
        res, predicted, measured = residual(x, params)
        return res, [[p] for p in predicted], [[m] for m in measured]

    fitted, initial = problem.params.copy(), result.initial.copy()
    for e in result.estimates:
        fitted[e.knob.name].value[:] = e.fitted
        if e.knob.name not in result.solved:  # sysid's sections read the last solve's Jacobian
            fitted[e.knob.name].frozen = initial[e.knob.name].frozen = True
    sequences = problem.sequences[shown[0]:shown[0] + 1] if len(shown) == 1 else _subset(problem.sequences, shown)
    with contextlib.redirect_stdout(io.StringIO()):
        builder = sysid.default_report([sequences], initial, fitted, per_sequence, result.result,
                                       title=f"Calibration of {problem.machine.name}", generate_videos=False)
    builder.save(str(path))


def _subset(sequences, shown):
    from mujoco import sysid

    return sysid.ModelSequences(sequences.name, sequences.spec, [sequences.sequence_name[i] for i in shown],
                                [sequences.initial_state[i] for i in shown], [sequences.control[i] for i in shown],
                                [sequences.sensordata[i] for i in shown])
