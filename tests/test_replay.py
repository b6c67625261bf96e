"""The web replay: every visual geom of any machine becomes one scene node of MuJoCo's size, posed
by MuJoCo's own kinematics; the server binds locally, serves and frees its port; the timeline
plays; several runs load from run directories and compare or batch folders, or are refused with
one line; the offline export stays small. Browser checks are in test_browser.py."""

import dataclasses
import os
import shutil
import signal
import socket
import subprocess
import sys
import time
import urllib.request

import mujoco
import numpy as np
import pytest
from conftest import HEAVY_MJCF, PAPER_MJCF, ROOT, SCENES, SHORT_VIA_POINTS, VARIANT_MJCF

from bwr_twin import Machine
from bwr_twin.drawing.geometry import VISUAL_GROUP, BodyPoser, visual_geoms
from bwr_twin.model.machine import paper_to_world
from bwr_twin.replay import Plan, Recording, ReplayServer, export_html, readout
from bwr_twin.replay.charts import charts
from bwr_twin.replay.recording import cache_key
from bwr_twin.replay.scenery import ANGLE_OF_REPOSE, CREST_HEIGHT_FRACTION, stockpile

MACHINES = pytest.mark.parametrize(
    "mjcf", [PAPER_MJCF, VARIANT_MJCF, HEAVY_MJCF], ids=["paper", "variant", "heavy"]
)
EXPORT_LIMIT = 5_000_000  # bytes: the offline recording must stay under 5 MB


@pytest.fixture(scope="session")
def short_scene():
    from bwr_twin.config.scene import load_scene

    return load_scene(SCENES / "paper_individual_gains.toml", {"path.via_points": SHORT_VIA_POINTS})


@pytest.fixture(scope="session")
def short_run(short_scene, tmp_path_factory):
    """A 20 s reclaim, simulated once: (run directory, RunResult)."""
    from bwr_twin.results.rundir import write_run
    from bwr_twin.sim.lockstep import simulate

    result = simulate(short_scene)
    run_dir = tmp_path_factory.mktemp("replay") / "short"
    write_run(result, run_dir, plots=False)
    return run_dir, result


@pytest.fixture(scope="session")
def short_recording(short_run):
    return Recording.from_run_dir(short_run[0])


def expected_extent(model: mujoco.MjModel, g: int) -> np.ndarray:
    """The bounding box MuJoCo's size semantics give a geom, in its own frame."""
    size, kind = model.geom_size[g], mujoco.mjtGeom(model.geom_type[g])
    if kind == mujoco.mjtGeom.mjGEOM_BOX:
        return 2 * size
    if kind == mujoco.mjtGeom.mjGEOM_SPHERE:
        return np.full(3, 2 * size[0])
    if kind == mujoco.mjtGeom.mjGEOM_ELLIPSOID:
        return 2 * size
    if kind == mujoco.mjtGeom.mjGEOM_CYLINDER:
        return 2 * np.array([size[0], size[0], size[1]])
    if kind == mujoco.mjtGeom.mjGEOM_CAPSULE:
        return 2 * np.array([size[0], size[0], size[1] + size[0]])
    raise AssertionError(f"no expectation for {kind}")


# -- MJCF to scene ----------------------------------------------------------------------------


@MACHINES
def test_one_node_per_visual_geom_with_mujoco_sizes(mjcf):
    machine = Machine(mjcf)
    model = machine.model
    visual = [g for g in range(model.ngeom) if model.geom_group[g] == VISUAL_GROUP]
    with ReplayServer(Plan.from_scene(_scene_for(mjcf)), port=0) as server:
        geoms, nodes = zip(*server.view.drawn_geoms())
        assert len(nodes) == len(geoms) == len(visual) > 0
        for geom, node, g in zip(geoms, nodes, visual):
            assert geom.name == (mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g) or f"geom{g}")
            assert np.allclose(geom.size, model.geom_size[g])
            extent = np.ptp(node.vertices, axis=0)
            assert np.allclose(extent, expected_extent(model, g), rtol=1e-5), geom.name
            assert node.color == tuple(round(255 * c) for c in geom.rgba[:3])


def _scene_for(mjcf):
    """The short scene on another machine, its path moved to where that machine reaches."""
    from bwr_twin.config.scene import load_scene

    machine = Machine(mjcf)
    home = machine.fk(np.zeros(3))
    reach = machine.fk(np.array([0.0, 0.2, 0.05]))
    via = [{"t": 0.0, "p": home.tolist()}, {"t": 20.0, "p": reach.tolist()}]
    return load_scene(
        SCENES / "paper_individual_gains.toml",
        {"machine.mjcf": str(mjcf), "path.frame": "world", "path.via_points": via},
    )


@MACHINES
def test_geoms_are_posed_by_mujoco_kinematics(mjcf):
    machine = Machine(mjcf)
    model, data = machine.model, mujoco.MjData(machine.model)
    rng = np.random.default_rng(4)
    geoms = visual_geoms(machine)
    poser = BodyPoser(machine)
    for _ in range(3):
        q = rng.uniform(machine.envelope[:, 0], machine.envelope[:, 1])
        data.qpos[:] = q
        mujoco.mj_kinematics(model, data)
        visual = [g for g in range(model.ngeom) if model.geom_group[g] == VISUAL_GROUP]
        expected = np.concatenate(
            [
                geom.vertices @ data.geom_xmat[g].reshape(3, 3).T + data.geom_xpos[g]
                for geom, g in zip(geoms, visual)
            ]
        )
        assert np.allclose(poser.world_vertices(geoms, q), expected, atol=1e-4)


def test_mesh_and_plane_geoms_are_drawn_from_the_model(tmp_path):
    """A different MJCF changes the picture: a variant machine with a mesh and a plane added."""
    text = VARIANT_MJCF.read_text()
    text = text.replace(
        "<worldbody>", '<asset><mesh name="hopper" vertex="0 0 0  2 0 0  0 3 0  0 0 4"/></asset>\n<worldbody>'
    )
    text = text.replace(
        '<site name="bucket_wheel_center"',
        '<geom class="visual" type="mesh" mesh="hopper" pos="20 0 1"/>\n<site name="bucket_wheel_center"',
    )
    text = text.replace("<worldbody>", '<worldbody>\n<geom type="plane" size="30 4 0.1" group="2"/>', 1)
    mjcf = tmp_path / "bwr_variant_mesh.xml"
    mjcf.write_text(text)
    machine = Machine(mjcf)
    geoms = visual_geoms(machine)
    assert [g.type for g in geoms].count("mesh") == 1 and [g.type for g in geoms].count("plane") == 1
    mesh = next(g for g in geoms if g.type == "mesh")
    # MuJoCo moves a mesh into its inertial frame; in the world it sits where the MJCF put it.
    data = mujoco.MjData(machine.model)
    mujoco.mj_kinematics(machine.model, data)
    boom = data.xpos[mujoco.mj_name2id(machine.model, mujoco.mjtObj.mjOBJ_BODY, "boom")]
    drawn = np.round(BodyPoser(machine).world_vertices([mesh], np.zeros(3)), 4)
    written = np.array([[0, 0, 0], [2, 0, 0], [0, 3, 0], [0, 0, 4]]) + (20, 0, 1) + boom
    assert np.allclose(drawn[np.lexsort(drawn.T)], written[np.lexsort(written.T)], atol=1e-4)
    assert len(mesh.faces) == 4
    plane = next(g for g in geoms if g.type == "plane")
    assert np.allclose(np.ptp(plane.vertices, axis=0), (60, 8, 0)) and plane.body == "world"


def test_undrawable_geom_type_is_a_model_error(tmp_path):
    from bwr_twin import ModelError

    text = VARIANT_MJCF.read_text().replace(
        "<worldbody>",
        '<asset><hfield name="yard" nrow="2" ncol="2" size="10 10 1 0.1"/></asset>\n'
        '<worldbody>\n<geom type="hfield" hfield="yard" group="2"/>',
    )
    mjcf = tmp_path / "bwr_variant_hfield.xml"
    mjcf.write_text(text)
    with pytest.raises(ModelError, match="bwr_variant_hfield.xml: geom 'geom0': type hfield cannot be drawn"):
        visual_geoms(Machine(mjcf))


def test_only_moving_rigid_bodies_get_poses():
    poser = BodyPoser(Machine(PAPER_MJCF))
    assert poser.names == ["world", "carriage", "turntable", "boom"]
    assert poser.moving == [False, True, True, True]
    # The heavy machine's welded parts ride on their carriers: still three poses per frame.
    assert sum(BodyPoser(Machine(HEAVY_MJCF)).moving) == 3


def test_primitive_meshes_are_closed_and_face_outwards():
    from bwr_twin.drawing.geometry import box, capsule, cylinder, ellipsoid

    for vertices, faces in (box((1, 2, 3)), cylinder(1, 2), capsule(1, 2), ellipsoid((1, 2, 3))):
        corners = vertices[faces]
        normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
        assert np.all(np.linalg.norm(normals, axis=1) > 1e-9)  # no degenerate triangles
        assert np.all(
            np.einsum("ij,ij->i", normals, corners.mean(axis=1)) > 0
        )  # outward, for a centred solid


# -- surroundings -----------------------------------------------------------------------------


def test_stockpile_lies_under_the_reclaimed_via_points(paper_machine):
    from conftest import PAPER_VIA_POINTS

    points = paper_to_world(np.array([p for _, p in PAPER_VIA_POINTS]))
    pile = stockpile(points, rail_y=paper_machine.geometry.slew_axis_xy[1])
    assert pile.side == 1.0  # paper x negative = world +Y
    digging = points[points[:, 1] > 20]  # p_int1..3, beside the rail
    crest = pile.vertices[4:]
    assert pile.vertices[:4, 2].max() == 0 and np.allclose(
        crest[:, 2], CREST_HEIGHT_FRACTION * digging[:, 2].min()
    )
    assert crest[:, 0].min() <= digging[:, 0].min() and crest[:, 1].max() >= digging[:, 1].max()
    flank = (crest[0, 1] - pile.vertices[0, 1], crest[0, 2])
    assert np.degrees(np.arctan2(flank[1], flank[0])) == pytest.approx(np.degrees(ANGLE_OF_REPOSE))
    assert stockpile(points * (1, 0, 1), rail_y=0.0) is None  # a path along the rail digs nothing


def test_close_via_points_share_one_label_and_each_is_named_once(paper_machine):
    from conftest import PAPER_VIA_POINTS

    from bwr_twin.replay.view import label_groups

    paper = paper_to_world(np.array([p for _, p in PAPER_VIA_POINTS]))
    assert label_groups(paper, 1.0) == {0: [0, 4], 1: [1], 2: [2], 3: [3]}  # the path ends where it began
    chain = np.array([[0.0, 0, 0], [0.8, 0, 0], [1.6, 0, 0], [9.0, 0, 0]])  # 0-1 and 1-2 close, 0-2 not
    groups = label_groups(chain, 1.0)
    assert groups == {0: [0, 1], 2: [2], 3: [3]}
    assert sorted(i for members in groups.values() for i in members) == [0, 1, 2, 3]


def test_slider_labels_via_points_that_do_not_crowd_each_other():
    from bwr_twin.replay.panel import via_point_marks

    names = [f"P{i + 1}" for i in range(5)]
    assert via_point_marks([0.0, 200.0, 300.0, 500.0, 700.0], names) == tuple(
        (t, f"P{i + 1}") for i, t in enumerate([0.0, 200.0, 300.0, 500.0, 700.0])
    )
    assert via_point_marks([0.0, 620.0, 680.0, 1680.0], names) == ((0.0, "P1"), (620.0, "P2"), 680.0, (1680.0, "P4"))
    # A bench plan's unnamed via points (travel steps) are marked, never labelled.
    assert via_point_marks([0.0, 100.0, 900.0], ["bench 1", "", "pass 1"]) == ((0.0, "bench 1"), 100.0,
                                                                               (900.0, "pass 1"))
    # A bench plan's passes, ten in a row: "bench 1pass 1pass 2..." would print over each other.
    times = [0.0, 20.0, *(100.0 * k for k in range(1, 11)), 1136.0]
    names = ["bench 1", "", *(f"pass {k}" for k in range(1, 11)), "end"]
    labels = [mark[1] for mark in via_point_marks(times, names) if isinstance(mark, tuple)]
    assert labels[0] == "bench 1" and len(labels) <= 6 and "pass 1" not in labels  # every other pass at most
    benches = via_point_marks(times, names, labelled={"bench 1", "end"})
    assert [m for m in benches if isinstance(m, tuple)] == [(0.0, "bench 1"), (1136.0, "end")]
    assert len(benches) == len(times)  # every via point keeps its mark


def test_the_grade_scale_has_round_bins_over_the_grades_shown():
    """9 bins of a round width cover the 2nd to 98th percentile of a pile's top grades; a grade
    beyond falls in the end bin, bare ground in none; the legend names each bin and the band."""
    from bwr_twin.replay.grade_scale import GradeScale, round_edges
    from bwr_twin.stockpile.history import PileHistory

    np.testing.assert_allclose(round_edges(60.13, 63.87, 9), np.arange(60.0, 64.01, 0.5))  # 8 bins
    np.testing.assert_allclose(round_edges(59.95, 64.03, 9), np.arange(59.5, 64.51, 0.5))  # 10
    np.testing.assert_allclose(round_edges(0.012, 0.031, 9), np.arange(0.01, 0.0326, 0.0025))
    grades = np.random.default_rng(1).normal(62.0, 1.0, 10_000).astype(np.float32)
    start = np.full((2, 3), np.nan, np.float32)
    history = PileHistory(np.arange(3.0), np.arange(2.0), np.zeros((2, 3)), np.array([1.0]), np.array([0, len(grades)]),
                          np.zeros(len(grades), np.int32), np.zeros(len(grades), np.float32), start, grades,
                          "Fe %", (61.0, 63.0))
    scale = GradeScale.of([history])
    low, high = np.percentile(grades, (2, 98))
    assert scale.edges[0] <= low < scale.edges[1] and scale.edges[-2] < high <= scale.edges[-1]
    assert len(scale.colours) == len(scale.edges) - 1 == len(set(scale.colours)) and 7 <= len(scale.colours) <= 10
    assert scale.bins(np.array([np.nan, 0.0, scale.edges[1], 1e3])).tolist() == [-1, 0, 1, len(scale.colours) - 1]
    labels = scale.labels()
    assert labels[0].startswith("< ") and labels[-1].startswith("≥ ") and " – " in labels[4]
    assert "61–63 Fe %" in scale.legend_html() and "bare ground" in scale.legend_html()
    plain = dataclasses.replace(history, grade_start=None, grades=None)
    assert GradeScale.of([plain]) is None


# -- recordings, readout, charts --------------------------------------------------------------


def test_run_directory_and_result_give_the_same_recording(short_run, short_recording):
    from_result = Recording.from_result(short_run[1])
    for a, b in (
        (from_result.plan.time, short_recording.plan.time),
        (from_result.q_actual, short_recording.q_actual),
        (from_result.qd_actual, short_recording.qd_actual),
        (from_result.plan.cp_desired, short_recording.plan.cp_desired),
        (from_result.cp_actual, short_recording.cp_actual),
    ):
        assert np.allclose(a, b, rtol=1e-9, atol=1e-12)
    assert short_recording.plan.time[-1] == pytest.approx(20.0) and len(short_recording.plan.time) == 201
    assert np.allclose(short_recording.plan.via_points[1], paper_to_world(np.array(SHORT_VIA_POINTS[1]["p"])))


def test_plan_from_scene_matches_the_run(short_scene, short_recording):
    plan = Plan.from_scene(short_scene)
    assert np.allclose(plan.q_desired, short_recording.plan.q_desired, atol=1e-9)
    assert np.allclose(plan.qd_desired, short_recording.plan.qd_desired, atol=1e-9)


def test_instant_interpolates_between_records(short_recording):
    r = short_recording
    middle = r.at(0.5 * (r.plan.time[10] + r.plan.time[11]))
    assert np.allclose(middle.q_actual, 0.5 * (r.q_actual[10] + r.q_actual[11]))
    assert np.allclose(r.at(-5).q_actual, r.q_actual[0]) and np.allclose(r.at(1e6).q_actual, r.q_actual[-1])


def test_readout_shows_engineering_units(short_recording):
    instant = short_recording.at(10.0)
    rows = readout.rows(instant)
    assert [r[0] for r in rows] == ["travel", "slew", "luff"]
    assert rows[0][1].endswith(" m") and rows[1][1].endswith(" deg") and rows[2][3].endswith(" deg")
    assert float(rows[1][2].split()[0]) == pytest.approx(np.degrees(instant.q_actual[1]), abs=1e-3)
    assert "t = 10.0 s" in readout.as_text(instant, 20.0)


def test_one_runs_charts_hold_its_axes_sampled_once_a_second(short_recording):
    for chart in charts(short_recording):
        x, *series = chart.data([True])
        assert len(series) == len(chart.lines) == len(chart.series([True])) - 1
        assert all(len(s) == len(x) == 21 for s in series)  # 20 s, a point a second
        assert np.all(np.diff(x) > 0) and np.all(np.isfinite(np.concatenate(series)))
        assert chart.ranges([True]) == chart.scales  # uPlot fits one run's scales itself


def test_error_charts_are_the_papers_errors_in_engineering_units(short_run, short_recording):
    result = short_run[1]
    position, velocity, _ = charts(short_recording)
    assert "Position error" in position.title and "Velocity error" in velocity.title
    at = np.searchsorted(result.time, position.time[-1])  # the last charted sample, t = 20 s
    assert position.lines[0].values[-1] == pytest.approx(result.q_desired[at, 0] - result.q[at, 0], abs=1e-9)
    assert velocity.lines[1].values[-1] == pytest.approx(
        np.degrees(result.qd_desired[at, 1] - result.qd[at, 1]), abs=1e-9
    )
    assert velocity.lines[1].series["label"] == "slew [deg/s]" and velocity.axes[1]["label"] == "travel [m/s]"


def test_cache_key_follows_what_decides_the_run(short_scene, tmp_path, monkeypatch):
    """The seed, the MJCF's content, the rule base's content and the simulation code each change
    the key; where the scene file lives does not."""
    from bwr_twin.config.scene import load_scene
    from bwr_twin.replay import recording

    def scene(**overrides):
        return load_scene(SCENES / "paper_individual_gains.toml", {"path.via_points": SHORT_VIA_POINTS, **overrides})

    key = cache_key(short_scene)
    assert cache_key(scene()) == key
    moved = tmp_path / "moved.toml"
    moved.write_text(f'extends = "{SCENES / "paper_individual_gains.toml"}"\n')
    assert cache_key(load_scene(moved, {"path.via_points": SHORT_VIA_POINTS})) == key
    assert cache_key(scene(**{"simulation.seed": 2})) != key

    heavier = tmp_path / "bwr.xml"  # the same file name, one mass changed
    heavier.write_text(PAPER_MJCF.read_text().replace('mass="2000"', 'mass="2100"', 1))
    assert heavier.read_text() != PAPER_MJCF.read_text()
    assert cache_key(scene(**{"machine.mjcf": str(heavier)})) != key

    rules = tmp_path / "rules.toml"
    text = (SCENES / "rulebases" / "paper_table2.toml").read_text()
    rules.write_text(text.replace('["NM", "NS", "NS", "O",  "PS", "PS", "PM"]', '["NM", "NS", "NS", "PS", "PS", "PS", "PM"]'))
    assert rules.read_text() != text
    assert cache_key(scene(**{"controller.rule_base": str(rules)})) != key

    code = tmp_path / "code"
    code.mkdir()
    (code / "loop.py").write_text("STEP = 1\n")
    monkeypatch.setattr(recording, "_SIMULATION_CODE", (code,))
    before = cache_key(short_scene)
    (code / "loop.py").write_text("STEP = 2\n")
    assert cache_key(short_scene) != before


# -- the server -------------------------------------------------------------------------------


def _port_is_free(port: int) -> bool:
    with socket.socket() as probe:
        try:
            probe.bind(("127.0.0.1", port))
        except OSError:
            return False
        return True


def test_server_starts_on_port_0_serves_locally_and_frees_its_port(short_recording):
    with ReplayServer(short_recording, port=0) as server:
        port = server.port
        assert port > 0 and server.url == f"http://127.0.0.1:{port}"
        assert server.server.get_host() == "127.0.0.1"
        with urllib.request.urlopen(server.url, timeout=10) as page:
            assert page.status == 200 and b"<html" in page.read(2000).lower()
    assert _port_is_free(port)


def test_busy_port_is_replaced_by_the_next_free_one(short_recording):
    with socket.socket() as squatter:
        squatter.bind(("127.0.0.1", 0))
        squatter.listen()
        busy = squatter.getsockname()[1]
        with ReplayServer(short_recording, port=busy) as server:
            assert server.port != busy


def test_unusable_host_is_a_one_line_error(short_recording):
    from bwr_twin import BwrError

    with pytest.raises(BwrError, match="cannot listen on host '192.0.2.1'"):
        ReplayServer(short_recording, host="192.0.2.1", port=0)  # TEST-NET-1: never this machine's


def test_timeline_plays_pauses_and_jumps(short_recording):
    with ReplayServer(short_recording, port=0) as server:
        player = server.player
        player.set_speed(10)
        player.toggle()
        time.sleep(0.5)
        player.toggle()
        time.sleep(0.2)
        paused_at = player.time
        assert not player.playing and 1.0 < paused_at < 20.0  # about 5 s of run in 0.5 s at 10x
        time.sleep(0.2)
        assert player.time == paused_at and player.panel.time_slider.value == pytest.approx(paused_at)
        player.seek(12.5)
        time.sleep(0.2)
        assert player.time == 12.5 and "t = 12.5 s" in player.panel.readout.content
        player.set_speed(100)
        player.toggle()  # plays to the end and stops there
        time.sleep(0.5)
        assert not player.playing and player.time == player.end
        assert player.panel.speed_slider.value == 100


def test_preview_shows_the_machine_before_the_recording(short_scene, short_recording):
    with ReplayServer(Plan.from_scene(short_scene), port=0) as server:
        assert server.player is None and len(server.view.machines[0].nodes) > 0
        server.load(short_recording)
        assert server.player is not None and server.player.time == 0.0


# -- the command line and the export ----------------------------------------------------------


STOP_TIMEOUT = 60  # s for a replay to stop: seconds here, more on a CI machine busy with other tests


def _start_cli(*args):
    return subprocess.Popen(
        [sys.executable, "-m", "bwr_twin.replay", *map(str, args)],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env={**os.environ, "PYTHONFAULTHANDLER": "1"},  # SIGABRT prints every thread's stack
    )


def _stopped(proc: subprocess.Popen) -> int:
    """The replay's exit status; if it does not stop in time, fail with where its threads stand."""
    try:
        return proc.wait(timeout=STOP_TIMEOUT)
    except subprocess.TimeoutExpired:
        proc.send_signal(signal.SIGABRT)
        _, err = proc.communicate(timeout=30)
        pytest.fail(f"the replay did not stop within {STOP_TIMEOUT} s; its threads:\n{err[-6000:]}")


def test_cli_replays_a_run_directory_until_interrupted(short_run):
    with socket.socket() as squatter:
        squatter.bind(("127.0.0.1", 0))
        squatter.listen()
        busy = squatter.getsockname()[1]
        proc = _start_cli(short_run[0], "--port", busy)
        notice, line = proc.stdout.readline(), proc.stdout.readline()
    assert notice.startswith(f"port {busy} is busy; using "), notice + proc.stderr.read()
    port = int(notice.split()[-1])
    assert line.startswith(f"replay at http://127.0.0.1:{port}"), line
    with urllib.request.urlopen(f"http://127.0.0.1:{port}", timeout=10) as page:
        assert page.status == 200
    proc.send_signal(signal.SIGINT)
    assert _stopped(proc) == 0
    assert _port_is_free(port)


def test_cli_picks_a_free_port_for_port_0(short_run):
    proc = _start_cli(short_run[0], "--port", "0")
    line = proc.stdout.readline()
    proc.terminate()
    assert _stopped(proc) == 128 + signal.SIGTERM  # a terminated replay stops cleanly too
    assert line.startswith("replay at http://127.0.0.1:"), line
    port = int(line.split(":")[2].split()[0])
    assert port > 0 and _port_is_free(port)


@pytest.mark.parametrize(
    "args, message",
    [
        (["nowhere.toml"], "nowhere.toml: scene file not found, nor a shipped scene"),
        (["tests"], "tests: not a run directory of bwr_twin.run"),
        (["--port", "70000"], "70000 is not a TCP port"),
    ],
    ids=["missing", "not-a-run", "port"],
)
def test_cli_bad_input_exits_2_with_one_line(args, message):
    proc = _start_cli(*args)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 2 and "Traceback" not in err
    assert message in err.strip().splitlines()[-1]


@pytest.mark.parametrize(
    "damage, message",
    [
        (lambda d: (d / "scene.json").write_text("[1, 2]\n"), "scene.json: not a scene as bwr_twin.run writes it"),
        (lambda d: (d / "scene.json").write_text(
            (d / "scene.json").read_text().replace('"via_points": [', '"via_points": "none", "old": [')),
         "scene.json: not a scene as bwr_twin.run writes it"),
        (lambda d: (d / "timeseries.csv").write_text((d / "timeseries.csv").read_text().splitlines()[0] + "\n"),
         "timeseries.csv: 0 rows of samples; a replay needs at least 2"),
        (lambda d: (d / "timeseries.csv").write_text("\n".join((d / "timeseries.csv").read_text().splitlines()[:2]) + "\n"),
         "timeseries.csv: 1 rows of samples; a replay needs at least 2"),
    ],
    ids=["scene-a-list", "via-points-a-string", "header-only", "one-row"],
)
def test_a_malformed_run_directory_gets_one_line_and_nothing_written(short_run, tmp_path, damage, message):
    run_dir = tmp_path / "run"
    shutil.copytree(short_run[0], run_dir)
    damage(run_dir)
    before = {p.name: p.read_bytes() for p in run_dir.iterdir()}
    proc = _start_cli(run_dir, "--export", tmp_path / "replay.html")
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 2 and "Traceback" not in err, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and message in lines[0], lines
    assert not (tmp_path / "replay.html").exists()
    assert {p.name: p.read_bytes() for p in run_dir.iterdir()} == before


def test_a_scene_is_simulated_in_a_child_process_that_reports_its_progress(short_scene, short_recording):
    from bwr_twin.replay.simulation import simulate_in_child

    shares = []
    recording = simulate_in_child(short_scene, use_cache=False, progress=shares.append)
    assert len(shares) >= 10 and shares == sorted(shares) and 0 < shares[0] and shares[-1] == pytest.approx(1.0)
    assert np.array_equal(recording.q_actual, short_recording.q_actual)  # same scene and seed, same run


def test_a_diverging_simulation_in_the_child_is_a_one_line_error(tmp_path):
    from conftest import write_short_scene

    scene = write_short_scene(tmp_path, edit=lambda t: t.replace("[0.01, 0.04, 0.06]", "[1e12, 1e12, 1e12]"))
    out = tmp_path / "replay.html"
    proc = _start_cli(scene, "--no-cache", "--export", out)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 2 and "Traceback" not in err, err
    assert err.strip().splitlines() == [err.strip()] and "short.toml" in err and "diverged" in err
    assert not out.exists() and sorted(p.name for p in tmp_path.iterdir()) == ["short.toml"]


def test_export_is_self_contained_and_small(short_recording, tmp_path):
    out = tmp_path / "short.html"
    size = export_html(short_recording, out)
    html = out.read_text()
    assert size == out.stat().st_size < EXPORT_LIMIT
    assert "__VISER_EMBED_DATA__" in html and "http://" not in html.split("__VISER_EMBED_DATA__")[1][:200]
    assert sorted(p.name for p in tmp_path.iterdir()) == [".short.html.bwr_twin", "short.html"]  # no partial file


@pytest.mark.slow
def test_export_of_the_paper_reclaim_fits_in_5_mb(tmp_path):
    out = tmp_path / "reclaim.html"
    command = [sys.executable, "-m", "bwr_twin.replay", "--export", out, "--no-cache"]
    proc = subprocess.run(command, cwd=ROOT, capture_output=True, text=True, timeout=600, check=False)
    assert proc.returncode == 0, proc.stderr
    assert "700 s reclaim" in proc.stdout and out.stat().st_size <= EXPORT_LIMIT


@pytest.mark.slow
def test_export_of_the_digging_reclaim_fits_in_5_mb(tmp_path):
    out = tmp_path / "dig.html"
    command = [sys.executable, "-m", "bwr_twin.replay", "heavy_dig_pile", "--export", out, "--no-cache"]
    proc = subprocess.run(command, cwd=ROOT, capture_output=True, text=True, timeout=600, check=False)
    assert proc.returncode == 0, proc.stderr
    assert "403 s reclaim" in proc.stdout and out.stat().st_size <= EXPORT_LIMIT  # the pile's tiles included


# -- several runs -------------------------------------------------------------------------------


@pytest.fixture(scope="session")
def compare_dir(short_run, tmp_path_factory):
    """A folder as bwr_twin.compare or a batch leaves it: three run directories (the short run under
    three names), a failed run's folder and the comparison's own files."""
    folder = tmp_path_factory.mktemp("compare")
    for name in ("b-seed=1", "a-seed=1", "c-seed=1"):
        shutil.copytree(short_run[0], folder / name)
    (folder / "d-seed=1").mkdir()
    (folder / "d-seed=1" / "error.txt").write_text("diverged\n")
    shutil.copy(short_run[0] / "scene.json", folder / "d-seed=1")
    (folder / "comparison.csv").write_text("controller,axis\nb,travel\nb,slew\na,travel\nc,travel\n")
    return folder


def _moved(run_dir, tmp_path, name, edit):
    """A copy of `run_dir` whose scene.json is passed through `edit`."""
    import json

    copy = tmp_path / name
    shutil.copytree(run_dir, copy)
    scene = json.loads((copy / "scene.json").read_text())
    edit(scene)
    (copy / "scene.json").write_text(json.dumps(scene))
    return copy


def test_a_compare_or_batch_folder_gives_its_run_directories_by_name(compare_dir, tmp_path):
    from bwr_twin.replay.runs import choose_runs, load_runs, run_folders

    # In the comparison's order of controllers; not the failed run.
    assert [f.name for f in run_folders(compare_dir)] == ["b-seed=1", "a-seed=1", "c-seed=1"]
    assert run_folders(compare_dir / "a-seed=1") == [compare_dir / "a-seed=1"]
    chosen = choose_runs([compare_dir], ["c*", "a-seed=1"])
    assert [f.name for f in chosen] == ["a-seed=1", "c-seed=1"]
    runs = load_runs(chosen)
    assert [run.label for run in runs] == ["a-seed=1 (fuzzy_model)", "c-seed=1 (fuzzy_model)"]
    # One folder named twice is one run; the same name in two folders is told apart by the folder's.
    assert choose_runs([compare_dir / "a-seed=1", compare_dir / "b-seed=1" / ".." / "a-seed=1"]) == [
        compare_dir / "a-seed=1"]
    shutil.copytree(compare_dir / "a-seed=1", tmp_path / "other" / "a-seed=1")
    twice = load_runs(choose_runs([compare_dir / "a-seed=1", tmp_path / "other"]))
    assert [run.name for run in twice] == [f"{compare_dir.name}/a-seed=1", "other/a-seed=1"]


def test_more_than_8_runs_or_a_selection_of_none_is_refused(compare_dir, tmp_path):
    from bwr_twin import BwrError
    from bwr_twin.replay.runs import MAX_RUNS, choose_runs

    many = tmp_path / "batch"
    many.mkdir()
    for k in range(MAX_RUNS + 1):
        shutil.copytree(compare_dir / "a-seed=1", many / f"{k:04d}-seed={k + 1}")
    with pytest.raises(BwrError, match=r"batch: 9 runs, more than the 8 one replay shows; choose at most 8 with --runs"):
        choose_runs([many])
    assert len(choose_runs([many], ["000[0-7]-*"])) == MAX_RUNS
    with pytest.raises(BwrError, match=r"--runs 000\*: 9 runs, more than the 8"):
        choose_runs([many], ["000*"])
    with pytest.raises(BwrError, match=r"--runs 000\[0-7\]-\*: 9 runs, more than the 8 .*choose at most 7 with"):
        choose_runs([many], ["000[0-7]-*"], also=1)  # beside a scene's run: 7 more at most
    with pytest.raises(BwrError, match=r"--runs seed=9,x\*: matches none of the 3 runs in .*compare.* \(b-seed=1, "):
        choose_runs([compare_dir], ["seed=9", "x*"])


def test_runs_of_another_path_or_machine_are_refused_naming_the_folder(short_run, tmp_path):
    from bwr_twin import BwrError
    from bwr_twin.replay.runs import check_one_world, load_runs

    def shift(scene):
        scene["trajectory"]["via_points"][1]["p"][0] -= 1.0

    def machine(scene):
        scene["machine"]["mjcf"] = str(VARIANT_MJCF)

    other_path = _moved(short_run[0], tmp_path, "moved", shift)
    other_machine = _moved(short_run[0], tmp_path, "variant", machine)
    folders = [short_run[0], short_run[0], other_path]
    plans = [run.recording.plan for run in load_runs(folders)]
    with pytest.raises(BwrError, match=r"moved: not the machine and path of .*short: via point P2 \(t = 20 s\) at "
                                       r"\(.*\) m against .*; --side-by-side shows them apart"):
        check_one_world(plans, folders)
    check_one_world(plans[:2], folders[:2])  # two runs of one path share a world
    folders = [short_run[0], other_machine]
    with pytest.raises(BwrError, match=r"variant: not the machine and path of .*short: machine .*bwr_variant.xml "
                                       r"against .*bwr.xml"):
        check_one_world([run.recording.plan for run in load_runs(folders)], folders)


def test_side_by_side_runs_stand_in_a_row_spaced_by_what_each_draws(short_run, tmp_path):
    from bwr_twin.replay.runs import load_runs

    first, variant = load_runs([short_run[0], _moved(short_run[0], tmp_path, "variant",
                                                     lambda s: s["machine"].update(mjcf=str(VARIANT_MJCF)))])
    with ReplayServer(first.recording, port=0, others=[variant], side_by_side=True) as server:
        view = server.view
        assert len(view.sites) == 2 and view.site_of == [0, 1]
        offset = np.asarray(view.machines[1].root.position)
        assert offset[0] == 0 and offset[2] == 0 and np.array_equal(view.sites[1].frame.position, offset)
        # The second run's lane starts beyond everything the first draws across the rail.
        first_lane = np.concatenate([*view.sites[0].points, view.machines[0].vertices(first.recording.plan.q_desired[0])])
        second_lane = view.machines[1].vertices(variant.recording.plan.q_desired[0]) + offset
        side = view.sites[0].pile_side
        assert (side * second_lane[:, 1]).min() > (side * first_lane[:, 1]).max()


def test_several_runs_charts_overlay_them_and_fit_the_shown_ones(short_recording):
    import dataclasses

    off = dataclasses.replace(short_recording, q_actual=short_recording.q_actual + (0.5, 0.0, 0.0))
    position_travel, *_ = charts([short_recording, off], ["near", "off"])
    assert position_travel.title == "Position error, travel (desired - actual)"
    assert [s["label"] for s in position_travel.series([True, True])[1:]] == ["near [m]", "off [m]"]
    both = position_travel.ranges([True, True])["y"]["range"]
    near = position_travel.ranges([True, False])["y"]["range"]
    assert both[0] < -0.5 < near[0] and both[1] >= near[1]  # hiding the run 0.5 m off narrows the range
    assert len(position_travel.data([True, False])) == 2  # x and the one run shown
    trajectory = charts([short_recording, off], ["near", "off"])[-1]
    assert [s["label"] for s in trajectory.series([False, True])[1:]] == ["desired [deg]", "off [deg]"]


def test_several_runs_readout_gives_each_runs_errors_with_units(short_recording):
    instant = short_recording.at(10.0)
    text = readout.runs_markdown(10.0, [instant, instant], ["a", "b"], ["#eb5f14", "#5a6eff"], 20.0)
    assert "| run | travel [m] | slew [deg] | luff [deg] |" in text and "t = 10.0 s** of 20 s" in text
    travel = f"{instant.q_error[0]:+.4f}"
    assert f'#eb5f14">&#9632;</span> a | {travel} |' in text and f"</span> b | {travel} |" in text
    assert "no run shown" in readout.runs_markdown(10.0, [], [], [], 20.0)


def test_the_chooser_hides_a_run_and_paints_the_machines(short_recording, tmp_path):
    from bwr_twin.replay.machine_view import GHOST_OPACITY
    from bwr_twin.replay.runs import Run

    with ReplayServer(short_recording, port=0, name="short", others=[Run(short_recording, "again")]) as server:
        player, view = server.player, server.view
        first, second = view.machines
        assert second.nodes[0].opacity == pytest.approx(GHOST_OPACITY)  # the second seen through
        assert [box.label for box in player.panel.shown_boxes] == ["short (fuzzy_model)", "again (fuzzy_model)"]
        player.show_run(1, False)
        until(lambda: "again" not in player.panel.readout.content, "run 2 gone from the readout")
        assert not second.visible and len(player.panel.chart_handles[0].series) == 2  # x and run 1
        player.paint(None)  # each in its own colour
        until(lambda: first.nodes[0].color == first.colour, "run 1 in its colour")
        assert first.nodes[0].opacity is None and second.nodes[0].color == second.colour


def until(condition, what: str, timeout: float = 10.0) -> None:
    deadline = time.monotonic() + timeout
    while not condition():
        assert time.monotonic() < deadline, f"not within {timeout:g} s: {what}"
        time.sleep(0.02)


@pytest.mark.parametrize(
    "args, message",
    [
        (lambda d, t: [d["many"]], "many: 9 runs, more than the 8 one replay shows"),
        (lambda d, t: [d["compare"], "--runs", "nothing*"], "--runs nothing*: matches none of the 3 runs in"),
        (lambda d, t: [d["compare"] / "a-seed=1", d["moved"]], "moved: not the machine and path of"),
        (lambda d, t: [d["compare"] / "a-seed=1", "--ghost", t], "--ghost must name a run directory"),
        (lambda d, t: [d["compare"] / "a-seed=1", SCENES / "pid_paper.toml"], "only the first source may be a scene"),
    ],
    ids=["too-many", "none-selected", "another-path", "ghost-not-a-run", "scene-second"],
)
def test_cli_refuses_what_one_replay_cannot_show_with_one_line(compare_dir, short_run, tmp_path, args, message):
    many = tmp_path / "many"
    many.mkdir()
    for k in range(9):
        shutil.copytree(compare_dir / "a-seed=1", many / f"{k:04d}")
    folders = {"many": many, "compare": compare_dir,
               "moved": _moved(short_run[0], tmp_path, "moved", lambda s: s["trajectory"]["via_points"][1]["p"].reverse())}
    out = tmp_path / "replay.html"
    proc = _start_cli(*args(folders, tmp_path / "replay.html"), "--export", out)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 2 and "Traceback" not in err, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and message in lines[0], lines
    assert not out.exists()


def test_cli_exports_the_runs_of_a_compare_folder_in_one_small_file(compare_dir, tmp_path):
    out = tmp_path / "three.html"
    proc = _start_cli(compare_dir, "--export", out)
    stdout, err = proc.communicate(timeout=120)
    assert proc.returncode == 0, err
    assert "3 runs of the 20 s reclaim" in stdout
    html = out.read_text()
    assert html.count('class="bwr-chart"') == 9 and 'id="bwr-readout-data"' in html
    assert "http://" not in html.split("__VISER_EMBED_DATA__")[1][:200]
    assert sorted(p.name for p in tmp_path.iterdir()) == [".three.html.bwr_twin", "three.html"]


FOUR_RUNS_LIMIT = 10_000_000  # bytes: four runs of the paper's reclaim in one offline file


@pytest.mark.slow
def test_export_of_four_controllers_on_the_paper_reclaim_fits_in_10_mb(tmp_path):
    compare = [sys.executable, "-m", "bwr_twin.compare", "paper_individual_gains", "--controllers",
               "paper_individual_gains", "paper_shared_gain", "pid_paper", "computed_torque_paper",
               "--out", tmp_path / "compare"]
    subprocess.run(compare, cwd=ROOT, capture_output=True, text=True, timeout=900, check=True)
    out = tmp_path / "four.html"
    command = [sys.executable, "-m", "bwr_twin.replay", tmp_path / "compare", "--export", out]
    proc = subprocess.run(command, cwd=ROOT, capture_output=True, text=True, timeout=600, check=False)
    assert proc.returncode == 0, proc.stderr
    assert "4 runs of the 700 s reclaim" in proc.stdout and out.stat().st_size <= FOUR_RUNS_LIMIT


def test_a_bench_plans_times_before_its_run_are_labelled_as_the_plans(tmp_path):
    """While a bench reclaim is simulated, the page shows its plan's times (as its speed law alone
    would run it): labelled so, and the note says the plan's duration is an upper bound."""
    from test_reclaim_plan import small_scene

    plan = Plan.from_scene(small_scene(tmp_path))
    with ReplayServer(plan, port=0) as server:
        labels = [node.text for node in server.view.sites[0]._path_nodes if hasattr(node, "text")]
        assert labels and all(line.endswith(" s (plan)") for label in labels for line in label.split("\n"))
        assert f"its plan takes at most {plan.duration:g} s" in server._waiting[0].content


def test_the_camera_fits_every_point_in_the_picture_beside_the_panel():
    """A wide pile far from the camera and a machine near it: all in the part of the picture the
    panel leaves, through the camera's perspective, and one edge touched (as close as it can be)."""
    from bwr_twin.replay.scenery import ASPECT, CAMERA_FOV, FRAME_MARGIN, frame_view

    rng = np.random.default_rng(3)
    points = np.concatenate([rng.uniform((-150, 20, 0), (150, 60, 15), (400, 3)),  # a long pile
                             rng.uniform((-20, -15, 0), (20, 5, 40), (400, 3))])  # a machine by the rail
    panel = 0.3
    view = frame_view(points, pile_side=1.0, panel_share=panel)
    forward = (view.look_at - view.position) / np.linalg.norm(view.look_at - view.position)
    right = np.cross(forward, (0.0, 0.0, 1.0))
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    relative = points - view.position
    depth = relative @ forward
    x = relative @ right / depth / (np.tan(CAMERA_FOV / 2) * ASPECT)  # -1 to 1 across the window
    y = relative @ up / depth / np.tan(CAMERA_FOV / 2)
    limit = 1.0 - FRAME_MARGIN
    assert x.min() >= -limit - 1e-6 and x.max() <= limit * (1 - 2 * panel) + 1e-6
    assert np.abs(y).max() <= limit + 1e-6
    assert max(-x.min() - limit, x.max() - limit * (1 - 2 * panel), np.abs(y).max() - limit) > -1e-3
