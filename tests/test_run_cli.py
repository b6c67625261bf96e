"""`python -m bwr_twin.run`: results that follow the output contract, identical for the same
seed, a bench reclaim's plan and waypoints, and bad input that exits non-zero with one line and
leaves nothing behind."""

import json
import subprocess
import sys

import numpy as np
import pytest
from conftest import ROOT, VARIANT_MJCF, write_short_scene

from bwr_twin.model.machine import AXES
from bwr_twin.results.run_files import read_timeseries

CONTRACT_KEYS = {"position_error_max", "position_error_max_time", "velocity_error_max", "acceleration_error_max", "position_error_rms"}
def run_cli(*args, cwd=ROOT):
    return subprocess.run([sys.executable, "-m", "bwr_twin.run", *map(str, args)], capture_output=True, text=True, cwd=cwd)


def test_run_writes_contract_results(tmp_path):
    out = tmp_path / "run"
    proc = run_cli(write_short_scene(tmp_path), "--out", out)
    assert proc.returncode == 0, proc.stderr
    assert "position error max" in proc.stdout and "travel" in proc.stdout
    metrics = json.loads((out / "metrics.json").read_text())
    for axis in AXES:
        assert CONTRACT_KEYS <= set(metrics[axis])
        assert 0 <= metrics[axis]["position_error_max_time"] <= 20
    series = read_timeseries(out / "timeseries.csv").columns
    assert series["time_s"][0] == 0 and series["time_s"][-1] == pytest.approx(20)
    assert {"travel_q_desired_m", "slew_q_actual_rad", "luff_drive_force_Nm", "cp_actual_x_m"} <= set(series)
    # The recorded errors agree with the metrics (record period 0.1 s, metrics at 0.01 s).
    error = series["travel_q_desired_m"] - series["travel_q_actual_m"]
    assert np.max(np.abs(error)) <= abs(metrics["travel"]["position_error_max"]) + 1e-12
    for png in ("positions.png", "velocities.png", "accelerations.png", "fuzzy_outputs.png",
                "errors_position.png", "errors_velocity.png", "errors_acceleration.png", "drive_forces.png", "cp_path.png"):
        assert (out / png).stat().st_size > 10_000, png
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]  # no staging debris


def test_same_scene_and_seed_give_identical_results(tmp_path):
    scene = write_short_scene(tmp_path)
    for name in ("a", "b"):
        assert run_cli(scene, "--out", tmp_path / name, "--seed", 5, "--no-plots").returncode == 0
    assert (tmp_path / "a" / "timeseries.csv").read_bytes() == (tmp_path / "b" / "timeseries.csv").read_bytes()
    assert run_cli(scene, "--out", tmp_path / "c", "--seed", 6, "--no-plots").returncode == 0
    assert (tmp_path / "a" / "timeseries.csv").read_bytes() != (tmp_path / "c" / "timeseries.csv").read_bytes()


def test_model_option_swaps_the_machine(tmp_path):
    proc = run_cli(write_short_scene(tmp_path), "--out", tmp_path / "variant", "--model", VARIANT_MJCF, "--no-plots")
    assert proc.returncode == 0, proc.stderr  # the variant reaches the short path's via points
    metrics = json.loads((tmp_path / "variant" / "metrics.json").read_text())
    assert metrics["run"]["mjcf"] == metrics["run"]["controller_mjcf"] == str(VARIANT_MJCF)


@pytest.mark.parametrize(
    "edit, message",
    [
        (lambda t: t.replace("p = [-3.0, -11.0, 54.0]", "p = [-3.0, -80.0, 54.0]"), r"via point 2 \(t = 20 s\) at world .* beyond the boom's reach"),
        (lambda t: t.replace("p = [-3.0, -11.0, 54.0]", "p = [-3.0, -11.0, 90.0]"), r"via point 2 .*travel = 3\d\.\d+ m is outside the operating envelope \[-25.000 m, 25.000 m\]"),
        (lambda t: t.replace("t = 20.0", "t = 0.0"), r"via point 2 \(t = 0.0 s\) must come after via point 1"),
        (lambda t: t.replace("seed = 1", "seed = 1\ncolour = 2"), r"unknown key 'simulation.colour'"),
        (lambda t: t.replace("seed = 1", "seed = 1.5"), r"'simulation.seed' must be an integer, got 1.5"),
        (lambda t: t.replace("[simulation]", "[simulation"), r"malformed TOML"),
        (lambda t: t.replace("/mjcf/bwr.xml", "/mjcf/missing.xml"), r"'machine.mjcf' names a file that does not exist"),
        (lambda t: t.replace("output_gain = [0.01, 0.04, 0.06]", "output_gain = [1e12, 1e12, 1e12]"), r"the simulation diverged \(MuJoCo: bad controls, near t = 0.0\d s\)"),
    ],
    ids=["unreachable", "envelope", "times", "unknown-key", "type", "toml", "mjcf", "divergence"],
)
def test_bad_input_exits_with_one_line_and_writes_nothing(tmp_path, edit, message):
    import re

    out = tmp_path / "out"
    proc = run_cli(write_short_scene(tmp_path, edit=edit), "--out", out)
    assert proc.returncode == 2
    assert "Traceback" not in proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, lines
    assert lines[0].startswith("error: ") and "short.toml" in lines[0], lines[0]
    assert re.search(message, lines[0]), lines[0]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["short.toml"]


def test_a_negative_seed_exits_2_naming_the_key(tmp_path):
    proc = run_cli(write_short_scene(tmp_path), "--out", tmp_path / "out", "--seed", "-1")
    assert proc.returncode == 2 and "Traceback" not in proc.stderr
    assert proc.stderr.strip().endswith("'simulation.seed' must be >= 0, got -1")
    assert not (tmp_path / "out").exists()


def test_missing_scene_file_exits_2(tmp_path):
    proc = run_cli(tmp_path / "nope.toml", "--out", tmp_path / "out")
    assert proc.returncode == 2 and "nope.toml: scene file not found" in proc.stderr


def test_a_bench_reclaim_prints_its_plan_line_and_writes_its_waypoints(tmp_path):
    """The small bench scene of test_reclaim_plan run from the command line: the plan line says
    how the plan was carried out, metrics.json keeps where each segment began, and a replay of
    the run directory names them and jumps to the bench."""
    from test_reclaim_plan import RECLAIM, scene_file

    from bwr_twin.replay import Recording

    out = tmp_path / "bench"
    proc = run_cli(scene_file(tmp_path), "--out", out)
    assert proc.returncode == 0, proc.stderr
    (plan_line,) = [line for line in proc.stdout.splitlines() if "landing error" in line]
    assert plan_line.startswith(("steady cutting ", "no steady cutting ")), plan_line
    metrics = json.loads((out / "metrics.json").read_text())
    reclaim, run = metrics["reclaim"], metrics["run"]
    assert reclaim["target_rate_tph"] == RECLAIM["target_rate"]
    assert f"; landing error {reclaim['landing_error_m']:.3f} m;" in plan_line
    (bench,) = reclaim["bench_t"]  # stop: one bench
    assert bench > 0
    names = run["waypoint_names"]
    assert len(run["waypoint_times"]) == len(run["waypoints"]) == len(names)
    assert names[0] == "bench 1" and names[-1] == "end" and {"pass 1", "pass 2", "pass 3"} <= set(names)
    stages = run["waypoint_stages"]  # the same, typed: what the replay reads
    assert stages[0] == {"kind": "bench", "number": 1} and stages[-1] == {"kind": "end", "number": None}
    assert [s["kind"] for s in stages].count("bench") == 1 and {"pass", "move"} <= {s["kind"] for s in stages}
    assert (out / "reclaim.png").stat().st_size > 10_000

    recording = Recording.from_run_dir(out)
    assert recording.plan.names == names
    np.testing.assert_array_equal(recording.plan.via_times, run["waypoint_times"])
    assert [name for name, _ in recording.plan.landmarks] == ["bench 1"]


def test_a_refused_bench_plan_exits_with_one_line_and_writes_nothing(tmp_path):
    """A bench higher than 0.6 x the wheel's diameter is refused as it is planned, before the
    simulation, naming the key."""
    from test_reclaim_plan import scene_file

    proc = run_cli(scene_file(tmp_path, {"bench_height": 6.5}), "--out", tmp_path / "out")
    assert proc.returncode == 2 and "Traceback" not in proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, lines
    assert lines[0].startswith("error: ") and "small.toml" in lines[0], lines[0]
    assert "'bench_height' 6.5 m is more than 0.6 x the wheel's 10 m diameter" in lines[0], lines[0]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["small.toml"]


@pytest.mark.parametrize("command", ["run", "batch", "compare", "tune", "replay", "fis", "gym_help"])
def test_every_command_explains_itself(command):
    if command == "gym_help":  # the examples' command lines
        args = [str(ROOT / "examples" / "gym_pd.py"), "--help"]
    else:
        args = ["-m", f"bwr_twin.{command}", "--help"]
    proc = subprocess.run([sys.executable, *args], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.startswith("usage: ") and "Traceback" not in proc.stderr


def test_the_summary_names_each_cv_and_gives_the_steady_share_as_a_fraction():
    """The reclaim lines `run` prints, from heavy_bench_reclaim's metrics (seed 1): each CV says
    whose rate it is and that it is std/mean, `steady_within_10pct` (0-1, whatever its name) is a
    fraction of the steady cutting time, every other number has its unit, and a null
    `steady_rate_cv` (a steady rate of mean zero) is printed as n/a."""
    from bwr_twin.results.summary import summary_table

    axis = {"position_error_max": 0.064, "position_error_max_time": 1034.1, "velocity_error_max": 0.019,
            "velocity_error_max_time": 173.2, "acceleration_error_max": 0.052, "acceleration_error_max_time": 527.3,
            "position_error_rms": 0.0147}
    reclaim = {"mass_t": 795.2, "volume_m3": 331.3, "rate_mean_tph": 5184.0, "rate_cv": 0.5703, "spill_t": 0.0,
               "rate_max_tph": 9001.0, "carrying_time_s": 552.24, "digging_force_max_N": 184_633.0,
               "target_rate_tph": 8000.0, "steady_time_s": 133.24, "steady_rate_mean_tph": 7929.0,
               "steady_rate_cv": 0.05639, "steady_within_10pct": 0.9402, "landing_error_m": 0.04879,
               "overcut_max_m": 0.4592, "bench_t": [795.2], "bench_planned_t": [772.2]}
    metrics = {**dict.fromkeys(AXES, axis), "cp_error_max": 0.2945, "cp_error_max_time": 1035.4, "reclaim": reclaim}

    lines = summary_table(metrics).splitlines()
    assert lines[-2] == ("reclaimed 795.2 t (331.3 m³): mean 5184 t/h over 552 s of carrying, peak 9001 t/h, "
                         "reclaim rate CV while carrying (std/mean) 0.57; spilled 0.0 t; digging load up to 185 kN")
    assert lines[-1] == ("steady cutting 133 s at a mean 7929 t/h (0.9 % below the 8000 t/h target), "
                         "steady reclaim rate CV (std/mean) 0.056, within ±10 % of the target for 0.94 of the "
                         "steady cutting time (94 %); landing error 0.049 m; over-cut up to 0.46 m; "
                         "bench tonnes 795 t (planned 772 t)")
    text = "\n".join(lines)  # no CV but these two, each named
    named = ("reclaim rate CV while carrying (std/mean)", "steady reclaim rate CV (std/mean)")
    assert text.count("CV") == 2 and all(text.count(label) == 1 for label in named)

    stalled = {**reclaim, "steady_rate_mean_tph": 0.0, "steady_rate_cv": None, "steady_within_10pct": 0.0}
    plan = summary_table({**metrics, "reclaim": stalled}).splitlines()[-1]
    assert plan.startswith("steady cutting 133 s at a mean 0 t/h (100.0 % below the 8000 t/h target), "
                           "steady reclaim rate CV (std/mean) n/a, within ±10 % of the target for 0.00 of the "
                           "steady cutting time (0 %);"), plan
