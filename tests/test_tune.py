"""CMA-ES tuning: a tiny budget end to end, kill -9 and resume to the uninterrupted result, a
diverging candidate ranked infeasible, and the one-line errors of bad tuning files."""

import csv
import os
import pickle
import re
import signal
import subprocess
import sys
import time

import pytest
from conftest import ROOT, write_short_scene

TINY = """scene = "short.toml"
[parameters]
"controller.output_gain.travel" = {{ low = 0.002, high = {high}, scale = "log" }}
"controller.input_scale_e" = {{ low = 10.0, high = 200.0 }}
[seeds]
training = [1]
held_out = [11]
[objective]
position_error_rms = 1.0
position_error_max = 0.5
[budget]
evaluations = {evaluations}
[optimizer]
population = 4
seed = 3
sigma0 = {sigma0}
"""


def write_tuning(folder, *, evaluations=13, high=0.2, sigma0=0.25):
    write_short_scene(folder)
    (folder / "tune.toml").write_text(TINY.format(evaluations=evaluations, high=high, sigma0=sigma0))
    return folder / "tune.toml"


def tune(*args, cwd, **popen):
    return subprocess.run([sys.executable, "-m", "bwr_twin.tune", *map(str, args)], cwd=cwd,
                          capture_output=True, text=True, timeout=900, **popen)


def history(out):
    return list(csv.DictReader((out / "history.csv").open()))


def test_a_tiny_tuning_improves_on_the_start_and_its_best_scene_runs_as_it_is(tmp_path):
    write_tuning(tmp_path)
    proc = tune("tune.toml", "--out", "out", "--workers", "2", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    out = tmp_path / "out"
    rows = history(out)
    assert len(rows) == 13 and rows[0]["generation"] == "0" and rows[0]["objective"] == "1.5"  # 1 + 0.5
    best = min(float(r["objective"]) for r in rows if r["feasible"] == "True")
    assert best < 1.5
    text = (out / "best_scene.toml").read_text()
    assert text.startswith("# Found by python -m bwr_twin.tune tune.toml") and "13 evaluations" in text
    run = subprocess.run([sys.executable, "-m", "bwr_twin.run", out / "best_scene.toml", "--out", tmp_path / "check",
                          "--no-plots"], capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, run.stderr
    held_out = list(csv.DictReader((out / "held_out.csv").open()))
    travel = next(r for r in held_out if r["axis"] == "travel" and r["metric"] == "position_error_rms")
    assert float(travel["tuned"]) < float(travel["start"])
    assert "Held-out seeds [11]" in (out / "held_out.md").read_text()
    assert (out / "convergence.png").stat().st_size > 10_000


def _session_processes(session: int) -> list[int]:
    found = []
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                if os.getsid(int(entry)) == session:
                    found.append(int(entry))
            except ProcessLookupError:
                pass
    return found


def test_killed_and_rerun_it_ends_where_an_uninterrupted_tuning_ends(tmp_path):
    write_tuning(tmp_path, evaluations=41)  # 10 generations: killed after the first, long before the end
    whole = tune("tune.toml", "--out", "whole", "--workers", "2", cwd=tmp_path)
    assert whole.returncode == 0, whole.stderr
    killed = subprocess.Popen([sys.executable, "-m", "bwr_twin.tune", "tune.toml", "--out", "killed", "--workers", "2"],
                              cwd=tmp_path, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                              start_new_session=True)
    state = tmp_path / "killed" / "tuner_state.pkl"
    deadline = time.monotonic() + 300
    while time.monotonic() < deadline:  # until the first generation after the start is saved
        try:
            if pickle.loads(state.read_bytes()).generation >= 1:
                break
        except (FileNotFoundError, EOFError, pickle.UnpicklingError):
            pass
        time.sleep(0.05)
    assert killed.poll() is None, "the tuning ended before it could be killed"
    os.killpg(killed.pid, signal.SIGKILL)
    killed.wait()
    time.sleep(2.0)  # workers notice their parent is gone within half a second
    assert _session_processes(killed.pid) == []
    assert not (tmp_path / "killed" / "best_scene.toml").exists()
    resumed = tune("tune.toml", "--out", "killed", "--workers", "2", cwd=tmp_path)
    assert resumed.returncode == 0, resumed.stderr
    for name in ("history.csv", "best_scene.toml", "held_out.csv"):
        assert (tmp_path / "killed" / name).read_bytes() == (tmp_path / "whole" / name).read_bytes(), name
    assert not [p for p in (tmp_path / "killed").iterdir() if ".partial-" in p.name]


def test_a_diverging_candidate_is_infeasible_not_a_crash(tmp_path):
    write_tuning(tmp_path, evaluations=9, high=1e12, sigma0=1.0)  # travel output gains up to 1e12 blow up
    proc = tune("tune.toml", "--out", "out", "--workers", "2", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    rows = history(tmp_path / "out")
    reasons = {r["infeasible_because"] for r in rows if r["feasible"] == "False"}
    assert reasons & {"a run diverged"} or any("envelope" in r or "end stop" in r for r in reasons), reasons


def test_another_tuning_file_does_not_resume_a_directory(tmp_path):
    write_tuning(tmp_path, evaluations=5)
    assert tune("tune.toml", "--out", "out", "--workers", "1", cwd=tmp_path).returncode == 0
    (tmp_path / "tune.toml").write_text((tmp_path / "tune.toml").read_text().replace("seed = 3", "seed = 4"))
    before = {p.name: p.read_bytes() for p in (tmp_path / "out").iterdir()}
    proc = tune("tune.toml", "--out", "out", cwd=tmp_path)
    assert proc.returncode == 2 and "holds a tuning by another tuning file" in proc.stderr
    assert {p.name: p.read_bytes() for p in (tmp_path / "out").iterdir()} == before


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (('"controller.input_scale_e" = { low = 10.0, high = 200.0 }', '"controller.input_scale_e" = { low = 60.0, high = 200.0 }'),
         r"'parameters.controller.input_scale_e' starts at the base scene's 50, outside \[60, 200\]"),
        (('scale = "log"', 'scale = "cubic"'), r"'parameters.controller.output_gain.travel.scale' must be \"linear\" or \"log\""),
        (("held_out = [11]", "held_out = [1]"), r"'seeds.held_out' shares seeds with 'seeds.training' \(\[1\]\)"),
        (("position_error_rms = 1.0", "position_eror_rms = 1.0"), r"'objective.position_eror_rms' is not known"),
        (("evaluations = 13", "evaluations = 0"), r"'budget.evaluations' must be an integer >= 1, got 0"),
        (('"controller.input_scale_e"', '"encoders.velocity_source"'),
         r"'parameters.encoders.velocity_source' is not a number \('true'\) in the base scene"),
        (("population = 4", "population = nan"), r"'optimizer.population' must be an integer >= 2, got nan"),
    ],
    ids=["start-outside-bounds", "unknown-scale", "held-out-seen", "unknown-metric", "no-budget", "not-a-number",
         "nan"],
)
def test_bad_tuning_files_get_one_line_and_leave_nothing(tmp_path, edit, message):
    path = write_tuning(tmp_path)
    path.write_text(path.read_text().replace(*edit))
    proc = tune("tune.toml", "--out", "out", cwd=tmp_path)
    assert proc.returncode == 2 and "Traceback" not in proc.stderr, proc.stderr
    (line,) = proc.stderr.strip().splitlines()
    assert line.startswith("error: ") and "tune.toml" in line and re.search(message, line), line
    assert sorted(p.name for p in tmp_path.iterdir()) == ["short.toml", "tune.toml"]


def test_the_shipped_tuning_files_load(tmp_path):
    from bwr_twin.config.tuning import load_tuning

    for name in ("paper_gains", "heavy_wind"):
        tuning = load_tuning(ROOT / "scenes" / "tuning" / f"{name}.toml")
        assert len(tuning.parameters) == 5 and not set(tuning.training_seeds) & set(tuning.held_out_seeds)


def test_a_dask_cluster_tunes_exactly_as_the_local_pool(tmp_path):
    from distributed import LocalCluster

    write_tuning(tmp_path, evaluations=9)
    local = tune("tune.toml", "--out", "local", "--workers", "2", cwd=tmp_path)
    assert local.returncode == 0, local.stderr
    loopback = {"host": "127.0.0.1", "dashboard_address": None}
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, **loopback) as cluster:
        remote = tune("tune.toml", "--out", "dask", "--scheduler", cluster.scheduler_address, cwd=tmp_path)
    assert remote.returncode == 0, remote.stderr
    for name in ("history.csv", "held_out.csv"):
        assert (tmp_path / "dask" / name).read_bytes() == (tmp_path / "local" / name).read_bytes(), name
