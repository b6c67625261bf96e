"""The web replay: every visual geom of any machine becomes one scene node of MuJoCo's size, posed
by MuJoCo's own kinematics; the server binds locally, serves and frees its port; the timeline
plays; the offline export stays small. Browser checks are in test_browser.py."""

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
from bwr_twin.model.machine import paper_to_world
from bwr_twin.replay import Plan, Recording, ReplayServer, export_html, readout
from bwr_twin.replay.charts import MARKER_TOP, charts
from bwr_twin.replay.geometry import VISUAL_GROUP, BodyPoser, visual_geoms
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
        nodes = server.view.geom_nodes
        geoms = server.view.geoms
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
    from bwr_twin.replay.geometry import box, capsule, cylinder, ellipsoid

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
    from bwr_twin.replay.app import via_point_marks

    names = [f"P{i + 1}" for i in range(5)]
    assert via_point_marks([0.0, 200.0, 300.0, 500.0, 700.0], names) == tuple(
        (t, f"P{i + 1}") for i, t in enumerate([0.0, 200.0, 300.0, 500.0, 700.0])
    )
    assert via_point_marks([0.0, 620.0, 680.0, 1680.0], names) == ((0.0, "P1"), (620.0, "P2"), 680.0, (1680.0, "P4"))
    # A bench plan's unnamed via points (travel steps) are marked, never labelled.
    assert via_point_marks([0.0, 100.0, 900.0], ["bench 1", "", "pass 1"]) == ((0.0, "bench 1"), 100.0,
                                                                               (900.0, "pass 1"))


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


def test_chart_marker_stands_at_the_current_time(short_recording):
    for chart in charts(short_recording):
        x, *series, marker = chart.data(7.3)
        assert len(series) == len(chart.values) and all(len(s) == len(x) for s in series)
        assert np.all(np.diff(x) >= 0) and np.all(np.isfinite(np.concatenate(series)))
        assert x[np.argmax(marker)] == 7.3 and marker.max() == MARKER_TOP


def test_error_charts_are_the_papers_errors_in_engineering_units(short_run, short_recording):
    result = short_run[1]
    position, velocity, _ = charts(short_recording)
    assert "Position error" in position.title and "Velocity error" in velocity.title
    at = np.searchsorted(result.time, position.time[-1])  # the last charted sample, t = 20 s
    assert position.values[0][-1] == pytest.approx(result.q_desired[at, 0] - result.q[at, 0], abs=1e-9)
    assert velocity.values[1][-1] == pytest.approx(
        np.degrees(result.qd_desired[at, 1] - result.qd[at, 1]), abs=1e-9
    )
    assert velocity.series[2]["label"] == "slew [deg/s]" and velocity.axes[1]["label"] == "travel [m/s]"


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
        assert player.time == paused_at and player.time_slider.value == pytest.approx(paused_at)
        player.seek(12.5)
        time.sleep(0.2)
        assert player.time == 12.5 and "t = 12.5 s" in player.readout.content
        player.set_speed(100)
        player.toggle()  # plays to the end and stops there
        time.sleep(0.5)
        assert not player.playing and player.time == player.end
        assert player.speed_slider.value == 100


def test_preview_shows_the_machine_before_the_recording(short_scene, short_recording):
    with ReplayServer(Plan.from_scene(short_scene), port=0) as server:
        assert server.player is None and len(server.view.geom_nodes) > 0
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
    assert [p.name for p in tmp_path.iterdir()] == ["short.html"]  # no partial file left behind


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
