"""Bench reclaiming planned from the pile (bwr_twin.planning.bench): what the planner refuses
before anything is simulated, the shape of its plan on a small windrow, the references that
follow it, the stop conditions, the rate control (built in and an engineer's), a lockstep of
bench runs, the shipped heavy_bench_reclaim scene and the replay of a bench reclaim.

Most scenes here are small: heavy_dig_pile's machine, PID and digging load on a 4 m long,
4 m high windrow, grid 0.5 m, 2 m benches of three 1 m cuts, started a few metres short of the
landing. They plan in under a second and simulate their 90 s in a few seconds.
"""

from __future__ import annotations

from itertools import pairwise

import numpy as np
import pytest
from conftest import HEAVY_MJCF, SCENES

from bwr_twin import SceneError
from bwr_twin.config.scene import load_scene
from bwr_twin.model.machine import Machine
from bwr_twin.planning.bench import plan_scene
from bwr_twin.planning.follower import BenchReference, nominal
from bwr_twin.planning.plan import Move, Pass
from bwr_twin.replay import Plan, Recording
from bwr_twin.sim.lockstep import lockstep_key, simulate, simulate_grouped, simulate_lockstep

# The small scene's [reclaim] and [stockpile.windrow] (degrees where the scene takes degrees).
RECLAIM = {
    "target_rate": 4000.0,  # t/h: about 0.3 deg/s at the face's middle
    "bench_height": 2.0,
    "cut_depth": 1.0,
    "bench_length": 3.0,
    "slew_limits": [20.0, 80.0],
    "start": [-49.0, 44.0, -7.0],  # 2 m of travel short of the landing, slew and luff near the first pass's
    "acceleration": [0.1, 0.2, 0.2],
    "stop": {"benches": 1},
}
WINDROW = {"length": 4.0, "crest_width": 2.0, "height": 4.0, "angle_of_repose": 37.0, "centre": [0.0, 45.0]}
MIRRORED_START = [-20.0, 44.0, -7.0]  # beyond the windrow's far end: the plan travels towards -X
TWO_BENCHES = {"reclaim": {"stop": {"benches": 2}, "start": [-56.0, 44.0, -7.0]}, "windrow": {"height": 4.5}}
TOLERANCE = 1e-9


def toml(value) -> str:
    """A Python value as a TOML value."""
    if isinstance(value, dict):
        return "{ " + ", ".join(f"{k} = {toml(v)}" for k, v in value.items()) + " }"
    if isinstance(value, list):
        return "[" + ", ".join(toml(v) for v in value) + "]"
    if isinstance(value, str):
        return f'"{value}"'
    return repr(value)


def scene_file(folder, reclaim=None, windrow=None, *, base="heavy_dig_pile.toml", stockpile=True, extra="",
               name="small.toml"):
    """folder/name: the small bench scene over a shipped base, its [reclaim] and windrow keys
    replaced by `reclaim` and `windrow`; no [stockpile] tables if not `stockpile`."""
    lines = [f'extends = "{SCENES / base}"', "", "[reclaim]"]
    lines += [f"{k} = {toml(v)}" for k, v in (RECLAIM | (reclaim or {})).items()]
    if stockpile:
        lines += ["", "[stockpile]", "grid_spacing = 0.5", "", "[stockpile.windrow]"]
        lines += [f"{k} = {toml(v)}" for k, v in (WINDROW | (windrow or {})).items()]
    path = folder / name
    path.write_text("\n".join(lines) + "\n" + extra)
    return path


def small_scene(folder, reclaim=None, windrow=None, **kwargs):
    """The small bench scene, written by scene_file and loaded."""
    return load_scene(scene_file(folder, reclaim, windrow, **kwargs))


def slew_rate_control(type_name: str, **settings) -> str:
    """A [reclaim.rate_control] table naming `type_name`."""
    return "\n[reclaim.rate_control]\n" + f"type = {toml(type_name)}\n" + "".join(
        f"{k} = {toml(v)}\n" for k, v in settings.items())


def pass_durations(result) -> np.ndarray:
    """s each slew pass took in a run: its waypoints are the starts of the plan's segments."""
    plan = plan_scene(result.scene)
    times = np.array(result.metrics["run"]["waypoint_times"])
    kinds = [isinstance(s, Pass) for s in plan.segments]
    return np.diff(times)[np.flatnonzero(kinds)]


@pytest.fixture(scope="module")
def small_plan(tmp_path_factory):
    return plan_scene(small_scene(tmp_path_factory.mktemp("plan")))


@pytest.fixture(scope="module")
def small_run(tmp_path_factory):
    """The small scene simulated open loop, once for the tests that compare with it."""
    return simulate(small_scene(tmp_path_factory.mktemp("run")))


@pytest.fixture(scope="module")
def heavy_run():
    """The shipped heavy_bench_reclaim scene, simulated once (about 70 s)."""
    return simulate(load_scene(SCENES / "heavy_bench_reclaim.toml"))


# -- refusals before anything is simulated ----------------------------------------------------


@pytest.mark.parametrize("reclaim, windrow, message", [
    ({"bench_height": 6.5}, None,
     r"small.toml: \[reclaim\]: 'bench_height' 6.5 m is more than 0.6 x the wheel's 10 m diameter \(6 m\)"),
    ({"target_rate": 15000.0}, None,
     r"'target_rate' 15,000 t/h is beyond the wheel's capacity of 14,112 t/h .*at 2400 kg/m3"),
    # 14,000 t/h is within the wheel's capacity, but a 1 m face cut 0.2 m deep needs 11 deg/s of slew.
    ({"target_rate": 14000.0, "bench_height": 1.0, "cut_depth": 0.2, "bench_length": 0.6}, None,
     r"'target_rate' 14,000 t/h needs a slew speed of .* deg/s .*beyond the slew drive's rated 0.500 deg/s"),
    ({"cut_depth": 5.5, "bench_length": 6.0}, None, r"'cut_depth' 5.5 m is more than the wheel's radius 5 m"),
    ({"slew_limits": [20.0, 120.0]}, None,
     r"'slew_limits' \(high\) 120 deg is outside the slew envelope \[-110.000 deg, 110.000 deg\]"),
    ({"start": [-49.0, 44.0, -12.0]}, None,
     r"'start': luff = -12.000 deg is outside the operating envelope \[-11.000 deg, 11.000 deg\]"),
    ({"acceleration": [0.1, 2.0, 0.2]}, None,
     r"'acceleration' \(slew\) 2 deg/s2 needs .* beyond the slew drive's rating \[-1.13e\+07, 1.13e\+07\]"),
    ({"acceleration": [0.1, 0.2, 3.0]}, None,
     r"'acceleration' \(luff\) 3 deg/s2 needs .* beyond the luff drive's rating \[-1.55e\+07, 3.05e\+07\]"),
    ({"acceleration": [0.5, 0.2, 0.2]}, None,
     r"'acceleration' \(travel\) 0.5 m/s2 needs .* beyond the travel drive's rating \[-5.4e\+05, 5.4e\+05\]"),
    # A 27 m windrow: its top bench's floor, 25 m, is above the luff envelope's reach.
    (None, {"height": 27.0},
     (r"bench 1's floor at 25.00 m \(pile top 27.00 m less 1 x 'bench_height' 2 m\) is out of the wheel's "
      r"reach: the luff envelope puts the wheel's lowest point between -1.49 and 19.49 m")),
    (None, {"centre": [0.0, 100.0]},
     r"bench 1 \(floor at 2.00 m\) finds no pile within 'slew_limits' \[20.0, 80.0\] deg along the travel envelope"),
    ({"start": [-45.0, 44.0, -7.0]}, None,
     r"at 'start' travel -45 m the wheel would already cut the pile on bench 1: start farther from the pile"),
    ({"stop": {"tonnes": 1000.0}, "start": [-60.0, 44.0, -7.0]}, None,
     r"the pile within reach holds [\d,]+ t in 2 bench\(es\), less than 'stop.tonnes' 1,000 t"),
], ids=["bench too high", "rate beyond capacity", "slew beyond the drive", "cut deeper than the wheel",
        "slew limits outside the envelope", "start outside the envelope", "slew acceleration",
        "luff acceleration", "travel acceleration", "pile out of the luff's reach", "no pile along the rail",
        "start in the pile", "too few tonnes"])
def test_the_planner_refuses_what_cannot_be_done_naming_the_key_and_limit(tmp_path, reclaim, windrow, message):
    """A plan the machine or the pile cannot carry out is refused as it is planned, in one line
    naming the scene, the key and the limit."""
    scene = small_scene(tmp_path, reclaim, windrow)
    with pytest.raises(SceneError, match=message):
        plan_scene(scene)


def test_a_refused_plan_is_refused_before_the_simulation_starts(tmp_path):
    """simulate() plans first: the refusal comes at once, not after a run."""
    scene = small_scene(tmp_path, {"bench_height": 6.5})
    with pytest.raises(SceneError, match=r"'bench_height' 6.5 m is more than 0.6 x"):
        simulate(scene)


BOTH_MOTIONS = '\n[path]\nframe = "world"\nvia_points = [{ t = 0.0, p = [56.5, 15.1, 21.7] }, ' \
               "{ t = 60.0, p = [54.5, 22.0, 19.0] }]\n"


@pytest.mark.parametrize("kwargs, message", [
    ({"base": "paper_individual_gains.toml", "stockpile": False}, r"small.toml: \[reclaim\] needs a \[stockpile\]"),
    ({"extra": BOTH_MOTIONS}, r"small.toml: a scene needs one of a \[path\] of via points, a \[reclaim\] or a \[stacking\], "
                              r"got \[path\] and \[reclaim\]"),
    ({"reclaim": {"stop": {"benches": 1, "time": 10.0}}},
     r"\[reclaim.stop\] needs exactly one of 'benches', 'tonnes' or 'time', got benches, time"),
    ({"reclaim": {"stop": {}}}, r"\[reclaim.stop\] needs exactly one of 'benches', 'tonnes' or 'time', got none"),
    ({"extra": slew_rate_control("belt_scale", trim_limits=[1.2, 2.0])},
     r"'reclaim.rate_control.trim_limits' must hold 0 < low <= 1 <= high, got \[1.2, 2.0\]"),
    ({"extra": slew_rate_control("belt_scale", trim_limits=[0.5, 0.9])},
     r"'reclaim.rate_control.trim_limits' must hold 0 < low <= 1 <= high, got \[0.5, 0.9\]"),
    # pid_heavy.toml has a stockpile but no [digging]: the wheel's power says nothing of the rate.
    ({"base": "pid_heavy.toml", "extra": slew_rate_control("wheel_power")},
     r"'reclaim.rate_control.type' \"wheel_power\" needs \[digging\]"),
], ids=["no stockpile", "path and reclaim", "two stop keys", "no stop key", "trim low above 1", "trim high below 1",
        "wheel power without digging"])
def test_scene_rules_of_reclaim(tmp_path, kwargs, message):
    """Rules that need no machine are checked as the scene loads."""
    with pytest.raises(SceneError, match=message):
        load_scene(scene_file(tmp_path, **kwargs))


def test_a_reclaim_scene_replaces_the_path_of_the_scene_it_extends(tmp_path):
    """heavy_dig_pile has a [path]; a scene extending it with a [reclaim] follows the plan alone."""
    scene = small_scene(tmp_path)
    assert scene.trajectory is None and scene.reclaim.target_rate == RECLAIM["target_rate"]
    assert load_scene(SCENES / "heavy_dig_pile.toml").trajectory is not None


# -- the plan ---------------------------------------------------------------------------------


def benches_of(plan) -> list[list[Pass]]:
    """The plan's passes, bench by bench."""
    return [[p for p in plan.passes if p.bench == b] for b in range(plan.benches)]


def test_passes_alternate_and_each_cuts_within_its_slew(tmp_path):
    """Each pass slews back across the face the last one crossed, turning beyond the cut it
    predicts, and the segments join end to end."""
    plan = plan_scene(small_scene(tmp_path, **TWO_BENCHES))
    assert plan.benches == 2
    for passes in benches_of(plan):
        assert len(passes) == 3  # bench_length 3 m of 1 m cuts
        directions = [p.direction for p in passes]
        assert all(a == -b for a, b in pairwise(directions)), directions
        for p in passes:
            low, high = sorted((p.start, p.end))
            assert low < min(p.cut) <= max(p.cut) < high, (p.number, p.cut, p.start, p.end)
            assert p.volume > 0
    # Each pass starts where the one before it (or the move between them) ended.
    for before, after in pairwise(plan.segments):
        end = before.end if isinstance(before, Move) else np.array([before.travel, before.end, before.luff])
        start = after.start if isinstance(after, Move) else np.array([after.travel, after.start, after.luff])
        np.testing.assert_allclose(start, end, atol=TOLERANCE)


@pytest.mark.parametrize("start, ahead", [(RECLAIM["start"], 1.0), (MIRRORED_START, -1.0)],
                         ids=["pile towards +X", "pile towards -X"])
def test_travel_advances_one_cut_depth_a_pass_into_the_pile(tmp_path, start, ahead):
    """The travel steps one cut depth between passes, towards the pile whichever side it lies."""
    plan = plan_scene(small_scene(tmp_path, {"start": start}))
    travels = np.array([p.travel for p in plan.passes])
    np.testing.assert_allclose(np.diff(travels), ahead * RECLAIM["cut_depth"], atol=TOLERANCE)
    assert (travels[0] - start[0]) * ahead > 0  # the approach travels towards the pile
    steps = [s for s in plan.segments if isinstance(s, Move) and s.kind == "travel step"]
    assert len(steps) == 2
    for step in steps:
        np.testing.assert_allclose(step.end - step.start, [ahead * RECLAIM["cut_depth"], 0.0, 0.0], atol=TOLERANCE)


def test_the_cut_windows_come_from_the_pile(tmp_path, small_plan):
    """The same machine and start against a windrow 3 m farther from the rail: every pass's
    predicted cut begins and ends at a larger slew angle."""
    farther = plan_scene(small_scene(tmp_path, windrow={"centre": [0.0, 48.0]}))
    assert len(farther.passes) == len(small_plan.passes) == 3
    for near, far in zip(small_plan.passes, farther.passes):
        assert min(far.cut) > min(near.cut) + np.radians(1.0)
        assert max(far.cut) > max(near.cut) + np.radians(1.0)


def test_each_bench_puts_the_wheels_lowest_point_a_bench_height_lower(tmp_path):
    """Bench n's floor, where the wheel's lowest point runs, is the pile's top less n bench heights."""
    scene = small_scene(tmp_path, **TWO_BENCHES)
    plan = plan_scene(scene)
    machine = Machine(scene.machine.mjcf)
    top = TWO_BENCHES["windrow"]["height"]  # the windrow's flat crest
    for p in plan.passes:
        lowest = machine.fk(np.array([p.travel, p.start, p.luff]))[2] - machine.wheel.radius
        assert lowest == pytest.approx(top - (p.bench + 1) * RECLAIM["bench_height"], abs=1e-6)
    assert all(t > 0 for t in plan.bench_tonnes())


def follow_open_loop(plan, period):
    """A BenchReference of one run followed without trim: (n, 3) q, qd, qdd and (n,) the
    segment of each period."""
    reference = BenchReference(plan, 1, period, lambda q: np.zeros_like(q))
    rows = []
    while not reference.finished[0]:
        rows.append((reference.q[0].copy(), reference.qd[0].copy(), reference.qdd[0].copy(), reference.segment[0]))
        reference.advance()
    return tuple(np.array(r) for r in zip(*rows))


def test_the_references_stay_within_the_accelerations_and_rated_speeds(small_plan):
    """What the drives are asked stays within the scene's accelerations and their rated speeds."""
    period = 0.01
    q, qd, qdd, segment = follow_open_loop(small_plan, period)
    assert np.all(np.abs(qdd) <= small_plan.acceleration * (1 + 1e-9))
    assert np.all(np.abs(qd) <= small_plan.rated_speed * (1 + 1e-9))
    # Within a pass the slew's acceleration is constant over a period: q, qd and qdd agree, and
    # travel and luff hold. k: the periods that a pass's next period follows.
    k = np.flatnonzero([isinstance(small_plan.segments[s], Pass) and s == after
                        for s, after in pairwise(segment)])
    assert len(k) > 1000
    np.testing.assert_allclose(qd[k + 1, 1] - qd[k, 1], qdd[k, 1] * period, atol=1e-15, rtol=0)
    np.testing.assert_allclose(q[k + 1, 1] - q[k, 1], qd[k, 1] * period + 0.5 * qdd[k, 1] * period**2,
                               atol=1e-15, rtol=0)
    np.testing.assert_array_equal(q[k + 1][:, [0, 2]], q[k][:, [0, 2]])


def test_the_nominal_reference_has_a_continuous_velocity(small_plan):
    """No axis changes speed in one control period by more than its acceleration allows: the
    moves and the passes start and end at rest, and each pass brakes onto its end."""
    period = 0.01
    time, _, qd, waypoints, _ = nominal(small_plan, period, Machine(HEAVY_MJCF).fk)
    assert time[-1] == pytest.approx(small_plan.nominal_duration, rel=0.05)
    step = np.abs(np.diff(qd, axis=0)).max(axis=0)
    np.testing.assert_array_less(step, small_plan.acceleration * period * (1 + 1e-6))
    assert np.abs(qd[-1]).max() == 0.0
    assert len(waypoints.times) == len(small_plan.segments) + 1


class NumpyScalarReference:
    """BenchReference as it was first written, numpy on scalars (its speed law too): the
    sequence the float arithmetic of bwr_twin.planning.follower must reproduce to the bit."""

    def __init__(self, plan, runs, period):
        self.plan, self.runs, self.period = plan, runs, period
        self.q = np.repeat(plan.start[None], runs, axis=0)
        self.qd, self.qdd = np.zeros((runs, 3)), np.zeros((runs, 3))
        self.segment = np.zeros(runs, dtype=np.int64)
        self.bench = np.full(runs, plan.segments[0].bench, dtype=np.int64)
        self.elapsed, self.stopping, self.finished = np.zeros(runs), np.zeros(runs, bool), np.zeros(runs, bool)
        self._a, self._top, self._trim = float(plan.acceleration[1]), float(plan.rated_speed[1]), np.ones(runs)
        for run in range(runs):
            self._plan_period(run)

    def phase(self):
        cutting, steady, depth = np.zeros(self.runs, bool), np.zeros(self.runs, bool), np.full(self.runs, np.nan)
        for run in range(self.runs):
            p = None if self.finished[run] else self.plan.segments[self.segment[run]]
            if isinstance(p, Pass):
                slew = self.q[run, 1]
                cutting[run], steady[run] = p.cuts_at(slew), p.steady_at(slew)
                depth[run] = p.cut_depth * abs(np.cos(slew))
        return self.bench.copy(), cutting, steady, depth

    def advance(self, trim=None, stop=None):
        if trim is not None:
            self._trim = trim
        if stop is not None:
            self.stopping |= stop
        for run in range(self.runs):
            if self.finished[run]:
                continue
            segment = self.plan.segments[self.segment[run]]
            if isinstance(segment, Move):
                self.elapsed[run] += self.period
                if self.elapsed[run] >= segment.duration - 1e-9:
                    self._next(run, segment.end)
            else:
                q, qd, qdd = self.q[run], self.qd[run], self.qdd[run]
                slew = q[1] + qd[1] * self.period + 0.5 * qdd[1] * self.period**2
                speed = qd[1] + qdd[1] * self.period
                q[1], qd[1] = slew, speed
                if (segment.end - slew) * segment.direction <= 1e-9 or (self.stopping[run] and speed == 0.0):
                    q[1] = segment.end if not self.stopping[run] else slew
                    self._next(run, q.copy())
            if not self.finished[run]:
                self._plan_period(run)

    def _next(self, run, at):
        self.segment[run] += 1
        self.elapsed[run] = 0.0
        self.q[run], self.qd[run], self.qdd[run] = at, 0.0, 0.0
        if self.segment[run] >= len(self.plan.segments) or self.stopping[run]:
            self.finished[run] = True
            self.segment[run] = len(self.plan.segments)
        else:
            self.bench[run] = self.plan.segments[self.segment[run]].bench

    def _plan_period(self, run):
        segment, law = self.plan.segments[self.segment[run]], self.plan.law
        if isinstance(segment, Move):
            self.q[run], self.qd[run], self.qdd[run] = segment.sample(self.elapsed[run])
            return
        q, qd, qdd = self.q[run], self.qd[run], self.qdd[run]
        direction, a, dt = segment.direction, self._a, self.period
        if self.stopping[run]:
            wanted = 0.0
        else:
            remaining = max((segment.end - q[1]) * direction, 0.0)
            angle = q[1] if law.law == "cosine" else 0.5 * (segment.cut[0] + segment.cut[1])
            cosine = max(abs(np.cos(angle)), np.cos(law.cap))
            speed = law.volume_rate / (segment.face_height * segment.cut_depth * cosine * segment.radius)
            rest = remaining - 0.5 * abs(qd[1]) * dt
            brake = np.sqrt((a * dt) ** 2 + 2.0 * a * max(rest, 0.0)) - a * dt
            wanted = max(min(min(speed * self._trim[run], self._top, brake), 2.0 * remaining / dt - abs(qd[1])), 0.0)
        change = np.clip(direction * wanted - qd[1], -a * dt, a * dt)
        if self.stopping[run] and abs(qd[1]) <= a * dt:
            change = -qd[1]
        qdd[:] = 0.0
        qdd[1] = change / dt


def test_the_reference_is_the_numpy_one_to_the_bit_on_the_heavy_bench():
    """Three runs follow heavy_bench_reclaim's plan under wandering trims, one of them stopped
    early: every period's references and phase are those of the numpy reference, exactly."""
    scene = load_scene(SCENES / "heavy_bench_reclaim.toml")
    plan, limits = plan_scene(scene), scene.reclaim.rate_control.trim_limits
    runs, rng, period = 3, np.random.default_rng(3), scene.simulation.control_period
    expected, got = NumpyScalarReference(plan, runs, period), BenchReference(plan, runs, period, Machine(HEAVY_MJCF).fk)
    trim, rows = np.ones(runs), {"expected": [], "got": []}
    while not expected.finished.all():
        phase = got.phase()
        for name, r, fields in (("expected", expected, expected.phase()),
                                ("got", got, (phase.bench, phase.cutting, phase.steady, phase.planned_depth))):
            rows[name].append(np.concatenate([r.q.ravel(), r.qd.ravel(), r.qdd.ravel(), r.segment, r.bench,
                                              r.finished, *fields]))
        trim = np.clip(trim + rng.normal(0.0, 0.02, runs), *limits)
        stop = np.array([False, True, False]) if len(rows["got"]) == 40_000 else None
        expected.advance(trim, stop)
        got.advance(trim, stop)
    assert got.finished.all() and len(rows["got"]) > 80_000
    np.testing.assert_array_equal(np.array(rows["got"]), np.array(rows["expected"]))
    assert 400.0 < got.waypoints(1)[0].times[-1] < got.waypoints(0)[0].times[-1] - 100.0  # the stopped run rests


# -- stop conditions and rate control, simulated ------------------------------------------------

STOP_TIME = 48.0  # s: in the second pass of the small scene (it runs from about 39 s to 59 s)
STOP_TONNES = 8.0  # t: half the bench, in its third pass


def test_a_time_stop_brakes_the_pass_to_rest_at_that_time(tmp_path):
    """stop.time cuts the pass short: the slew brakes at once and the run ends at rest."""
    result = simulate(small_scene(tmp_path, {"stop": {"time": STOP_TIME}}))
    plan = plan_scene(result.scene)
    period = result.scene.simulation.control_period
    braking = plan.rated_speed[1] / plan.acceleration[1]  # s from the fastest slew to rest
    assert STOP_TIME <= result.time[-1] <= STOP_TIME + braking + 2 * period
    assert np.all(result.qd_desired[-1] == 0.0)
    second = plan.passes[1]
    low, high = sorted((second.start, second.end))
    assert low < result.q_desired[-1, 1] < high  # stopped within the pass, not at its end
    assert result.metrics["run"]["waypoint_times"][-1] == pytest.approx(result.time[-1])


@pytest.fixture(scope="module")
def tonnes_runs(tmp_path_factory):
    """The small scene under the belt-scale loop until 8 t are reclaimed, seeds 1 and 2. The
    loop trims each run's slew from its own belt, so the two runs stop at different times."""
    folder = tmp_path_factory.mktemp("tonnes")
    path = scene_file(folder, {"stop": {"tonnes": STOP_TONNES}}, extra=slew_rate_control("belt_scale"))
    scenes = [load_scene(path, {"simulation.seed": seed}) for seed in (1, 2)]
    return scenes, [simulate(s) for s in scenes]


def test_a_tonnes_stop_ends_the_run_once_the_belt_has_carried_them(tonnes_runs):
    _, (result, _) = tonnes_runs
    reclaim = result.metrics["reclaim"]
    plan = plan_scene(result.scene)
    assert reclaim["mass_t"] >= STOP_TONNES
    assert reclaim["mass_t"] < 0.8 * sum(plan.bench_tonnes())  # well short of the bench's end
    # The buckets have discharged the tonnes onto the belt by the time the belt scale has seen
    # them pass; from then on the pass only brakes to rest.
    conveyed = np.cumsum(result.reclaim.rate[:-1] * np.diff(result.time)) / 3600.0  # t
    assert conveyed[-1] >= STOP_TONNES
    seen = result.time[1:][np.argmax(conveyed >= STOP_TONNES)]
    braking = plan.rated_speed[1] / plan.acceleration[1]
    assert result.time[-1] <= seen + braking + 2 * result.scene.simulation.control_period
    assert np.all(result.qd_desired[-1] == 0.0)


def test_each_bench_reclaim_is_a_lockstep_of_its_own(tonnes_runs):
    """A run's result does not depend on which runs share its lockstep (bwr_twin.sim.lockstep):
    bench reclaims end when their own rate loops have carried out the plan, so no two seeds
    share one, and a batch runs each as it runs alone."""
    scenes, alone = tonnes_runs
    durations = [r.metrics["run"]["duration"] for r in alone]
    assert durations[0] != durations[1]  # the seeds' loops stop them at different times
    assert lockstep_key(scenes[0]) != lockstep_key(scenes[1])
    with pytest.raises(ValueError, match="lockstep_key"):
        simulate_lockstep(scenes)
    grouped = simulate_grouped(scenes)  # as `compare` runs the seeds of a controller
    for again, single in zip(grouped, alone):
        np.testing.assert_array_equal(again.q, single.q)
        np.testing.assert_array_equal(again.reclaim.rate, single.reclaim.rate)


CONSTANT_TRIM = '''
import numpy as np

from bwr_twin.control import RateControl


class FourFifths(RateControl):
    """The speed law less a fifth, whatever the belt says."""

    def trim(self, signals):
        return np.full(len(self.target), 0.8)
'''


def test_an_engineers_rate_control_trims_every_pass(tmp_path, small_run):
    """A RateControl from the scene's folder trims the speed law: the passes slow, the plan's
    path stays."""
    (tmp_path / "my_rate.py").write_text(CONSTANT_TRIM)
    trimmed = simulate(small_scene(tmp_path, extra=slew_rate_control("my_rate.py:FourFifths")))
    slower = pass_durations(trimmed) / pass_durations(small_run)
    # A pass cruises 1 / 0.8 = 1.25 times as long; it reaches its slower speed sooner.
    assert np.all((slower > 1.15) & (slower < 1.25)), slower
    np.testing.assert_allclose(trimmed.metrics["run"]["waypoints"], small_run.metrics["run"]["waypoints"], atol=1e-9)
    # The same cut, at four fifths of the rate.
    assert trimmed.metrics["reclaim"]["mass_t"] == pytest.approx(small_run.metrics["reclaim"]["mass_t"], rel=0.1)


@pytest.mark.parametrize("source, message", [
    (CONSTANT_TRIM.replace("(RateControl)", "(object)"),
     r"my_rate.py: has no class 'FourFifths' derived from bwr_twin.control.RateControl"),
    (CONSTANT_TRIM.replace("def trim(self, signals):", "def trim(self, signals)"), r"my_rate.py:\d+: "),
    (CONSTANT_TRIM.replace("import numpy as np", "import numpy as np\nraise RuntimeError('no belt')"),
     r"my_rate.py: importing it raised RuntimeError: no belt"),
], ids=["not a RateControl", "syntax error", "raises on import"])
def test_a_bad_rate_control_file_is_named(tmp_path, source, message):
    """An engineer's file that gives no RateControl is refused naming the file, when the scene is read."""
    (tmp_path / "my_rate.py").write_text(source)
    with pytest.raises(SceneError, match=message):
        small_scene(tmp_path, extra=slew_rate_control("my_rate.py:FourFifths"))


def test_a_missing_rate_control_file_is_named(tmp_path):
    """The file part of the type is relative to the scene's folder, and named when missing."""
    with pytest.raises(SceneError, match=r"'reclaim.rate_control.type': .*nowhere.py does not exist"):
        small_scene(tmp_path, extra=slew_rate_control("nowhere.py:FourFifths"))


# -- the shipped scene ------------------------------------------------------------------------


def test_the_heavy_bench_holds_its_target_rate(heavy_run):
    """The shipped scene's promise: its belt-scale loop holds 8,000 t/h within 5 % on the full
    face, the wheel lands where the planner said, and the bench yields what was planned."""
    assert heavy_run.scene.reclaim.rate_control.type == "belt_scale"
    reclaim = heavy_run.metrics["reclaim"]
    target = reclaim["target_rate_tph"]
    assert target == 8000.0
    assert reclaim["steady_time_s"] > 60.0
    assert abs(reclaim["steady_rate_mean_tph"] - target) <= 0.05 * target
    assert reclaim["steady_rate_cv"] <= 0.10
    assert reclaim["landing_error_m"] <= 0.2
    assert reclaim["spill_t"] == 0.0
    (carried,), (planned,) = reclaim["bench_t"], reclaim["bench_planned_t"]
    assert carried == pytest.approx(planned, rel=0.10)
    # The run ended at rest, every segment of its bench done.
    assert np.all(heavy_run.qd_desired[-1] == 0.0)
    assert len(heavy_run.metrics["run"]["waypoint_times"]) == len(plan_scene(heavy_run.scene).segments) + 1


# -- the replay -------------------------------------------------------------------------------


def test_the_replay_plans_a_bench_reclaim_as_the_open_loop_run_follows_it(small_run):
    """The replay shows a bench scene before it is simulated: the plan followed open loop."""
    plan = Plan.from_scene(small_run.scene)
    bench = plan_scene(small_run.scene)
    np.testing.assert_array_equal(plan.q_desired[0], bench.start)
    assert plan.duration == pytest.approx(bench.nominal_duration, rel=0.05)
    assert plan.pile is not None
    # Open loop, the reference does not depend on the plant: the run followed the same one.
    np.testing.assert_array_equal(plan.time, small_run.time)
    np.testing.assert_array_equal(plan.q_desired, small_run.q_desired)
    np.testing.assert_array_equal(plan.via_times, small_run.metrics["run"]["waypoint_times"])
    np.testing.assert_allclose(plan.via_points, small_run.metrics["run"]["waypoints"], atol=1e-12)


def test_a_recorded_bench_reclaim_has_the_runs_waypoints_as_via_points(small_run):
    """A bench reclaim has no via points of its own: the replay marks where the run began each segment."""
    recording = Recording.from_result(small_run)
    run = small_run.metrics["run"]
    assert len(run["waypoint_times"]) == len(plan_scene(small_run.scene).segments) + 1
    np.testing.assert_array_equal(recording.plan.via_times, run["waypoint_times"])
    np.testing.assert_array_equal(recording.plan.via_points, run["waypoints"])
    np.testing.assert_allclose(recording.plan.via_points[0], small_run.machine.fk(plan_scene(small_run.scene).start))
    np.testing.assert_array_equal(recording.q_actual, small_run.q)
