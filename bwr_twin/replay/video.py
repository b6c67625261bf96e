"""A replay as a video file: `python -m bwr_twin.replay RUN_DIR --video out.mp4`.

The pictures (bwr_twin.replay.video_frames) are rendered offscreen by MuJoCo and piped to the
ffmpeg that the imageio-ffmpeg wheel ships, which encodes them as H.264 in yuv420p (what Chromium
and every phone play) into an MP4 with its index first, so that it plays while it downloads.
The file is written under a temporary name and renamed into place only when complete; its
comment tag marks it as the twin's (bwr_twin.ownership), so a later video replaces it
and nothing else. The run's N seconds make round(N x fps / speed) frames, from its first record
to its last. A video that would take more than MAX_HOURS, from the measured cost of its first
frames, is refused before anything is written.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path

import imageio_ffmpeg
import numpy as np

from bwr_twin.errors import BwrError
from bwr_twin.ownership import VIDEO_WRITER, check_output, write_atomically, written_by
from bwr_twin.replay.recording import Recording

DEFAULT_FPS = 30.0
DEFAULT_SPEED = 10.0  # simulated seconds per second of video, as the browser's default speed
DEFAULT_SIZE = (1280, 720)
FPS_RANGE = (1.0, 60.0)
SPEED_RANGE = (0.1, 1000.0)  # a tenth of real time: a slow motion; a thousandfold: a glance
SIZE_RANGE = ((64, 64), (3840, 2160))  # px: a thumbnail to 4K UHD
MAX_HOURS = 1.0  # beyond this a video is refused unless --force
MEASURED_FRAMES = 3  # timed after the first, which also uploads the model's meshes and textures
ENCODE_S_PER_MEGAPIXEL = 0.010  # x264 at PRESET on the 2-core reference machine: 6-9 ms at 1280x720
PRESET = "veryfast"  # x264's: half the time of its default "medium", for a file of the same size here
CRF = 23  # x264's constant quality: its default, no visible loss at this picture's detail


def fps_option(text: str) -> float:
    """--fps: frames per second within FPS_RANGE."""
    return _number(text, "frames per second", FPS_RANGE)


def speed_option(text: str) -> float:
    """--speed: simulated seconds per second of video within SPEED_RANGE."""
    return _number(text, "times real time", SPEED_RANGE)


def _number(text: str, unit: str, limits: tuple[float, float]) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not limits[0] <= value <= limits[1]:
        raise argparse.ArgumentTypeError(f"{text} is outside {limits[0]:g}-{limits[1]:g} {unit}")
    return value


def size_option(text: str) -> tuple[int, int]:
    """--size WIDTHxHEIGHT in pixels: even (H.264 in yuv420p halves both) and within SIZE_RANGE."""
    try:
        width, height = (int(part) for part in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not WIDTHxHEIGHT in pixels, e.g. 1280x720") from None
    (low_w, low_h), (high_w, high_h) = SIZE_RANGE
    if not (low_w <= width <= high_w and low_h <= height <= high_h):
        raise argparse.ArgumentTypeError(f"{text} is outside {low_w}x{low_h} to {high_w}x{high_h} pixels")
    if width % 2 or height % 2:
        raise argparse.ArgumentTypeError(f"{text} has an odd side; H.264 in yuv420p needs even ones")
    return width, height


def frame_times(recording: Recording, fps: float, speed: float) -> np.ndarray:
    """The time (s) of the run each frame shows, from its first record to its last."""
    plan = recording.plan
    count = round(plan.duration * fps / speed)
    if count < 2:
        frames = f"{count} frame{'s' * (count != 1)}"
        raise BwrError(f"--speed {speed:g}: the {plan.duration:g} s run makes {frames} at {fps:g} fps; a "
                       "video needs at least 2 (lower --speed or raise --fps)")
    return np.linspace(plan.time[0], plan.time[-1], count)


@dataclass(frozen=True)
class Written:
    """What `write_video` wrote."""

    frames: int
    seconds: float  # of video
    bytes: int
    wall: float  # s it took


def write_video(
    recordings: Sequence[Recording],
    path: str | Path,
    *,
    names: Sequence[str] = (),
    fps: float = DEFAULT_FPS,
    speed: float = DEFAULT_SPEED,
    size: tuple[int, int] = DEFAULT_SIZE,
    charts: bool = False,
    force: bool = False,
    progress: bool = True,
) -> Written:
    """Render the runs (one, or several of one path and machine: the first solid, the others
    translucent) at `speed` times real time into the video `path`, atomically.

    `names` label the runs when there are several (default: run 1, run 2, ...); `charts` adds the
    error charts' strip; `force` renders a video that would take more than MAX_HOURS; `progress`
    draws a progress line on a terminal."""
    from bwr_twin.replay.video_frames import FrameRenderer  # OpenGL only for a video

    started = time.perf_counter()
    path = Path(path)
    check_output(path, "video", option="--video")
    times = frame_times(recordings[0], fps, speed)
    names = list(names) or [f"run {k + 1}" for k in range(len(recordings))]
    renderer = FrameRenderer(recordings, names, size, charts=charts)
    try:
        first = [renderer.frame(float(times[0]))]
        measuring = time.perf_counter()
        first += [renderer.frame(float(t)) for t in times[1 : 1 + MEASURED_FRAMES]]
        per_frame = (time.perf_counter() - measuring) / max(1, len(first) - 1)
        _check_cost(path, len(times), size, per_frame, force)
        frames = _rendered(renderer, times, first, progress)
        write_atomically(path, lambda partial: _encode(partial, path, frames, size, fps), record=True,
                         option="--video")
    finally:
        renderer.close()
    return Written(len(times), len(times) / fps, path.stat().st_size, time.perf_counter() - started)


def _check_cost(path: Path, frames: int, size: tuple[int, int], per_frame: float, force: bool) -> None:
    """Refuse, unless `force`, a video whose frames would take more than MAX_HOURS."""
    encode = ENCODE_S_PER_MEGAPIXEL * size[0] * size[1] / 1e6
    seconds = frames * (per_frame + encode)
    if seconds > MAX_HOURS * 3600 and not force:
        raise BwrError(f"{path}: would take about {seconds / 3600:.1f} h, more than {MAX_HOURS:g} h: "
                       f"{frames} frames of {size[0]}x{size[1]} at {1e3 * per_frame:.0f} ms to render "
                       f"(measured) and {1e3 * encode:.0f} ms to encode each; lower --size or --fps, raise "
                       "--speed, or pass --force")


def _rendered(renderer, times: np.ndarray, first: list[np.ndarray], progress: bool) -> Iterator[np.ndarray]:
    """Every frame at `times`, the ones already rendered first, with the progress line."""
    from bwr_twin.progress import simulated_seconds

    start, duration = float(times[0]), float(times[-1] - times[0])
    with simulated_seconds("rendering", unit="s of the run") as advance:
        for i, t in enumerate(times):
            yield first[i] if i < len(first) else renderer.frame(float(t))
            if progress:
                advance(float(t) - start, duration)


def _encode(partial: Path, path: Path, frames: Iterator[np.ndarray], size: tuple[int, int],
            fps: float) -> None:
    """H.264 in an MP4 at `partial` (the temporary name of `path`), marked as the twin's."""
    writer = imageio_ffmpeg.write_frames(
        str(partial), size, fps=Fraction(fps).limit_denominator(1001), codec="libx264", pix_fmt_out="yuv420p",
        quality=None, macro_block_size=1, ffmpeg_log_level="error",
        output_params=["-preset", PRESET, "-crf", str(CRF), "-movflags", "+faststart",
                       "-metadata", f"comment={VIDEO_WRITER}", "-f", "mp4"])  # the temporary name has no .mp4
    writer.send(None)
    try:
        for frame in frames:
            writer.send(frame)
    except OSError as exc:  # ffmpeg stopped reading: its own message is on stderr
        raise BwrError(f"{path}: ffmpeg stopped encoding ({str(exc).splitlines()[0]})") from None
    finally:
        writer.close()
    if not written_by(partial, VIDEO_WRITER, suffix=path.suffix):
        raise BwrError(f"{path}: ffmpeg left no complete MP4 file (is the disk full?)")
    check_output(path, "video", option="--video")  # still the twin's to replace, just before it goes
