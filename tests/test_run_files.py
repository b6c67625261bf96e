"""The readers of a run directory's files (bwr_twin/results/run_files.py): what the twin writes reads
back as the run held it, to the CSV's printed precision (10 significant digits), and a damaged
file is refused with one line naming the file, the row and the column or key."""

from __future__ import annotations

import json
import re
import shutil
from pathlib import Path

import numpy as np
import pytest
from conftest import write_short_scene

from bwr_twin.config.scene import load_scene
from bwr_twin.errors import BwrError
from bwr_twin.model.machine import paper_to_world
from bwr_twin.results.run_files import COLUMNS, read_scene, read_timeseries, timeseries_of
from bwr_twin.results.rundir import SCENE_FILE, TIMESERIES_FILE, timeseries_columns, write_run
from bwr_twin.signals import LOOP, RECLAIM, UNITS
from bwr_twin.sim.lockstep import simulate

PRINTED = dict(rtol=1e-9, atol=1e-300)  # np.savetxt's "%.10g"


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """The 20 s scene under the fuzzy controller (it declares signals), simulated once and written."""
    folder = tmp_path_factory.mktemp("run_files")
    result = simulate(load_scene(write_short_scene(folder)), nthread=1)
    write_run(result, folder / "run", plots=False)
    return result, folder / "run"


def test_the_time_series_reads_back_as_the_run_held_it(run):
    result, folder = run
    series = read_timeseries(folder / TIMESERIES_FILE, envelope=result.machine.envelope)
    np.testing.assert_allclose(series.time, result.time, **PRINTED)
    for signal in LOOP:
        np.testing.assert_allclose(series.signals[signal.name], getattr(result, signal.name), **PRINTED)
        assert series.units[signal.name] == UNITS[signal.kind]
    assert series.controller_signals == tuple(s.column for s in result.signal_schema) == (
        "fuzzy_output", "acceleration_command")
    for signal in result.signal_schema:
        np.testing.assert_allclose(series.signals[signal.column], result.controller_signals[signal.name], **PRINTED)
        assert series.units[signal.column] == UNITS[signal.kind]
    np.testing.assert_allclose(series.cp_desired, result.cp_desired, **PRINTED)
    np.testing.assert_allclose(series.cp_actual, result.cp, **PRINTED)
    np.testing.assert_allclose(series.wind_speed, result.wind_speed, **PRINTED)
    assert series.reclaim is series.neighbour is series.grade is series.stacked is None
    names, _ = timeseries_columns(result)
    assert list(series.columns) == names


def test_a_run_in_memory_gives_the_record_its_file_gives(run):
    result, folder = run
    read = read_timeseries(folder / TIMESERIES_FILE)
    held = timeseries_of(*timeseries_columns(result))
    assert held.controller_signals == read.controller_signals and held.units == read.units
    for name, values in held.signals.items():
        np.testing.assert_allclose(read.signals[name], values, **PRINTED)


def test_the_scene_reads_back_as_the_run_resolved_it(run):
    result, folder = run
    scene, recorded = result.scene, read_scene(folder / SCENE_FILE)
    assert (recorded.path, recorded.mjcf, recorded.controller) == (scene.path, scene.machine.mjcf, "fuzzy_model")
    assert (recorded.timestep, recorded.control_period, recorded.record_period, recorded.seed) == (
        scene.simulation.timestep, scene.simulation.control_period, scene.simulation.record_period,
        scene.simulation.seed)
    np.testing.assert_array_equal(recorded.via_times, [v.t for v in scene.trajectory.via_points])
    np.testing.assert_allclose(recorded.via_points, paper_to_world(np.array([v.p for v in scene.trajectory.via_points])))
    assert not (recorded.stockpile or recorded.reclaim or recorded.stacking) and recorded.neighbour_mjcf is None
    assert (recorded.title, recorded.activity) == ("short.toml", "reclaim")


def _cell(row: int, column: str, value: str):
    """Set one cell (row 1 = the first after the header)."""
    def edit(lines: list[str]) -> list[str]:
        cells = lines[row].split(",")
        cells[lines[0].split(",").index(column)] = value
        lines[row] = ",".join(cells)
        return lines
    return edit


def _header(old: str, new: str):
    def edit(lines: list[str]) -> list[str]:
        lines[0] = lines[0].replace(old, new)
        return lines
    return edit


def _cut(row: int):
    def edit(lines: list[str]) -> list[str]:
        return lines[:row] + [lines[row][:30]]
    return edit


# (id, edit of the CSV's lines, the one line it is refused with, after the file's name)
DAMAGED_CSV = [
    ("missing-column", _header("luff_q_actual_rad", "luff_q_actual_deg"),
     r": no column 'luff_q_actual_rad', which bwr_twin.run writes \(docs/contracts.md\): renamed 'luff_q_actual_deg'\?"),
    ("dropped-column", _header(",wind_speed_m/s", ""),
     r": no column 'wind_speed_m/s', which bwr_twin.run writes \(docs/contracts.md\)$"),
    ("twice", _header("slew_q_actual_rad", "travel_q_actual_m"),
     r": the column 'travel_q_actual_m' appears twice in the header"),
    ("text", _cell(7, "slew_qd_actual_rad/s", "abc"), r": row 7, column 'slew_qd_actual_rad/s': 'abc' is not a number"),
    ("nan", _cell(5, "slew_q_actual_rad", "nan"), r": row 5, column 'slew_q_actual_rad': nan, not a finite number"),
    ("inf", _cell(3, "cp_actual_z_m", "inf"), r": row 3, column 'cp_actual_z_m': inf, not a finite number"),
    ("minus-inf", _cell(4, "travel_fuzzy_output_1", "-inf"),
     r": row 4, column 'travel_fuzzy_output_1': -inf, not a finite number"),
    ("huge-position", _cell(9, "travel_q_actual_m", "1e308"),
     r": row 9, column 'travel_q_actual_m': 1e\+308 m lies outside \[-75, 75\] m \(the machine's operating envelope "
     r"\[-25, 25\] m and as much again either side\)"),
    ("huge-angle", _cell(2, "luff_q_desired_rad", "-7"),
     r": row 2, column 'luff_q_desired_rad': -7 rad lies outside \[-0.785398, 0.785398\] rad"),
    ("huge-cp", _cell(2, "cp_desired_y_m", "1e308"), r": row 2, column 'cp_desired_y_m': 1e\+308 m lies outside "
     r"\[-10000, 10000\] m \(metres from the yard's origin"),
    ("truncated", _cut(50), r": row 50 has \d+ values for the header's \d+ columns \(a truncated or damaged file\): "
     r"column '\S+' is the last it fills"),
    ("time-backwards", _cell(6, "time_s", "0.1"), r": row 6, column 'time_s': 0.1 s does not come after the row "
     r"before's 0.4 s"),
    ("lone-controller-column", _header("luff_fuzzy_output_1", "luff_fuzzy_out_1"),
     r": no column 'luff_fuzzy_output_<unit>' beside 'travel_fuzzy_output_1'"),
    ("empty", lambda lines: [], r": no header; a time series starts with its column names"),
]


@pytest.mark.parametrize("edit, message", [case[1:] for case in DAMAGED_CSV], ids=[case[0] for case in DAMAGED_CSV])
def test_a_damaged_time_series_is_refused_in_one_line(run, tmp_path, edit, message):
    result, folder = run
    path = tmp_path / TIMESERIES_FILE
    path.write_text("\n".join(edit((folder / TIMESERIES_FILE).read_text().splitlines())) + "\n")
    with pytest.raises(BwrError) as caught:
        read_timeseries(path, envelope=result.machine.envelope)
    text = str(caught.value)
    assert "\n" not in text and text.startswith(str(path)), text
    assert re.match(message, text[len(str(path)):]), text


def test_without_the_machine_a_position_is_held_to_the_yard(run, tmp_path):
    _, folder = run
    path = tmp_path / TIMESERIES_FILE
    path.write_text("\n".join(_cell(4, "travel_q_measured_m", "1e308")(
        (folder / TIMESERIES_FILE).read_text().splitlines())) + "\n")
    with pytest.raises(BwrError, match=r"row 4, column 'travel_q_measured_m': 1e\+308 m lies outside \[-10000, "
                                       r"10000\] m \(metres from the yard's origin"):
        read_timeseries(path)
    path.write_text("\n".join(_cell(4, "slew_q_measured_rad", "7")(
        (folder / TIMESERIES_FILE).read_text().splitlines())) + "\n")
    with pytest.raises(BwrError, match=r"row 4, column 'slew_q_measured_rad': 7 rad lies outside \[-6.28319, "
                                       r"6.28319\] rad \(radians: no slew or luff"):
        read_timeseries(path)


def _reclaim_csv(path: Path, belt_scale: str, rate: str = "0") -> Path:
    """Two rows of a reclaim's columns: every value 0 but the belt scale's and the rate's."""
    names = [*COLUMNS, *(c.format(xyz=x) for _, column, width in RECLAIM for c in [column]
                         for x in ("xyz" if width == 3 else "x"))]
    rows = []
    for t in (0.0, 0.1):
        cells = {name: "0" for name in names} | {"time_s": str(t), "belt_scale_t/h": belt_scale, "reclaim_rate_t/h": rate}
        rows.append(",".join(cells[name] for name in names))
    path.write_text(",".join(names) + "\n" + "\n".join(rows) + "\n")
    return path


def test_the_contract_nan_is_read_and_no_other(tmp_path):
    """A machine without instruments writes NaN for its belt scale: that is read; a NaN rate is not."""
    series = read_timeseries(_reclaim_csv(tmp_path / TIMESERIES_FILE, "nan"))
    assert np.isnan(series.reclaim["belt_scale"]).all() and series.reclaim["digging_force"].shape == (2, 3)
    with pytest.raises(BwrError, match=r"row 1, column 'belt_scale_t/h': inf, not a finite number"):
        read_timeseries(_reclaim_csv(tmp_path / TIMESERIES_FILE, "inf"))
    with pytest.raises(BwrError, match=r"row 1, column 'reclaim_rate_t/h': nan, not a finite number"):
        read_timeseries(_reclaim_csv(tmp_path / TIMESERIES_FILE, "0", rate="nan"))


def _drop(*keys: str):
    def edit(scene: dict) -> dict:
        table = scene
        for key in keys[:-1]:
            table = table[key]
        del table[keys[-1]]
        return scene
    return edit


def _set(value, *keys):
    def edit(scene: dict) -> dict:
        table = scene
        for key in keys[:-1]:
            table = table[key]
        table[keys[-1]] = value
        return scene
    return edit


# (id, edit of the scene.json object, or its text, and the reason of the one line it is refused with)
DAMAGED_SCENE = [
    ("no-machine-mjcf", _drop("machine", "mjcf"), r"no key 'machine.mjcf'"),
    ("no-path", _drop("path"), r"no key 'path'"),
    ("no-trajectory", _drop("trajectory"), r"no key 'trajectory'"),
    ("period-text", _set("abc", "simulation", "record_period"),
     r"'simulation.record_period' is text \('abc'\), not a number"),
    ("seed-fraction", _set(1.5, "simulation", "seed"), r"'simulation.seed' is the number 1.5, not a whole number"),
    ("controller-a-list", _set([1], "controller"), r"'controller' is a list, not an object"),
    ("via-points-text", _set("none", "trajectory", "via_points"),
     r"'trajectory.via_points' is text \('none'\), not a list"),
    ("via-point-no-t", _drop("trajectory", "via_points", 1, "t"),
     r"no key 'trajectory.via_points\[1\].t'"),
    ("via-point-two-numbers", _set([1.0, 2.0], "trajectory", "via_points", 0, "p"),
     r"'trajectory.via_points\[0\].p' is not three numbers"),
    ("frame", _set("moon", "trajectory", "frame"), r"'trajectory.frame' is 'moon', not 'paper' or 'world'"),
    ("neighbour-true", _set(True, "neighbour"), r"'neighbour' is true, not an object or null"),
    ("a-list", lambda s: [1, 2], r"a list, not an object"),
]


@pytest.mark.parametrize("edit, reason", [case[1:] for case in DAMAGED_SCENE], ids=[case[0] for case in DAMAGED_SCENE])
def test_a_damaged_scene_is_refused_in_one_line(run, tmp_path, edit, reason):
    _, folder = run
    path = tmp_path / SCENE_FILE
    path.write_text(json.dumps(edit(json.loads((folder / SCENE_FILE).read_text()))))
    with pytest.raises(BwrError) as caught:
        read_scene(path)
    text = str(caught.value)
    assert "\n" not in text and text.startswith(f"{path}: not a scene as bwr_twin.run writes it: "), text
    assert re.search(reason, text), text


def test_a_scene_that_is_not_json_is_refused_in_one_line(run, tmp_path):
    _, folder = run
    path = tmp_path / SCENE_FILE
    path.write_text((folder / SCENE_FILE).read_text()[:200])
    with pytest.raises(BwrError, match=rf"^{path}: not JSON \(line \d+, column \d+: .*\)$"):
        read_scene(path)
    shutil.copy(folder / SCENE_FILE, path)
    assert read_scene(path).mjcf == load_scene(folder.parent / "short.toml").machine.mjcf
