"""Seconds from `python -m bwr_twin.replay` to a browser page that shows the machine.

    python tools/bench_replay.py [SCENE | RUN_DIR] [--cached] [--runs N]

Starts headless Chromium first (a user's browser is already open), then launches the real
command with --port 0 (and --no-cache unless --cached, so the simulation is part of it), reads
the URL it prints, loads the page and polls until the renderer has drawn at least as many
triangles as the machine's visual geoms have, that is, until the machine is on the canvas.
Prints that time, and when the simulation is done and the timeline ready. Needs Debian's
chromium and the `playwright` Python package (no `playwright install`).
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

from headless import RENDERED_TRIANGLES, chromium_context, find_chromium  # noqa: E402

from bwr_twin.shipped import DEFAULT_SCENE  # noqa: E402

TIMEOUT = 60.0  # s, per stage


def machine_triangles(source: Path) -> int:
    """Triangles of the machine's visual geoms, from the scene's (or run's) MJCF."""
    import json

    from bwr_twin.config.scene import load_scene
    from bwr_twin.model.machine import Machine
    from bwr_twin.replay.geometry import visual_geoms

    mjcf = (
        json.loads((source / "scene.json").read_text())["machine"]["mjcf"]
        if source.is_dir()
        else load_scene(source).machine.mjcf
    )
    return sum(len(g.faces) for g in visual_geoms(Machine(mjcf)))


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
    args = parser.parse_args()
    chromium = find_chromium()
    if chromium is None:
        print("error: no chromium on PATH (apt-get install chromium)", file=sys.stderr)
        return 2

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


if __name__ == "__main__":
    sys.exit(main())
