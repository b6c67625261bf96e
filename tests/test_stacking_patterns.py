"""The windrow, cone-shell and strata patterns (docs/blending.md), each stacked by the heavy
stacker in a short real run: the stream balances with what the pile holds, the pile has the
pattern's shape, every pass cruises within the travel's rated speed, and a pattern the machine
cannot lay is refused naming the key."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from conftest import SCENES

from bwr_twin import SceneError
from bwr_twin.config.scene import load_scene
from bwr_twin.model.machine import Machine
from bwr_twin.pile.relaxation import Talus
from bwr_twin.planning.stacking import LOWEST_MARGIN, plan_stacking, target_ridge
from bwr_twin.results.summary import summary_table
from bwr_twin.sim.lockstep import simulate
from bwr_twin.units import SECONDS_PER_HOUR

SCENE = SCENES / "heavy_chevron_stack.toml"
# Each a few simulated minutes: small piles on short axes, slow enough for one pass a row.
RUNS = {
    # 500 t at 2,500 t/h on 20 m: 3 bottom rows, 6 rows in all, 720 s.
    "windrow": {"stacking.pattern": "windrow", "stacking.layers": 3, "stacking.tonnes": 500.0,
                "stacking.rate": 2500.0, "stacking.axis_x": [-10.0, 10.0]},
    # 2,000 t in 8 cones on 40 m, 5.7 m apart: each against the one before, 720 s.
    "cone_shell": {"stacking.pattern": "cone_shell", "stacking.layers": 8, "stacking.tonnes": 2000.0,
                   "stacking.axis_x": [-20.0, 20.0]},
    # 1,500 t in 2 strata on 30 m, rows 3 m apart: 3 rows and 1, 540 s; the head 5 m above each
    # stratum, above the lowest the boom luffs (5.96 m), so that it rises stratum by stratum.
    "strata": {"stacking.pattern": "strata", "stacking.layers": 2, "stacking.tonnes": 1500.0,
               "stacking.axis_x": [-15.0, 15.0], "stacking.row_spacing": 3.0, "stacking.drop": 5.0},
}
TRACKING = 0.3  # m: how far the PID on the stacker's inertias lets the discharge point lag its reference


@pytest.fixture(scope="module")
def machine():
    return Machine(load_scene(SCENE).machine.mjcf)


@pytest.fixture(scope="module")
def runs():
    """Each pattern's run, its pile's heights kept every 10 s."""
    return {name: simulate(load_scene(SCENE, {"simulation.record_period": 0.5, **overrides}), pile_frame_period=10.0)
            for name, overrides in RUNS.items()}


def _plan(name: str, machine: Machine, **more):
    scene = load_scene(SCENE, {**RUNS[name], **{f"stacking.{k}": v for k, v in more.items()}})
    return scene.stacking, plan_stacking(scene, machine, scene.simulation.control_period)


def _lowest(machine: Machine) -> float:
    g = machine.geometry
    return g.pivot_height + g.boom_length * math.sin(g.boom_angle0 + machine.envelope[2, 0]) + LOWEST_MARGIN


def _heights_at(result, t: float) -> np.ndarray:
    """The pile's heights (ny, nx) as its frames left them at `t` s."""
    history = result.stacking.history
    z = history.z_start.copy().ravel()
    for i in np.flatnonzero(history.frame_time <= t):
        z[history.cells[history.offsets[i]:history.offsets[i + 1]]] = history.heights[history.offsets[i]:history.offsets[i + 1]]
    return z.reshape(history.z_start.shape)


@pytest.mark.parametrize("name", RUNS)
def test_the_tonnes_and_the_grade_balance_exactly(runs, name):
    """What came in is what the pile's layers hold, in tonnes and tonnes x grade, to 1e-9; the
    tonnes are the scene's, and no slope stands steeper than the angle of repose."""
    result = runs[name]
    metrics, section = result.metrics["stacking"], result.scene.stacking
    assert metrics["pattern"] == name
    assert abs(metrics["balance_relative"]) <= 1e-9 and abs(metrics["grade_balance_relative"]) <= 1e-9
    assert metrics["tonnes_in_t"] == pytest.approx(section.tonnes, rel=1e-9)
    talus = Talus.of(section.grid_spacing, section.angle_of_repose)
    assert talus.excess(result.stacking.z) <= talus.tolerance and metrics["relaxations_unconverged"] == 0


def test_each_pattern_says_how_many_equal_layers_its_passes_amount_to(runs):
    """The law's N: (sum w)^2 / sum w^2 of the passes' weights. The windrow's 3 bottom rows of one
    and 3 higher rows of two give 81 / 15; the strata's 3 rows of a third and 1 whole, 4 / 4/3;
    cones, which do not run the pile's length, none. The console and pile.npz say the same."""
    assert runs["windrow"].metrics["stacking"]["equivalent_layers"] == pytest.approx(81 / 15)
    assert runs["strata"].metrics["stacking"]["equivalent_layers"] == pytest.approx(3.0)
    assert math.isnan(runs["cone_shell"].metrics["stacking"]["equivalent_layers"])
    assert runs["windrow"].stacking.pile_arrays()["equivalent_layers"] == pytest.approx(81 / 15)
    assert "stacked 500.0 t in 3 windrow rows across " in summary_table(runs["windrow"].metrics)
    assert " in 8 cone shells " in summary_table(runs["cone_shell"].metrics)


@pytest.mark.parametrize("name", RUNS)
def test_the_pile_stays_inside_its_grid(runs, name):
    """The grid holds the pattern's footprint: no material reaches its closed border."""
    z = runs[name].stacking.z
    assert z[0].max() == z[-1].max() == z[:, 0].max() == z[:, -1].max() == 0.0


@pytest.mark.parametrize("name", RUNS)
def test_the_stream_never_stops_and_the_passes_share_its_time_by_weight(name, machine):
    """The passes and the turns between them fill tonnes / rate exactly; each pass's time is its
    weight's share of what the turns leave; every cruise is within the travel's rated speed, and
    each row starts where the last ended along the rail (serpentine)."""
    section, plan = _plan(name, machine)
    total = section.tonnes / section.rate * SECONDS_PER_HOUR
    durations = plan.passes[:, 1] - plan.passes[:, 0]
    weights = np.array([lane.weight for lane in plan.layout])
    assert plan.passes[-1, 1] == pytest.approx(total, rel=1e-12) and plan.time[-1] == pytest.approx(total)
    np.testing.assert_allclose(durations / durations.sum(), weights / weights.sum(), rtol=1e-12)
    assert np.abs(plan.rows[1][:, 0]).max() <= machine.rated_speed[0] and plan.speed <= machine.rated_speed[0]
    rows = [lane for lane in plan.layout if not lane.dwell]
    for before, after in itertools.pairwise(rows):
        assert after.start == before.end


def test_windrow_rows_sit_in_the_valleys_of_the_layer_below(machine):
    """Layer j's m - j rows stand at y0 - W/2 + (i + (j + 1)/2) W/m, their heads `drop` above the
    layer's crest (j + 1) H / m or as low as the boom luffs; a bottom row one small triangle of
    the m^2, a higher one two."""
    section, plan = _plan("windrow", machine)
    m, (height, foot), y0 = section.layers, target_ridge(section), section.axis_y
    width = 2 * foot
    assert len(plan.layout) == m * (m + 1) // 2 and sum(lane.weight for lane in plan.layout) == m * m
    for j in range(m):
        lanes = [lane for lane in plan.layout if lane.layer == j]
        expected = [y0 - width / 2 + (i + (j + 1) / 2) * width / m for i in range(m - j)]
        np.testing.assert_allclose(sorted(lane.y for lane in lanes), expected, atol=1e-12)
        assert all(lane.weight == (1.0 if j == 0 else 2.0) for lane in lanes)
        head = max(section.drop + (j + 1) * height / m, _lowest(machine))
        assert all(lane.head == pytest.approx(head, abs=1e-12) for lane in lanes)
    np.testing.assert_allclose(plan.crests, height * np.arange(1, m + 1) / m)


def test_windrow_lays_its_bottom_rows_as_separate_ridges(runs, machine):
    """Once the bottom layer's m rows are laid, the section across the middle of the axis shows m
    ridges at the rows' y, with valleys between; each row's deposits fall on its line."""
    result = runs["windrow"]
    section, plan = _plan("windrow", machine)
    m, record = section.layers, result.stacking
    bottom = [lane.y for lane in plan.layout[:m]]
    z = _heights_at(result, plan.passes[m - 1, 1] - 10.0)  # before the turn to the second layer
    across = z[:, np.argmin(np.abs(record.x))]
    peaks = [i for i in range(1, len(across) - 1) if across[i] > 0.3 and across[i] >= across[i - 1]
             and across[i] > across[i + 1]]
    assert len(peaks) == m
    np.testing.assert_allclose(sorted(record.y[peaks]), sorted(bottom), atol=2 * section.grid_spacing)
    for left, right in zip(sorted(peaks), sorted(peaks)[1:]):
        assert across[left:right].min() < 0.6 * min(across[left], across[right])
    for lane, (start, end) in zip(plan.layout, plan.passes):
        during = (record.t > start + 20.0) & (record.t < end - 20.0)  # the cruise, the turns settled
        np.testing.assert_allclose(record.point[during, 1], lane.y, atol=TRACKING)


def test_cone_shell_dwells_at_evenly_spaced_cones(runs, machine):
    """The cones stand evenly from the axis's start to its end, the machine still while each is
    laid (its travel reference at rest, its true travel within the tracking), the stream landing
    on the cone's spot; the head is held `drop` above the ridge's crest."""
    result = runs["cone_shell"]
    section, plan = _plan("cone_shell", machine)
    height, _ = target_ridge(section)
    spots = np.linspace(*section.axis_x, section.layers)
    np.testing.assert_array_equal([lane.start for lane in plan.layout], spots)
    assert all(lane.dwell and lane.head == height + section.drop for lane in plan.layout)
    np.testing.assert_array_equal(plan.crests, np.full(section.layers, height))
    assert plan.speed == 0.0
    for spot, (start, end) in zip(spots, plan.passes):
        dwell = (plan.time >= start) & (plan.time <= end)
        assert np.all(plan.rows[1][dwell] == 0.0) and np.all(plan.rows[0][dwell, 0] == plan.rows[0][dwell][0, 0])
        settled = (result.time > start + 30.0) & (result.time < end)
        assert np.abs(result.qd[settled, 0]).max() < 0.02  # m/s: standing, but for the disturbance the PID rejects
        landed = (result.stacking.t > start + 30.0) & (result.stacking.t < end)
        np.testing.assert_allclose(result.stacking.point[landed], [[spot, section.axis_y]] * landed.sum(),
                                   atol=TRACKING)


def test_cone_shell_builds_a_row_of_cones_along_the_axis(runs):
    """Along the axis the pile rises to a crest over every cone's spot and dips between."""
    result = runs["cone_shell"]
    section, record = result.scene.stacking, result.stacking
    along = record.z[np.argmin(np.abs(record.y - section.axis_y))]
    spots = np.linspace(*section.axis_x, section.layers)
    tops = [along[np.abs(record.x - spot) <= 1.0].max() for spot in spots]
    saddles = [along[np.argmin(np.abs(record.x - 0.5 * (a + b)))] for a, b in itertools.pairwise(spots)]
    assert min(tops) > max(saddles)


def test_strata_lie_in_rows_across_their_width_at_rising_heights(machine):
    """Stratum k, topped at h_k = H (1 - sqrt(1 - k/N)), is laid in n_k = round(w_k / row_spacing)
    rows evenly over its width at mid-height w_k, centred on the axis, their heads `drop` above
    h_k, rising stratum by stratum; each stratum holds the same tonnes."""
    section, plan = _plan("strata", machine)
    n, (height, foot), y0 = section.layers, target_ridge(section), section.axis_y
    tops = height * (1 - np.sqrt(1 - np.arange(n + 1) / n))
    np.testing.assert_allclose(plan.crests, tops[1:], rtol=1e-12)
    heads = []
    for k in range(1, n + 1):
        lanes = [lane for lane in plan.layout if lane.layer == k - 1]
        width = 2 * foot * (1 - (tops[k - 1] + tops[k]) / (2 * height))
        rows = max(1, round(width / section.row_spacing))
        expected = y0 - width / 2 + (np.arange(rows) + 0.5) * width / rows
        np.testing.assert_allclose(sorted(lane.y for lane in lanes), expected, atol=1e-12)
        assert all(lane.head == pytest.approx(tops[k] + section.drop, abs=1e-12) for lane in lanes)
        heads.append(lanes[0].head)
        durations = [end - start for lane, (start, end) in zip(plan.layout, plan.passes) if lane.layer == k - 1]
        assert sum(durations) == pytest.approx((plan.passes[:, 1] - plan.passes[:, 0]).sum() / n, rel=1e-12)
    assert [len([lane for lane in plan.layout if lane.layer == k]) for k in range(n)] == [3, 1]
    assert np.all(np.diff(heads) > 0)


def test_strata_run_holds_each_stratum_head_and_spans_its_rows(runs, machine):
    """In the run the discharge point keeps each pass's head, and the first stratum's deposits
    span its rows across the pile."""
    result = runs["strata"]
    _, plan = _plan("strata", machine)
    heads = machine.fk(result.q)[:, 2]
    for lane, (start, end) in zip(plan.layout, plan.passes):
        during = (result.time > start + 20.0) & (result.time < end - 20.0)
        np.testing.assert_allclose(heads[during], lane.head, atol=TRACKING)
    first = [lane.y for lane in plan.layout if lane.layer == 0]
    laid = result.stacking.point[result.stacking.t < plan.passes[len(first) - 1, 1], 1]
    assert laid.min() == pytest.approx(min(first), abs=TRACKING) and laid.max() == pytest.approx(max(first), abs=TRACKING)


@pytest.mark.parametrize("name, overrides, message", [
    ("windrow", {"stacking.tonnes": 2000.0, "stacking.rate": 10000.0, "stacking.axis_x": [-20.0, 20.0]},
     (r"\[stacking\]'s pass 1 would cruise at 0.7\d\d m/s, above the travel's rated 0.500 m/s \(stacker_heavy.xml\): "
      r"fewer rows \('layers'\)")),
    ("cone_shell", {"stacking.layers": 2},
     (r"first cone, 1000 t alone on the floor, would stand 6.\d\d m high, above its discharge point 5.96 m up .*"
      r"more cones \('stacking.layers'\)")),
    ("strata", {"stacking.row_spacing": 2.0},
     r"\[stacking\]'s pass 1 would cruise at 0.80\d m/s, above the travel's rated 0.500 m/s .*a wider 'row_spacing'"),
    ("strata", {"stacking.row_spacing": 0.5},
     r"leaves pass 1 of its \d+ passes .* less than the 49.0 s a 30 m pass takes at 0.05 m/s\^2: .*a wider 'row_spacing'"),
    ("cone_shell", {"stacking.layers": 120},
     r"turns between its 120 passes take \d+\.\d s, all the 720.0 s the stream takes .*fewer 'layers'"),
    ("strata", {"stacking.row_spacing": 0.0}, r"'stacking.row_spacing' must be > 0, got 0.0"),
    ("strata", {"stacking.pattern": "spiral"},
     r"'stacking.pattern' must be one of \['chevron', 'windrow', 'cone_shell', 'strata'\], got 'spiral'"),
])
def test_a_pattern_the_machine_cannot_lay_is_refused_naming_the_key(name, overrides, message):
    with pytest.raises(SceneError, match=message):
        simulate(load_scene(SCENE, {**RUNS[name], **overrides}))


@pytest.mark.parametrize("name", ["windrow", "strata", "cone_shell"])
def test_each_shipped_pattern_scene_plans_its_20_kt_within_the_rated_travel(name, machine):
    """heavy_<pattern>_stack: heavy_chevron_stack's pile on another pattern, planned whole: the
    stream's two hours, every pass within the travel's rated speed."""
    scene = load_scene(SCENES / f"heavy_{name}_stack.toml")
    plan = plan_stacking(scene, machine, scene.simulation.control_period)
    assert scene.stacking.pattern == name and scene.stacking.tonnes == 20000.0
    assert plan.time[-1] == pytest.approx(scene.stacking.tonnes / scene.stacking.rate * SECONDS_PER_HOUR)
    assert np.all(plan.speeds <= machine.rated_speed[0]) and np.all(np.abs(plan.rows[1][:, 0]) <= machine.rated_speed[0] + 1e-9)
