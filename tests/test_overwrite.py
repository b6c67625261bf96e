"""--overwrite replaces only what the twin wrote, as its manifest records it (docs/reliability.md,
class 19): every writer replaces its own earlier output; with a file the engineer added (notes.txt,
a folder) or one of the twin's edited since, it refuses in one line naming that file, exit status
2, and every file is left byte for byte as it was. A killed video writer's temporary file is
removed by the next video, and nothing else is.

The outputs are written once, by the real commands, and copied for each case.
"""

from __future__ import annotations

import os
import re
import shutil
import signal
import subprocess
import sys
import time
import zipfile
from pathlib import Path

import pytest
from conftest import write_short_scene
from test_hostile import assert_refused, cli, snapshot
from test_hostile_tools import TIPPER, TUNING

from bwr_twin.errors import BwrError
from bwr_twin.ownership import MARKER_FILE, mark, sidecar
from bwr_twin.shipped import RULE_BASES, SCENES

PID = SCENES / "pid_paper.toml"
SWEEP = 'scene = "short.toml"\nseeds = [1]\n'
VIDEO = ["--size", "64x64", "--speed", "100"]  # 6 frames of the short run

# Folders: name -> (the command that writes it again, one of the files the twin wrote in it)
FOLDERS = {
    "run": (["run", "short.toml", "--out", "run", "--no-plots", "--overwrite"], "metrics.json"),
    "batch": (["batch", "sweep.toml", "--out", "batch", "--workers", "1"], "summary.csv"),
    "compare": (["compare", "short.toml", "--controllers", "short.toml", PID, "--seeds", "1", "--out", "compare",
                 "--overwrite"], "comparison.md"),
    "plc": (["export", "plc", PID, "--out", "plc", "--overwrite"], "FB_BwrPid.st"),
    "tune": (["tune", "tune.toml", "--out", "tune", "--workers", "1"], "history.csv"),
}
# Single files: name -> the command that writes it again
FILES = {
    "short.fmu": ["export", "fmu", "short.toml", "--out", "short.fmu", "--overwrite"],
    "paper.fis": ["fis", "convert", RULE_BASES / "paper_table2.toml", "paper.fis", "--overwrite"],
    "tipper.png": ["fis", "surface", TIPPER, "--out", "tipper.png", "--overwrite"],
    "run.html": ["replay", "run", "--export", "run.html"],
    "run.mp4": ["replay", "run", "--video", "run.mp4", *VIDEO],
}


def ok(proc: subprocess.CompletedProcess) -> None:
    assert proc.returncode == 0, proc.stderr


@pytest.fixture(scope="module")
def written(tmp_path_factory) -> Path:
    """A folder of every writer's output, each written once by its command, and kept as it was
    beside it (a batch's runs name the scene's path: the cases change it where it was written)."""
    folder = tmp_path_factory.mktemp("written") / "work"
    write_short_scene(folder)
    (folder / "sweep.toml").write_text(SWEEP)
    ok(cli("run", "short.toml", "--out", "run", "--no-plots", cwd=folder))
    ok(cli("batch", "sweep.toml", "--out", "batch", "--workers", "1", cwd=folder))
    ok(cli("compare", "short.toml", "--controllers", "short.toml", PID, "--seeds", "1", "--out", "compare",
           cwd=folder))
    ok(cli("export", "plc", PID, "--out", "plc", cwd=folder))
    _tuning_folder(folder)
    for command in FILES.values():
        ok(cli(*[part for part in command if part != "--overwrite"], cwd=folder))
    shutil.copytree(folder, folder.parent / "pristine", symlinks=True)
    return folder


def _tuning_folder(folder: Path) -> None:
    """tune/ as a tuning of tune.toml leaves it between generations: its history written."""
    from bwr_twin.config.tuning import load_tuning
    from bwr_twin.tune.outputs import write_history

    (folder / "tune.toml").write_text(TUNING)
    tuning = load_tuning(folder / "tune.toml")
    (folder / "tune").mkdir()
    mark(folder / "tune", "tuning", file="tune.toml", tuning=tuning.digest)
    write_history(folder / "tune", [{"generation": 0, "candidate": 0, "objective": 3.0, "feasible": True}])


@pytest.fixture
def work(written) -> Path:
    """Every output as it was written, for one case to change."""
    shutil.rmtree(written)
    return Path(shutil.copytree(written.parent / "pristine", written, symlinks=True))


def refused(work: Path, command: list, pattern: str) -> None:
    before = snapshot(work)
    assert_refused(cli(*command, cwd=work), pattern)
    assert snapshot(work) == before


# --- folders ----------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", [name for name in FOLDERS if name != "tune"])
def test_a_folder_the_twin_wrote_is_written_again(work, name):
    command, _ = FOLDERS[name]
    ok(cli(*command, cwd=work))
    assert (work / name / MARKER_FILE).is_file()


def _notes(folder: Path) -> Path:
    (folder / "notes.txt").write_text("my notes\n")
    return folder / "notes.txt"


def _subfolder(folder: Path) -> Path:
    (folder / "mine").mkdir()
    return folder / "mine"


ADDED = {"notes": _notes, "subfolder": _subfolder}


@pytest.mark.parametrize("added", ADDED)
@pytest.mark.parametrize("name", FOLDERS)
def test_a_file_or_folder_the_engineer_added_is_named_and_kept(work, name, added):
    foreign = ADDED[added](work / name)
    refused(work, FOLDERS[name][0], rf"{re.escape(str(foreign.relative_to(work)))}: was not written by the twin "
                                    r"\(not in .*\.bwr_twin\); .* move it away")


def test_a_file_added_inside_a_run_of_a_comparison_is_named_and_kept(work):
    run = next(path for path in sorted((work / "compare").iterdir()) if path.is_dir())
    foreign = _notes(run)
    refused(work, FOLDERS["compare"][0], rf"{re.escape(str(foreign.relative_to(work)))}: was not written by the twin")


@pytest.mark.parametrize("name", FOLDERS)
def test_a_file_of_the_twin_edited_since_is_named_and_kept(work, name):
    own = work / name / FOLDERS[name][1]
    with own.open("a") as f:
        f.write("\n(* checked by hand *)\n")
    refused(work, FOLDERS[name][0], rf"{name}/{re.escape(own.name)}: changed since the twin wrote it")


def test_a_folder_written_before_manifests_is_not_overwritten(work):
    marker = work / "run" / MARKER_FILE
    marker.write_text('{"written_by": "bwr_twin", "kind": "run"}\n')
    refused(work, FOLDERS["run"][0], r"run: holds no record of the files the twin wrote in it")


def test_a_damaged_batch_run_is_not_run_again_over_the_engineers_file(work):
    run = next(path for path in (work / "batch").iterdir() if (path / "metrics.json").is_file())
    (run / "metrics.json").write_text("{")  # damaged: the batch runs it again, as it always has
    (run / "notes.txt").write_text("my notes\n")
    refused(work, FOLDERS["batch"][0], rf"{run.name}/notes.txt: was not written by the twin")
    (run / "notes.txt").unlink()
    proc = cli(*FOLDERS["batch"][0], cwd=work)
    assert proc.returncode == 0 and "running them again" in proc.stderr, proc.stderr
    assert (run / "metrics.json").read_text().startswith("{\n")


def test_a_tuning_writes_its_own_files_again_and_refuses_an_edited_one(work):
    from bwr_twin.tune.outputs import write_history

    folder = work / "tune"
    write_history(folder, [{"generation": 1, "candidate": 1, "objective": 2.0, "feasible": True}])
    assert "2.0" in (folder / "history.csv").read_text()
    with (folder / "history.csv").open("a") as f:
        f.write("my row\n")
    before = snapshot(work)
    with pytest.raises(BwrError, match=r"tune/history.csv: changed since the twin wrote it"):
        write_history(folder, [{"generation": 2, "candidate": 1, "objective": 1.0, "feasible": True}])
    assert snapshot(work) == before


# --- single files -----------------------------------------------------------------------------------


@pytest.mark.parametrize("name", FILES)
def test_a_file_the_twin_wrote_is_written_again(work, name):
    before = (work / name).stat().st_ino
    ok(cli(*FILES[name], cwd=work))
    assert (work / name).stat().st_ino != before and sidecar(work / name).is_file()  # a new file took its name


def _edit(path: Path) -> None:
    """Change the file and keep its writer's mark where it is."""
    if path.suffix == ".fmu":
        with zipfile.ZipFile(path, "a") as archive:
            comment = archive.comment
            archive.writestr("documentation/notes.txt", "my notes\n")
            archive.comment = comment
    else:
        with path.open("ab") as f:
            f.write(b"\n% my edit\n")


@pytest.mark.parametrize("name", FILES)
def test_a_file_of_the_twin_edited_since_is_not_replaced(work, name):
    _edit(work / name)
    refused(work, FILES[name], rf"{re.escape(name)}: changed since the twin wrote it")


@pytest.mark.parametrize("name", FILES)
def test_a_marked_file_without_its_manifest_is_not_replaced(work, name):
    sidecar(work / name).unlink()
    refused(work, FILES[name], rf"{re.escape(name)}: holds no record of what the twin wrote")


def test_an_fmu_is_replaced_only_with_overwrite(work):
    refused(work, FILES["short.fmu"][:-1], r"short.fmu: already exists; choose another --out or pass --overwrite")


# --- what killed writers leave ----------------------------------------------------------------------


def test_a_killed_video_writers_partial_file_is_removed_by_the_next_video(work):
    writing = subprocess.Popen([sys.executable, "-m", "bwr_twin.replay", "run", "--video", "clip.mp4", "--size",
                                "64x64", "--speed", "0.5", "--fps", "60"], cwd=work, start_new_session=True,
                               stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + 120
    while not list(work.glob(".clip.mp4.partial-*")) and time.monotonic() < deadline:
        assert writing.poll() is None, "the video finished before it could be killed"
        time.sleep(0.05)
    os.killpg(writing.pid, signal.SIGKILL)  # the command and its ffmpeg
    writing.wait()
    (stale,) = work.glob(".clip.mp4.partial-*")
    kept = {name: f"not the twin's {name}\n".encode() for name in
            (".notes", ".clip.mp4.partial-notes", f".other.mp4.partial-{writing.pid}",
             f".clip.mp4.partial-{os.getpid()}")}  # the last one's writer is alive: it may be writing
    for name, content in kept.items():
        (work / name).write_bytes(content)
    ok(cli("replay", "run", "--video", "clip.mp4", *VIDEO, cwd=work))
    assert not stale.exists()
    assert {name: (work / name).read_bytes() for name in kept} == kept
    assert (work / "clip.mp4").is_file()
