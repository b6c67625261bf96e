"""Collision shapes and their clearance to the pile: against MuJoCo's own distance on the same
surface, a boom lowered into the pile reported with its time, and scenes without shapes unchanged."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
from conftest import HEAVY_MJCF, SCENES

from bwr_twin import ModelError
from bwr_twin.collision.pile import clearances
from bwr_twin.config.scene import load_scene
from bwr_twin.model.machine import Machine
from bwr_twin.model.shapes import BOX, CAPSULE
from bwr_twin.results.summary import summary_table
from bwr_twin.sim.lockstep import simulate

SPACING = 0.5


def _rough_pile(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    x, y = np.arange(0.0, 6.01, SPACING), np.arange(0.0, 5.01, SPACING)
    X, Y = np.meshgrid(x, y)
    z = 2.0 - 0.08 * ((X - 3) ** 2 + (Y - 2.5) ** 2) + rng.uniform(0, 0.3, X.shape)
    return x, y, np.maximum(z, 0.0)


def _mujoco_distance(x, y, z, kind, half, position, rotation) -> float:
    """MuJoCo's mj_geomDistance from the shape to the surface's triangles, each a prism 1 m deep
    (the hfield's split of each cell along its diagonal), the least over them."""
    spec = mujoco.MjSpec()
    triangles = []
    for r in range(len(y) - 1):
        for c in range(len(x) - 1):
            corners = {(i, j): (x[c + i], y[r + j], z[r + j, c + i]) for i in (0, 1) for j in (0, 1)}
            triangles += [(corners[0, 0], corners[1, 1], corners[1, 0]), (corners[0, 0], corners[1, 1], corners[0, 1])]
    for n, triangle in enumerate(triangles):
        top = np.array(triangle)
        vertices = np.vstack([top, top - [0, 0, 1.0]])
        spec.add_mesh(name=f"t{n}", uservert=vertices.ravel().tolist())
        spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_MESH, meshname=f"t{n}", contype=0, conaffinity=0)
    quat = np.empty(4)
    mujoco.mju_mat2Quat(quat, rotation.ravel())
    size = list(half) if kind == BOX else [half[0], half[2], 0.0]
    geom_type = mujoco.mjtGeom.mjGEOM_BOX if kind == BOX else mujoco.mjtGeom.mjGEOM_CAPSULE
    spec.worldbody.add_geom(type=geom_type, size=size, pos=list(position), quat=list(quat), contype=0, conaffinity=0)
    model = spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    shape, fromto = model.ngeom - 1, np.zeros(6)
    return min(mujoco.mj_geomDistance(model, data, shape, g, 50.0, fromto) for g in range(model.ngeom - 1))


@pytest.mark.parametrize("kind", [BOX, CAPSULE], ids=["box", "capsule"])
def test_the_clearance_to_the_pile_is_mujoco_s_distance_to_its_surface_within_the_vertex_bound(kind):
    """The clearance is the least distance to the surface's vertices: never below MuJoCo's distance
    to the triangles between them, and above it by at most s^2 / (4 d)."""
    rng = np.random.default_rng(5)
    x, y, z = _rough_pile(rng)
    for _ in range(12):
        half = np.array([0.8, 0.4, 0.3]) if kind == BOX else np.array([0.3, 0.0, 1.0])
        rotation, quat = np.empty(9), rng.normal(size=4)
        mujoco.mju_quat2Mat(rotation, quat / np.linalg.norm(quat))
        rotation = rotation.reshape(3, 3)
        position = np.array([rng.uniform(1.5, 4.5), rng.uniform(1.5, 3.5), rng.uniform(4.0, 5.5)])
        ours = clearances(z, x, y, np.array([kind]), half[None], position[None], rotation[None], 10.0)[0]
        theirs = _mujoco_distance(x, y, z, kind, half, position, rotation)
        assert theirs > 0.3  # above the surface: what the bound is for
        assert theirs - 1e-6 <= ours <= theirs + SPACING**2 / (4 * theirs) + 1e-6, (ours, theirs)


def test_a_shape_below_the_surface_has_minus_its_depth():
    x, y = np.arange(0.0, 10.01, 0.25), np.arange(0.0, 10.01, 0.25)
    z = np.full((len(y), len(x)), 3.0)
    box = np.array([2.0, 0.5, 0.5])
    for centre, expected in ((2.0, -1.5), (3.6, 0.1), (8.0, 4.5)):  # underside at 1.5, 3.1, 7.5 m
        got = clearances(z, x, y, np.array([BOX]), box[None], np.array([[5.0, 5.0, centre]]), np.eye(3)[None], 10.0)
        assert got[0] == pytest.approx(expected, abs=1e-9)
    far = clearances(z, x, y, np.array([BOX]), box[None], np.array([[5.0, 5.0, 30.0]]), np.eye(3)[None], 10.0)
    assert far[0] == 10.0  # beyond the watch


def test_the_heavy_machine_declares_its_shapes_and_a_bad_one_is_refused(tmp_path):
    machine = Machine(HEAVY_MJCF)
    parts = {s.part: s for s in machine.collision_shapes}
    assert set(parts) == {"portal", "tail", "boom", "counterweight", "wheel"}
    assert parts["wheel"].cuts and not parts["boom"].cuts
    assert [s.mount.joints for s in machine.collision_shapes] == [1, 2, 3, 3, 3]
    touching = tmp_path / "touching.xml"
    touching.write_text(HEAVY_MJCF.read_text().replace(
        '<geom name="collision_boom" class="collision"', '<geom name="collision_boom" class="collision" contype="1"'))
    with pytest.raises(ModelError, match=r"collision geom 'collision_boom' \(group 5\) must have contype=\"0\" "
                                         r"conaffinity=\"0\""):
        Machine(touching)


@pytest.fixture(scope="module")
def boom_into_pile():
    return simulate(load_scene(SCENES / "heavy_boom_into_pile.toml"))


def test_a_boom_lowered_into_the_pile_is_reported_with_its_time(boom_into_pile):
    """The boom's underside meets the pile as the luff passes about 0.4 deg down (the boom 1.75 m
    deep about its line): the contact starts then, is deepest at the path's lowest point and ends
    as the boom rises past the same luff."""
    result = boom_into_pile
    collision = result.metrics["collision"]
    (contact,) = collision["contacts"]
    assert contact["bodies"] == ["boom", "pile"]
    assert 150.0 < contact["time_s"] < 250.0 and 350.0 < contact["end_s"] < 450.0
    assert contact["depth_time_s"] == pytest.approx(300.0, abs=5.0) and contact["depth_m"] > 3.0
    assert collision["pile"]["boom"]["clearance_m"] == pytest.approx(-contact["depth_m"])
    # Before the contact the boom was clear: its measured clearance at the record's samples.
    machine = result.machine
    boom = next(s for s in machine.collision_shapes if s.part == "boom")
    before = result.time < contact["time_s"] - 1.0
    positions, rotations = boom.mount.poses(result.q[before][-1:])
    pile = result.reclaim
    clearance = clearances(pile.z_start, pile.x, pile.y, np.array([boom.kind]), boom.half[None], positions,
                           rotations, 10.0)[0]
    assert 0.0 < clearance < 1.5
    # The wheel's envelope is no collision with the pile it cuts.
    assert "wheel" not in collision["pile"]


def test_scenes_without_a_pile_have_no_collision_object():
    assert "collision" not in simulate(load_scene(SCENES / "pid_paper.toml")).metrics


@pytest.fixture(scope="module")
def interlocked():
    return simulate(load_scene(SCENES / "heavy_boom_interlocked.toml"))


def test_the_interlock_stops_the_boom_short_of_the_pile_in_the_period_it_decides(interlocked, boom_into_pile):
    """The same error with the interlock: it warns, slows and stops in that order, each as the
    predicted clearance crosses its zone; no contact, the boom's least clearance at least the stop
    zone's metre; the reference stands still from the period of the stop on (no period late)."""
    collision = interlocked.metrics["collision"]
    assert collision["contacts"] == [] and boom_into_pile.metrics["collision"]["contacts"]
    warn, slow, stop = collision["interventions"]
    assert [warn["kind"], slow["kind"], stop["kind"]] == ["warn", "slow", "stop"]
    zones = interlocked.scene.interlock
    for event, edge in ((warn, zones.warn), (slow, zones.slow), (stop, zones.stop)):
        assert event["part"] == "boom" and edge - 0.01 < event["predicted_clearance_m"] <= edge
    assert collision["pile"]["boom"]["clearance_m"] >= zones.stop
    held = interlocked.time >= stop["time_s"] - 1e-9
    np.testing.assert_array_equal(interlocked.q_desired[held], np.repeat(interlocked.q_desired[held][:1],
                                                                         held.sum(), axis=0))
    np.testing.assert_array_equal(interlocked.qd_desired[held], 0.0)
    before = np.flatnonzero(interlocked.time < stop["time_s"] - 1e-9)[-1]
    assert np.abs(interlocked.qd_desired[before]).max() > 0  # still moving the record sample before
    # Until the first warning the run follows the path as the run without the interlock does.
    early = interlocked.time < warn["time_s"] - 1e-9
    np.testing.assert_array_equal(interlocked.q[early], boom_into_pile.q[early])


def test_an_interlock_is_refused_where_it_cannot_act(tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text('extends = "heavy_boom_interlocked"\n[interlock]\nslow = 3.5\n')
    with pytest.raises(Exception, match=r"\[interlock\] zones must hold 0 < 'stop' < 'slow' < 'warn' m, got stop "
                                        r"1.0, slow 3.5, warn 3.0"):
        load_scene(path)
    path.write_text('extends = "heavy_boom_interlocked"\n[interlock]\nencoder_window = 0.001\n')
    with pytest.raises(Exception, match=r"'interlock.encoder_window' must span at least a control period \(0.01 s\), "
                                        r"got 0.001 s"):
        load_scene(path)
    path.write_text('extends = "pid_paper"\n[interlock]\nwarn = 3.0\nslow = 2.0\nstop = 1.0\n')
    with pytest.raises(Exception, match=r"\[interlock\] keeps the machine clear of the pile and of a neighbour, but "
                                        r"the scene has neither \[stockpile\] nor \[neighbour\]"):
        load_scene(path)


LUFF_STUCK = [{"kind": "encoder_stuck", "axis": "luff", "start": 120.0}]


def test_without_its_encoder_check_the_interlock_sees_what_the_encoders_show():
    """A luff encoder stuck before the boom nears the pile: the PID, seeing no motion, drives the
    boom down, and an interlock that does not check its encoders, reading the same frozen encoder,
    believes it stands where it was: no intervention, and the twin reports the contact."""
    result = simulate(load_scene(SCENES / "heavy_boom_interlocked.toml",
                                 {"faults": LUFF_STUCK, "interlock.encoder_check": False}))
    collision = result.metrics["collision"]
    assert collision["interventions"] == []
    (contact,) = collision["contacts"]
    assert contact["bodies"] == ["boom", "pile"] and contact["time_s"] > 120.0 and contact["end_s"] is None


def test_a_stuck_encoder_parts_from_its_drive_and_the_interlock_quick_stops_the_drives():
    """The same stuck encoder, with the check: the luff's drive turns while its encoder stands, and
    once the two part by the tolerance at the shapes the interlock quick-stops the drives. They
    brake on their own speed feedback, whatever the PID commands, and the boom stands clear."""
    result = simulate(load_scene(SCENES / "heavy_boom_interlocked.toml", {"faults": LUFF_STUCK}))
    collision = result.metrics["collision"]
    (stop,) = collision["interventions"]
    lock = result.scene.interlock
    assert stop["kind"] == "quick_stop" and stop["axis"] == "luff"
    assert 120.0 < stop["time_s"] < 120.0 + 10 * lock.encoder_window
    assert lock.encoder_tolerance < stop["encoder_apart_m"] < 1.5 * lock.encoder_tolerance  # caught as it crossed
    assert collision["contacts"] == [] and collision["pile"]["boom"]["clearance_m"] > lock.stop
    after = result.time > stop["time_s"]
    # The drives' own forces, not the PID's, from the period of the stop on ...
    assert np.abs(result.drive_force[after] - result.drive_force_command[after]).max() > 1e3
    # ... which bring every joint to a stand and hold it there.
    standing = result.time > stop["time_s"] + 5.0
    assert np.abs(result.qd[standing]).max() < 1e-4
    assert f"quick stop at {stop['time_s']:.2f} s (luff encoder" in summary_table(result.metrics)


def test_the_encoder_check_stops_in_the_period_the_encoder_parts_from_its_drive():
    """The check alone, on readings given: an encoder that follows its drive through speed
    changes never trips it; once it sticks, the quick stop comes in the very period in which the
    encoder's motion over the window parts from the drive's integrated speed by the tolerance."""
    from bwr_twin.collision.interlock import ZoneInterlock

    settings = load_scene(SCENES / "heavy_boom_interlocked.toml").interlock
    period, levers = 0.1, np.array([1.0, 60.0, 40.0])
    lock = ZoneInterlock(settings, 1, period, ["boom"], levers)
    t = np.arange(400) * period
    speed = np.stack([0.3 * np.sin(t / 7), 0.004 * np.sin(t / 3), 0.002 * np.cos(t / 5)], axis=1)  # m/s, rad/s
    q = np.concatenate([np.zeros((1, 3)), np.cumsum(0.5 * (speed[1:] + speed[:-1]) * period, axis=0)])
    stuck = 250
    reading = q.copy()
    reading[stuck:, 1] = q[stuck, 1]  # the slew encoder sticks
    window = round(settings.encoder_window / period)
    tripped = None  # the first period the encoder is the tolerance off its drive at the shapes
    for k in range(len(t)):
        lock.drive_speed[:] = speed[k]
        pace = lock.pace(t[k], reading[k:k + 1], np.zeros((1, 3)), np.full((1, 1), 50.0))
        first = max(k - window, 0)
        apart = abs((reading[k, 1] - reading[first, 1]) - (q[k, 1] - q[first, 1])) * levers[1]
        if tripped is None and apart > settings.encoder_tolerance:
            tripped = k
        assert lock.quick_stop[0] == (tripped is not None) and pace[0] == (0.0 if tripped is not None else 1.0)
    assert tripped is not None and t[tripped] > t[stuck]
    (event,) = lock.interventions[0]
    assert event["kind"] == "quick_stop" and event["axis"] == "slew" and event["time_s"] == t[tripped]


def test_the_batch_summary_has_the_least_clearance_and_the_contacts(boom_into_pile, interlocked):
    from bwr_twin.batch.report import _flat_metrics

    hit, kept = _flat_metrics(boom_into_pile.metrics), _flat_metrics(interlocked.metrics)
    assert hit["collision.contacts"] == 1 and hit["collision.clearance_min_m"] == pytest.approx(-4.64, abs=0.01)
    assert kept["collision.contacts"] == 0 and kept["collision.clearance_min_m"] >= 1.0


ENGINEERS_INTERLOCK = '''
import numpy as np
from bwr_twin.collision.interlock import Interlock


class StopAtTwoMetres(Interlock):
    """Stops for good when any shape comes within 2.5 m of the pile it knows, no prediction."""

    def __init__(self, settings, runs, period, parts, levers):
        super().__init__(settings, runs, period, parts, levers)
        self.stopped = np.zeros(runs, dtype=bool)

    def pace(self, time, q_measured, qd_measured, clearance):
        newly = (clearance.min(axis=1) < 2.5) & ~self.stopped
        for run in np.flatnonzero(newly):
            self.interventions[run].append({"kind": "stop", "time_s": time})
        self.stopped |= newly
        return np.where(self.stopped, 0.0, 1.0)


class Runaway(Interlock):
    def pace(self, time, q_measured, qd_measured, clearance):
        return np.full(len(q_measured), 2.0)
'''


def test_an_engineer_s_interlock_replaces_the_built_in(tmp_path):
    (tmp_path / "my_interlock.py").write_text(ENGINEERS_INTERLOCK)
    scene = tmp_path / "mine.toml"
    scene.write_text(f'extends = "{SCENES / "heavy_boom_interlocked.toml"}"\n[interlock]\n'
                     'type = "my_interlock.py:StopAtTwoMetres"\n')
    result = simulate(load_scene(scene))
    collision = result.metrics["collision"]
    (stop,) = collision["interventions"]
    assert stop["kind"] == "stop" and collision["contacts"] == []
    assert collision["pile"]["boom"]["clearance_m"] > 2.0  # stopped at 2.5 m, less its braking
    scene.write_text(f'extends = "{SCENES / "heavy_boom_interlocked.toml"}"\n[interlock]\n'
                     'type = "my_interlock.py:Runaway"\n')
    with pytest.raises(Exception, match=r"mine.toml: interlock .*my_interlock.py:Runaway: pace\(\) returned \[2.\] at "
                                        r"t = 0.00 s; paces lie in \[0, 1\]"):
        simulate(load_scene(scene))


def test_a_bench_reclaim_is_slowed_by_the_interlock_from_the_next_period(tmp_path):
    """The small bench scene's boom passes 5.0 m above its pile: with a slow zone at 6 m the
    interlock slows the plan where it comes near (its moves' time and its passes' speed law at
    the slow share), once and for the rest of the bench, the machine at full pace staying near; the
    plan is carried out to its end all the same, later, and the boom keeps farther from the pile."""
    from test_reclaim_plan import scene_file

    plain = simulate(load_scene(scene_file(tmp_path)))
    zones = "\n[interlock]\nwarn = 7.0\nslow = 6.0\nstop = 4.5\n"
    slowed = simulate(load_scene(scene_file(tmp_path, extra=zones, name="slowed.toml")))
    collision = slowed.metrics["collision"]
    assert [i["kind"] for i in collision["interventions"]] == ["warn", "slow"]
    assert collision["contacts"] == []
    assert slowed.metrics["run"]["duration"] > 1.5 * plain.metrics["run"]["duration"]
    names = slowed.metrics["run"]["waypoint_names"]
    assert names == plain.metrics["run"]["waypoint_names"] and names[-1] == "end"  # every pass, to the plan's end
    assert slowed.metrics["reclaim"]["bench_t"][0] > 0.8 * plain.metrics["reclaim"]["bench_t"][0]
    assert collision["pile"]["boom"]["clearance_m"] > plain.metrics["collision"]["pile"]["boom"]["clearance_m"]
    slow_from = collision["interventions"][1]["time_s"]
    after = slowed.time > slow_from + 1.0
    assert np.abs(slowed.qd_desired[after, 0]).max() <= 0.3 * 0.5 + 1e-9  # the travel at most the slow share of its rated 0.5 m/s
