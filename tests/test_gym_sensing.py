"""The Gymnasium environment with `instruments=True` (docs/gym.md): the belt scale and the wheel
current in the observation, scaled by their spans, equal to the readings of the same run stepped
in a lockstep of its own; the vector environment the same; scenes without them refused.

heavy_dig_pile's short cut (test_stockpile.SHORT_DIG) under zero drive forces (force mode, action
0): the luff sinks, the wheel digs the flank from about 5 s at its drive's rating, and the belt
scale weighs the material from about 14 s.
"""

from __future__ import annotations

import gymnasium
import numpy as np
import pytest
from test_stockpile import SHORT_DIG

import bwr_twin.gym  # noqa: F401  (registers the id)
from bwr_twin.config.scene import load_scene
from bwr_twin.errors import SceneError
from bwr_twin.gym import ENV_ID
from bwr_twin.gym.scales import INSTRUMENTS, OBSERVATION_LIMIT
from bwr_twin.shipped import MJCF, find_scene
from bwr_twin.sim.lockstep import Lockstep

STEPS = 1600  # 16 s: through the cut and the scale's first weighing
CHECKED = (1, 2, 300, 700, 1200, 1450, 1500, 1600)  # steps at which readings are compared
SEED = 11
ZERO = np.zeros(3, dtype=np.float32)
DIG = {"scene": "heavy_dig_pile", "overrides": SHORT_DIG, "action_mode": "force"}


def lockstep_readings(seed: int) -> dict[int, tuple[float, float]]:
    """The belt scale (t/h) and wheel current (A) after each checked step of the same run, in a
    lockstep of its own under zero forces."""
    loop = Lockstep([load_scene(find_scene("heavy_dig_pile"), {**SHORT_DIG, "simulation.seed": seed})], nthread=1,
                    observe=False)
    found = {}
    for _ in range(STEPS):
        loop.measure()
        loop.advance(np.zeros((1, 3)))
        if loop.k in CHECKED:
            found[loop.k] = (float(loop.instruments.belt_scale[0]), float(loop.instruments.wheel_current[0]))
    return found


@pytest.fixture(scope="module")
def episode():
    """A single environment's observations over STEPS zero actions, with and without instruments."""
    env = gymnasium.make(ENV_ID, instruments=True, **DIG).unwrapped
    plain = gymnasium.make(ENV_ID, **DIG).unwrapped
    first, _ = env.reset(seed=SEED)
    plain_first, _ = plain.reset(seed=SEED)
    observations, plain_observations, own = [first], [plain_first], {}
    for step in range(1, STEPS + 1):
        observation, _, terminated, truncated, _ = env.step(ZERO)
        assert not (terminated or truncated), step
        observations.append(observation)
        plain_observations.append(plain.step(ZERO)[0])
        if step in CHECKED:
            readings = env.episodes.locksteps[0].instruments
            own[step] = (float(readings.belt_scale[0]), float(readings.wheel_current[0]))
    return env, np.array(observations), np.array(plain_observations), own


def test_the_observation_holds_the_instruments_scaled_as_the_lockstep_reads_them(episode):
    env, observations, _, own = episode
    scales = env.scales.instruments
    assert scales[0] == pytest.approx(98 * 1.0 / 60 * 2400 * 3.6)  # t/h: the wheel's capacity, 14,112 t/h
    loop = env.episodes.locksteps[0]
    assert scales[1] == pytest.approx(1.0e6 * loop.instruments.motor.amps_per_watt)  # A at the rated 1 MW: 1,024 A
    alone = lockstep_readings(SEED)
    for step in CHECKED:
        expected = np.array(alone[step]) / scales
        assert own[step] == alone[step], step  # the environment's run is the run alone
        np.testing.assert_array_equal(observations[step, INSTRUMENTS], expected.astype(np.float32), err_msg=str(step))
    # Before the first period there is no reading; then idle current, then cutting at the rating.
    assert observations[0, INSTRUMENTS].tolist() == [0.0, 0.0]
    assert observations[1, 20] == pytest.approx(0.3, abs=0.03)  # 300 kW turning empty
    assert observations[STEPS, 20] == pytest.approx(1.0, abs=0.03)
    assert observations[STEPS, 19] > 0.3  # the scale weighs what the wheel cut 8.9 s before
    assert abs(observations[1200, 19]) < 0.01  # ... and nothing before that
    assert env.observation_space.shape == (21,) and all(env.observation_space.contains(o) for o in observations)
    assert np.abs(observations).max() <= OBSERVATION_LIMIT


def test_the_other_entries_are_those_of_the_environment_without_instruments(episode):
    _, observations, plain_observations, _ = episode
    assert plain_observations.shape[1] == 19
    np.testing.assert_array_equal(observations[:, :19], plain_observations)


def test_the_vector_environment_observes_the_instruments_of_each_sub_environment(episode):
    _, observations, _, _ = episode
    envs = gymnasium.make_vec(ENV_ID, num_envs=2, nthread=1, instruments=True, **DIG)
    assert envs.single_observation_space.shape == (21,) and envs.observation_space.shape == (2, 21)
    first, _ = envs.reset(seed=SEED)  # sub-environments SEED and SEED + 1
    vector = [first]
    for _ in range(CHECKED[4]):
        vector.append(envs.step(np.zeros((2, 3), dtype=np.float32))[0])
    vector = np.array(vector)
    np.testing.assert_array_equal(vector[:, 0], observations[:CHECKED[4] + 1])  # bit for bit the single one's
    other = lockstep_readings(SEED + 1)
    scales = envs.unwrapped.scales.instruments
    for step in CHECKED[:5]:
        expected = (np.array(other[step]) / scales).astype(np.float32)
        np.testing.assert_array_equal(vector[step, 1, INSTRUMENTS], expected, err_msg=str(step))
    assert not np.array_equal(vector[1:, 0, 20], vector[1:, 1, 20])  # each its own noise


def test_a_scene_without_instruments_is_refused_naming_it(tmp_path):
    scene = find_scene("pid_paper")
    with pytest.raises(SceneError, match=rf"^{scene}: instruments=True observes the belt scale and the wheel "
                                         r"current, .* this scene has no \[stockpile\]"):
        gymnasium.make(ENV_ID, scene="pid_paper", instruments=True)
    with pytest.raises(SceneError, match=r"no \[stockpile\]"):
        gymnasium.make_vec(ENV_ID, num_envs=2, scene="pid_paper", instruments=True)
    # A pile, but a machine without its wheel motor.
    text = (MJCF / "bwr_heavy.xml").read_text()
    lines = [line for line in text.splitlines() if not line.strip().startswith(('<numeric name="wheel_motor"',
                                                                                 '<numeric name="wheel_current_noise"'))]
    assert len(lines) == len(text.splitlines()) - 2
    machine = tmp_path / "heavy_no_motor.xml"
    machine.write_text("\n".join(lines))
    overrides = {**SHORT_DIG, "machine.mjcf": str(machine)}
    with pytest.raises(SceneError, match=r"heavy_dig_pile\.toml: instruments=True observes .* its machine "
                                         r"heavy_no_motor\.xml describes no wheel motor \(custom numeric "
                                         r"'wheel_motor'\)"):
        gymnasium.make(ENV_ID, scene="heavy_dig_pile", overrides=overrides, instruments=True)
    gymnasium.make(ENV_ID, scene="heavy_dig_pile", overrides=overrides)  # without instruments it is a scene as any
    with pytest.raises(ValueError, match=r"instruments must be True or False, got 'yes'"):
        gymnasium.make(ENV_ID, instruments="yes", **DIG)
