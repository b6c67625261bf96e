"""Seconds from `python -m bwr_twin.replay` to a browser page that shows the machine, or every
machine of several runs.

    python tools/bench_replay.py [SCENE | RUN_DIR] [--cached] [--runs N]
    python tools/bench_replay.py COMPARE_DIR --against-one [--runs N]

Starts headless Chromium first (a user's browser is already open), then launches the real
command with --port 0 (and --no-cache unless --cached, so the simulation is part of it), reads
the URL it prints, loads the page and polls until the renderer has drawn at least as many
triangles as the machines' visual geoms have, that is, until every machine is on the canvas.
Prints that time, and when the simulation is done and the timeline ready.

With a folder of several run directories (a `bwr_twin.compare` output) and --against-one, it
times the replay of all of them against the replay of the first alone, launch for launch in
turn, and prints the ratio of the medians. Needs Debian's chromium and the `playwright` Python
package (no `playwright install`).
"""

from __future__ import annotations

import argparse
import re
import statistics
import subprocess
import sys
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))  # the headless-browser driver the browser tests use

from headless import RENDERED_TRIANGLES, chromium_context, find_chromium

from bwr_twin.shipped import DEFAULT_SCENE

TIMEOUT = 60.0  # s, per stage


def machine_triangles(source: Path) -> int:
    """Triangles of the machines' visual geoms, from the scene's (or runs') MJCF: all of the first
    run's, and the moving ones of each other run of its world."""
    from bwr_twin.config.scene import load_scene
    from bwr_twin.drawing.geometry import BodyPoser, visual_geoms
    from bwr_twin.model.machine import Machine
    from bwr_twin.replay.runs import run_folders
    from bwr_twin.results.run_files import read_scene
    from bwr_twin.results.rundir import SCENE_FILE

    if not source.is_dir():
        return sum(len(g.faces) for g in visual_geoms(Machine(load_scene(source).machine.mjcf)))
    total = 0
    for k, folder in enumerate(run_folders(source)):
        machine = Machine(read_scene(folder / SCENE_FILE).mjcf)
        poser = BodyPoser(machine)
        moving = {name for name, moves in zip(poser.names, poser.moving) if moves}
        total += sum(len(g.faces) for g in visual_geoms(machine) if k == 0 or g.body in moving)
    return total


def measure(page, source: Path, cached: bool, triangles: int) -> tuple[float, float | None]:
    """(seconds to the machine on screen, seconds to the timeline) for one launch of the command."""
    command = [sys.executable, "-m", "bwr_twin.replay", str(source), "--port", "0"] + (
        [] if cached else ["--no-cache"]
    )
    started = time.perf_counter()
    proc = subprocess.Popen(command, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    ready: list[float] = []
    try:
        url = None
        while url is None:
            line = proc.stdout.readline()
            if not line:
                raise RuntimeError(f"the replay exited with status {proc.wait()} before printing its URL")
            if match := re.search(r"http://\S+", line):
                url = match.group(0)

        def watch_for_timeline() -> None:
            for line in proc.stdout:
                if "timeline is ready" in line:
                    ready.append(time.perf_counter() - started)

        threading.Thread(target=watch_for_timeline, daemon=True).start()
        page.goto(url)
        page.wait_for_function(
            f"() => ({RENDERED_TRIANGLES})() >= {triangles}", timeout=TIMEOUT * 1000, polling=50
        )
        shown = time.perf_counter() - started
        if cached:
            ready.append(shown)  # a cached run has its timeline from the start
        deadline = time.perf_counter() + TIMEOUT
        while not ready and time.perf_counter() < deadline:
            time.sleep(0.05)
        return shown, (ready[0] if ready else None)
    finally:
        proc.terminate()
        proc.wait(timeout=10)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "source", nargs="?", type=Path, default=DEFAULT_SCENE, help="scene file or run directory"
    )
    parser.add_argument("--cached", action="store_true", help="let the replay use (and fill) its run cache")
    parser.add_argument("--runs", type=int, default=3, help="launches to time (default: 3)")
    parser.add_argument("--against-one", action="store_true",
                        help="time the folder's runs together against its first run alone")
    args = parser.parse_args()
    chromium = find_chromium()
    if chromium is None:
        print("error: no chromium on PATH (apt-get install chromium)", file=sys.stderr)
        return 2
    if args.against_one:
        return _against_one(chromium, args.source, args.runs)

    triangles = machine_triangles(args.source)
    shown, ready = [], []
    with chromium_context(chromium) as browser:
        for run in range(args.runs):
            page = browser.new_page()
            seconds, timeline = measure(page, args.source, args.cached, triangles)
            page.close()
            shown.append(seconds)
            if timeline is not None:
                ready.append(timeline)
            print(
                f"run {run + 1}: machine on screen after {seconds:.2f} s, timeline ready after "
                + (f"{timeline:.2f} s" if timeline is not None else "(not within the time limit)")
            )
    kind = "cached run" if args.cached else "simulation included"
    print(
        f"command to a page showing the machine: median {statistics.median(shown):.2f} s, "
        f"max {max(shown):.2f} s over {len(shown)} runs ({kind})"
    )
    if ready:
        print(f"command to a ready timeline: median {statistics.median(ready):.2f} s")
    return 0


def _against_one(chromium: str, folder: Path, launches: int) -> int:
    """Several runs against the first alone, launch for launch in turn; prints both and their ratio."""
    from bwr_twin.replay.runs import run_folders

    folder = folder.resolve()  # the command runs in the checkout
    runs = run_folders(folder)
    if len(runs) < 2:
        print(f"error: {folder}: --against-one needs a folder of several run directories", file=sys.stderr)
        return 2
    cases = {"one run": (runs[0], machine_triangles(runs[0])), f"{len(runs)} runs": (folder, machine_triangles(folder))}
    shown: dict[str, list[float]] = {name: [] for name in cases}
    with chromium_context(chromium) as browser:
        for launch in range(launches):
            for name, (source, triangles) in cases.items():
                page = browser.new_page()
                seconds, _ = measure(page, source, True, triangles)
                page.close()
                shown[name].append(seconds)
                print(f"launch {launch + 1}, {name}: every machine on screen after {seconds:.2f} s")
    one, several = (statistics.median(times) for times in shown.values())
    print(f"command to a page showing every machine: one run median {one:.2f} s, {len(runs)} runs median "
          f"{several:.2f} s over {launches} launches each: {several / one:.2f}x")
    return 0


if __name__ == "__main__":
    sys.exit(main())
