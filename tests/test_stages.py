"""The loop walks a list of stages: each scene gets the stages it names, in the period's order,
and the loop calls a stage only for the hooks it implements. What only watches (the clearance
monitors) is an observer, not a stage, and a loop that keeps no results has none."""

import numpy as np
from conftest import write_short_scene

from bwr_twin.config.plugin_calls import call, construct
from bwr_twin.config.plugins import controller_class
from bwr_twin.config.scene import load_scene
from bwr_twin.shipped import find_scene
from bwr_twin.sim import stages
from bwr_twin.sim.assembly import assemble
from bwr_twin.sim.lockstep import SECTIONS, Lockstep, simulate


class Counting(stages.Stage):
    def __init__(self):
        self.calls = []

    def world(self, k, row):
        self.calls.append(("world", k))

    def finish(self, k):
        self.calls.append(("finish", k))


def test_the_hooks_hold_only_the_stages_that_implement_them_in_order():
    first, second, bare = Counting(), Counting(), stages.Stage()
    hooks = stages.Hooks.of([first, bare, second])
    assert hooks.world == (first, second) and hooks.finish == (first, second)
    assert hooks.measure == hooks.drives == hooks.stepped == hooks.metrics == hooks.result == ()


def names(scene_name: str, overrides: dict | None = None, *, part: str = "stages", observe: bool = True) -> list[str]:
    scene = load_scene(find_scene(scene_name), overrides)
    return [type(s).__name__ for s in getattr(assemble([scene], nthread=1, observe=observe), part)]


def test_a_path_scene_has_only_the_encoders_and_the_disturbances():
    assert names("paper_individual_gains") == ["EncoderReading", "DisturbanceForces"]


def test_a_scanned_bench_reclaim_with_faults_has_its_stages_in_the_periods_order():
    faults = [{"kind": "encoder_stuck", "axis": "slew", "start": 100.0, "duration": 5.0},
              {"kind": "drive_trip", "axis": "luff", "start": 200.0, "duration": 1.0}]
    assert names("heavy_scanned_reclaim", {"faults": faults}) == [
        "EncoderReading", "OwnReferences", "EncoderFaults", "DisturbanceForces", "ScanningStage",
        "ReclaimStage", "RateInstrumentReading", "FaultsOnDrives"]
    assert "EncoderFaults" not in names("heavy_scanned_reclaim")  # a scene has only the stages it names


def test_the_clearance_monitors_watch_and_only_where_the_runs_are_observed():
    assert names("heavy_scanned_reclaim", part="watchers") == ["PileWatch"]
    assert names("heavy_two_machines_interlocked", part="watchers") == ["PileWatch", "MachineWatch"]
    assert names("paper_individual_gains", part="watchers") == []
    assert names("heavy_two_machines_interlocked", part="watchers", observe=False) == []
    # ... while the interlock, which acts, keeps its own clearance to the pile it knows
    assert "InterlockStage" in names("heavy_two_machines_interlocked", observe=False)


def test_a_lockstep_that_keeps_no_results_moves_its_machine_exactly_as_one_that_does():
    """The monitors only watch: without them, the same controller moves the machine the same."""
    scene = load_scene(find_scene("heavy_two_machines_interlocked"), {"path.via_points": [
        {"t": 0.0, "p": [-2.780, 0.0, 18.794]}, {"t": 40.0, "p": [-3.2, 4.0, 18.4]}]})
    paths = []
    for observe in (True, False):
        loop = Lockstep([scene], nthread=1, observe=observe)
        cls = controller_class(scene.controller.type)
        controller = construct("test", cls, loop.controller_context(), [scene.controller.settings])
        q = []
        while not loop.done:
            q_measured, qd_measured = loop.measure()
            command = call("test", controller.compute, "compute", loop.k * loop.period, q_measured, qd_measured,
                           *loop.reference_now(), loop.alive)
            loop.advance(command)
            q.append(loop.q_true.copy())
        paths.append(np.array(q))
    assert np.ptp(paths[0][:, 0, 1]) > 0.05  # the slew moved
    np.testing.assert_array_equal(paths[0], paths[1])


def test_two_machines_under_an_interlock_hear_the_neighbour_before_the_interlock_decides():
    trip = [{"kind": "drive_trip", "axis": "travel", "start": 10.0, "duration": 1.0}]
    order = names("heavy_two_machines_interlocked", {"faults": trip})
    assert order.index("NeighbourMachine") < order.index("InterlockStage")
    assert order[:2] == ["EncoderReading", "OwnReferences"]  # each run's paced path kept before it moves on
    assert order[-2:] == ["InterlockStage", "FaultsOnDrives"]  # a trip overrides the quick stop: the last word


def test_a_stage_is_called_every_period_and_once_at_the_end(tmp_path):
    loop = Lockstep([load_scene(write_short_scene(tmp_path))], nthread=1)
    counting = Counting()
    loop._hooks = stages.Hooks.of([*loop._parts.stages, counting])
    while not loop.done:
        loop.measure()
        loop.advance(np.zeros((1, 3)))
    assert [k for hook, k in counting.calls if hook == "world"] == list(range(loop.samples))
    assert [call for call in counting.calls if call[0] == "finish"] == [("finish", loop.samples)]


def test_metrics_sections_follow_the_output_contracts_order():
    result = simulate(load_scene(find_scene("heavy_dig_pile")))
    sections = [key for key in result.metrics if key in SECTIONS]
    assert sections == [s for s in SECTIONS if s in result.metrics] and sections[-1] == "run"
    assert list(result.metrics)[-len(sections):] == sections  # after the loop's own


def test_every_random_stream_has_its_own_number_and_draws_what_it_drew_before():
    from bwr_twin.streams import Stream, stream

    assert len(Stream.__members__) == len(Stream)  # no two sources share a number
    before = np.random.SeedSequence(7).spawn(2)  # how the disturbances and gusts were seeded
    for source, seeded in zip((Stream.DISTURBANCE, Stream.GUST), before):
        np.testing.assert_array_equal(np.random.default_rng(stream(7, source)).random(4),
                                      np.random.default_rng(seeded).random(4))
