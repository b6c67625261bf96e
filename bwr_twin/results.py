"""What a run leaves behind: metrics, a self-describing time series and the run's settings,
written into a directory that appears only when complete.

Layout of a run directory (the output contract of DESIGN.md, plus more):
    metrics.json      per-axis error maxima (signed), their times, RMS, drive saturation
    timeseries.csv    every signal at the record period; units in the column names
    scene.json        the resolved scene, so the run can be replayed without its files' paths
    *.png             the paper's figures for this run (bwr_twin.plots)
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import tempfile
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np

from bwr_twin.errors import BwrError
from bwr_twin.machine import AXES, UNITS, to_display
from bwr_twin.simulate import RunResult

METRICS_FILE = "metrics.json"
TIMESERIES_FILE = "timeseries.csv"
SCENE_FILE = "scene.json"

# Unit of each signal kind per axis: travel is linear, slew and luff are angular.
_SI_UNITS = {
    "q": ("m", "rad", "rad"),
    "qd": ("m/s", "rad/s", "rad/s"),
    "qdd": ("m/s2", "rad/s2", "rad/s2"),
    "force": ("N", "Nm", "Nm"),
    "1": ("1", "1", "1"),
}
# (column stem, RunResult attribute, unit kind)
_SIGNALS = (
    ("q_desired", "q_desired", "q"),
    ("q_actual", "q", "q"),
    ("q_measured", "q_measured", "q"),
    ("qd_desired", "qd_desired", "qd"),
    ("qd_actual", "qd", "qd"),
    ("qd_measured", "qd_measured", "qd"),
    ("qdd_desired", "qdd_desired", "qdd"),
    ("qdd_actual", "qdd", "qdd"),
    ("fuzzy_output", "fuzzy_output", "1"),
    ("acceleration_command", "acceleration_command", "qdd"),
    ("drive_force_command", "drive_force_command", "force"),
    ("drive_force", "drive_force", "force"),
    ("disturbance", "disturbance", "force"),
)


_KIND = {stem: kind for stem, _, kind in _SIGNALS}


def column_name(stem: str, axis: int) -> str:
    """The timeseries.csv column of one signal of one axis: column_name("qd_actual", 1) is
    'slew_qd_actual_rad/s'."""
    return f"{AXES[axis]}_{stem}_{_SI_UNITS[_KIND[stem]][axis]}"


def _signed_max(x: np.ndarray) -> tuple[float, int]:
    """The value of largest magnitude, sign kept, and its index."""
    i = int(np.argmax(np.abs(x)))
    return float(x[i]), i


def compute_metrics(result: RunResult) -> dict:
    """Per-axis error figures (error = desired - actual) in SI units, per DESIGN.md."""
    limits = result.machine.drive_limits
    metrics: dict = {}
    for j, axis in enumerate(AXES):
        e = result.q_desired[:, j] - result.q[:, j]
        ev = result.qd_desired[:, j] - result.qd[:, j]
        ea = result.qdd_desired[:, j] - result.qdd[:, j]
        pos_max, i = _signed_max(e)
        vel_max, iv = _signed_max(ev)
        acc_max, ia = _signed_max(ea)
        command = result.drive_force_command[:, j]
        metrics[axis] = {
            "position_error_max": pos_max,
            "position_error_max_time": float(result.time[i]),
            "velocity_error_max": vel_max,
            "velocity_error_max_time": float(result.time[iv]),
            "acceleration_error_max": acc_max,
            "acceleration_error_max_time": float(result.time[ia]),
            "position_error_rms": float(np.sqrt(np.mean(e**2))),
            "position_error_final": float(e[-1]),
            "drive_force_max": _signed_max(result.drive_force[:, j])[0],
            "drive_force_rms": float(np.sqrt(np.mean(result.drive_force[:, j] ** 2))),
            "drive_limit": [float(limits[j, 0]), float(limits[j, 1])] if np.isfinite(limits[j]).any() else None,
            "saturation_fraction": float(np.mean((command < limits[j, 0]) | (command > limits[j, 1]))),
        }
    cp_error = np.linalg.norm(result.cp_desired - result.cp, axis=1)
    k = int(np.argmax(cp_error))
    metrics["cp_error_max"] = float(cp_error[k])
    metrics["cp_error_max_time"] = float(result.time[k])
    scene = result.scene
    metrics["units"] = {
        "travel": "m, m/s, m/s^2, N",
        "slew": "rad, rad/s, rad/s^2, N m",
        "luff": "rad, rad/s, rad/s^2, N m",
        "cp_error_max": "m",
        "times": "s",
    }
    metrics["run"] = {
        "scene": str(scene.path),
        "mjcf": str(scene.machine.mjcf),
        "controller_mjcf": str(scene.controller_mjcf),
        "seed": scene.simulation.seed,
        "duration": result.trajectory.duration,
        "control_period": scene.simulation.control_period,
        "timestep": scene.simulation.timestep,
    }
    return metrics


def timeseries_columns(result: RunResult) -> tuple[list[str], np.ndarray]:
    """Column names (with units) and values of the recorded time series, at the record period."""
    every = max(1, round(result.scene.simulation.record_period / result.scene.simulation.control_period))
    rows = np.arange(0, len(result.time), every)
    if rows[-1] != len(result.time) - 1:
        rows = np.append(rows, len(result.time) - 1)  # always keep the last sample
    names, columns = ["time_s"], [result.time[rows]]
    for stem, attribute, _ in _SIGNALS:
        values = getattr(result, attribute)
        for j in range(len(AXES)):
            names.append(column_name(stem, j))
            columns.append(values[rows, j])
    for label, cp in (("desired", result.cp_desired), ("actual", result.cp)):
        for c, coordinate in enumerate("xyz"):
            names.append(f"cp_{label}_{coordinate}_m")
            columns.append(cp[rows, c])
    names.append("wind_speed_m/s")
    columns.append(result.wind_speed[rows])
    return names, np.column_stack(columns)


def read_timeseries(path: str | Path) -> dict[str, np.ndarray]:
    """Read a timeseries.csv back into {column name: array}."""
    path = Path(path)
    with open(path) as f:
        names = f.readline().strip().split(",")
    values = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    return {name: values[:, i] for i, name in enumerate(names)}


def summary_table(metrics: dict) -> str:
    """The maximum errors with their times, in engineering units (m, deg)."""
    lines = [
        f"{'axis':<7} {'position error max':>24} {'velocity error max':>26} {'acceleration error max':>30} {'pos. RMS':>12}"
    ]
    for j, axis in enumerate(AXES):
        m = metrics[axis]
        lines.append(
            f"{axis:<7} {_largest(m, j, 'position', ''):>24} {_largest(m, j, 'velocity', '/s'):>26} "
            f"{_largest(m, j, 'acceleration', '/s^2'):>30} {to_display(j, m['position_error_rms']):>9.4g} {UNITS[j]}"
        )
    lines.append(f"largest CP distance from its desired position: {metrics['cp_error_max']:.4g} m @ {metrics['cp_error_max_time']:.1f} s")
    return "\n".join(lines)


def _largest(axis_metrics: dict, j: int, kind: str, per: str) -> str:
    """'+0.01812 m @ 204.1 s': the largest error of one kind, in engineering units, and its time."""
    value, time = axis_metrics[f"{kind}_error_max"], axis_metrics[f"{kind}_error_max_time"]
    return f"{to_display(j, value):+.4g} {UNITS[j]}{per} @ {time:5.1f} s"


def _umask() -> int:
    """The process's umask: reading it means setting it, so it is set back at once."""
    mask = os.umask(0)
    os.umask(mask)
    return mask


def write_atomically(path: Path, write: Callable[[Path], None]) -> None:
    """Call write(temporary path), then rename the file into place; no partial file is left."""
    temporary = path.parent / f".{path.name}.partial-{os.getpid()}"
    try:
        write(temporary)
        os.replace(temporary, path)
    finally:
        temporary.unlink(missing_ok=True)


@contextlib.contextmanager
def staged_directory(out_dir: Path, *, overwrite: bool = False) -> Iterator[Path]:
    """A temporary sibling of `out_dir` that is renamed into place only if the block succeeds.

    An existing `out_dir` is refused (BwrError) unless `overwrite`; then it is replaced only
    after the new one is complete. On any failure the temporary directory is removed and
    `out_dir` is untouched.
    """
    out_dir = Path(out_dir)
    if out_dir.exists() and not overwrite:
        raise BwrError(f"{out_dir}: already exists; choose another --out or pass --overwrite")
    out_dir.parent.mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(prefix=f".{out_dir.name}.partial-", dir=out_dir.parent))
    try:
        staging.chmod(0o777 & ~_umask())  # mkdtemp's 0700 would make results private
        yield staging
        if out_dir.exists():
            old = Path(tempfile.mkdtemp(prefix=f".{out_dir.name}.old-", dir=out_dir.parent))
            os.replace(out_dir, old / out_dir.name)
            os.replace(staging, out_dir)
            shutil.rmtree(old, ignore_errors=True)
        else:
            os.replace(staging, out_dir)
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        raise


def write_run(
    result: RunResult,
    out_dir: str | Path,
    *,
    overwrite: bool = False,
    plots: bool = True,
) -> dict:
    """Write a run directory atomically; returns the metrics."""
    metrics = compute_metrics(result)
    with staged_directory(Path(out_dir), overwrite=overwrite) as staging:
        names, values = timeseries_columns(result)
        np.savetxt(staging / TIMESERIES_FILE, values, delimiter=",", header=",".join(names), comments="", fmt="%.10g")
        (staging / METRICS_FILE).write_text(json.dumps(metrics, indent=2) + "\n")
        (staging / SCENE_FILE).write_text(json.dumps(result.scene.to_dict(), indent=2) + "\n")
        if plots:
            from bwr_twin.plots import save_run_figures

            save_run_figures(result, staging)
    return metrics
