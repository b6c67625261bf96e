"""The replay in a real headless Chromium: the page draws the machine, Play advances the time
slider, four controllers share one page and the chooser hides one, the charts' cursor follows the
timeline and a click on a chart seeks it, and the exported HTML plays from a file:// URL, its
charts' cursor following the playback. Screenshots go to test-artifacts/.

The browser is Debian's `chromium`, driven by Python playwright (never `playwright install`).
Without it these tests skip and say why; with CI=true a missing browser fails them instead.
WebGL renders in software there, so waits are generous: every wait is on a state (a control
shown and enabled, a button's new label, the player's time, a pose), never a fixed sleep, and every
Playwright call waits up to WAIT_MS, clicks included (a click first waits for the control's box
to stand still over two animation frames, which take seconds each on a busy machine).
"""

import io
import os
import time
from collections import Counter

import numpy as np
import pytest
from conftest import ROOT, SCENES, SHORT_VIA_POINTS
from headless import RENDERED_TRIANGLES, chromium_context, find_chromium

from bwr_twin.drawing.geometry import visual_geoms
from bwr_twin.replay import Recording, ReplayServer, export_html

try:
    from playwright.sync_api import expect
except ImportError:  # the browser fixture skips these tests, and says why
    expect = None

pytestmark = pytest.mark.browser

ARTIFACTS = ROOT / "test-artifacts"
WAIT_MS = 90_000  # software WebGL on a busy 2-core machine
MACHINE_SHARE = 1e-3  # of the screenshot's pixels in the machine's colour: it is on the canvas


def _unavailable(reason: str):
    if os.environ.get("CI") == "true":
        pytest.fail(f"{reason}; CI=true requires the browser tests to run")
    pytest.skip(reason)


@pytest.fixture(scope="module")
def browser():
    chromium = find_chromium()
    if chromium is None:
        _unavailable("no chromium on PATH (apt-get install --no-install-recommends chromium)")
    try:
        import playwright  # noqa: F401
    except ImportError:
        _unavailable("the playwright Python package is not installed (pip install -e '.[dev]')")
    with chromium_context(chromium) as context:
        context.set_default_timeout(WAIT_MS)  # goto, click, screenshot: not Playwright's 30 s
        yield context


def record(folder, via_points) -> Recording:
    """The individual-gains scene over `via_points`, simulated and read back as the replay reads it."""
    from bwr_twin.config.scene import load_scene
    from bwr_twin.results.rundir import write_run
    from bwr_twin.sim.lockstep import simulate

    write_run(simulate(load_scene(SCENES / "paper_individual_gains.toml", {"path.via_points": via_points})),
              folder, plots=False)
    return Recording.from_run_dir(folder)


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    return record(tmp_path_factory.mktemp("browser") / "short", SHORT_VIA_POINTS)


def wait_for_machine(page, geoms) -> None:
    """Until the renderer's last frame drew at least the machine's triangles."""
    triangles = sum(len(g.faces) for g in geoms)
    page.wait_for_function(
        f"() => ({RENDERED_TRIANGLES})() >= {triangles}",
        timeout=WAIT_MS,
        polling=100,
    )


def click(control) -> None:
    """A user's click on a control of the page, once it shows and is enabled."""
    expect(control).to_be_visible(timeout=WAIT_MS)
    expect(control).to_be_enabled(timeout=WAIT_MS)
    control.click(timeout=WAIT_MS)


def until(condition, what: str) -> None:
    """Wait for a condition of the replay server's own state, which the page changes."""
    deadline = time.monotonic() + WAIT_MS / 1000
    while not condition():
        assert time.monotonic() < deadline, f"not within {WAIT_MS / 1000:g} s: {what}"
        time.sleep(0.1)


def machine_pixels(png: bytes, geoms, tolerance: float = 0.04) -> float:
    """Share of the picture in the machine's commonest colour (any shade of it; `tolerance` in
    chromaticity, wider for a machine seen through translucent ones)."""
    from PIL import Image

    rgb = np.asarray(Image.open(io.BytesIO(png)).convert("RGB"), dtype=float)
    colour = np.array(Counter(g.rgba[:3] for g in geoms).most_common(1)[0][0])
    chromaticity = rgb / np.maximum(rgb.sum(axis=2, keepdims=True), 1.0)
    close = np.linalg.norm(chromaticity - colour / colour.sum(), axis=2) < tolerance
    return float(np.mean(close & (rgb.sum(axis=2) > 60)))


def screenshot_showing_machine(page, geoms, name: str, tolerance: float = 0.04) -> bytes:
    """A screenshot, saved to test-artifacts/, once the machine's colour shows (the page fades in)."""
    deadline = time.monotonic() + WAIT_MS / 1000
    while True:
        png = page.screenshot(timeout=WAIT_MS)
        if machine_pixels(png, geoms, tolerance) > MACHINE_SHARE or time.monotonic() > deadline:
            break
        time.sleep(1.0)
    ARTIFACTS.mkdir(exist_ok=True)
    (ARTIFACTS / name).write_bytes(png)
    return png


def test_page_renders_the_machine_and_play_advances_time(browser, recording):
    with ReplayServer(recording, port=0) as server:
        page = browser.new_page()
        try:
            page.goto(server.url)
            wait_for_machine(page, server.view.geoms)
            play = page.get_by_role("button", name="Play")
            time_slider = page.locator('[role="slider"][aria-valuemax="20"]')  # the run lasts 20 s
            expect(time_slider).to_be_visible(timeout=WAIT_MS)
            before = float(time_slider.get_attribute("aria-valuenow", timeout=WAIT_MS))
            click(play)
            page.wait_for_function(
                "before => Number(document.querySelector('[role=slider][aria-valuemax=\"20\"]')"
                ".getAttribute('aria-valuenow')) > before + 1",
                arg=before,
                timeout=WAIT_MS,
            )
            assert server.player.playing or server.player.time == server.player.end
            png = screenshot_showing_machine(page, server.view.geoms, "replay.png")
            assert machine_pixels(png, server.view.geoms) > MACHINE_SHARE
        finally:
            page.close()


CONTROLLERS = ("paper_shared_gain", "pid_paper", "computed_torque_paper")  # beside the individual gains
TINTED = 0.1  # chromaticity tolerance for the solid machine seen through three translucent ones
GRADE_REPAINTED = 0.005  # of the scene's pixels: the small stacked pile, in grade colours instead of ore


def changed_pixels(before: bytes, after: bytes) -> float:
    """Share of the picture whose colour changed by more than a shade."""
    from PIL import Image

    a, b = (np.asarray(Image.open(io.BytesIO(png)).convert("RGB"), dtype=float) for png in (before, after))
    return float(np.mean(np.abs(a - b).sum(axis=2) > 30))


@pytest.fixture(scope="module")
def four_runs(recording, tmp_path_factory):
    """The short path under four controllers: the individual gains' run first, as Runs."""
    from bwr_twin.config.scene import load_scene
    from bwr_twin.replay.runs import Run
    from bwr_twin.results.rundir import write_run
    from bwr_twin.sim.lockstep import simulate

    folder = tmp_path_factory.mktemp("four")
    runs = [Run(recording, "paper_individual_gains")]
    for name in CONTROLLERS:
        table = load_scene(SCENES / f"{name}.toml").controller.to_dict()
        table = {k: list(v) if isinstance(v, tuple) else str(v) if hasattr(v, "parts") else v for k, v in table.items()}
        scene = load_scene(SCENES / "paper_individual_gains.toml",
                           {"path.via_points": SHORT_VIA_POINTS, "controller": table})
        write_run(simulate(scene), folder / name, plots=False)
        runs.append(Run(Recording.from_run_dir(folder / name), name))
    return runs


@pytest.fixture(scope="class")
def four_runs_page(browser, four_runs):
    """The four runs served, and one page that shows them all (the first solid, the rest translucent),
    open for the tests of one class only: a live page left open renders on, in software, and
    slows every page the module opens after it."""
    first, *others = four_runs
    with ReplayServer(first.recording, port=0, name=first.name, others=others) as server:
        page = browser.new_page()
        try:
            page.goto(server.url)
            machines = server.view.machines
            triangles = sum(len(g.faces) for g in server.view.geoms) + sum(
                len(g.faces) for machine in machines[1:] for g in machine.geoms)
            page.wait_for_function(f"() => ({RENDERED_TRIANGLES})() >= {triangles}", timeout=WAIT_MS, polling=100)
            yield server, page
        finally:
            page.close()


# Each run's machine hangs under the scene node /runs/<k>: the page's scene tree says which it shows.
RUNS_SHOWN = """() => Object.entries(window.__viserSceneTree?.getState() ?? {})
    .filter(([name]) => /^\\/runs\\/\\d+$/.test(name))
    .map(([name, node]) => [name, node.visibility !== false])"""


CURSOR = "document.querySelector('.bwr-time-cursor')"


class TestFourRunsServedOnOnePage:
    """The four runs on one live page, which closes after them."""

    def test_four_controllers_share_one_world_and_the_chooser_hides_one(self, four_runs_page, four_runs):
        server, page = four_runs_page
        boxes = page.get_by_role("checkbox")
        expect(boxes).to_have_count(4, timeout=WAIT_MS)
        for k, run in enumerate(four_runs):
            expect(boxes.nth(k)).to_be_checked(timeout=WAIT_MS)
            expect(page.get_by_text(run.label)).to_be_visible(timeout=WAIT_MS)
        assert sorted(page.evaluate(RUNS_SHOWN)) == [[f"/runs/{k}", True] for k in range(4)]
        server.player.seek(10.0)
        # Each machine stands where its own run stood at 10 s.
        until(lambda: all(stands_at(m, run.recording, 10.0) for m, run in zip(server.view.machines, four_runs)),
              "each machine at its run's 10 s")
        assert not np.allclose(four_runs[1].recording.at(10.0).q_actual, four_runs[0].recording.at(10.0).q_actual)
        geoms = server.view.geoms
        four = screenshot_showing_machine(page, geoms, "replay_four_runs.png", TINTED)
        assert machine_pixels(four, geoms, TINTED) > MACHINE_SHARE  # the solid machine, seen through the others
        readout_row = page.locator("td", has_text="pid_paper")  # its row in the readout's table
        expect(readout_row).to_have_count(1, timeout=WAIT_MS)

        click(boxes.nth(2))  # pid_paper
        until(lambda: server.player.shown == [True, True, False, True], "the player hiding run 3")
        shown = "[['/runs/0', true], ['/runs/1', true], ['/runs/2', false], ['/runs/3', true]]"
        page.wait_for_function(f"() => JSON.stringify(({RUNS_SHOWN})().sort()) === JSON.stringify({shown})",
                               timeout=WAIT_MS, polling=100)
        # Its translucent machine lay over the others: without it, the machine's pixels change.
        deadline = time.monotonic() + WAIT_MS / 1000
        while changed_pixels(four, three := page.screenshot(timeout=WAIT_MS)) < MACHINE_SHARE:
            assert time.monotonic() < deadline, "hiding a run changed nothing on the canvas"
        (ARTIFACTS / "replay_three_runs.png").write_bytes(three)
        chart = server.player.panel.chart_handles[0]  # position error, travel: a line per run shown
        assert [series["label"].split(" [")[0] for series in chart.series[1:]] == [
            "paper_individual_gains", "paper_shared_gain", "computed_torque_paper"]
        expect(readout_row).to_have_count(0, timeout=WAIT_MS)  # gone from the readout
        click(boxes.nth(2))
        until(lambda: all(server.player.shown), "the player showing run 3 again")


    def test_the_charts_cursor_follows_the_timeline_and_a_click_seeks_it(self, four_runs_page):
        server, page = four_runs_page
        lefts = []
        for t in (5.0, 15.0):
            server.player.seek(t)
            # The cursor takes the time first and its place once the chart is laid out: wait for both,
            # however long a busy machine takes to lay it out, within a pixel of the chart's own x.
            page.wait_for_function(f"""() => {{
                const cursor = {CURSOR}, chart = Object.values(window.__viserTestpoints.uplots)[0]?.chart;
                if (!cursor || !chart || cursor.dataset.time !== '{t:g}') return false;
                const left = parseFloat(cursor.style.left), x = chart.valToPos({t}, 'x');
                return Number.isFinite(left) && Number.isFinite(x) && Math.abs(left - x) <= 1.0;
            }}""", timeout=WAIT_MS, polling=100)
            lefts.append(page.evaluate(f"() => parseFloat({CURSOR}.style.left)"))
        assert lefts[1] > lefts[0] + 20
        # A click at 12 s on the first chart seeks there.
        chart = page.locator(".uplot-container .u-over").first
        chart.scroll_into_view_if_needed(timeout=WAIT_MS)
        x = page.evaluate("() => Object.values(window.__viserTestpoints.uplots)[0].chart.valToPos(12, 'x')")
        box = chart.bounding_box(timeout=WAIT_MS)
        page.mouse.click(box["x"] + x, box["y"] + box["height"] / 2)
        until(lambda: abs(server.player.time - 12.0) < 0.3, "the click's seek to 12 s")
        page.wait_for_function(f"() => Math.abs(Number({CURSOR}?.dataset.time) - 12) < 0.3", timeout=WAIT_MS)


def stands_at(machine, run, t: float) -> bool:
    """Whether a run's machine in the replay stands where `run` stood at time t."""
    own = machine.own
    positions, _ = own.poser.poses(run.at(t).q_actual)
    return all(np.allclose(frame.position, positions[i], atol=1e-6) for frame, i in zip(own.bodies, own.moving))


# The short path over four of WAIT_MS: played at the slowest speed (1 x real time), the run cannot
# end, and turn Pause back into Play, while two software-rendered tabs catch up, however slowly.
LONG_S = 4 * WAIT_MS / 1000
LONG_VIA_POINTS = [SHORT_VIA_POINTS[0], {**SHORT_VIA_POINTS[1], "t": LONG_S}]


def test_two_tabs_share_one_timeline(browser, tmp_path):
    long = record(tmp_path / "long", LONG_VIA_POINTS)
    with ReplayServer(long, port=0) as server:
        server.player.set_speed(1)
        tabs = [browser.new_page(), browser.new_page()]
        try:
            for tab in tabs:
                tab.set_viewport_size(
                    {"width": 800, "height": 600}
                )  # two software-rendered tabs: keep them small
                tab.goto(server.url)
                expect(tab.get_by_role("button", name="Play")).to_be_enabled(timeout=WAIT_MS)
            click(tabs[0].get_by_role("button", name="Play"))
            until(lambda: server.player.playing, "the player playing")
            for tab in tabs:  # the other tab sees it too
                expect(tab.get_by_role("button", name="Pause")).to_be_visible(timeout=WAIT_MS)
            tabs[1].bring_to_front()
            click(tabs[1].get_by_role("button", name="Pause"))
            until(lambda: not server.player.playing, "the player paused")
            assert server.player.time < server.player.end  # paused by the click, not by the run's end
            for tab in tabs:
                expect(tab.get_by_role("button", name="Play")).to_be_visible(timeout=WAIT_MS)
            slider = f'[role="slider"][aria-valuemax="{LONG_S:g}"]'
            server.player.seek(12.0)
            for tab in tabs:
                tab.wait_for_function(
                    f"() => Number(document.querySelector('{slider}').getAttribute('aria-valuenow')) === 12",
                    timeout=WAIT_MS,
                )
        finally:
            for tab in tabs:
                tab.close()


def test_export_plays_from_a_file_url(browser, recording, tmp_path):
    out = tmp_path / "replay.html"
    export_html(recording, out)
    geoms = visual_geoms(recording.plan.machine)
    page = browser.new_page()
    fetched = []
    page.on("request", lambda request: fetched.append(request.url))
    try:
        page.goto(out.resolve().as_uri())
        wait_for_machine(page, geoms)
        png = screenshot_showing_machine(page, geoms, "export.png")
        assert machine_pixels(png, geoms) > MACHINE_SHARE
        assert [url for url in fetched if not url.startswith(("file:", "data:", "blob:"))] == []
    finally:
        page.close()


def test_an_export_of_four_runs_charts_them_beside_the_scene_with_a_cursor_that_seeks(browser, four_runs,
                                                                                       tmp_path):
    first, *others = four_runs
    out = tmp_path / "four.html"
    export_html(first.recording, out, name=first.name, others=others)
    geoms = visual_geoms(first.recording.plan.machine)
    page = browser.new_page()
    page.set_viewport_size({"width": 960, "height": 600})  # software WebGL draws a playing scene slowly
    try:
        page.goto(out.resolve().as_uri())
        wait_for_machine(page, geoms)
        expect(page.locator("#bwr-charts .bwr-chart")).to_have_count(9, timeout=WAIT_MS)  # 3 quantities x 3 axes
        # The recording plays: the cursor follows its time.
        page.wait_for_function(f"() => Number({CURSOR}?.dataset.time) > 1", timeout=WAIT_MS, polling=100)
        plot = page.locator("#bwr-charts .bwr-plot").first
        box = plot.bounding_box(timeout=WAIT_MS)
        page.mouse.click(box["x"] + 0.75 * box["width"], box["y"] + 0.5 * box["height"])  # at 15 s of 20
        page.wait_for_function(f"() => Math.abs(Number({CURSOR}.dataset.time) - 15) < 0.2", timeout=WAIT_MS,
                               polling=100)
        # The playback paused there: at 1.5 s of the recording, which plays the run at 10x.
        playback = "Number(document.querySelector('[role=slider]').getAttribute('aria-valuenow'))"
        page.wait_for_function(f"() => Math.abs({playback} - 1.5) < 0.02", timeout=WAIT_MS, polling=100)
        png = screenshot_showing_machine(page, geoms, "export_four_runs.png", TINTED)
        assert machine_pixels(png, geoms, TINTED) > MACHINE_SHARE
    finally:
        page.close()


def test_the_pile_is_dug_as_the_replay_plays(browser, tmp_path):
    from test_stockpile import SHORT_DIG

    from bwr_twin.config.scene import load_scene
    from bwr_twin.replay.simulation import PILE_FRAME_PERIOD
    from bwr_twin.results.rundir import write_run
    from bwr_twin.sim.lockstep import simulate

    scene = load_scene(SCENES / "heavy_dig_pile.toml", SHORT_DIG)
    write_run(simulate(scene, pile_frame_period=PILE_FRAME_PERIOD), tmp_path / "dig", plots=False)
    dig = Recording.from_run_dir(tmp_path / "dig")
    assert len(dig.pile.frame_time) > 5  # the pile as it was dug, every few seconds

    with ReplayServer(dig, port=0) as server:
        page = browser.new_page()
        try:
            page.goto(server.url)
            tiles = server.view.sites[0].pile._tiles
            pile_triangles = sum(len(t._ore.faces) + len(t._cut.faces) for t in tiles)
            machine_triangles = sum(len(g.faces) for g in server.view.geoms)
            page.wait_for_function(f"() => ({RENDERED_TRIANGLES})() >= {machine_triangles + pile_triangles}",
                                   timeout=WAIT_MS, polling=100)  # the browser draws the whole pile
            assert all(len(t._cut.faces) == 1 for t in tiles)  # nothing cut yet: each a placeholder
            server.player.seek(float(dig.plan.time[-1]))
            until(lambda: any(len(t._cut.faces) > 1 for t in tiles), "a tile sent again as dug")
            cut = [t for t in tiles if len(t._cut.faces) > 1]
            start, tile = server.view.sites[0].pile._start, cut[0]
            assert (start[tile.rows, tile.cols].ravel() - tile._cut.vertices[:, 2]).max() > 0.3  # m lower than it stood
            screenshot_showing_machine(page, server.view.geoms, "replay_pile_dug.png")
            server.player.seek(0.0)  # back in time: the pile stands whole again
            until(lambda: all(len(t._cut.faces) == 1 for t in tiles), "every tile a placeholder again")
        finally:
            page.close()


JUMP_BUTTONS = """() => {
    const label = [...document.querySelectorAll('label')].find(l => l.textContent === 'Jump to');
    let row = label;
    while (row && !row.querySelector('button')) row = row.parentElement;
    return row ? [...row.querySelectorAll('button')].map(b => b.textContent) : [];
}"""
# viser draws labels on the canvas, not in the DOM: the page's scene tree (its E2E hook) holds them.
SCENE_LABELS = """() => Object.values(window.__viserSceneTree?.getState() ?? {})
    .filter(n => n?.message?.type === 'LabelMessage').map(n => n.message.props.text)"""


def test_a_bench_reclaim_names_its_bench_and_passes_in_the_page(browser, tmp_path):
    """The small bench scene of test_reclaim_plan, replayed: the bench is a Jump-to button that
    seeks to its start and a label where the run began it; the passes, a metre apart, are named
    on the time slider and in the readout's plan line, not by labels on top of each other."""
    from test_reclaim_plan import small_scene

    from bwr_twin.replay.simulation import PILE_FRAME_PERIOD
    from bwr_twin.results.rundir import write_run
    from bwr_twin.sim.lockstep import simulate

    result = simulate(small_scene(tmp_path), pile_frame_period=PILE_FRAME_PERIOD)
    write_run(result, tmp_path / "bench", plots=False)
    bench = Recording.from_run_dir(tmp_path / "bench")

    with ReplayServer(bench, port=0) as server:
        page = browser.new_page()
        try:
            page.goto(server.url)
            jump = page.get_by_role("button", name="bench 1")
            expect(jump).to_be_enabled(timeout=WAIT_MS)
            assert page.evaluate(JUMP_BUTTONS) == ["bench 1"]  # the benches only, not every pass
            page.wait_for_function(f"() => ({SCENE_LABELS})().length > 0", timeout=WAIT_MS, polling=100)
            labels = page.evaluate(SCENE_LABELS)
            lines = [line for label in labels for line in label.split("\n")]  # close points share a label
            assert any(line.startswith("bench 1  t = 0 s") for line in lines), labels
            assert not any(line.startswith("pass") for line in lines), labels
            expect(page.get_by_text("plan: bench 1").first).to_be_visible(timeout=WAIT_MS)  # the readout
            server.player.seek(50.0)
            until(lambda: server.player.time == 50.0, "the seek to 50 s")
            jump.dispatch_event("click")  # click() waits ~25 s for the button to be "stable" here
            until(lambda: server.player.time == bench.plan.landmarks[0][1], "the jump to bench 1")
        finally:
            page.close()


def test_a_stacking_replay_colours_its_pile_by_grade(browser):
    """The small stacking of test_stacking, replayed at its end: "Pile colour" grade repaints the
    pile in its top layers' grades (the scene, left of the panel, changes) and shows the legend."""
    from test_stacking import SCENE, SMALL

    from bwr_twin.config.scene import load_scene
    from bwr_twin.sim.lockstep import simulate

    stacking = Recording.from_result(simulate(load_scene(SCENE, SMALL), pile_frame_period=10.0))
    with ReplayServer(stacking, port=0) as server:
        server.player.seek(float(stacking.plan.time[-1]))
        pile = server.view.sites[0].pile
        until(lambda: pile.dug._applied == len(stacking.pile.frame_time), "the pile at its end")
        page = browser.new_page()
        page.set_viewport_size({"width": 960, "height": 600})  # software WebGL: a smaller page draws sooner
        scene = {"x": 0, "y": 0, "width": 560, "height": 600}  # left of the panel
        try:
            page.goto(server.url)
            triangles = sum(len(g.faces) for g in server.view.geoms) + sum(
                len(t._ore.faces) + len(t._cut.faces) for t in pile._tiles)
            page.wait_for_function(f"() => ({RENDERED_TRIANGLES})() >= {triangles}", timeout=WAIT_MS, polling=100)
            screenshot_showing_machine(page, server.view.geoms, "replay_stack_ore.png")  # the page has faded in
            before = page.screenshot(clip=scene, timeout=WAIT_MS)
            click(page.get_by_role("combobox", name="Pile colour"))
            click(page.get_by_role("option", name="grade"))
            until(lambda: server.player.pile_colour == "grade", "the player colouring the pile by grade")
            expect(page.get_by_text("Top layer's grade, Fe %")).to_be_visible(timeout=WAIT_MS)
            deadline = time.monotonic() + WAIT_MS / 1000
            while changed_pixels(before, after := page.screenshot(clip=scene, timeout=WAIT_MS)) < GRADE_REPAINTED:
                assert time.monotonic() < deadline, "colouring the pile by grade changed nothing in the scene"
            (ARTIFACTS / "replay_stack_grade.png").write_bytes(after)
            # The grade stacked is charted beside the errors: uPlot drew it with its points.
            titles = page.evaluate("() => Object.values(window.__viserTestpoints.uplots).map("
                                   "u => [u.chart.root.querySelector('.u-title')?.textContent, u.chart.data[0].length])")
            assert any(title == "Grade stacked, as it arrived" and points > 2 for title, points in titles), titles
        finally:
            page.close()


def test_the_shadows_view_shows_the_machine_its_ghost_and_the_alarms(browser):
    """The shadow's page: the measured machine and the twin's ghost both drawn, an alarm listed.
    (The shadow's publishing is async; Playwright's sync API holds this thread's event loop.)"""
    import asyncio
    from concurrent.futures import ThreadPoolExecutor

    from bwr_twin.model.machine import Machine
    from bwr_twin.shadow.detect import Alarm
    from bwr_twin.shadow.twin import Blocks
    from bwr_twin.shadow.view import ShadowView

    view = ShadowView(Machine(ROOT / "mjcf" / "bwr_heavy.xml"), port=0)
    n, zeros = 30, np.zeros((30, 3))
    residual = np.tile([0.0, 0.02, 0.0], (n, 1))  # the slew 0.02 rad (1.1 deg) ahead of its twin
    blocks = Blocks(np.arange(n, dtype=float), np.arange(1.0, n + 1), zeros + 1e5, residual, zeros, zeros,
                    zeros, zeros, zeros, zeros, zeros, zeros, np.zeros((n, 3, 2)), np.full(n, 10))
    alarm = Alarm("friction_rise", "slew", 30.0, 12.0, 27.9, "%", 80.0, 40.0)
    health = {"travel": 100.0, "slew": 0.0, "luff": 96.0, "wheel end": 100.0}
    with ThreadPoolExecutor(1) as other:
        other.submit(asyncio.run, view.residuals(blocks, np.array([10.0, 0.3, 0.05]))).result()
        other.submit(asyncio.run, view.verdict(health, [alarm])).result()
    page = browser.new_page()
    try:
        page.goto(view.url)
        wait_for_machine(page, view.measured.geoms + view.twin.geoms)  # the solid machine and its ghost
        expect(page.get_by_text("slew friction_rise")).to_be_visible(timeout=WAIT_MS)
        ARTIFACTS.mkdir(exist_ok=True)
        (ARTIFACTS / "shadow.png").write_bytes(page.screenshot(timeout=WAIT_MS))
    finally:
        page.close()
        view.server.stop()
