"""The laser scans in the replay: the fan of the latest scan and the hits of the last second, drawn
from scans.npz; the pile the automation knew from its scans, which is survey.npz's at the plan's
start and at the end, shown in place of the true pile from the GUI, in the page and in the
offline export; and none of it for a run that did not scan.

The runs are real: heavy_dig_pile's first 96 s (its scanner records) and the small bench scene
surveyed and planned on its scans (test_scanned_reclaim), written as bwr_twin.run writes them and
read back as the replay reads them. The page checks drive Debian's chromium through playwright,
as test_browser.py does.
"""

from __future__ import annotations

import time

import numpy as np
import pytest
from conftest import SCENES
from test_browser import (
    WAIT_MS,
    browser,  # noqa: F401  (a fixture)
    changed_pixels,
    click,
    expect,
    screenshot_showing_machine,
    until,
    wait_for_machine,
)
from test_scanned_reclaim import FINE, SCANNED, SURVEY
from test_stockpile import SHORT_DIG

from bwr_twin.config.scene import load_scene
from bwr_twin.drawing.geometry import visual_geoms
from bwr_twin.replay import Recording, ReplayServer, export_html
from bwr_twin.replay.pile import display_step, samples
from bwr_twin.replay.scan_view import EXPORT, LIVE
from bwr_twin.replay.scans import MISS_SHARE
from bwr_twin.replay.simulation import PILE_FRAME_PERIOD
from bwr_twin.results.rundir import write_run
from bwr_twin.sim.lockstep import simulate


def run_dir(folder, scene) -> tuple:
    """The scene simulated as the replay simulates it, written as a run directory and read back."""
    write_run(simulate(scene, pile_frame_period=PILE_FRAME_PERIOD), folder, plots=False)
    return folder, Recording.from_run_dir(folder)


@pytest.fixture(scope="module")
def dig(tmp_path_factory):
    return run_dir(tmp_path_factory.mktemp("dig") / "run", load_scene(SCENES / "heavy_dig_pile.toml", SHORT_DIG))


@pytest.fixture(scope="module")
def surveyed(tmp_path_factory):
    from test_reclaim_plan import scene_file

    folder = tmp_path_factory.mktemp("surveyed")
    return run_dir(folder / "run", load_scene(scene_file(folder, extra=SURVEY + SCANNED), FINE))


@pytest.fixture(scope="module")
def unscanned(tmp_path_factory):
    scene = load_scene(SCENES / "heavy_dig_pile.toml", {**SHORT_DIG, "sensing.scanners": False})
    return run_dir(tmp_path_factory.mktemp("unscanned") / "run", scene)


def kabsch(local: np.ndarray, world: np.ndarray) -> np.ndarray:
    """The rotation R that best takes unit vectors `local` (n, 3) onto `world` (n, 3)."""
    u, _, vt = np.linalg.svd(world.T @ local)
    return u @ np.diag([1.0, 1.0, np.linalg.det(u @ vt)]) @ vt


def test_the_fan_ends_at_the_hits_of_the_latest_scan_at_or_before_the_time(dig):
    folder, recording = dig
    with np.load(folder / "scans.npz") as saved:
        t, origin, hits = saved["t"], saved["origin"], saved["hits"]
    returned = ~np.isnan(hits[:, :, 0])
    # A scan some way in whose fan both meets the pile and looks past it.
    k = int(np.flatnonzero((t > 30.0) & returned.any(axis=1) & ~returned.all(axis=1))[0])
    period = float(t[k + 1] - t[k])
    scanner = recording.plan.machine.scanners[0]
    with ReplayServer(recording, port=0) as server:
        view = server.view.sites[0].scans
        for cursor in (float(t[k]), float(t[k] + 0.5 * period), float(t[k + 1] - 1e-3)):  # at the scan, until the next
            server.player.seek(cursor)
            until(lambda at=cursor: server.player.time == at and view.fan == (k,), f"the fan of scan {k} at {cursor} s")
        fan = view.fan_node.points
        np.testing.assert_array_equal(fan[:, 1], hits[k][returned[k]])  # float32, as scans.npz holds them
        np.testing.assert_array_equal(fan[:, 0], np.broadcast_to(origin[k].astype(np.float32), fan[:, 0].shape))
        # The rays that returned nothing: short, from the origin, along their own direction in the fan,
        # which the hits give (their ranges' noise lies along the rays).
        misses = view.miss_node.points.astype(float)
        assert view.miss_node.visible and len(misses) == scanner.rays - returned[k].sum()
        reach = np.linalg.norm(misses[:, 1] - misses[:, 0], axis=1)
        np.testing.assert_allclose(reach, MISS_SHARE * scanner.max_range, rtol=1e-5)
        toward = hits[k][returned[k]] - origin[k]
        rotation = kabsch(scanner.directions[returned[k]], toward / np.linalg.norm(toward, axis=1)[:, None])
        expected = scanner.directions[~returned[k]] @ rotation.T
        np.testing.assert_allclose((misses[:, 1] - misses[:, 0]) / reach[:, None], expected, atol=1e-5)
        # The cloud: the hits of the scans of the last second, evenly thinned to at most LIVE's count.
        window = hits[(t > t[k + 1] - 1e-3 - 1.0) & (t <= t[k + 1] - 1e-3)].reshape(-1, 3)
        window = window[~np.isnan(window[:, 0])]
        assert len(window) > LIVE.cloud_points  # 25 scans of some 150 hits each: thinned
        kept = window[:: int(np.ceil(len(window) / LIVE.cloud_points))]
        cloud = view.hit_node.points.astype(float) + view.hit_node.position
        assert len(cloud) == len(kept) <= LIVE.cloud_points
        np.testing.assert_allclose(cloud, kept, atol=0.05)  # float16 about the pile's centre
        server.player.seek(0.0)  # the first scan is at 0 s: its fan, and the cloud of it alone
        until(lambda: view.fan == (0,), "the fan of the first scan")
        assert len(view.hit_node.points) == returned[0].sum()


def test_the_scanned_pile_is_the_one_the_plan_was_made_on_and_the_one_the_run_ended_with(surveyed):
    """Shown at the plan's start, the scanned pile is survey.npz's z_plan; at the end, its z; where it
    is unknown no face is drawn; and the GUI's choice shows it in place of the true pile."""
    folder, recording = surveyed
    with np.load(folder / "survey.npz") as known:
        z_plan, z_end, t_plan, t_end = known["z_plan"], known["z"], float(known["t_plan"]), float(known["t_end"])
    assert recording.scans.plan_time == t_plan and np.isnan(z_plan).any() and not np.isnan(z_plan).all()
    assert not np.array_equal(z_plan, z_end, equal_nan=True)  # the scanner saw more after the plan
    step = display_step(z_end.shape)
    rows, cols = samples(z_end.shape[0], step), samples(z_end.shape[1], step)
    with ReplayServer(recording, port=0) as server:
        site = server.view.sites[0]
        known_view = site.scans.known
        assert site.pile.visible and not known_view.visible
        server.player.show_pile("scanned")
        until(lambda: server.player.pile_shown == "scanned", "the player showing the scanned pile")
        assert known_view.visible and not site.pile.visible
        assert server.player.panel.pile_shown.value == "scanned"
        for at, z in ((t_plan, z_plan), (t_end, z_end)):
            server.player.seek(at)
            until(lambda at=at: server.player.time == at, f"the seek to {at} s")
            expected = z[np.ix_(rows, cols)].astype(np.float32)
            until(lambda expected=expected: np.array_equal(known_view.z, expected, equal_nan=True),
                  f"the scanned pile of survey.npz at {at} s")
        # Unknown cells are not drawn: each tile's faces are the display cells whose corners are known.
        shown = known_view.z
        for tile in known_view.tiles:
            z = shown[tile.rows, tile.cols]
            cells = int((~np.isnan(z[:-1, :-1]) & ~np.isnan(z[1:, :-1]) & ~np.isnan(z[:-1, 1:])
                         & ~np.isnan(z[1:, 1:])).sum())
            assert len(tile.node.faces) == (2 * cells if cells else 1)  # none: one degenerate face
            assert np.isfinite(tile.node.vertices).all()
        server.player.show_pile("true")
        until(lambda: site.pile.visible and not known_view.visible, "the true pile shown again")


PILE_CHOICE = "Pile shown"
REPAINTED = 0.01  # of the picture's pixels: the scanned pile's grey-blue in place of the ore
# The page's scene tree (its test hook) says which nodes it shows.
SHOWN = """names => names.map(name => window.__viserSceneTree?.getState()?.[name]?.effectiveVisibility ?? null)"""


@pytest.mark.browser
def test_the_page_draws_the_fan_and_switches_to_the_scanned_pile(browser, dig):  # noqa: F811
    _, recording = dig
    with ReplayServer(recording, port=0) as server:
        server.player.seek(60.0)
        page = browser.new_page()
        try:
            page.goto(server.url)
            wait_for_machine(page, server.view.geoms)
            nodes = ["/sites/0/pile", "/sites/0/scanned", "/sites/0/scan/fan", "/sites/0/scan/hits"]
            page.wait_for_function(f"() => JSON.stringify(({SHOWN})({nodes})) === '[true,false,true,true]'",
                                   timeout=WAIT_MS, polling=100)
            before = screenshot_showing_machine(page, server.view.geoms, "replay_scans_true.png")
            choice = page.get_by_role("combobox", name=PILE_CHOICE)
            click(choice)
            click(page.get_by_role("option", name="scanned"))
            until(lambda: server.player.pile_shown == "scanned", "the player showing the scanned pile")
            page.wait_for_function(f"() => JSON.stringify(({SHOWN})({nodes})) === '[false,true,true,true]'",
                                   timeout=WAIT_MS, polling=100)
            deadline = time.monotonic() + WAIT_MS / 1000
            while changed_pixels(before, page.screenshot(timeout=WAIT_MS)) < REPAINTED:
                assert time.monotonic() < deadline, "showing the scanned pile changed nothing on the canvas"
            screenshot_showing_machine(page, server.view.geoms, "replay_scans_scanned.png")
            click(page.get_by_role("checkbox", name="Scan fan and hits"))
            until(lambda: not server.player.fan_shown, "the player hiding the fan")
            page.wait_for_function(f"() => ({SHOWN})(['/sites/0/scan'])[0] === false", timeout=WAIT_MS, polling=100)
        finally:
            page.close()


# The export's nodes, as three.js draws them: `visible` is what the page's controls choose.
DRAWN = "names => names.map(name => window.__viserMutable?.nodeRefFromName?.[name]?.visible ?? null)"


@pytest.mark.browser
def test_the_export_draws_the_fan_and_its_page_switches_the_pile(browser, dig, tmp_path):  # noqa: F811
    _, recording = dig
    out = tmp_path / "dig.html"
    export_html(recording, out)
    page = browser.new_page()
    page.set_viewport_size({"width": 960, "height": 600})
    try:
        page.goto(out.resolve().as_uri())
        wait_for_machine(page, visual_geoms(recording.plan.machine))
        nodes = ["/sites/0/pile", "/sites/0/scanned", "/sites/0/scan"]
        page.wait_for_function(f"() => JSON.stringify(({DRAWN})({nodes})) === '[true,false,true]'",
                               timeout=WAIT_MS, polling=100)
        # The recording plays its scans: the fan thinned to EXPORT's rays, the cloud to its hits.
        sizes = """() => { const tree = window.__viserSceneTree.getState();
            return ['/sites/0/scan/fan', '/sites/0/scan/hits'].map(n => tree[n].message.props.points.length); }"""
        page.wait_for_function(f"() => ({sizes})()[0] > 6", timeout=WAIT_MS, polling=100)  # past the placeholder
        fan, cloud = page.evaluate(sizes)
        assert fan <= EXPORT.rays * 2 * 3 and 0 < cloud <= EXPORT.cloud_points * 3, (fan, cloud)
        page.select_option("#bwr-pile-shown", "scanned")
        page.wait_for_function(f"() => JSON.stringify(({DRAWN})({nodes})) === '[false,true,true]'",
                               timeout=WAIT_MS, polling=100)
        page.locator("#bwr-fan-shown").uncheck()
        page.wait_for_function(f"() => JSON.stringify(({DRAWN})({nodes})) === '[false,true,false]'",
                               timeout=WAIT_MS, polling=100)
        page.select_option("#bwr-pile-shown", "true")
        page.wait_for_function(f"() => JSON.stringify(({DRAWN})({nodes})) === '[true,false,false]'",
                               timeout=WAIT_MS, polling=100)
        expect(page.get_by_text("rebuilt from them every 5 s of the run")).to_be_visible(timeout=WAIT_MS)
    finally:
        page.close()


@pytest.mark.browser
def test_a_run_without_scans_shows_none_of_it(browser, unscanned, tmp_path):  # noqa: F811
    folder, recording = unscanned
    assert not (folder / "scans.npz").exists() and recording.scans is None and recording.pile is not None
    with ReplayServer(recording, port=0) as server:
        assert not server.view.scanning and server.player.panel.pile_shown is None
        page = browser.new_page()
        try:
            page.goto(server.url)
            wait_for_machine(page, server.view.geoms)
            expect(page.get_by_role("button", name="Play")).to_be_visible(timeout=WAIT_MS)
            page.wait_for_function(f"() => ({SHOWN})(['/sites/0/pile'])[0] === true", timeout=WAIT_MS, polling=100)
            names = page.evaluate("() => Object.keys(window.__viserSceneTree.getState())")
            assert [name for name in names if "/scan" in name] == []
            assert page.get_by_text(PILE_CHOICE).count() == 0 and page.get_by_text("Scanner").count() == 0
        finally:
            page.close()
    out = tmp_path / "unscanned.html"
    export_html(recording, out)
    page_html = out.read_text()
    assert "bwr-pile-shown" not in page_html
    assert "bwr-scanner" not in page_html
