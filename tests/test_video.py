"""The replay as a video: MuJoCo renders it offscreen (EGL), the ffmpeg of imageio-ffmpeg encodes
it, and the file read back has the frames, size and duration asked for; the machine moves from
frame to frame; bad options and foreign files are refused in one line with nothing written."""

import dataclasses
import os
import subprocess
import sys

import imageio_ffmpeg
import numpy as np
import pytest
from conftest import ROOT, SCENES, SHORT_VIA_POINTS, write_short_scene

from bwr_twin.ownership import VIDEO_WRITER, sidecar, written_by
from bwr_twin.replay import Recording
from bwr_twin.replay.__main__ import main

SHORT_RUN = 20.0  # s, SHORT_VIA_POINTS' run


@pytest.fixture(autouse=True)
def _keep_mujoco_gl(monkeypatch):
    """The renderer sets MUJOCO_GL in this process; the tests after these do not inherit it."""
    monkeypatch.setenv("MUJOCO_GL", os.environ.get("MUJOCO_GL", "egl"))


@pytest.fixture(scope="module")
def short_run(tmp_path_factory):
    """A 20 s reclaim's run directory, simulated once."""
    from bwr_twin.config.scene import load_scene
    from bwr_twin.results.rundir import write_run
    from bwr_twin.sim.lockstep import simulate

    scene = load_scene(SCENES / "paper_individual_gains.toml", {"path.via_points": SHORT_VIA_POINTS})
    run_dir = tmp_path_factory.mktemp("video") / "short"
    write_run(simulate(scene), run_dir, plots=False)
    return run_dir


def _replay(*args, cwd=ROOT) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "bwr_twin.replay", *map(str, args)], cwd=cwd,
                          capture_output=True, text=True, timeout=300, check=False)


def _frames(path) -> tuple[dict, list[np.ndarray]]:
    """The video's metadata and every frame, decoded by ffmpeg."""
    reader = imageio_ffmpeg.read_frames(str(path))
    meta = next(reader)
    width, height = meta["size"]
    return meta, [np.frombuffer(frame, np.uint8).reshape(height, width, 3) for frame in reader]


def test_a_run_directory_becomes_an_h264_video_of_the_frames_size_and_duration_asked(short_run, tmp_path):
    out = tmp_path / "short.mp4"
    proc = _replay(short_run, "--video", out, "--fps", 30, "--speed", 10, "--size", "320x240", "--charts")
    assert proc.returncode == 0, proc.stderr
    frames_asked = round(SHORT_RUN * 30 / 10)
    assert f"wrote {out}" in proc.stdout and f"{frames_asked} frames" in proc.stdout
    meta, frames = _frames(out)
    assert meta["codec"] == "h264" and meta["pix_fmt"].startswith("yuv420p")
    assert meta["size"] == (320, 240) and meta["fps"] == 30
    assert len(frames) == frames_asked
    assert meta["duration"] == pytest.approx(frames_asked / 30, abs=0.05)
    assert written_by(out, VIDEO_WRITER)
    assert sorted(p.name for p in tmp_path.iterdir()) == [".short.mp4.bwr_twin", "short.mp4"]  # no partial file
    # The machine moves: the scene between header and chart strip changes from first to last frame.
    view = slice(40, 160)
    first, last = (frame[view].astype(int) for frame in (frames[0], frames[-1]))
    assert np.abs(first - last).mean() > 0.5
    assert np.abs(frames[0].astype(int) - frames[1].astype(int)).mean() < np.abs(first - last).mean()


def test_a_scene_is_simulated_first_and_rendered(tmp_path):
    scene = write_short_scene(tmp_path)
    out = tmp_path / "scene.mp4"
    proc = _replay(scene, "--no-cache", "--video", out, "--speed", 100, "--size", "160x120", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    _, frames = _frames(out)
    assert len(frames) == round(SHORT_RUN * 30 / 100)
    assert not (tmp_path / "out").exists()  # --no-cache: nothing cached


def test_frames_show_each_run_and_its_errors(short_run):
    from bwr_twin.replay.video_frames import FrameRenderer

    recording = Recording.from_run_dir(short_run)
    single = FrameRenderer([recording], ["short"], (160, 120))
    pair = FrameRenderer([recording, recording], ["short", "again"], (160, 120))
    try:
        one, two = single.frame(10.0), pair.frame(10.0)
        assert one.shape == two.shape == (120, 160, 3)
        machine = single.scene.model.ngeom  # the second machine, translucent, joins the first
        assert pair.scene.scene.ngeom > single.scene.scene.ngeom + machine // 2
        lines = [text for text, _ in pair.readout_lines(10.0)]
        assert lines[0].endswith("t = 10.0 s of 20 s")
        assert lines[1].startswith("short (solid): error") and lines[2].startswith("again: error")
        assert " m " in lines[1] and lines[1].endswith(" deg")
    finally:
        single.close()
        pair.close()


def test_the_pile_is_drawn_as_it_was_dug(short_run):
    """A pile under the path whose history lowers a patch at t = 5 s: the hfield falls there and
    the texture shows the cut in fresh ore, as the browser marks it."""
    from bwr_twin.pile.surface import Surface
    from bwr_twin.replay.pile import CUT_COLOUR, ORE_COLOUR
    from bwr_twin.replay.video_frames import FrameRenderer
    from bwr_twin.stockpile.history import PileHistory

    recording = Recording.from_run_dir(short_run)
    x, y = np.arange(40.0, 70.0, 0.5), np.arange(-10.0, 15.0, 0.5)
    z_start = np.full((len(y), len(x)), 6.0)
    dug = np.flatnonzero(((np.abs(x - 55)[None, :] < 3) & (np.abs(y - 1)[:, None] < 3)).ravel())
    history = PileHistory(x, y, z_start, np.array([5.0]), np.array([0, len(dug)]), dug, np.full(len(dug), 4.0))
    plan = dataclasses.replace(recording.plan, pile=Surface(x, y, z_start))
    renderer = FrameRenderer([dataclasses.replace(recording, plan=plan, pile=history)], ["dug"], (160, 120))
    try:
        model, texture = renderer.scene.model, renderer.scene.pile_texture
        texels = model.tex_data[model.tex_adr[texture]:][: z_start.size * 3].reshape(-1, 3)
        before = renderer.frame(1.0)
        assert not renderer.scene.pile_changed and (texels == ORE_COLOUR).all()
        after = renderer.frame(10.0)
        assert renderer.scene.pile_changed
        assert (texels == CUT_COLOUR).all(axis=1).sum() == len(dug)  # a display grid of every sample here
        hfield = renderer.scene.pile_hfield
        heights = model.hfield_data[model.hfield_adr[hfield]:][: z_start.size] * model.hfield_size[hfield, 2]
        assert np.allclose(np.sort(heights)[: len(dug)], 4.0) and np.allclose(np.sort(heights)[len(dug):], 6.0)
        assert np.abs(before.astype(int) - after.astype(int)).max() > 50
    finally:
        renderer.close()


@pytest.mark.parametrize(
    "option, message",
    [
        (["--fps", "0"], "argument --fps: 0 is outside 1-60 frames per second"),
        (["--fps", "120"], "argument --fps: 120 is outside 1-60 frames per second"),
        (["--speed", "-1"], "argument --speed: -1 is outside 0.1-1000 times real time"),
        (["--size", "1281x720"], "argument --size: 1281x720 has an odd side"),
        (["--size", "8000x8000"], "argument --size: 8000x8000 is outside 64x64 to 3840x2160 pixels"),
        (["--size", "big"], "argument --size: 'big' is not WIDTHxHEIGHT"),
        (["--speed", "1000"], "--speed 1000: the 20 s run makes 1 frame at 30 fps"),
        (["--export", "x.html"], "--video draws the runs of one path in one scene; not with --export"),
    ],
    ids=["fps-0", "fps-120", "speed-negative", "size-odd", "size-huge", "size-text", "too-few-frames",
         "export"],
)
def test_bad_options_are_refused_in_one_line_with_nothing_written(short_run, tmp_path, capsys, option,
                                                                   message):
    out = tmp_path / "bad.mp4"
    try:
        status = main([str(short_run), "--video", str(out), *option])
    except SystemExit as exit_:  # argparse's refusals
        status = exit_.code
    err = capsys.readouterr().err.strip().splitlines()
    assert status == 2 and len(err) == 1 and err[0].startswith("error: ") and message in err[0], err
    assert list(tmp_path.iterdir()) == []


def test_options_of_a_video_without_one_are_refused(capsys):
    with pytest.raises(SystemExit) as exit_:
        main(["--fps", "25"])
    assert exit_.value.code == 2 and "shape a --video" in capsys.readouterr().err


def test_a_video_estimated_past_the_limit_is_refused_before_anything_is_written(short_run, tmp_path, capsys,
                                                                              monkeypatch):
    monkeypatch.setattr("bwr_twin.replay.video.MAX_HOURS", 1e-6)  # the real per-frame cost, a tiny bound
    status = main([str(short_run), "--video", str(tmp_path / "long.mp4"), "--size", "160x120"])
    err = capsys.readouterr().err.strip().splitlines()
    assert status == 2 and len(err) == 1, err
    assert all(part in err[0] for part in ("long.mp4: would take about", "to render (measured)", "--force"))
    assert list(tmp_path.iterdir()) == []


def _foreign_video(path, comment: str | None) -> bytes:
    """A one-frame MP4 that ffmpeg writes with `comment` as its comment tag, or none."""
    metadata = ["-metadata", f"comment={comment}"] if comment is not None else []
    writer = imageio_ffmpeg.write_frames(str(path), (64, 64), fps=10, macro_block_size=1,
                                         ffmpeg_log_level="error", output_params=metadata)
    writer.send(None)
    writer.send(np.zeros((64, 64, 3), np.uint8))
    writer.close()
    return path.read_bytes()


@pytest.mark.parametrize("comment", [None, f"{VIDEO_WRITER}, edited", f"not {VIDEO_WRITER}"])
def test_a_file_the_twin_did_not_write_is_left_alone(short_run, tmp_path, capsys, comment):
    foreign = tmp_path / "holiday.mp4"
    before = _foreign_video(foreign, comment)
    assert main([str(short_run), "--video", str(foreign), "--size", "64x64", "--speed", "100"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "holiday.mp4: exists and was not written by the twin; it is left alone" in err[0]
    assert foreign.read_bytes() == before
    assert list(tmp_path.iterdir()) == [foreign]


def test_a_video_the_twin_wrote_is_replaced(short_run, tmp_path):

    own = tmp_path / "own.mp4"
    for speed in ("100", "50"):
        assert main([str(short_run), "--video", str(own), "--size", "64x64", "--speed", speed]) == 0
    _, frames = _frames(own)
    assert len(frames) == round(SHORT_RUN * 30 / 50)  # the second video replaced the first
    assert sorted(tmp_path.iterdir()) == [sidecar(own), own]  # and its manifest


def test_mujoco_gl_defaults_to_egl_and_a_missing_backend_is_one_line():
    env = {k: v for k, v in os.environ.items() if k != "MUJOCO_GL"}
    code = ("import os\nfrom bwr_twin.errors import BwrError\n"
            "from bwr_twin.replay.video_frames import gl_context\n"
            "try:\n    gl_context(64, 64)\nexcept BwrError as exc:\n    print(exc)\n"
            "else:\n    print(os.environ['MUJOCO_GL'])")

    def context(**variables) -> str:
        return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                              env={**env, **variables}).stdout.strip()

    assert context() == "egl"
    out = context(MUJOCO_GL="glfw", DISPLAY="", WAYLAND_DISPLAY="")  # no display to open a window on
    assert out.startswith("MUJOCO_GL=glfw: no OpenGL context for rendering offscreen"), out
    assert "\n" not in out
