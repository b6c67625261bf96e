"""A second machine on the rail: one MuJoCo model of both, the neighbour on its schedule, and
the two machines' shapes measured against each other with MuJoCo's own distance."""

from __future__ import annotations

import time

import mujoco
import numpy as np
import pytest
from conftest import SCENES

from bwr_twin import SceneError
from bwr_twin.config.scene import load_scene
from bwr_twin.errors import EnvelopeError
from bwr_twin.model.machine import Machine
from bwr_twin.results.summary import summary_table
from bwr_twin.sim.lockstep import Lockstep, simulate

SCENE = SCENES / "heavy_two_machines.toml"
STACKER = SCENES.parent / "mjcf" / "stacker_heavy.xml"  # the scene's neighbour
# The first machine onto its top bench and resting there while the neighbour closes in.
SHORT = {"path.via_points": [{"t": 0.0, "p": [-2.780, 0.0, 18.794]}, {"t": 180.0, "p": [-5.698, 18.927, 15.0]},
                             {"t": 400.0, "p": [-5.698, 18.927, 15.0]}]}


@pytest.fixture(scope="module")
def meeting():
    return simulate(load_scene(SCENE, SHORT))


def test_one_model_holds_both_machines_the_first_machines_joints_first():
    heavy, stacker = Machine(SCENES.parent / "mjcf" / "bwr_heavy.xml"), Machine(STACKER)
    model = heavy.physics_model(0.002, neighbour=stacker.path)
    names = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, j) for j in range(model.njnt)]
    assert names == ["travel", "slew", "luff", "neighbour/travel", "neighbour/slew", "neighbour/luff"]
    assert model.nu == heavy.model.nu + stacker.model.nu and heavy.model.nq == 3
    np.testing.assert_array_equal(model.body_mass[heavy.model.nbody:], stacker.model.body_mass[1:])  # the stacker's bodies
    loop = Lockstep([load_scene(SCENE, SHORT)])
    assert loop._plant.qpos.shape == (1, 3) and loop._plant.neighbour_q.shape == (1, 3)
    np.testing.assert_allclose(loop._plant.neighbour_q[0], [-190.0, 0.0, 0.0])


def test_the_neighbour_follows_its_schedule_on_its_own_drives(meeting):
    """Its drives hold the schedule: where it stands is its own MuJoCo state, pushed on by the
    contact's absence (the shapes make none): at the end, within a few centimetres of the last step."""
    loop = Lockstep([load_scene(SCENE, {**SHORT, "neighbour.schedule": [{"t": 0.0, "q": [-190.0, 0.0, 0.0]},
                                                                       {"t": 100.0, "q": [-180.0, 10.0, 2.0]}]})])
    while not loop.done:
        loop.advance(np.zeros((1, 3)))
        loop.measure()
    q = loop._plant.neighbour_q[0]
    np.testing.assert_allclose(q, [-180.0, np.radians(10.0), np.radians(2.0)], atol=0.05)


def test_the_stackers_chute_meeting_the_machine_is_a_contact_with_its_time(meeting):
    collision = meeting.metrics["collision"]
    (first, *_) = collision["contacts"]
    assert first["bodies"] == ["tail", "neighbour/chute"]
    assert 200.0 < first["time_s"] < 360.0 and first["depth_m"] > 1.0
    pair = collision["machines"]["tail | neighbour/chute"]
    assert pair["clearance_m"] == pytest.approx(-first["depth_m"]) and pair["time_s"] == first["depth_time_s"]
    assert collision["machines"]["wheel | neighbour/chute"]["clearance_m"] == 10.0  # never within the watch
    lines = summary_table(meeting.metrics).splitlines()
    assert any(line.startswith("warning: collision: the tail met the neighbour/chute") for line in lines)
    assert any(line.startswith("least clearance to the neighbour: tail | neighbour/") for line in lines)


def test_the_clearance_is_mujocos_distance_between_the_two_machines_shapes():
    """Beyond the watch, in reach and in contact: the monitor's clearance of the tail to the
    neighbour's wheel is MuJoCo's distance between the two boxes, on a model of both posed here
    (two heavy reclaimers: the clearance takes any two machines)."""
    from bwr_twin.collision.machines import MachineClearance

    heavy = Machine(SCENES.parent / "mjcf" / "bwr_heavy.xml")
    still = np.zeros((1, 3))
    for travel in (-170.0, -125.0, -118.0):
        clearance = MachineClearance(heavy, heavy, 1, 0.01)
        clearance.step(0, np.array([[-60.0, 0.3, 0.0]]), still, np.array([[travel, 0.0, 0.0]]), still, None)
        model, data = clearance.model, mujoco.MjData(clearance.model)
        data.qpos[:6] = [-60.0, 0.3, 0.0, travel, 0.0, 0.0]
        mujoco.mj_kinematics(model, data)
        tail = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "collision_tail")
        wheel = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "neighbour/collision_wheel")
        expected = min(mujoco.mj_geomDistance(model, data, tail, wheel, 10.0, np.zeros(6)), 10.0)
        pairs, contacts = clearance.metrics(0)
        assert pairs["tail | neighbour/wheel"]["clearance_m"] == pytest.approx(expected, abs=1e-12)
        assert (["tail", "neighbour/wheel"] in [c["bodies"] for c in contacts]) == (expected <= 0.0)
    assert expected < 0.0  # the last in contact


def test_a_schedule_out_of_order_or_envelope_is_refused_naming_the_step(tmp_path):
    with pytest.raises(SceneError, match=r"'neighbour.schedule\[1\]' t = 0 s must come after schedule\[0\]'s 0 s"):
        load_scene(SCENE, {"neighbour.schedule": [{"t": 0.0, "q": [0.0, 0.0, 0.0]}, {"t": 0.0, "q": [1.0, 0.0, 0.0]}]})
    with pytest.raises(EnvelopeError, match=r"'neighbour.schedule\[0\]' puts slew at 150.* outside the envelope"):
        simulate(load_scene(SCENE, {**SHORT, "neighbour.schedule": [{"t": 0.0, "q": [-190.0, 150.0, 0.0]}]}))


def test_the_replay_draws_the_neighbour_where_the_run_put_it(meeting, tmp_path):
    """The run directory keeps the neighbour's schedule and joints; the replay reads them back and
    poses the neighbour's bodies with its own kinematics, beside the machine's."""
    from bwr_twin.drawing.geometry import BodyPoser
    from bwr_twin.replay import Plan, Recording, ReplayServer
    from bwr_twin.results.run_files import read_timeseries
    from bwr_twin.results.rundir import write_run

    write_run(meeting, tmp_path / "run")
    series = read_timeseries(tmp_path / "run" / "timeseries.csv")
    np.testing.assert_allclose(series.neighbour["q"][:, 0], meeting.neighbour["q"][:, 0], atol=1e-6)
    recording = Recording.from_run_dir(tmp_path / "run")
    np.testing.assert_allclose(recording.neighbour_q, Recording.from_result(meeting).neighbour_q, atol=1e-6)
    planned = Plan.from_scene(load_scene(SCENE, SHORT))
    np.testing.assert_allclose(planned.neighbour_q_desired[-1], [-125.0, 0.0, 0.0])
    with ReplayServer(recording, port=0) as server:
        view = server.view.machines[0]
        assert view.neighbour is not None and len(view.neighbour.nodes) > 0
        server.player.seek(300.0)
        time_index = int(np.searchsorted(recording.plan.time, 300.0))
        expected, _ = BodyPoser(recording.plan.neighbour).poses(recording.neighbour_q[time_index])
        deadline = time.monotonic() + 30.0  # the player poses the scene on its own thread
        while time.monotonic() < deadline:
            shown = np.array([frame.position for frame in view.neighbour.bodies])
            if np.allclose(shown, expected[view.neighbour.moving], atol=0.05):
                break
            time.sleep(0.05)
        np.testing.assert_allclose(shown, expected[view.neighbour.moving], atol=0.05)


@pytest.fixture(scope="module")
def interlocked():
    return simulate(load_scene(SCENES / "heavy_two_machines_interlocked.toml", SHORT))


def test_the_interlock_stops_both_machines_short_of_each_other(meeting, interlocked):
    """The same stacker that ran its chute into the machine's tail is stopped, with the machine,
    beyond the stop zone: no contact, the stop on the tail's or counterweight's clearance to it, and the
    neighbour's schedule held from then on."""
    collision = interlocked.metrics["collision"]
    assert collision["contacts"] == [] and meeting.metrics["collision"]["contacts"]
    least = min(pair["clearance_m"] for pair in collision["machines"].values())
    assert least >= interlocked.scene.interlock.stop
    stop = next(i for i in collision["interventions"] if i["kind"] == "stop")
    assert stop["part"] in ("tail | neighbour", "counterweight | neighbour")  # what the stacker's boom meets
    assert stop["predicted_clearance_m"] <= interlocked.scene.interlock.stop
    after = interlocked.time >= stop["time_s"] + 30.0  # braked to rest well within 30 s
    schedule = interlocked.neighbour["q_desired"][after]
    np.testing.assert_array_equal(schedule, schedule[:1].repeat(len(schedule), axis=0))  # held
    assert np.ptp(interlocked.neighbour["q"][after, 0]) < 0.05
    assert interlocked.neighbour["q"][-1, 0] < -128.0  # short of the -125 m it was sent to


def test_a_later_report_stops_the_machines_sooner(interlocked):
    """The interlock hears the neighbour report_delay late and allows for what it may cover since."""
    def stop_time(result):
        return next(i["time_s"] for i in result.metrics["collision"]["interventions"] if i["kind"] == "stop")

    late = simulate(load_scene(SCENES / "heavy_two_machines_interlocked.toml", {**SHORT, "neighbour.report_delay": 5.0}))
    assert late.metrics["collision"]["contacts"] == []
    assert stop_time(late) < stop_time(interlocked)


def test_the_video_draws_the_neighbour_where_the_run_put_it(meeting):
    """The video's model holds the neighbour too, posed from the recording beside the machine."""
    from bwr_twin.replay import Recording
    from bwr_twin.replay.video_scene import ReplayScene

    recording = Recording.from_result(meeting)
    scene = ReplayScene([recording], 320, 180)
    scene.update(300.0)
    model, data = scene.model, scene.data[0]
    carriage = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "neighbour/carriage")
    own = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "carriage")
    assert data.xpos[carriage, 0] == pytest.approx(recording.at(300.0).neighbour_q[0], abs=1e-9)
    assert data.xpos[own, 0] == pytest.approx(recording.at(300.0).q_actual[0], abs=1e-9)
    assert scene.scene.ngeom > 0
