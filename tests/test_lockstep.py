"""The lockstep engine: a run's result does not depend on the runs that share its lockstep, the
physics-only copy steps exactly as the full model, the controller's belief and law are the
paper's, and the encoders estimate velocity as documented."""

import json

import mujoco
import numpy as np
import pytest
from conftest import HEAVY_MJCF, PAPER_MJCF, SHORT_VIA_POINTS, write_short_scene

from bwr_twin import Machine
from bwr_twin.config.scene import load_scene
from bwr_twin.control.belief import Belief
from bwr_twin.control.controller import FuzzyModelController
from bwr_twin.control.fuzzy import FuzzySurface
from bwr_twin.control.interface import ControllerContext
from bwr_twin.control.rulebase import RuleBase
from bwr_twin.results.rundir import METRICS_FILE, write_run
from bwr_twin.sim.encoders import Encoders
from bwr_twin.sim.lockstep import lockstep_key, simulate, simulate_lockstep
from bwr_twin.sim.parameters import RunParameters


@pytest.fixture(scope="module")
def short_scene(tmp_path_factory):
    return write_short_scene(tmp_path_factory.mktemp("lockstep"))


def varied(scene_file, index):
    """Run `index` of a lockstep: its own seed, gains, encoders, disturbances, friction and wind."""
    rng = np.random.default_rng(index)
    overrides = {
        "simulation.seed": index + 100,
        "controller.output_gain": rng.uniform(0.005, 0.08, 3).tolist(),
        "controller.input_scale_e": float(rng.uniform(30, 70)),
        "encoders.resolution": rng.uniform(0.0005, 0.003, 3).tolist(),
        "disturbance.amplitude": rng.uniform(0, 300, 3).tolist(),
    }
    if index % 3 == 0:
        overrides["plant.frictionloss"] = rng.uniform(0, 200, 3).tolist()
    if index % 4 == 1:
        overrides |= {"plant.wind_speed": 18.0, "plant.gust_amplitude": 4.0, "plant.wind_direction": 45.0}
    if index % 5 == 2:
        overrides["encoders.velocity_source"] = "encoder"
    if index % 7 == 3:
        overrides["controller.acceleration_feedforward"] = True
    return load_scene(scene_file, overrides)


def test_a_run_gives_the_same_metrics_alone_and_in_a_lockstep_of_256(short_scene, tmp_path):
    scenes = [varied(short_scene, i) for i in range(256)]
    assert len({lockstep_key(scene) for scene in scenes}) == 1
    together = simulate_lockstep(scenes)
    for i in (0, 1, 2, 3, 117, 255):  # plain, windy, encoder velocity, feed-forward, friction
        alone = simulate(scenes[i], nthread=1)
        write_run(alone, tmp_path / f"alone_{i}", plots=False)
        write_run(together[i], tmp_path / f"together_{i}", plots=False)
        for name in (METRICS_FILE, "timeseries.csv"):
            assert (tmp_path / f"alone_{i}" / name).read_bytes() == (tmp_path / f"together_{i}" / name).read_bytes()


def test_each_runs_signals_are_its_own_contiguous_rows(short_scene):
    results = simulate_lockstep([varied(short_scene, i) for i in range(3)])
    first, second = results[0], results[1]
    for name in ("q", "qd_measured", "drive_force", "disturbance", "wind_speed"):
        assert getattr(first, name).flags.c_contiguous, name
        assert len(getattr(first, name)) == len(first.time), name
    before = second.q.copy()
    first.q[...] = np.nan  # an engineer's edit of one run's result
    np.testing.assert_array_equal(second.q, before)
    assert not np.array_equal(before, results[2].q)  # the runs differ: each row is its own run's


def test_a_diverging_run_fails_alone_and_the_others_go_on(short_scene):
    good = load_scene(short_scene)
    bad = load_scene(short_scene, {"controller.output_gain": [1e12, 1e12, 1e12]})
    results = simulate_lockstep([good, bad, good])
    assert "the simulation diverged (MuJoCo: bad controls" in str(results[1])
    assert json.dumps(results[0].metrics) == json.dumps(results[2].metrics) == json.dumps(simulate(good).metrics)


@pytest.mark.parametrize("mjcf", [PAPER_MJCF, HEAVY_MJCF], ids=["paper", "heavy"])
def test_the_physics_only_copy_steps_exactly_as_the_full_model(mjcf):
    machine = Machine(mjcf)
    physics = machine.physics_model()
    assert physics.ngeom < machine.model.ngeom
    full_data, physics_data = mujoco.MjData(machine.model), mujoco.MjData(physics)
    rng = np.random.default_rng(0)
    for data in (full_data, physics_data):
        data.qpos[:] = [1.0, 0.3, 0.05]
    for _ in range(1000):
        ctrl = rng.uniform(-1, 1, 3) * machine.model.actuator_gear[:, 0] * 1e3
        full_data.ctrl[:] = physics_data.ctrl[:] = ctrl
        mujoco.mj_step(machine.model, full_data)
        mujoco.mj_step(physics, physics_data)
    np.testing.assert_array_equal(full_data.qpos, physics_data.qpos)
    np.testing.assert_array_equal(full_data.qvel, physics_data.qvel)


def test_the_belief_gives_mujocos_mass_matrix_and_bias(paper_machine):
    rng = np.random.default_rng(1)
    q = rng.uniform([-20, -1.5, -0.25], [20, 1.5, 0.25], (5, 3))
    qd = rng.uniform(-0.3, 0.3, (5, 3))
    belief = Belief(paper_machine, 5)
    belief.update(q, qd)
    data = mujoco.MjData(paper_machine.model)
    for run in range(5):
        data.qpos[:], data.qvel[:] = q[run], qd[run]
        mujoco.mj_forward(paper_machine.model, data)
        dense = np.zeros((3, 3))
        mujoco.mj_fullM(paper_machine.model, data, dense)
        np.testing.assert_allclose(belief.mass_matrix[run], dense, rtol=1e-12, atol=1e-9)
        np.testing.assert_allclose(belief.bias[run], data.qfrc_bias, rtol=1e-12, atol=1e-9)


def test_with_zero_fuzzy_output_the_force_is_the_bias_and_with_feedforward_inverse_dynamics(paper_machine, short_scene):
    """tau = M(q)u + bias: with e = ec = 0 the FLC gives 0 (Table 2 is symmetric), so tau is
    qfrc_bias; with feed-forward, u = qdd_d and tau is mj_inverse's force without the passive
    forces, which the belief leaves out by design."""
    scene = load_scene(short_scene, {"controller.acceleration_feedforward": True})
    surface = FuzzySurface.load(RuleBase.from_toml(scene.controller.settings.rule_base))
    rng = np.random.default_rng(2)
    q = rng.uniform([-20, -1.5, -0.25], [20, 1.5, 0.25], (4, 3))
    qd = rng.uniform(-0.3, 0.3, (4, 3))
    qdd = rng.uniform(-0.01, 0.01, (4, 3))
    context = ControllerContext(runs=4, control_period=0.01, machine=paper_machine)
    plain = FuzzyModelController(context, [load_scene(scene.path).controller.settings] * 4, surface)
    feedforward = FuzzyModelController(context, [scene.controller.settings] * 4, surface)
    bias = plain.compute(q, qd, q, qd, qdd, None)
    tau = feedforward.compute(q, qd, q, qd, qdd, None)
    assert np.all(np.abs(plain.fuzzy_output) < 1e-12)  # the centroid of O, to rounding
    data = mujoco.MjData(paper_machine.model)
    for run in range(4):
        data.qpos[:], data.qvel[:], data.qacc[:] = q[run], qd[run], qdd[run]
        mujoco.mj_inverse(paper_machine.model, data)
        np.testing.assert_allclose(bias[run], data.qfrc_bias, rtol=1e-12, atol=1e-9)
        # qfrc_inverse = M qacc + bias - passive: the force needed with the damping helping.
        np.testing.assert_allclose(tau[run], data.qfrc_inverse + data.qfrc_passive, rtol=1e-10, atol=1e-9)


def test_encoders_quantise_and_estimate_the_velocity_of_a_ramp(short_scene):
    """A ramp at constant speed: positions are quantised to the resolution, and the estimated
    velocity, averaged over the last 5 s, is the ramp's speed; the other run sees the true one."""
    period, speed = 0.01, np.array([0.2, 0.02, -0.01])  # m/s, rad/s, rad/s
    resolution = (0.00153, 0.00153, 0.00076)
    scenes = [load_scene(short_scene, {"encoders.resolution": list(resolution), "encoders.velocity_source": source,
                                       "encoders.velocity_filter": 0.5}) for source in ("encoder", "true")]
    encoders = Encoders(RunParameters.of(scenes), period, np.zeros(3))
    estimates = []
    q_measured, qd_measured = np.zeros((2, 3)), np.zeros((2, 3))
    for k in range(1, 1001):  # 10 s, twenty filter time constants
        q = np.tile(speed * k * period, (2, 1))
        encoders.measure(q, np.tile(speed, (2, 1)), q_measured, qd_measured)
        estimates.append(qd_measured[0].copy())
    np.testing.assert_array_equal(q_measured, np.round(q / resolution) * resolution)
    assert np.all(np.abs(q_measured - q) <= np.array(resolution) / 2)
    np.testing.assert_allclose(np.mean(estimates[-500:], axis=0), speed, rtol=0.05)
    np.testing.assert_array_equal(qd_measured[1], speed)  # the plant's own velocity


def test_encoder_velocity_and_feedforward_in_closed_loop(tmp_path):
    """The paper's gains still track with an encoder-estimated velocity; feed-forward of the
    desired acceleration lowers the travel error of the shared-gain controller."""
    scene_file = write_short_scene(tmp_path, SHORT_VIA_POINTS)
    true_velocity = simulate(load_scene(scene_file)).metrics
    estimated = simulate(load_scene(scene_file, {"encoders.velocity_source": "encoder"})).metrics
    assert abs(estimated["travel"]["position_error_max"]) < 3 * abs(true_velocity["travel"]["position_error_max"])
    assert estimated["travel"]["position_error_max"] != true_velocity["travel"]["position_error_max"]
    shared = {"controller.output_gain": [0.001, 0.001, 0.001]}
    without = simulate(load_scene(scene_file, shared)).metrics
    with_feedforward = simulate(load_scene(scene_file, shared | {"controller.acceleration_feedforward": True})).metrics
    assert with_feedforward["travel"]["position_error_rms"] < 0.5 * without["travel"]["position_error_rms"]
