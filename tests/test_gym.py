"""The Gymnasium environment: the checker, seeding, episode ends, force-mode limits, the vector
environment against single ones, the refusal of a bench reclaim, and the example scripts."""

import re
import subprocess
import sys
import warnings

import gymnasium
import numpy as np
import pytest
from conftest import PAPER_MJCF, ROOT, unrated_paper_mjcf, write_short_scene
from gymnasium.utils.env_checker import check_env

import bwr_twin.gym  # noqa: F401  (registers the id)
from bwr_twin.errors import ModelError, SceneError
from bwr_twin.gym import ENV_ID
from bwr_twin.gym.scales import REFERENCE_ACCELERATION, REFERENCE_POSITION, REFERENCE_VELOCITY

# A 2 s reclaim (201 control periods), 30 cm along the rail.
TINY_VIA_POINTS = [{"t": 0.0, "p": [0.0, -11.0, 55.0]}, {"t": 2.0, "p": [0.0, -11.0, 54.7]}]
# Full force (10 MN on travel) drives the paper machine out of its +-25 m of travel within a second.
PUSH = dict(action_mode="force", force_scale=(1e7, 1e8, 1e8))
HUGE = dict(action_mode="force", force_scale=(1e300, 1e300, 1e300))  # an action of 1 diverges


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    return write_short_scene(tmp_path_factory.mktemp("gym"), TINY_VIA_POINTS)


@pytest.fixture(scope="module")
def tiny_unrated(tmp_path_factory):
    """The tiny scene on the paper's machine without drive ratings: forces beyond any drive's."""
    folder = tmp_path_factory.mktemp("gym_unrated")
    unrated = unrated_paper_mjcf(folder)
    return write_short_scene(folder, TINY_VIA_POINTS, edit=lambda text: text.replace(f'"{PAPER_MJCF}"', f'"{unrated}"'))


def steps(env, actions):
    """Observations, rewards and flags of `actions` from the env's current state."""
    out = [env.step(a) for a in actions]
    return [o[0] for o in out], [o[1] for o in out], [(o[2], o[3]) for o in out]


def test_checker_passes_without_warnings(tiny):
    env = gymnasium.make(ENV_ID, scene=str(tiny))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_env(env.unwrapped)


def test_same_seed_and_actions_give_the_same_episode(tiny):
    env = gymnasium.make(ENV_ID, scene=str(tiny)).unwrapped
    actions = np.random.default_rng(0).uniform(-1, 1, (100, 3)).astype(np.float32)
    first, _ = env.reset(seed=7)
    run_1 = steps(env, actions)
    again, _ = env.reset(seed=7)
    run_2 = steps(env, actions)
    assert np.array_equal(first, again) and np.array_equal(run_1[0], run_2[0]) and run_1[1] == run_2[1]
    env.reset(seed=8)  # another seed: other disturbances, other velocities
    assert not np.array_equal(steps(env, actions)[0], run_1[0])
    # An unseeded reset draws the next scene seed from the seeded generator: reproducible too.
    seeds = []
    for _ in range(2):
        env.reset(seed=7)
        seeds.append(env.reset()[1]["seed"])
    assert seeds[0] == seeds[1] != 7


def test_the_path_end_terminates(tiny):
    env = gymnasium.make(ENV_ID, scene=str(tiny)).unwrapped
    observation, info = env.reset(seed=1)
    samples = round(2.0 / env.control_period) + 1
    observations = [observation]
    for k in range(samples):
        observation, reward, terminated, truncated, info = env.step(np.zeros(3, dtype=np.float32))
        observations.append(observation)
        assert terminated == (k == samples - 1) and not truncated
    assert info["ended"] == "path end" and info["time"] == pytest.approx(2.0 + env.control_period)
    # Feed-forward alone tracks within a centimetre; the reference stays within half its scale.
    assert np.abs(info["position_error"]).max() < 0.01
    observations = np.array(observations)
    assert np.abs(observations[:, REFERENCE_POSITION]).max() <= 1.0
    assert np.abs(observations[:, REFERENCE_VELOCITY]).max() <= 0.5 + 1e-6
    assert np.abs(observations[:, REFERENCE_ACCELERATION]).max() <= 0.5 + 1e-6
    with pytest.raises(RuntimeError, match="reset"):
        env.step(np.zeros(3, dtype=np.float32))


def test_leaving_the_envelope_truncates(tiny_unrated):
    env = gymnasium.make(ENV_ID, scene=str(tiny_unrated), **PUSH).unwrapped
    env.reset(seed=1)
    for k in range(200):
        observation, reward, terminated, truncated, info = env.step(np.array([1, 0, 0], dtype=np.float32))
        if terminated or truncated:
            break
    assert truncated and not terminated and k < 100
    assert re.fullmatch(r"left the operating envelope: travel = 2\d\.\d{3} m", info["ended"])
    assert observation in env.observation_space and reward < 0


def test_a_diverged_run_ends_the_episode_cleanly_and_silently(tiny_unrated, tmp_path, monkeypatch, capfd):
    monkeypatch.chdir(tmp_path)  # where MuJoCo would write MUJOCO_LOG.TXT
    env = gymnasium.make(ENV_ID, scene=str(tiny_unrated), **HUGE).unwrapped
    env.reset(seed=1)
    observation, reward, terminated, truncated, info = env.step(np.ones(3, dtype=np.float32))
    assert truncated and not terminated and info["ended"].startswith("diverged: MuJoCo")
    assert observation in env.observation_space and np.isfinite(reward)
    assert capfd.readouterr() == ("", "") and not list(tmp_path.iterdir())


def test_force_mode_needs_drive_ratings_or_a_scale(tiny, tiny_unrated):
    with pytest.raises(ModelError, match=r"bwr_unrated\.xml: action_mode 'force' needs drive ratings.*force_scale"):
        gymnasium.make(ENV_ID, scene=str(tiny_unrated), action_mode="force")
    paper = gymnasium.make(ENV_ID, scene=str(tiny), action_mode="force").unwrapped  # its assumed ratings
    assert paper.drive.high.tolist() == [3.2e3, 3.0e4, 1.1e6] and paper.drive.low.tolist() == [3.2e3, 3.0e4, 5.6e5]
    heavy = gymnasium.make(ENV_ID, scene="heavy_reclaim", action_mode="force").unwrapped
    assert heavy.drive.high.tolist() == [5.4e5, 1.13e7, 3.05e7] and heavy.drive.low.tolist() == [5.4e5, 1.13e7, 1.55e7]
    with pytest.raises(SceneError, match="no_such_scene"):
        gymnasium.make(ENV_ID, scene="no_such_scene")


def test_vector_env_is_one_lockstep_and_matches_single_envs_bit_for_bit(tiny_unrated):
    n, seed, periods = 3, 20, 150
    # PUSH's forces as shares of 1e300 N, so that an action of 1 makes MuJoCo fail.
    actions = np.random.default_rng(1).uniform(-1, 1, (periods, n, 3)) * np.array([1e-293, 1e-292, 1e-292])
    actions[:, 0] = (1e-293, 0, 0)  # sub-environment 0 leaves the envelope again and again
    actions[5, 1] = 1.0  # and sub-environment 1 diverges, alone in its lockstep
    envs = gymnasium.make_vec(ENV_ID, num_envs=n, scene=str(tiny_unrated), **HUGE)
    assert isinstance(envs.unwrapped, bwr_twin.gym.ReclaimVectorEnv)
    observations, _ = envs.reset(seed=seed)
    (loop,) = envs.unwrapped.episodes.locksteps
    assert loop.runs == n
    vector = [envs.step(a) for a in actions]
    assert len(envs.unwrapped.episodes.locksteps) > 1  # restarted episodes run in locksteps of their own
    ends, reasons = 0, {why for _, _, _, _, infos in vector if "ended" in infos for why in infos["ended"] if why}
    assert any(why.startswith("diverged") for why in reasons) and any(why.startswith("left") for why in reasons)
    for i in range(n):
        env = gymnasium.make(ENV_ID, scene=str(tiny_unrated), **HUGE).unwrapped
        observation, _ = env.reset(seed=seed + i)
        assert np.array_equal(observation, observations[i])
        ended = False
        for t, (obs, reward, terminated, truncated, _) in enumerate(vector):
            if ended:  # next-step autoreset: the vector env starts the next episode, as reset() does
                expected = (env.reset()[0], 0.0, False, False)
            else:
                expected = env.step(actions[t, i])[:4]
            assert np.array_equal(obs[i], expected[0]), (i, t)
            assert (reward[i], terminated[i], truncated[i]) == expected[1:], (i, t)
            ended = expected[2] or expected[3]
            ends += ended
    assert ends >= 3


@pytest.mark.parametrize("make", [
    lambda scene: gymnasium.make(ENV_ID, scene=scene),
    lambda scene: gymnasium.make_vec(ENV_ID, num_envs=2, scene=scene),
], ids=["make", "make_vec"])
def test_a_bench_reclaim_scene_is_refused_naming_path_and_reclaim(tmp_path, make):
    """The environment follows a [path] sampled in advance; a [reclaim]'s reference is decided as
    the run goes. The small bench scene extends heavy_dig_pile, which has a [path]: its [reclaim]
    must still be seen, and refused in one message naming both, whichever way the env is made."""
    from test_reclaim_plan import scene_file

    scene = scene_file(tmp_path)
    with pytest.raises(SceneError) as refused:
        make(str(scene))
    message = str(refused.value)
    assert message.startswith(f"{scene}: bwr_twin/Reclaim-v0 follows a scene's [path]; "
                              "this scene plans a [reclaim]")
    assert message.endswith("give a scene with a [path]")


@pytest.mark.parametrize("script", ["gym_pd.py", "gym_random.py"])
def test_example_prints_return_and_errors(script):
    done = subprocess.run([sys.executable, f"examples/{script}", "--seed", "3", "--duration", "2"],
                          cwd=ROOT, capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    lines = done.stdout.splitlines()
    assert lines[0].startswith("episode return: -") and "over 200 steps (2.00 s)" in lines[0]
    assert lines[1].startswith("max position error: travel ") and " m, slew " in lines[1] and lines[1].endswith(" deg")
    bad = subprocess.run([sys.executable, f"examples/{script}", "--scene", "no_such_scene"],
                         cwd=ROOT, capture_output=True, text=True, timeout=60)
    assert bad.returncode == 2 and bad.stderr.startswith("error: no_such_scene: scene file not found")
    assert len(bad.stderr.splitlines()) == 1


# -- what the environment refuses, and what it takes ------------------------------------------

@pytest.mark.parametrize("action, message", [
    (np.array([np.nan, 0, 0], dtype=np.float32), r"\(short\.toml\): action\[0\] \(travel\) is nan: actions must be finite"),
    (np.array([0, 0, np.inf]), r"action\[2\] \(luff\) is inf"),
    ([0.0, -np.inf, 0.0], r"action\[1\] \(slew\) is -inf"),
    (np.array([0.5j, 0, 0]), r"an action of complex numbers, expected real numbers of shape \(3,\)"),
    (np.zeros(2), r"an action of shape \(2,\), expected \(3,\): travel, slew, luff"),
    (np.zeros((1, 3)), r"an action of shape \(1, 3\), expected \(3,\)"),
    (np.zeros(4, dtype=np.float32), r"an action of shape \(4,\)"),
    ("abc", r"an action of shape \(\), expected \(3,\)"),
    ([[0, 0], [0]], r"not an array of shape \(3,\)"),
], ids=["nan", "inf", "-inf list", "complex", "short", "one row", "long", "string", "ragged"])
def test_bad_actions_are_refused_naming_the_element_and_the_shape(tiny_env, action, message):
    env = tiny_env
    env.reset(seed=1)
    before = env.episodes.observation.copy()
    with pytest.raises(ValueError, match=message) as refused:
        env.step(action)
    assert str(refused.value).startswith(f"{ENV_ID} (short.toml): ")
    assert np.array_equal(env.episodes.observation, before)  # nothing stepped
    observation, reward, terminated, truncated, info = env.step(np.zeros(3))
    assert not (terminated or truncated) and info["time"] == pytest.approx(env.control_period)


def test_bad_actions_of_a_vector_env_name_the_sub_environment(tiny):
    envs = gymnasium.make_vec(ENV_ID, num_envs=2, scene=str(tiny))
    envs.reset(seed=1)
    actions = np.zeros((2, 3), dtype=np.float32)
    actions[1, 2] = np.nan
    where = rf"{ENV_ID} \(short\.toml\), a vector of 2: "
    with pytest.raises(ValueError, match=where + r"actions\[1, 2\] \(sub-environment 1, luff\) is nan"):
        envs.step(actions)
    for bad, shape in ((np.zeros(6), r"\(6,\)"), (np.zeros((3, 3)), r"\(3, 3\)"), (np.zeros(3), r"\(3,\)")):
        with pytest.raises(ValueError, match=where + rf"an action of shape {shape}, expected \(2, 3\): one row "
                           r"\(travel, slew, luff\) per sub-environment"):
            envs.step(bad)
    with pytest.raises(ValueError, match="complex"):
        envs.step(np.zeros((2, 3), dtype=complex))
    _, _, terminated, truncated, infos = envs.step(np.zeros((2, 3)))
    assert not (terminated.any() or truncated.any()) and infos["time"] == pytest.approx([0.01, 0.01])


@pytest.fixture
def tiny_env(tiny):
    return gymnasium.make(ENV_ID, scene=str(tiny)).unwrapped


def test_every_seed_gymnasium_takes_runs(tiny_env, tiny):
    """The twin keeps seeds as int64; seeds from 2**63 on are mapped into that range, each to its own."""
    env = tiny_env
    scene_seeds = []
    for seed in (0, 2**63 - 1, 2**63, 2**64 - 1, 2**64, 10**30):
        observation, info = env.reset(seed=seed)
        assert observation in env.observation_space
        assert env.step(np.zeros(3))[1] <= 0.0
        scene_seeds.append(info["seed"])
    assert scene_seeds[:2] == [0, 2**63 - 1]  # below 2**63 the scene seed is the seed itself
    assert len(set(scene_seeds)) == len(scene_seeds) and all(0 <= s < 2**63 for s in scene_seeds)
    assert env.reset(seed=2**64 - 1)[1]["seed"] == scene_seeds[3]  # and the same every time
    envs = gymnasium.make_vec(ENV_ID, num_envs=2, scene=str(tiny))
    _, infos = envs.reset(seed=2**64 - 1)  # sub-environment 1 gets 2**64
    assert infos["seed"].tolist() == scene_seeds[3:5]


def test_duration_cuts_episodes_short_in_both_kinds_of_env(tiny):
    env = gymnasium.make(ENV_ID, scene=str(tiny), duration=0.5)
    env.reset(seed=1)
    for k in range(50):
        _, _, terminated, truncated, info = env.step(np.zeros(3, dtype=np.float32))
    assert truncated and not terminated and info["ended"] == "time limit" and k == 49
    assert info["time"] == pytest.approx(0.5)
    envs = gymnasium.make_vec(ENV_ID, num_envs=2, scene=str(tiny), duration=0.05)
    envs.reset(seed=1)
    ends = [envs.step(np.zeros((2, 3)))[3].tolist() for _ in range(6)]
    assert ends == [[False, False]] * 4 + [[True, True], [False, False]]  # then the next-step autoreset
    whole = gymnasium.make(ENV_ID, scene=str(tiny), duration=2.01).unwrapped  # the path's end comes first
    assert whole.episodes.limit == 201
    for duration, message in ((0, "duration must be a number of s > 0, got 0"),
                              (float("nan"), "duration must be a number of s > 0"),
                              ("5", "duration must be a number of s > 0, got '5'"),
                              (0.001, r"duration 0\.001 s: shorter than one control period \(0\.01 s\)"),
                              (3.0, r"duration 3 s: beyond the path of short\.toml \(2 s\), whose end terminates "
                                    r"an episode after 201 control periods; give at most 2\.01 s")):
        with pytest.raises(ValueError, match=message):
            gymnasium.make(ENV_ID, scene=str(tiny), duration=duration)


def test_the_env_cannot_be_pickled_or_copied_and_says_how_to_make_another(tiny):
    import copy
    import pickle

    wrapped = gymnasium.make(ENV_ID, scene=str(tiny))
    envs = gymnasium.make_vec(ENV_ID, num_envs=2, scene=str(tiny))
    everything = (pickle.dumps, copy.copy, copy.deepcopy)
    for thing, attempts, how in (
            # copy.copy of gymnasium's wrapper is a second wrapper of the same environment: no copy of it.
            (wrapped, (pickle.dumps, copy.deepcopy), rf"gymnasium\.make\('{ENV_ID}', \.\.\.\) and the same arguments"),
            (wrapped.unwrapped, everything, "gymnasium.make"),
            (envs, everything, rf"gymnasium\.make_vec\('{ENV_ID}', num_envs=2, \.\.\.\) and the same arguments")):
        for attempt in attempts:
            with pytest.raises(TypeError, match=rf"cannot be pickled or copied: it holds compiled MuJoCo models.*{how}"):
                attempt(thing)


def test_episodes_beyond_the_bounds_are_refused_with_the_estimate():
    with pytest.raises(SceneError) as refused:  # the paper's 700 s at a 10 ns timestep: 7e10 physics steps
        gymnasium.make(ENV_ID, scene="paper_individual_gains", overrides={"simulation.timestep": 1e-8})
    message = str(refused.value)
    assert re.match(r".*paper_individual_gains\.toml: would take more than 12 h: 1 run, 7e\+10 physics steps, "
                    r"about \d+(\.\d+)? days", message), message
    assert message.endswith(f"for one episode of {ENV_ID}; check the timestep and the via point times, or give a "
                            "shorter duration")
    with pytest.raises(SceneError, match="16 runs, 1.12e\\+12 physics steps"):
        gymnasium.make_vec(ENV_ID, num_envs=16, scene="paper_individual_gains",
                           overrides={"simulation.timestep": 1e-8})
    # Five periods of it are minutes, not days: made (not stepped here).
    short = gymnasium.make(ENV_ID, scene="paper_individual_gains", overrides={"simulation.timestep": 1e-8},
                           duration=0.05)
    assert short.unwrapped.episodes.limit == 5
