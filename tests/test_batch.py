"""`python -m bwr_twin.batch`: sweep files expand as documented, every run leaves what
`bwr_twin.run` leaves, a batch survives kill -9 and Ctrl-C, failures are recorded, two batches
never share a directory, a Dask cluster gives the local pool's results, and the paper's two
controllers reproduce Fig. 10 and Fig. 13 on every seed."""

import csv
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from conftest import HEAVY_MJCF, PAPER_MJCF, ROOT, SHORT_VIA_POINTS, VARIANT_MJCF, write_short_scene

from bwr_twin.batch import BatchLock
from bwr_twin.config.sweep import load_sweep
from bwr_twin.errors import SceneError
from bwr_twin.model.machine import AXES
from bwr_twin.ownership import MARKER_FILE
from bwr_twin.results.run_files import read_scene

# Ends at the paper's p_int2 (Sec. 4): the paper's machine reaches it, the test variant does not.
FAR_VIA_POINTS = [*SHORT_VIA_POINTS, {"t": 40.0, "p": [-55.0, -11.0, 2.0]}]
SHORT_SWEEP = """scene = "short.toml"
seeds = 2
[vary]
controller.output_gain.travel = [0.01, 0.02]
"""
BASE = 'scene = "short.toml"\n'  # sweep file texts, next to short.toml
VARY = BASE + "[vary]\n"
TIMESTEP = VARY + "simulation.timestep = "
RUN_FILES = {".bwr_twin", "metrics.json", "timeseries.csv", "scene.json", "positions.png", "velocities.png",
             "accelerations.png", "fuzzy_outputs.png", "errors_position.png", "errors_velocity.png",
             "errors_acceleration.png", "drive_forces.png", "cp_path.png"}


def write_sweep(folder, text, via_points=SHORT_VIA_POINTS):
    write_short_scene(folder, via_points)
    (folder / "sweep.toml").write_text(text)
    return folder / "sweep.toml"


def batch_cli(*args, **popen):
    command = [sys.executable, "-m", "bwr_twin.batch", *map(str, args)]
    if popen:
        return subprocess.Popen(command, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                **popen)
    return subprocess.run(command, cwd=ROOT, capture_output=True, text=True, check=False)


def run_dirs(out):
    return sorted(p.name for p in out.iterdir() if p.is_dir() and p.name[0].isdigit()) if out.is_dir() else []


def debris(out):
    return [p.name for p in [*out.iterdir(), *out.glob("plots/*")] if p.name.startswith(".") and p.name != MARKER_FILE]


def summary_rows(out):
    with open(out / "summary.csv", newline="") as f:
        return list(csv.DictReader(f))


def same_results(a, b):
    """Identical run directories (names, files, metrics and time series bytes) and summaries."""
    assert run_dirs(a) == run_dirs(b)
    for name in run_dirs(a):
        for file in ("metrics.json", "timeseries.csv", "scene.json"):
            assert (a / name / file).read_bytes() == (b / name / file).read_bytes(), (name, file)
    assert (a / "summary.csv").read_bytes() == (b / "summary.csv").read_bytes()


@pytest.fixture(scope="module")
def short_batch(tmp_path_factory):
    """An uninterrupted batch of the short sweep (2 gains x 2 seeds, 20 s each): the reference."""
    folder = tmp_path_factory.mktemp("short")
    sweep = write_sweep(folder, SHORT_SWEEP)
    out = folder / "reference"
    proc = batch_cli(sweep, "--out", out, "--workers", 2, "--plots")  # two locksteps of two runs
    assert proc.returncode == 0, proc.stderr
    return sweep, out, proc


# --- the sweep file ------------------------------------------------------------------------------


def test_sweep_is_the_cartesian_product_with_seeds_innermost(tmp_path):
    mjcf = os.path.relpath(PAPER_MJCF, tmp_path)  # paths in a sweep are relative to the sweep file
    sweep = load_sweep(write_sweep(tmp_path, f"""scene = "short.toml"
seeds = [3, 5]
[vary]
controller.output_gain.slew = {{ start = 0.02, stop = 0.06, num = 3 }}
"controller.output_gain.luff" = [0.05]
disturbance.hold_time = {{ start = 0.01, stop = 0.03, step = 0.01 }}
machine.mjcf = ["{mjcf}"]
"""))
    assert sweep.keys == (
        "controller.output_gain.slew", "controller.output_gain.luff", "disturbance.hold_time", "machine.mjcf")
    assert len(sweep.runs) == 3 * 1 * 3 * 1 * 2
    first, second = sweep.runs[0].run_id, sweep.runs[1].run_id
    assert first == "0000-output_gain.slew=0.02-output_gain.luff=0.05-hold_time=0.01-mjcf=bwr-seed=3"
    assert second == "0001-output_gain.slew=0.02-output_gain.luff=0.05-hold_time=0.01-mjcf=bwr-seed=5"
    hold_times = [run.scene.disturbance.hold_time for run in sweep.runs[:6:2]]
    assert hold_times == [0.01, 0.02, 0.03]  # a step range keeps a stop on its grid
    last = sweep.runs[-1].scene
    assert last.controller.settings.output_gain == (0.01, 0.06, 0.05)  # one axis varied, the others the base's
    assert last.simulation.seed == 5 and last.machine.mjcf == PAPER_MJCF
    assert len({run.run_id for run in sweep.runs}) == len(sweep.runs)
    assert load_sweep(tmp_path / "sweep.toml").runs == sweep.runs  # names are stable: resume relies on it


@pytest.mark.parametrize(
    "text, message",
    [
        (BASE + "colour = 1", r"unknown key 'colour' \(valid here: scene, seeds, vary\)"),
        ("seeds = 2", r"missing key 'scene'"),
        ('scene = "missing.toml"', r"'scene' names a file that does not exist"),
        (BASE + "seeds = 0", r"'seeds' must be a count"),
        (BASE + "seeds = [1, 1]", r"'seeds' lists 1 twice"),
        (TIMESTEP + "[]", r"'vary.simulation.timestep' is an empty list"),
        (TIMESTEP + "0.01", r"'vary.simulation.timestep' must be a list of values or a range"),
        (TIMESTEP + "{ start = 0.1, stop = 0.2 }", r"range '.*' needs exactly one of 'num' and 'step'"),
        (TIMESTEP + "{ start = 0.1, stop = 0.2, step = -1 }", r"'vary.simulation.timestep.step' must be a number > 0"),
        (TIMESTEP + "{ start = 0.1, stop = 0.2, num = 2, by = 1 }", r"unknown key 'vary.simulation.timestep.by'"),
        (VARY + "simulation.seed = [1, 2]", r"give the seeds as the top-level 'seeds'"),
        (VARY + '"controller.output_gain" = [[1.0, 1.0, 1.0]]\ncontroller.output_gain.travel = [0.1]',
         r"both 'controller.output_gain' and its axis"),
        (VARY + "simulation.colour = [1, 2]", r"short.toml: unknown key 'simulation.colour'"),
        (VARY + 'machine.mjcf = ["nowhere.xml"]', r"'machine.mjcf' names a file that does not exist"),
        (VARY + 'controller.output_gain.travel = ["a"]', r"'controller.output_gain\[0\]' must be a finite number"),
    ],
    ids=["unknown-key", "no-scene", "scene-missing", "seeds-zero", "seeds-twice", "empty-list", "not-a-list",
         "range-no-num", "range-step", "range-key", "seed-in-vary", "vector-and-axis", "scene-key", "mjcf",
         "type"],
)
def test_bad_sweep_files_are_refused_naming_file_and_key(tmp_path, text, message):
    with pytest.raises(SceneError, match=message) as caught:
        load_sweep(write_sweep(tmp_path, text))
    assert str(caught.value).startswith(f"{tmp_path / 'sweep.toml'}: ")


def test_bad_sweep_exits_2_with_one_line_and_writes_nothing(tmp_path):
    proc = batch_cli(write_sweep(tmp_path, BASE + "seeds = -1"), "--out", tmp_path / "out")
    assert proc.returncode == 2
    assert proc.stderr.startswith("error: ") and len(proc.stderr.strip().splitlines()) == 1, proc.stderr
    assert not (tmp_path / "out").exists()


# --- results, resume, interruption ---------------------------------------------------------------


def test_each_run_writes_what_bwr_twin_run_writes(short_batch, tmp_path):
    sweep, out, proc = short_batch
    assert "4 runs, 4 ok, 0 failed" in proc.stdout
    assert run_dirs(out) == ["0000-output_gain.travel=0.01-seed=1", "0001-output_gain.travel=0.01-seed=2",
                             "0002-output_gain.travel=0.02-seed=1", "0003-output_gain.travel=0.02-seed=2"]
    single = tmp_path / "single"
    command = [sys.executable, "-m", "bwr_twin.run", sweep.parent / "short.toml", "--out", single, "--seed", 2]
    run = subprocess.run(list(map(str, command)), cwd=ROOT, capture_output=True, text=True, check=False)
    assert run.returncode == 0, run.stderr
    batch_run = out / "0001-output_gain.travel=0.01-seed=2"  # the base scene's own gains
    assert {p.name for p in batch_run.iterdir()} == {p.name for p in single.iterdir()} == RUN_FILES
    for file in ("metrics.json", "timeseries.csv", "scene.json"):
        assert (batch_run / file).read_bytes() == (single / file).read_bytes(), file


def test_summary_has_one_row_per_run_in_sweep_order_and_plots(short_batch):
    _, out, _ = short_batch
    rows = summary_rows(out)
    assert [row["run"] for row in rows] == run_dirs(out)
    varied = [(row["controller.output_gain.travel"], row["seed"]) for row in rows]
    assert varied == [("0.01", "1"), ("0.01", "2"), ("0.02", "1"), ("0.02", "2")]
    for row in rows:
        assert row["status"] == "ok" and row["error"] == ""
        metrics = json.loads((out / row["run"] / "metrics.json").read_text())
        for axis in AXES:
            assert float(row[f"{axis}.position_error_max"]) == metrics[axis]["position_error_max"]
    assert (out / "plots" / "error_distributions.png").stat().st_size > 20_000
    assert not debris(out)


def test_the_spread_of_the_errors_is_printed_in_engineering_units(short_batch):
    _, out, proc = short_batch
    travel = sorted(abs(float(row["travel.position_error_max"])) for row in summary_rows(out))
    line = next(line for line in proc.stdout.splitlines() if line.split()[:2] == ["travel", "position"])
    smallest, median, largest = (float(part) for part in line.split()[2:7:2])
    assert (smallest, largest) == pytest.approx((travel[0], travel[-1]), rel=1e-3)
    assert median == pytest.approx((travel[1] + travel[2]) / 2, rel=1e-3)
    assert line.endswith(" m")
    slew = next(line for line in proc.stdout.splitlines() if line.split()[:2] == ["slew", "velocity"])
    assert slew.endswith(" deg/s")


def test_rerun_skips_what_is_complete(short_batch):
    sweep, out, _ = short_batch
    before = {name: (out / name / "metrics.json").stat().st_mtime_ns for name in run_dirs(out)}
    proc = batch_cli(sweep, "--out", out)
    assert proc.returncode == 0, proc.stderr
    assert "(4 already done, skipped)" in proc.stdout
    assert {name: (out / name / "metrics.json").stat().st_mtime_ns for name in run_dirs(out)} == before


def start_and_wait_for_first_run(sweep, out):
    """A batch of one-run locksteps (not the reference's two-run ones), stopped after its first."""
    proc = batch_cli(sweep, "--out", out, "--workers", 2, "--chunk", 1, "--plots", start_new_session=True)
    deadline = time.monotonic() + 120
    while not run_dirs(out):
        assert proc.poll() is None and time.monotonic() < deadline, proc.communicate()
        time.sleep(0.05)
    return proc


def test_kill_9_then_rerun_gives_the_uninterrupted_result(short_batch, tmp_path):
    sweep, reference, _ = short_batch
    out = tmp_path / "killed"
    proc = start_and_wait_for_first_run(sweep, out)
    os.killpg(proc.pid, signal.SIGKILL)  # the batch and its workers, mid-run
    proc.wait()
    survivors = run_dirs(out)
    assert 0 < len(survivors) < 4
    for name in survivors:  # what is there is complete
        assert {p.name for p in (out / name).iterdir()} == RUN_FILES
    assert len(summary_rows(out)) == 4  # the summary is whole, if not up to date
    assert (out / ".lock").exists()  # a dead batch's lock file: no longer locked
    rerun = batch_cli(sweep, "--out", out, "--plots")
    assert rerun.returncode == 0, rerun.stderr
    assert f"({len(survivors)} already done, skipped)" in rerun.stdout
    same_results(out, reference)
    assert not debris(out)


def test_a_damaged_run_is_run_again_and_said_so(short_batch, tmp_path):
    sweep, reference, _ = short_batch
    out = tmp_path / "damaged"
    shutil.copytree(reference, out)
    for name in run_dirs(out):  # the reference was run with --plots; this re-run writes none
        for figure in (out / name).glob("*.png"):
            figure.unlink()
    first, second = run_dirs(out)[:2]
    (out / first / "metrics.json").write_text('{"travel": ')  # cut short
    (out / second / "metrics.json").unlink()
    proc = batch_cli(sweep, "--out", out)
    assert proc.returncode == 0, proc.stderr
    assert "note: 2 run directories" in proc.stderr and "running them again" in proc.stderr
    assert "(2 already done, skipped)" in proc.stdout and "Traceback" not in proc.stderr
    same_results(out, reference)
    assert not debris(out)


def session_processes(session):
    """Live processes of a session (zombies aside), as {pid: command line}."""
    found = {}
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
            cmdline = (stat.parent / "cmdline").read_bytes().replace(b"\0", b" ").decode().strip()
        except (OSError, IndexError):
            continue
        if int(fields[3]) == session and fields[0] != "Z":  # fields after the name: state, ppid, pgrp, session
            found[int(stat.parent.name)] = cmdline
    return found


def test_kill_9_of_the_batch_leaves_no_worker_running(short_batch, tmp_path):
    sweep, _, _ = short_batch
    proc = batch_cli(sweep, "--out", tmp_path / "out", "--workers", 2, start_new_session=True)
    deadline = time.monotonic() + 60
    while len(session_processes(proc.pid)) < 3:  # the batch and its two workers
        assert proc.poll() is None and time.monotonic() < deadline, proc.communicate()
        time.sleep(0.05)
    os.kill(proc.pid, signal.SIGKILL)  # the batch alone, as an out-of-memory killer would
    proc.wait()
    deadline = time.monotonic() + 10
    while session_processes(proc.pid) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert session_processes(proc.pid) == {}


def test_ctrl_c_stops_promptly_and_keeps_only_complete_runs(short_batch, tmp_path):
    sweep, _, _ = short_batch
    out = tmp_path / "interrupted"
    proc = start_and_wait_for_first_run(sweep, out)
    interrupted = time.monotonic()
    os.killpg(proc.pid, signal.SIGINT)  # what a terminal sends to the whole foreground group
    _, stderr = proc.communicate(timeout=30)
    assert time.monotonic() - interrupted < 10
    assert proc.returncode == 130
    assert stderr.strip().splitlines()[-1].startswith("interrupted: ") and "Traceback" not in stderr
    assert 0 < len(run_dirs(out)) < 4 and not debris(out)
    done = {row["run"]: row["status"] for row in summary_rows(out)}
    assert {name for name, status in done.items() if status == "ok"} == set(run_dirs(out))
    assert set(done.values()) == {"ok", "pending"}


def test_a_failed_run_is_recorded_and_the_others_go_on(tmp_path):
    sweep = write_sweep(tmp_path, VARY + f'machine.mjcf = ["{PAPER_MJCF}", "{VARIANT_MJCF}"]\n', FAR_VIA_POINTS)
    out = tmp_path / "out"
    proc = batch_cli(sweep, "--out", out, "--no-plots")
    assert proc.returncode == 1, proc.stderr
    assert "2 runs, 1 ok, 1 failed" in proc.stdout
    ok, failed = summary_rows(out)
    assert ok["status"] == "ok" and ok["error"] == "" and ok["travel.position_error_max"]
    assert failed["status"] == "failed" and failed["travel.position_error_max"] == ""
    assert re.search(r"via point 3 \(t = 40 s\) .* exceeds the horizontal reach", failed["error"])
    assert {p.name for p in (out / failed["run"]).iterdir()} == {".bwr_twin", "error.txt", "scene.json"}
    assert failed["error"] in proc.stderr

    again = batch_cli(sweep, "--out", out, "--no-plots")  # deterministic: a failure is a result
    assert again.returncode == 1 and "(2 already done, skipped)" in again.stdout
    retried = batch_cli(sweep, "--out", out, "--no-plots", "--retry-failed")
    assert retried.returncode == 1 and "(1 already done, skipped)" in retried.stdout
    assert not debris(out)


def test_a_run_that_diverges_fails_alone_in_its_lockstep(tmp_path):
    sweep = write_sweep(tmp_path, VARY + "controller.output_gain.travel = [0.01, 1e12, 0.02]\n")
    out = tmp_path / "out"
    proc = batch_cli(sweep, "--out", out, "--workers", 1)  # one lockstep of three runs
    assert proc.returncode == 1, proc.stderr
    first, diverged, third = summary_rows(out)
    assert first["status"] == third["status"] == "ok"
    assert diverged["status"] == "failed" and "the simulation diverged" in diverged["error"]
    assert {p.name for p in (out / diverged["run"]).iterdir()} == {".bwr_twin", "error.txt", "scene.json"}
    alone = tmp_path / "alone"
    command = [sys.executable, "-m", "bwr_twin.run", sweep.parent / "short.toml", "--out", alone, "--no-plots"]
    assert subprocess.run(list(map(str, command)), cwd=ROOT, capture_output=True, check=False).returncode == 0
    assert (out / first["run"] / "metrics.json").read_bytes() == (alone / "metrics.json").read_bytes()


def test_the_heavy_machine_runs_in_a_batch_by_swapping_the_mjcf(tmp_path):
    heavy = HEAVY_MJCF
    sweep = write_sweep(tmp_path, VARY + f'machine.mjcf = ["{PAPER_MJCF}", "{heavy}"]\n')
    out = tmp_path / "out"
    proc = batch_cli(sweep, "--out", out, "--no-plots")
    assert proc.returncode == 0, proc.stderr
    paper, heavy_run = summary_rows(out)
    assert heavy_run["run"].endswith("mjcf=bwr_heavy-seed=1")
    assert read_scene(out / heavy_run["run"] / "scene.json").mjcf == heavy
    # 1,200 t against 7 t: the drives work far harder for the same path.
    assert float(heavy_run["travel.drive_force_rms"]) > 50 * float(paper["travel.drive_force_rms"])


def test_a_changed_scene_is_not_mixed_with_earlier_runs(tmp_path):
    sweep = write_sweep(tmp_path, BASE)
    out = tmp_path / "out"
    assert batch_cli(sweep, "--out", out, "--no-plots").returncode == 0
    scene = tmp_path / "short.toml"
    scene.write_text(scene.read_text().replace("amplitude = [100.0,", "amplitude = [50.0,"))
    proc = batch_cli(sweep, "--out", out, "--no-plots")
    assert proc.returncode == 2
    assert re.search(r"was run with other settings \(disturbance.amplitude\) than this sweep", proc.stderr)


def test_a_second_batch_on_the_same_directory_is_refused(tmp_path):
    sweep = write_sweep(tmp_path, BASE)
    out = tmp_path / "out"
    with BatchLock(out):
        proc = batch_cli(sweep, "--out", out)
    assert proc.returncode == 2
    assert proc.stderr.strip() == f"error: {out} is in use by another batch (pid {os.getpid()})"
    assert run_dirs(out) == [] and not debris(out)


# --- Dask -----------------------------------------------------------------------------------------


def test_a_dask_cluster_gives_the_local_pools_results(short_batch, tmp_path):
    from distributed import LocalCluster

    sweep, reference, _ = short_batch
    out = tmp_path / "dask"
    loopback = {"host": "127.0.0.1", "dashboard_address": None}
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, **loopback) as cluster:
        proc = batch_cli(sweep, "--out", out, "--scheduler", cluster.scheduler_address, "--no-plots")
    assert proc.returncode == 0, proc.stderr
    same_results(out, reference)


def test_an_unreachable_scheduler_exits_2(tmp_path):
    sweep = write_sweep(tmp_path, BASE)
    proc = batch_cli(sweep, "--out", tmp_path / "out", "--scheduler", "tcp://127.0.0.1:9")
    assert proc.returncode == 2
    assert proc.stderr.startswith("error: cannot reach the Dask scheduler at tcp://127.0.0.1:9"), proc.stderr


# --- the paper, on every seed ---------------------------------------------------------------------


@pytest.mark.slow
def test_ci_sweep_reproduces_the_paper_on_every_seed(tmp_path):
    out = tmp_path / "ci"
    proc = batch_cli("sweeps/ci_reproduction", "--out", out)
    assert proc.returncode == 0, proc.stderr
    rows = summary_rows(out)
    assert len(rows) == 8 and {row["status"] for row in rows} == {"ok"}
    for row in rows:
        gains = json.loads(row["controller.output_gain"])
        if gains == [0.001, 0.001, 0.001]:  # Fig. 10: about -4 m on travel near t = 340 s
            assert 3.0 <= abs(float(row["travel.position_error_max"])) <= 6.0, row["run"]
            assert 300.0 <= float(row["travel.position_error_max_time"]) <= 370.0, row["run"]
        else:  # Fig. 13: about 0.02 m and 0.01 m/s
            assert gains == [0.01, 0.04, 0.06]
            assert abs(float(row["travel.position_error_max"])) <= 0.03, row["run"]
            for axis in AXES:
                assert abs(float(row[f"{axis}.velocity_error_max"])) <= 0.015, (row["run"], axis)
