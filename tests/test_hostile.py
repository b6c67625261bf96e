"""Hostile input through the command lines: every case is refused with one line naming the file,
key or path and the limit, a non-zero exit, no traceback, and nothing destroyed or left behind.

`REFUSALS` is the catalogue of docs/reliability.md: one entry a case, grouped by its class.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import pytest
from conftest import PAPER_MJCF, ROOT, unrated_paper_mjcf, write_short_scene

from bwr_twin.config.scene import load_scene
from bwr_twin.ownership import mark
from bwr_twin.results.run_files import COLUMNS


def cli(module: str, *args, cwd: Path = ROOT, **popen) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", f"bwr_twin.{module}", *map(str, args)], cwd=cwd,
                          capture_output=True, text=True, timeout=600, **popen)


def snapshot(folder: Path) -> dict[str, str]:
    """Every path under `folder` with its content's hash: what 'nothing changed' compares."""
    found = {}
    for path in sorted(folder.rglob("*")):
        relative = str(path.relative_to(folder))
        found[relative] = "dir" if path.is_dir() else hashlib.sha256(path.read_bytes()).hexdigest()
    return found


def assert_refused(proc: subprocess.CompletedProcess, pattern: str) -> None:
    assert proc.returncode == 2, (proc.returncode, proc.stderr)
    assert "Traceback" not in proc.stderr, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, lines
    assert lines[0].startswith("error: ") and re.search(pattern, lines[0]), lines[0]


def edited(**replacements: str) -> Callable[[str], str]:
    def edit(text: str) -> str:
        for old, new in replacements.items():
            assert old in text, old
            text = text.replace(old, new)
        return text
    return edit


def foreign_folder(tmp: Path) -> Path:
    (tmp / "mine").mkdir()
    (tmp / "mine" / "thesis.txt").write_text("not the twin's")
    return tmp / "mine"


def marked(tmp: Path, name: str, kind: str) -> Path:
    (tmp / name).mkdir()
    mark(tmp / name, kind)
    (tmp / name / "metrics.json").write_text("{}\n")
    return tmp / name


def read_only(tmp: Path) -> Path:
    if os.geteuid() == 0:
        pytest.skip("root writes into read-only folders")
    (tmp / "locked").mkdir()
    (tmp / "locked").chmod(0o555)
    return tmp / "locked" / "out"


# A windrow beside the paper machine's rail, `y` m from it.
_PILE = """[stockpile]
bulk_density = 2400.0
grid_spacing = 0.25

[stockpile.windrow]
length = 20.0
crest_width = 4.0
height = 8.0
angle_of_repose = 37.0
centre = [0.0, {y}]

"""

# (id, command, argument builder(tmp) -> arguments, scene edit, pattern of the one error line)
REFUSALS = [
    # 1. Output paths
    ("run-into-foreign-folder", "run", lambda t: ["short.toml", "--out", foreign_folder(t)], None,
     r"mine: exists and holds files the twin did not write \(no \.bwr_twin marker\)"),
    ("run-overwrite-foreign-folder", "run", lambda t: ["short.toml", "--out", foreign_folder(t), "--overwrite"],
     None, r"mine: exists and holds files the twin did not write"),
    ("run-overwrite-a-file", "run", lambda t: ["short.toml", "--out", t / "short.toml", "--overwrite"], None,
     r"short.toml: is an input of this command"),
    ("run-overwrite-other-file", "run", lambda t: ["short.toml", "--out", t / "notes.txt", "--overwrite"], None,
     r"notes.txt: exists and is not a folder the twin wrote"),
    ("run-out-dot", "run", lambda t: ["short.toml", "--out", ".", "--overwrite"], None,
     r"\.: is the working directory or holds it"),
    ("run-out-parent", "run", lambda t: ["short.toml", "--out", "..", "--overwrite"], None,
     r"\.\.: is the working directory or holds it"),
    ("run-over-own-run-without-overwrite", "run", lambda t: ["short.toml", "--out", marked(t, "r", "run")], None,
     r"r: already exists; choose another --out or pass --overwrite"),
    ("run-over-a-batch", "run", lambda t: ["short.toml", "--out", marked(t, "b", "batch"), "--overwrite"], None,
     r"b: holds the results of a batch, not of a run"),
    ("run-out-holds-the-scene", "run", lambda t: [_moved_into(marked(t, "r", "run")), "--out", t / "r",
                                                   "--overwrite"], None, r"r: is an input of this command"),
    ("run-out-under-a-file", "run", lambda t: ["short.toml", "--out", t / "notes.txt" / "out"], None,
     r"notes.txt: is a file, so --out cannot be made inside it"),
    ("run-out-read-only", "run", lambda t: ["short.toml", "--out", read_only(t)], None,
     r"locked: is not writable \(permission denied\)"),
    ("export-onto-the-scene", "replay", lambda t: ["short.toml", "--export", "short.toml"], None,
     r"short.toml: is an input of this command"),
    ("export-not-html", "replay", lambda t: ["short.toml", "--export", "notes.txt"], None,
     r"notes.txt: --export must name an \.html file"),
    ("export-over-foreign-html", "replay", lambda t: ["short.toml", "--export", _foreign_html(t)], None,
     r"page.html: exists and was not written by the twin"),
    ("export-onto-a-folder", "replay", lambda t: ["short.toml", "--export", _folder(t, "view.html")], None,
     r"view.html: is a folder"),
    ("export-missing-folder", "replay", lambda t: ["short.toml", "--export", t / "nope" / "a.html"], None,
     r"a.html: the folder .*nope does not exist"),
    # 2. Batch results
    ("batch-into-foreign-folder", "batch", lambda t: [_sweep(t), "--out", foreign_folder(t)], None,
     r"mine: exists and holds files the twin did not write"),
    ("batch-into-a-run", "batch", lambda t: [_sweep(t), "--out", marked(t, "r", "run")], None,
     r"r: holds the results of a run, not of a batch"),
    ("batch-into-another-sweeps-results", "batch", lambda t: [_sweep(t), "--out", _other_batch(t)], None,
     r"b: holds the results of another sweep \(other.toml, 7 runs\) than sweep.toml plans"),
    ("batch-out-holds-the-sweep", "batch", lambda t: [_sweep(t), "--out", t], None,
     r"is the working directory or holds it|is an input of this command"),
    ("batch-dask-unreachable", "batch", lambda t: [_sweep(t), "--out", t / "b", "--scheduler", "tcp://127.0.0.1:9"],
     None, r"cannot reach the Dask scheduler at tcp://127.0.0.1:9"),
    # 3. Numbers that are not numbers
    ("nan-amplitude", "run", lambda t: ["short.toml", "--out", t / "o"],
     edited(**{"amplitude = [100.0,": "amplitude = [nan,"}), r"'disturbance.amplitude\[0\]' must be a finite number, got nan"),
    ("inf-control-period", "run", lambda t: ["short.toml", "--out", t / "o"],
     edited(**{"control_period = 0.01": "control_period = inf"}), r"'simulation.control_period' must be a finite number, got inf"),
    ("inf-via-point-time", "run", lambda t: ["short.toml", "--out", t / "o"],
     edited(**{"t = 20.0": "t = inf"}), r"'path.via_points\[1\].t' must be a finite number, got inf"),
    ("inf-frictionloss", "run", lambda t: ["short.toml", "--out", t / "o"],
     edited(**{"[controller]": "[plant]\nfrictionloss = [inf, 0.0, 0.0]\n\n[controller]"}),
     r"'plant.frictionloss\[0\]' must be a finite number, got inf"),
    ("nan-wind-direction", "run", lambda t: ["short.toml", "--out", t / "o"],
     edited(**{"[controller]": "[plant]\nwind_direction = nan\n\n[controller]"}), r"'plant.wind_direction' must be a finite number, got nan"),
    ("negative-seed-option", "run", lambda t: ["short.toml", "--out", t / "o", "--seed", "-1"], None,
     r"'simulation.seed' must be >= 0, got -1"),
    ("record-period-off-grid", "run", lambda t: ["short.toml", "--out", t / "o"],
     edited(**{"record_period = 0.1 ": "record_period = 0.015 "}),
     r"'simulation.record_period' \(0.015 s\) must be a whole multiple of 'simulation.control_period'"),
    ("nan-in-a-sweep", "batch", lambda t: [_sweep(t, "[vary]\ncontroller.output_gain.travel = [0.01, nan]\n"),
                                          "--out", t / "b"], None, r"sweep.toml: .*short.toml: 'controller.output_gain\[0\]' must be a finite number, got nan"),
    # 4. Runaway work
    ("nanosecond-timestep", "run", lambda t: ["short.toml", "--out", t / "o"],
     edited(**{"timestep = 0.002 ": "timestep = 1e-9 "}),
     r"short.toml: would take more than 12 h: 1 run, 2e\+10 physics steps, about [\d.]+ h"),
    ("via-point-in-30-years", "run", lambda t: ["short.toml", "--out", t / "o"],
     edited(**{"t = 20.0": "t = 1e9"}), r"would take more than 12 h and more than 50% of the .* of memory"),
    ("replay-of-a-runaway-scene", "replay", lambda t: ["short.toml", "--export", t / "a.html"],
     edited(**{"t = 20.0": "t = 1e9"}), r"short.toml: would take more than 12 h"),
    ("hundred-thousand-seeds", "batch", lambda t: [_sweep(t, seeds="100000"), "--out", t / "b"], None,
     r"expands to 100000 runs = 100000 \(seeds\), more than 20000; pass --force"),
    ("femto-step-range", "batch", lambda t: [_sweep(t, "[vary]\ncontroller.output_gain.travel = "
                                                      "{ start = 0.001, stop = 0.1, step = 1e-15 }\n"),
                                            "--out", t / "b"], None, r"gives 9.9e\+13 values, more than a sweep"),
    ("hundred-thousand-values", "batch", lambda t: [_sweep(t, "[vary]\ncontroller.output_gain.travel = "
                                                             "{ start = 0.001, stop = 0.1, num = 100000 }\n"),
                                                   "--out", t / "b"], None, r"expands to 100000 runs"),
    ("a-week-of-seeds", "batch", lambda t: [_sweep(t, seeds="1000"), "--out", t / "b"],
     edited(**{"timestep = 0.002 ": "timestep = 1e-7 "}),  # about 100 h on two workers
     r"sweep.toml: would take more than 12 h: 1000 runs, 2e\+11 physics steps, about [\d.]+ (h|days)"),
    # 5. Stockpiles the machine cannot dig
    ("stockpile-on-the-rail", "run", lambda t: ["short.toml", "--out", t / "o"],
     edited(**{"[simulation]": _PILE.format(y=2.0) + "[simulation]"}),
     r"short.toml: \[stockpile\]: the pile comes within 0.12 m of the rail axis; the machine needs 3.00 m clear"),
    ("stockpile-out-of-reach", "run", lambda t: ["short.toml", "--out", t / "o"],
     edited(**{"[simulation]": _PILE.format(y=300.0) + "[simulation]"}),
     r"short.toml: \[stockpile\]: no part of the pile .* is within the wheel's reach: 59.3 m from the slew axis"),
    ("stockpile-survey-missing", "replay", lambda t: ["short.toml", "--export", t / "a.html"],
     edited(**{"[simulation]": "[stockpile]\nbulk_density = 2400.0\nsurface_file = \"nowhere.csv\"\n\n[simulation]"}),
     r"'stockpile.surface_file' names a file that does not exist: .*nowhere.csv"),
    ("stockpile-grid-of-a-billion-cells", "run", lambda t: ["short.toml", "--out", t / "o"],
     edited(**{"[simulation]": _PILE.format(y=30.0).replace("grid_spacing = 0.25", "grid_spacing = 0.002") + "[simulation]"}),
     r"'stockpile.grid_spacing' gives .* height samples, more than 2e\+07: choose a coarser grid"),
    # 6. Replay input
    ("replay-scene-json-a-list", "replay", lambda t: [_run_dir(t, scene="[]", rows=2), "--export", t / "a.html"], None,
     r"run/scene.json: "),
    ("replay-header-only-csv", "replay", lambda t: [_run_dir(t, rows=0), "--export", t / "a.html"], None,
     r"timeseries.csv: [01] rows of samples; a replay needs at least 2"),
    ("replay-one-row", "replay", lambda t: [_run_dir(t, rows=1), "--port", "0"], None,
     r"timeseries.csv: [01] rows of samples; a replay needs at least 2"),
]


def _moved_into(folder: Path) -> Path:
    scene = folder / "short.toml"
    scene.write_text((folder.parent / "short.toml").read_text())
    return scene


def _foreign_html(tmp: Path) -> Path:
    (tmp / "page.html").write_text("<html><head></head><body>someone's report</body></html>\n")
    return tmp / "page.html"


def _folder(tmp: Path, name: str) -> Path:
    (tmp / name).mkdir()
    return tmp / name


def _sweep(tmp: Path, vary: str = "", seeds: str = "[1]") -> Path:
    (tmp / "sweep.toml").write_text(f'scene = "short.toml"\nseeds = {seeds}\n{vary}')
    return tmp / "sweep.toml"


def _other_batch(tmp: Path) -> Path:
    folder = tmp / "b"
    folder.mkdir()
    mark(folder, "batch", sweep="other.toml", runs=7, plan="0" * 64)
    (folder / "summary.csv").write_text("run,status\n")
    return folder


def _run_dir(tmp: Path, *, scene: str | None = None, rows: int | None = None) -> Path:
    """A run directory of the short scene, damaged as told."""
    folder = tmp / "run"
    folder.mkdir()
    mark(folder, "run")
    text = json.dumps(load_scene(tmp / "short.toml").to_dict()) if scene is None else scene
    (folder / "scene.json").write_text(text)
    row = ",0.0" * (len(COLUMNS) - 1)
    (folder / "timeseries.csv").write_text(",".join(COLUMNS) + "\n" + "".join(f"{i}.0{row}\n" for i in range(rows or 0)))
    (folder / "metrics.json").write_text("{}\n")
    return folder


@pytest.mark.parametrize("case", REFUSALS, ids=[case[0] for case in REFUSALS])
def test_hostile_input_is_refused_and_destroys_nothing(tmp_path, case):
    _, command, arguments, edit, pattern = case
    write_short_scene(tmp_path, edit=edit)
    (tmp_path / "notes.txt").write_text("an engineer's notes\n")
    args = arguments(tmp_path)
    before = snapshot(tmp_path)
    proc = cli(command, *args, cwd=tmp_path)
    assert_refused(proc, pattern)
    assert snapshot(tmp_path) == before  # nothing destroyed, nothing left behind


def test_the_catalogue_covers_every_class():
    classes = {"run-into", "export-", "batch-into", "nan-", "inf-", "nanosecond", "hundred", "stockpile-", "replay-"}
    assert all(any(case[0].startswith(c) for case in REFUSALS) for c in classes)
    assert len({case[0] for case in REFUSALS}) == len(REFUSALS)


# --- what the twin may replace: its own outputs -------------------------------------------------------


def test_overwrite_replaces_a_run_directory_the_twin_wrote(tmp_path):
    write_short_scene(tmp_path)
    assert cli("run", "short.toml", "--out", "o", "--no-plots", cwd=tmp_path).returncode == 0
    before = (tmp_path / "o").stat().st_ino  # the folder is replaced whole: another one takes its name
    proc = cli("run", "short.toml", "--out", "o", "--no-plots", "--overwrite", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert (tmp_path / "o").stat().st_ino != before
    assert json.loads((tmp_path / "o" / "metrics.json").read_text())["travel"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["o", "short.toml"]  # no staging folder left


@pytest.mark.slow
def test_an_export_replaces_only_an_earlier_export(tmp_path):
    write_short_scene(tmp_path)
    assert cli("run", "short.toml", "--out", "o", "--no-plots", cwd=tmp_path).returncode == 0
    for _ in range(2):  # the second replaces the first: it carries the twin's tag
        proc = cli("replay", "o", "--export", "o.html", cwd=tmp_path)
        assert proc.returncode == 0, proc.stderr
    assert b'content="bwr_twin.replay"' in (tmp_path / "o.html").read_bytes()[:4096]


def test_the_same_sweep_resumes_another_is_refused(tmp_path):
    write_short_scene(tmp_path)
    sweep = _sweep(tmp_path)
    assert cli("batch", sweep, "--out", "b", cwd=tmp_path).returncode == 0
    before = snapshot(tmp_path / "b")
    proc = cli("batch", sweep, "--out", "b", cwd=tmp_path)
    assert proc.returncode == 0 and "1 already done, skipped" in proc.stdout
    other = _sweep(tmp_path, seeds="[2]")
    assert_refused(cli("batch", other, "--out", "b", cwd=tmp_path),
                   r"b: holds the results of another sweep \(sweep.toml, 1 runs\)")
    assert snapshot(tmp_path / "b") == before


# --- 4. Ctrl-C while MuJoCo steps a long control period ---------------------------------------------


def test_ctrl_c_is_heard_within_a_control_period_of_ten_million_steps(tmp_path):
    # 10^7 physics steps a control period: one MuJoCo call would hold Ctrl-C back for about 40 s.
    write_short_scene(tmp_path, edit=edited(**{"timestep = 0.002 ": "timestep = 1e-8 ",
                                               "control_period = 0.01 ": "control_period = 0.1 ",
                                               "hold_time = 0.01 ": "hold_time = 0.1 "}))
    child = subprocess.Popen([sys.executable, "-m", "bwr_twin.run", "short.toml", "--out", "o", "--force"],
                             cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    time.sleep(6)  # well into the first control period
    child.send_signal(signal.SIGINT)
    started = time.monotonic()
    _, stderr = child.communicate(timeout=60)
    assert child.returncode == 130, stderr
    assert time.monotonic() - started < 15, "Ctrl-C waited for a whole control period"
    assert stderr.strip() == "interrupted: nothing written"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["short.toml"]


# --- 5. runs that leave the machine's limits ------------------------------------------------------------


@pytest.mark.parametrize("rated", [True, False], ids=["rated drives", "unrated drives"])
def test_a_run_beyond_the_machine_limits_says_so(tmp_path, rated):
    """On the paper's machine the drives' (assumed) ratings hold a runaway gain and say so; without
    ratings the same gain drives the machine out of its envelope and onto its end stops."""
    gain = {"output_gain = [0.01, 0.04, 0.06]": "output_gain = [1e3, 1e3, 1e3]"}
    if not rated:
        gain[f'"{PAPER_MJCF}"'] = f'"{unrated_paper_mjcf(tmp_path)}"'
    write_short_scene(tmp_path, edit=edited(**gain))
    proc = cli("run", "short.toml", "--out", "o", "--no-plots", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    metrics = json.loads((tmp_path / "o" / "metrics.json").read_text())
    if rated:
        assert metrics["travel"]["beyond_drive_rating_time"] is not None
        assert "travel was commanded beyond its drive rating at" in " ".join(metrics["limits"])
    else:
        assert metrics["travel"]["left_envelope_time"] > 0 and metrics["travel"]["end_stop_time"] > 0
        assert "travel left the operating envelope at" in " ".join(metrics["limits"])
    assert metrics["limits"]
    for flag in metrics["limits"]:
        assert f"warning: {flag}" in proc.stdout


def test_drive_ratings_are_flagged_and_shown_in_the_batch_summary(tmp_path):
    from conftest import HEAVY_MJCF

    write_short_scene(tmp_path, edit=edited(**{"output_gain = [0.01, 0.04, 0.06]": "output_gain = [10, 10, 10]"}))
    sweep = _sweep(tmp_path, f'[vary]\nmachine.mjcf = ["{HEAVY_MJCF}"]\n')
    proc = cli("batch", sweep, "--out", "b", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    summary = (tmp_path / "b" / "summary.csv").read_text()
    assert "was commanded beyond its drive rating at" in summary
    run = next(p for p in (tmp_path / "b").iterdir() if p.name.startswith("0000"))
    metrics = json.loads((run / "metrics.json").read_text())
    assert metrics["travel"]["beyond_drive_rating_time"] is not None


# --- 7. exposure ----------------------------------------------------------------------------------------


@pytest.mark.browser
def test_serving_every_interface_warns_with_the_real_addresses(tmp_path):
    from bwr_twin.exposure import network_addresses

    write_short_scene(tmp_path)
    assert cli("run", "short.toml", "--out", "o", "--no-plots", cwd=tmp_path).returncode == 0
    server = subprocess.Popen([sys.executable, "-m", "bwr_twin.replay", "o", "--host", "0.0.0.0", "--port", "0"],
                              cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        warning = server.stderr.readline()
    finally:
        server.send_signal(signal.SIGINT)
        server.communicate(timeout=30)
    assert warning.startswith("warning: --host 0.0.0.0 serves the replay on every network interface")
    assert "without a password" in warning
    for address in network_addresses():
        assert f"http://{address}:" in warning
