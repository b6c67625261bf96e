"""A log read from where it is: a run directory the twin wrote (its timeseries.csv) or a plant
historian's CSV or Parquet file through its column map (`bwr_twin.calibrate.historian`)."""

from __future__ import annotations

import math
from pathlib import Path

from bwr_twin.calibrate.historian import read_historian
from bwr_twin.calibrate.log import MachineLog, check_log
from bwr_twin.errors import BwrError
from bwr_twin.model.machine import Machine


def read_log(path: str | Path, machine: Machine, column_map: Path | None = None) -> MachineLog:
    """The log at `path`: a run directory the twin wrote, or a historian's CSV or Parquet file
    read through `column_map` (a TOML file). Checked: rate, time, finiteness; a problem is one BwrError naming
    the file, the column and the row."""
    path = Path(path)
    if path.is_dir():
        log = _run_directory(path, machine)
    elif column_map is not None:
        log = read_historian(path, column_map, machine)
    else:
        raise BwrError(f"{path}: not a run directory the twin wrote; a historian's CSV or Parquet file needs "
                       "--columns MAP.toml")
    check_log(log)
    return log


def _run_directory(path: Path, machine: Machine) -> MachineLog:
    """The run's log, with the wind's heading and air density from its scene.json (a run without
    one, or in still air, has no wind for the fit to apply)."""
    from bwr_twin.results.run_files import read_scene, read_timeseries
    from bwr_twin.results.rundir import SCENE_FILE

    csv = path / "timeseries.csv"
    if not csv.is_file():
        raise BwrError(f"{path}: holds no timeseries.csv; a log is a run directory the twin wrote or a "
                       "historian's CSV with --columns")
    series = read_timeseries(csv, envelope=machine.envelope)
    signals = series.signals
    heading, density = 0.0, 0.0
    if (path / SCENE_FILE).is_file():
        scene = read_scene(path / SCENE_FILE)
        heading, density = math.radians(scene.wind_direction), scene.air_density
    return MachineLog(path=path, time=series.time, q=signals["q_measured"], force=signals["drive_force"],
                      qd=signals["qd_measured"], wind=series.wind_speed, wind_heading=heading, air_density=density)
