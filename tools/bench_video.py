"""Seconds to render the paper's 700 s reclaim as a video, and the video read back.

    python tools/bench_video.py [RUN_DIR] [--size 1280x720] [--fps 30] [--speed 10] [--charts]

Without RUN_DIR, runs `python -m bwr_twin.run paper_individual_gains` into
out/bench-video/paper_individual_gains first (once; later runs reuse it). Then times the real
command, `python -m bwr_twin.replay RUN_DIR --video ...` (interpreter start and the run's
loading included), prints the wall time and the frames rendered per second, and reads the file
back with imageio-ffmpeg's ffmpeg: its frame count, duration, size and bytes.
(target at 10x, 1280x720 and 30 fps, 2,100 frames: at most 2 minutes on the 2-core machine)
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import time
from pathlib import Path

import imageio_ffmpeg

ROOT = Path(__file__).resolve().parents[1]
PAPER_SCENE = "paper_individual_gains"
OUT = ROOT / "out" / "bench-video"


def paper_run() -> Path:
    """The paper's run directory, simulated once."""
    run_dir = OUT / PAPER_SCENE
    if not run_dir.is_dir():
        command = [sys.executable, "-m", "bwr_twin.run", PAPER_SCENE, "--out", str(run_dir), "--no-plots"]
        subprocess.run(command, cwd=ROOT, check=True, stdout=subprocess.DEVNULL)
    return run_dir


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("run_dir", nargs="?", type=Path, help="a run directory (default: the paper's run)")
    parser.add_argument("--size", default="1280x720")
    parser.add_argument("--fps", default="30")
    parser.add_argument("--speed", default="10")
    parser.add_argument("--charts", action="store_true", help="with the strip of error charts")
    args = parser.parse_args()
    run_dir = args.run_dir or paper_run()
    OUT.mkdir(parents=True, exist_ok=True)
    video = OUT / f"{run_dir.name}{'-charts' if args.charts else ''}.mp4"
    command = [sys.executable, "-m", "bwr_twin.replay", str(run_dir), "--video", str(video),
               "--size", args.size, "--fps", args.fps, "--speed", args.speed]
    command += ["--charts"] if args.charts else []
    started = time.perf_counter()
    subprocess.run(command, cwd=ROOT, check=True, stdout=subprocess.DEVNULL)
    wall = time.perf_counter() - started
    frames, seconds = imageio_ffmpeg.count_frames_and_secs(str(video))
    reader = imageio_ffmpeg.read_frames(str(video))
    meta = next(reader)
    reader.close()
    print(f"{' '.join(command[1:])}")
    print(f"wall time {wall:.1f} s: {frames / wall:.1f} frames per second")
    print(f"{video}: {frames} frames, {seconds:g} s, {meta['size'][0]}x{meta['size'][1]} {meta['codec']} "
          f"{meta['pix_fmt']}, {video.stat().st_size / 1e6:.1f} MB")


if __name__ == "__main__":
    main()
