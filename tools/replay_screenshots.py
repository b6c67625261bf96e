"""Screenshots of several runs in the replay, for docs/replay.md: the live page, its chooser and
charts, and the offline export, taken in headless Chromium.

    python -m bwr_twin.compare paper_individual_gains --controllers paper_individual_gains \
        paper_shared_gain pid_paper computed_torque_paper --out out/compare
    python tools/replay_screenshots.py out/compare [--time 300] [--out docs/figures/replay_compare]

Writes four_runs.png (the live page), panel.png (the chooser with the second run hidden, the
readout and the first charts),
export.png (the export, paused at the time by a click on a chart) and side_by_side.png (the first
two runs in a row), each a PNG under 400 kB. Needs Debian's chromium and the `playwright` package.
"""

from __future__ import annotations

import argparse
import io
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))  # the headless-browser driver the browser tests use

from headless import RENDERED_TRIANGLES, chromium_context, find_chromium

from bwr_twin.drawing.geometry import visual_geoms
from bwr_twin.replay import ReplayServer, export_html
from bwr_twin.replay.runs import choose_runs, load_runs

WAIT_MS = 120_000
VIEWPORT = {"width": 1440, "height": 1000}  # as docs/replay.png
MAX_BYTES = 400_000  # a screenshot in the docs
PANEL_HEIGHT = 2400  # px: a window tall enough for the whole GUI panel
NOTICE_CLOSE = ".mantine-Notification-closeButton"  # viser's "software WebGL" notice, in every headless page


def save(png: bytes, path: Path) -> None:
    """As a PNG under MAX_BYTES: as taken if it fits, else in 256 colours (octree keeps the runs'
    few-pixel colours, which median cut merges into grey)."""
    from PIL import Image

    image = Image.open(io.BytesIO(png)).convert("RGB")
    image.save(path, optimize=True)
    if path.stat().st_size > MAX_BYTES:
        image.quantize(colors=256, method=Image.Quantize.FASTOCTREE).save(path, optimize=True)
    print(f"{path} ({path.stat().st_size / 1e3:.0f} kB)")


def settle(page, triangles: int) -> None:
    """Until the renderer draws every machine, with the software-WebGL notice closed."""
    page.wait_for_function(f"() => ({RENDERED_TRIANGLES})() >= {triangles}", timeout=WAIT_MS, polling=100)
    notice = page.locator(NOTICE_CLOSE)
    if notice.count():
        notice.first.dispatch_event("click")  # a click() waits for a still frame, which never comes
    page.wait_for_function(f"() => !document.querySelector('{NOTICE_CLOSE}')", timeout=WAIT_MS)


def triangles_of(server) -> int:
    view = server.view
    return sum(len(g.faces) for g in view.geoms) + sum(len(g.faces) for m in view.machines[1:] for g in m.geoms)


def live(browser, runs, t: float, out: Path) -> None:
    first, *others = runs
    with ReplayServer(first.recording, port=0, name=first.name, others=others) as server:
        page = browser.new_page()
        page.goto(server.url)
        server.player.seek(t)
        settle(page, triangles_of(server))
        page.wait_for_function(f"() => document.querySelector('.bwr-time-cursor')?.dataset.time === '{t:g}'",
                               timeout=WAIT_MS)
        time.sleep(2.0)  # a few frames of the posed scene: software WebGL draws one every few hundred ms
        save(page.screenshot(), out / "four_runs.png")
        page.get_by_role("checkbox").nth(1).dispatch_event("click")  # hide the second run: the charts refit
        page.wait_for_function("() => !document.querySelectorAll('input[type=checkbox]')[1].checked", timeout=WAIT_MS)
        page.set_viewport_size({"width": VIEWPORT["width"], "height": PANEL_HEIGHT})  # the panel unscrolled
        runs_folder = page.get_by_text("Runs", exact=True).first.bounding_box(timeout=WAIT_MS)
        second_chart = page.locator(".uplot-container").nth(1).bounding_box(timeout=WAIT_MS)
        left, top = runs_folder["x"] - 12, runs_folder["y"] - 8
        save(page.screenshot(clip={"x": left, "y": top, "width": VIEWPORT["width"] - left - 12,
                                   "height": second_chart["y"] + second_chart["height"] + 8 - top}), out / "panel.png")
        page.close()
    with ReplayServer(first.recording, port=0, name=first.name, others=others[:1], side_by_side=True) as server:
        page = browser.new_page()
        page.goto(server.url)
        server.player.seek(t)
        settle(page, triangles_of(server) + sum(len(g.faces) for g in server.view.sites[1].geoms))
        time.sleep(2.0)
        save(page.screenshot(), out / "side_by_side.png")
        page.close()


def export(browser, runs, t: float, out: Path) -> None:
    first, *others = runs
    with tempfile.TemporaryDirectory() as scratch:
        html = Path(scratch) / "four.html"
        size = export_html(first.recording, html, name=first.name, others=others)
        print(f"export of {len(runs)} runs: {size / 1e6:.1f} MB")
        page = browser.new_page()
        page.goto(html.as_uri())
        settle(page, sum(len(g.faces) for g in visual_geoms(first.recording.plan.machine)))
        plot = page.locator("#bwr-charts .bwr-plot").first.bounding_box()
        duration = float(first.recording.plan.time[-1] - first.recording.plan.time[0])
        page.mouse.click(plot["x"] + plot["width"] * t / duration, plot["y"] + plot["height"] / 2)
        page.wait_for_function(
            f"() => Math.abs(Number(document.querySelector('.bwr-time-cursor').dataset.time) - {t}) < 2",
            timeout=WAIT_MS)
        time.sleep(2.0)  # the paused scene's last frames
        save(page.screenshot(), out / "export.png")
        page.close()


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("folder", type=Path, help="a bwr_twin.compare output folder")
    parser.add_argument("--time", type=float, default=300.0, help="s of the runs to show (default: 300)")
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "figures" / "replay_compare")
    args = parser.parse_args()
    chromium = find_chromium()
    if chromium is None:
        print("error: no chromium on PATH (apt-get install chromium)", file=sys.stderr)
        return 2
    runs = load_runs(choose_runs([args.folder]))
    args.out.mkdir(parents=True, exist_ok=True)
    with chromium_context(chromium, VIEWPORT) as browser:
        live(browser, runs, args.time, args.out)
        export(browser, runs, args.time, args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
