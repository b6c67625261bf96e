"""Replay a reclaim in the browser.

    python -m bwr_twin.replay                     # the paper's reclaim, scenes/paper_individual_gains.toml
    python -m bwr_twin.replay SCENE               # simulate a scene, then replay it
    python -m bwr_twin.replay RUN_DIR             # replay a run of bwr_twin.run, no simulation
    python -m bwr_twin.replay [...] --export FILE.html   # write an offline recording and exit
    python -m bwr_twin.replay RUN_DIR --ghost RUN_DIR2   # a second run of the path, translucent

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
from pathlib import Path
from typing import TYPE_CHECKING


from bwr_twin.arguments import CommandParser
from bwr_twin.errors import BwrError
from bwr_twin.exposure import exposure_warning
from bwr_twin.replay.recording import Plan, Recording, path_difference
from bwr_twin.results.ownership import check_output
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
        "source",
        nargs="?",
        type=Path,
        default=DEFAULT_SCENE,
        help="scene TOML file or run directory (default: the paper's individual-gains scene)",
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
        "--no-cache", action="store_true", help="simulate even if a cached run exists; cache nothing"
    )
    parser.add_argument(
        "--ghost", type=Path, metavar="RUN_DIR", help="another run of the same path (say, another "
        "controller's, from bwr_twin.compare), shown as a translucent machine"
    )
    parser.add_argument(
        "--force", action="store_true", help=FORCE_HELP
    )
    args = parser.parse_args(argv)
    # A terminated replay stops like an interrupted one: server down, simulating child ended.
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(128 + signal.SIGTERM))

    server = None
    try:
        from bwr_twin.replay.simulation import simulate_in_child

        recording, scene = _open(args.source, use_cache=not args.no_cache)
        ghost = _ghost(args.ghost, recording.plan if recording else Plan.from_scene(scene)) if args.ghost else None
        if recording is None:
            check_estimate(estimate([scene]), where=scene.path, out_dir=Path("out"), force=args.force)
        if args.export is not None:
            inputs = [args.source, *(scene.input_files if scene is not None else ())]
            check_output(args.export, "export", inputs=inputs, option="--export")
            from bwr_twin.replay.export import export_html

            recording = recording or simulate_in_child(scene, use_cache=not args.no_cache)
            size = export_html(recording, args.export, ghost=ghost)
            duration = recording.plan.duration
            print(f"wrote {args.export} ({size / 1e6:.1f} MB): the {duration:g} s reclaim, offline")
            return 0

        from bwr_twin.replay.app import ReplayServer

        server = ReplayServer(recording or Plan.from_scene(scene), host=args.host, port=args.port, ghost=ghost)
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


def _ghost(run_dir: Path, plan: Plan) -> tuple[Recording, str]:
    """The ghost's recording and name, once it is known to follow the same path."""
    if not run_dir.is_dir():
        raise BwrError(f"{run_dir}: --ghost must name a run directory")
    ghost = Recording.from_run_dir(run_dir)
    differs = path_difference(ghost.plan, plan)
    if differs:
        raise BwrError(f"{run_dir}: --ghost follows another path than the replay: {differs}")
    return ghost, run_dir.name


def _open(source: Path, *, use_cache: bool) -> tuple[Recording | None, Scene | None]:
    """(recording, None) for a run directory or a cached scene run, else (None, scene)."""
    from bwr_twin.config.scene import load_scene
    from bwr_twin.replay.simulation import cached_run

    if source.is_dir():
        return Recording.from_run_dir(source), None
    scene = load_scene(find_scene(source))
    cached = cached_run(scene)
    if use_cache and cached.is_dir():
        return Recording.from_run_dir(cached), None
    return None, scene


if __name__ == "__main__":
    sys.exit(main())
