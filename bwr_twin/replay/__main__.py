"""Replay a reclaim in the browser.

    python -m bwr_twin.replay                     # the paper's reclaim, scenes/paper_individual_gains.toml
    python -m bwr_twin.replay SCENE               # simulate a scene, then replay it
    python -m bwr_twin.replay RUN_DIR             # replay a run of bwr_twin.run, no simulation
    python -m bwr_twin.replay RUN_DIR RUN_DIR ... # several runs of one path in one scene (at most 8)
    python -m bwr_twin.replay COMPARE_DIR         # the runs of a bwr_twin.compare (or batch) folder
    python -m bwr_twin.replay BATCH_DIR --runs '0000-*,0003-*'   # some of them, by name or glob
    python -m bwr_twin.replay RUN_DIR RUN_DIR --side-by-side     # runs of other paths or machines, in a row
    python -m bwr_twin.replay [...] --export FILE.html   # write an offline recording and exit
    python -m bwr_twin.replay [...] --video FILE.mp4     # render an H.264 video offscreen and exit

Serves http://127.0.0.1:8080 until Ctrl-C (--host to listen elsewhere, --port 0 for any free
port; a busy port is replaced by the next free one). A scene is simulated in a child process at
lower CPU priority while the page already shows the machine, its path and the simulation's
progress; the run is cached in out/replay-cache/ as a run directory of `bwr_twin.run`, so the
next replay of the same scene, models and code starts with its timeline. Bad input exits with
status 2 and a one-line message.
"""

from __future__ import annotations

import argparse
import signal
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from bwr_twin.arguments import CommandParser
from bwr_twin.errors import BwrError, leave
from bwr_twin.exposure import exposure_warning
from bwr_twin.ownership import check_output
from bwr_twin.replay.recording import Plan, Recording
from bwr_twin.replay.runs import MAX_RUNS, Run, check_one_world, choose_runs, load_runs
from bwr_twin.replay.video import (
    DEFAULT_FPS,
    DEFAULT_SIZE,
    DEFAULT_SPEED,
    FPS_RANGE,
    MAX_HOURS,
    SIZE_RANGE,
    SPEED_RANGE,
    fps_option,
    size_option,
    speed_option,
    write_video,
)
from bwr_twin.shipped import DEFAULT_SCENE, find_scene
from bwr_twin.sim.budget import FORCE_HELP, check_estimate, estimate

if TYPE_CHECKING:
    from bwr_twin.config.scene import Scene



def _port(text: str) -> int:
    port = int(text)
    if not 0 <= port <= 65535:
        raise argparse.ArgumentTypeError(f"{port} is not a TCP port (0-65535)")
    return port


SIGNAL_CHECK = 0.25  # s between the main thread's looks for a signal


def main(argv: list[str] | None = None) -> int:
    parser = CommandParser(prog="python -m bwr_twin.replay", description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "sources",
        nargs="*",
        type=Path,
        default=[DEFAULT_SCENE],
        metavar="SOURCE",
        help="a scene TOML file, or run directories and compare or batch folders (default: the paper's "
        "individual-gains scene); after a scene, run directories to show with its run",
    )
    parser.add_argument(
        "--runs", type=_patterns, default=(), metavar="NAME,...",
        help=f"only the runs whose directory names match these names or globs (at most {MAX_RUNS} runs in all)"
    )
    parser.add_argument(
        "--side-by-side", action="store_true",
        help="give each run its own rail, pile and path, in a row: runs of other paths or machines"
    )
    parser.add_argument(
        "--host", default="127.0.0.1", help="interface to listen on (default: this machine only)"
    )
    parser.add_argument(
        "--port", type=_port, default=8080, help="TCP port; 0 picks a free one (default: 8080)"
    )
    parser.add_argument(
        "--export", type=Path, metavar="FILE.html", help="write an offline HTML recording and exit"
    )
    parser.add_argument(
        "--video", type=Path, metavar="FILE.mp4", help="render an H.264 video offscreen with MuJoCo and exit"
    )
    parser.add_argument(
        "--fps", type=fps_option, metavar="N",
        help=f"the video's frames per second, {FPS_RANGE[0]:g}-{FPS_RANGE[1]:g} (default: {DEFAULT_FPS:g})"
    )
    parser.add_argument(
        "--speed", type=speed_option, metavar="X", help="simulated seconds per second of video, "
        f"{SPEED_RANGE[0]:g}-{SPEED_RANGE[1]:g} (default: {DEFAULT_SPEED:g})"
    )
    parser.add_argument(
        "--size", type=size_option, metavar="WxH", help="the video's width and height in pixels, even, "
        f"{SIZE_RANGE[0][0]}x{SIZE_RANGE[0][1]} to {SIZE_RANGE[1][0]}x{SIZE_RANGE[1][1]} "
        f"(default: {DEFAULT_SIZE[0]}x{DEFAULT_SIZE[1]})"
    )
    parser.add_argument(
        "--charts", action="store_true", help="the video with a strip of the error charts along its bottom"
    )
    parser.add_argument(
        "--no-cache", action="store_true", help="simulate even if a cached run exists; cache nothing"
    )
    parser.add_argument(
        "--ghost", type=Path, metavar="RUN_DIR", help="one more run directory to show (as a further SOURCE)"
    )
    parser.add_argument(
        "--force", action="store_true",
        help=f"{FORCE_HELP}; a --video even if it would take more than {MAX_HOURS:g} h"
    )
    args = parser.parse_args(argv)
    if args.video is None and (args.fps or args.speed or args.size or args.charts):
        parser.error("--fps, --speed, --size and --charts shape a --video; give one")
    if args.video is not None and (args.export is not None or args.side_by_side):
        parser.error(f"--video draws the runs of one path in one scene; not with "
                     f"{'--export' if args.export is not None else '--side-by-side'}")
    # A terminated replay stops like an interrupted one: server down, simulating child ended.
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(128 + signal.SIGTERM))

    server = None
    try:
        from bwr_twin.replay.simulation import simulate_in_child

        sources = [*args.sources, *([args.ghost] if args.ghost else [])]
        if args.ghost is not None and not args.ghost.is_dir():
            raise BwrError(f"{args.ghost}: --ghost must name a run directory")
        lead = _open(sources, args.runs, use_cache=not args.no_cache)
        recording, scene = lead.recording, lead.scene
        if recording is None:  # before the plan is sampled: a runaway path is refused, not allocated
            check_estimate(estimate([scene], force=args.force), where=scene.path, out_dir=Path("out"), force=args.force)
        plan = recording.plan if recording else Plan.from_scene(scene)
        if not args.side_by_side:
            check_one_world([plan, *(run.recording.plan for run in lead.others)], [lead.where, *lead.folders])
        if args.video is not None:
            return _video(args, lead, sources)
        if args.export is not None:
            inputs = [*sources, *(scene.input_files if scene is not None else ())]
            check_output(args.export, "export", inputs=inputs, option="--export")
            from bwr_twin.replay.export import export_html

            recording = recording or simulate_in_child(scene, use_cache=not args.no_cache)
            size = export_html(recording, args.export, name=lead.name, others=lead.others,
                               side_by_side=args.side_by_side)
            runs = f"{1 + len(lead.others)} runs of " if lead.others else ""
            print(f"wrote {args.export} ({size / 1e6:.1f} MB): {runs}the {recording.plan.duration:g} s {recording.plan.activity}, offline")
            return 0

        from bwr_twin.replay.app import ReplayServer

        server = ReplayServer(recording or plan, host=args.host, port=args.port, name=lead.name, others=lead.others,
                              side_by_side=args.side_by_side)
        if args.port not in (0, server.port):
            print(f"port {args.port} is busy; using {server.port}")
        print(f"replay at {server.url}  (Ctrl-C to stop)", flush=True)
        exposure = exposure_warning(args.host, server.port)
        if exposure:
            print(exposure, file=sys.stderr, flush=True)
        if recording is None:
            server.load(simulate_in_child(scene, use_cache=not args.no_cache, progress=server.show_progress))
            print("simulation done: the timeline is ready", flush=True)
        while True:  # Ctrl-C and SIGTERM may land on one of viser's threads: the main one
            time.sleep(SIGNAL_CHECK)  # runs their handler only once its sleep ends
    except BwrError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 0
    finally:
        if server is not None:
            server.stop()


def _video(args: argparse.Namespace, lead: Lead, sources: list[Path]) -> int:
    """Render the lead run (simulated first if need be) and the others into args.video."""
    from bwr_twin.replay.simulation import simulate_in_child

    inputs = [*sources, *(lead.scene.input_files if lead.scene is not None else ())]
    check_output(args.video, "video", inputs=inputs, option="--video")
    recording = lead.recording or simulate_in_child(lead.scene, use_cache=not args.no_cache)
    fps, speed = args.fps or DEFAULT_FPS, args.speed or DEFAULT_SPEED
    try:
        written = write_video([recording, *(run.recording for run in lead.others)], args.video,
                              names=[lead.name, *(run.name for run in lead.others)], fps=fps, speed=speed,
                              size=args.size or DEFAULT_SIZE, charts=args.charts, force=args.force)
    except KeyboardInterrupt:
        print("interrupted: nothing written", file=sys.stderr)
        return 130
    print(f"wrote {args.video} ({written.bytes / 1e6:.1f} MB): {written.frames} frames, "
          f"{written.seconds:g} s at {fps:g} fps, the {recording.plan.duration:g} s run at {speed:g}x, "
          f"in {written.wall:.0f} s")
    return 0


def _patterns(text: str) -> tuple[str, ...]:
    patterns = tuple(p.strip() for p in text.split(",") if p.strip())
    if not patterns:
        raise argparse.ArgumentTypeError("give run directory names or globs, comma-separated")
    return patterns


@dataclass
class Lead:
    """The first run (a recording, or a scene still to simulate) and the runs shown beside it."""

    recording: Recording | None
    scene: Scene | None
    name: str  # what the chooser calls it
    where: Path  # its run directory or scene file, for messages
    others: list[Run]
    folders: list[Path]  # the others' run directories


def _open(sources: list[Path], patterns: tuple[str, ...], *, use_cache: bool) -> Lead:
    """The runs to show: all from run directories (and compare or batch folders), or the first
    from a scene (its cached run, or None to simulate) and the rest from run directories."""
    from bwr_twin.config.scene import load_scene
    from bwr_twin.replay.simulation import cached_run

    first = sources[0]
    for source in sources[1:]:
        if source.is_file() or source.suffix == ".toml":
            raise BwrError(f"{source}: only the first source may be a scene; the others must be run directories")
    if first.is_dir():
        folders = choose_runs(sources, patterns)
        runs = load_runs(folders)
        return Lead(runs[0].recording, None, runs[0].name, folders[0], runs[1:], folders[1:])
    scene = load_scene(find_scene(first))
    folders = choose_runs(sources[1:], patterns, also=1) if sources[1:] or patterns else []
    others = load_runs(folders)
    cached = cached_run(scene)
    recording = Recording.from_run_dir(cached) if use_cache and cached.is_dir() else None
    return Lead(recording, scene, scene.path.stem, scene.path, others, folders)


if __name__ == "__main__":
    leave(main())
