"""Stacking in a run: the heavy stacker lays a small chevron pile on its pattern, the stream's
tonnes and grade balance with what the pile holds, no slope stands steeper than the angle of
repose, the layers hold the grade each deposit came at, and the run's files keep all of it."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest
from conftest import SCENES

from bwr_twin import SceneError
from bwr_twin.config.scene import load_scene
from bwr_twin.model.machine import Machine
from bwr_twin.pile.relaxation import Talus
from bwr_twin.planning.stacking import plan_stacking
from bwr_twin.replay.charts import charts
from bwr_twin.results.run_files import read_timeseries
from bwr_twin.results.rundir import write_run
from bwr_twin.results.summary import summary_table
from bwr_twin.sim.lockstep import simulate

SCENE = SCENES / "heavy_chevron_stack.toml"
# 2,000 t in 4 layers on a 40 m axis: 720 s of stacking.
SMALL = {"stacking.tonnes": 2000.0, "stacking.layers": 4, "stacking.axis_x": [-20.0, 20.0],
         "simulation.record_period": 0.5}


@pytest.fixture(scope="module")
def stacked():
    return simulate(load_scene(SCENE, SMALL))


def test_the_tonnes_and_the_grade_balance_exactly(stacked):
    """What came in, deposit by deposit, is what the pile's layers hold, in tonnes and in
    tonnes x grade, to 1e-9; and it is the rate over the run."""
    metrics, record = stacked.metrics["stacking"], stacked.stacking
    section = stacked.scene.stacking
    assert metrics["tonnes_in_t"] == pytest.approx(section.rate * stacked.time[-1] / 3600, rel=1e-12)
    assert metrics["tonnes_in_t"] == pytest.approx(section.tonnes, rel=1e-9)
    held = float(np.sum(record.thickness)) * 0.5**2 * section.bulk_density / 1000
    grade_held = float(np.sum(record.thickness * record.layer_grade)) * 0.5**2 * section.bulk_density / 1000
    assert abs(held - record.tonnes.sum()) <= 1e-9 * held
    assert abs(grade_held - np.sum(record.tonnes * record.grade)) <= 1e-9 * grade_held
    assert abs(metrics["balance_relative"]) <= 1e-9 and abs(metrics["grade_balance_relative"]) <= 1e-9
    np.testing.assert_allclose(record.thickness.sum(axis=2), record.z, atol=1e-9)  # the layers are the heights


def test_no_slope_stands_steeper_than_the_angle_of_repose(stacked):
    section = stacked.scene.stacking
    talus = Talus.of(section.grid_spacing, section.angle_of_repose)
    assert talus.excess(stacked.stacking.z) <= talus.tolerance
    assert stacked.metrics["stacking"]["relaxations_unconverged"] == 0


def test_the_machine_lays_a_chevron_ridge_along_its_axis(stacked):
    """The discharge point runs to and fro over the axis; the pile is a ridge there, its crest
    near the target's, standing at the angle of repose across it."""
    section, record, metrics = stacked.scene.stacking, stacked.stacking, stacked.metrics["stacking"]
    np.testing.assert_allclose(record.point[:, 1], section.axis_y, atol=0.3)  # on the axis, within the tracking
    assert record.point[:, 0].min() == pytest.approx(-20.0, abs=0.3) and record.point[:, 0].max() == pytest.approx(20.0, abs=0.3)
    assert 0.85 * metrics["target_height_m"] < metrics["crest_height_m"] < 1.15 * metrics["target_height_m"]
    middle = np.argmin(np.abs(record.x))
    across = record.z[:, middle]
    assert record.y[np.argmax(across)] == pytest.approx(section.axis_y, abs=1.0)
    flank = np.diff(across)[across[1:] > 0.5] / section.grid_spacing  # where it stands, not at its foot
    assert np.abs(flank).max() <= np.tan(np.radians(section.angle_of_repose)) * 1.01


def test_the_layers_hold_the_grade_each_deposit_came_at(stacked):
    """The first deposit lies at the bottom of the column under the pile's start, the last on
    top of the column under the last pass's end; the grade that came in has the scene's mean."""
    record = stacked.stacking
    ix = np.argmin(np.abs(record.x - record.point[0, 0]))
    iy = np.argmin(np.abs(record.y - record.point[0, 1]))
    assert record.layer_grade[iy, ix, 0] == pytest.approx(record.grade[0])
    ix = np.argmin(np.abs(record.x - record.point[-1, 0]))
    iy = np.argmin(np.abs(record.y - record.point[-1, 1]))
    top = record.count[iy, ix] - 1
    assert record.layer_grade[iy, ix, top] == pytest.approx(record.grade[-1])
    assert stacked.metrics["stacking"]["grade_in_mean"] == pytest.approx(62.0, abs=1.0)


def test_the_same_seed_stacks_the_same_pile_and_another_seed_another(stacked):
    again = simulate(load_scene(SCENE, SMALL))
    np.testing.assert_array_equal(again.stacking.layer_grade, stacked.stacking.layer_grade)
    other = simulate(load_scene(SCENE, {**SMALL, "simulation.seed": 2}))
    assert not np.array_equal(other.stacking.grade, stacked.stacking.grade)


def test_the_run_directory_keeps_the_layers_the_deposits_and_the_grade_in_time(stacked, tmp_path):
    write_run(stacked, tmp_path / "run")
    with np.load(tmp_path / "run" / "pile.npz") as pile:
        np.testing.assert_array_equal(pile["layer_grade"], stacked.stacking.layer_grade)
        np.testing.assert_array_equal(pile["deposit_grade"], stacked.stacking.grade)
        np.testing.assert_array_equal(pile["deposit_drop"], stacked.stacking.drop)
        np.testing.assert_array_equal(pile["z_end"], stacked.stacking.z)
    series = read_timeseries(tmp_path / "run" / "timeseries.csv")
    assert series.stacked[-1] == pytest.approx(2000.0, rel=1e-6)
    assert (series.grade.name, series.grade.kind) == ("Fe %", "stacked") and np.isfinite(series.grade.values).all()
    metrics = json.loads((tmp_path / "run" / "metrics.json").read_text())
    assert metrics["stacking"]["layers"] == 4
    assert (tmp_path / "run" / "stacking.png").stat().st_size > 10_000
    assert "stacked 2,000.0 t in 4 chevron layers" in summary_table(metrics)


def test_the_stream_falls_the_planned_drop_or_more_onto_the_pile_under_it(stacked):
    """Each deposit's fall, from the discharge point down to the pile under it as the deposit
    begins: at least the planned `drop` (the head is held that far above the crest the layer will
    reach), less the tracking error; more while the boom cannot luff lower, over the first layers."""
    drop, metrics = stacked.stacking.drop, stacked.metrics["stacking"]
    assert len(drop) == metrics["deposits"]
    assert drop.min() >= 2.0 - 0.3  # m: the scene's drop, less the PID's tracking of the head
    assert metrics["drop_min_m"] == drop.min() and metrics["drop_mean_m"] == pytest.approx(drop.mean())
    machine = Machine(stacked.scene.machine.mjcf)
    g = machine.geometry  # the lowest the head luffs, over the bare yard: the first deposits' fall
    lowest = g.pivot_height + g.boom_length * np.sin(g.boom_angle0 + machine.envelope[2, 0])
    assert drop[0] == pytest.approx(lowest + 0.5, abs=0.3)
    assert "the stream fell " in summary_table(stacked.metrics)


def test_the_plan_holds_the_drop_above_each_crest_and_luffs_up_between_passes():
    scene = load_scene(SCENE, SMALL)
    machine = Machine(scene.machine.mjcf)
    plan = plan_stacking(scene, machine, scene.simulation.control_period)
    heads = machine.fk(plan.rows[0])[:, 2]
    for (start, end), crest in zip(plan.passes, plan.crests):
        during = (plan.time > start) & (plan.time < end)
        lowest = heads[during].min()
        assert lowest >= crest + scene.stacking.drop - 1e-6  # the drop, or higher where the boom luffs no lower
    assert np.all(np.diff(plan.crests) > 0)
    assert np.abs(plan.rows[1][:, 0]).max() == pytest.approx(plan.speed) and plan.speed <= machine.rated_speed[0]


@pytest.mark.parametrize("overrides, message", [
    ({"stacking.layers": 12}, r"passes would cruise at 1.00\d m/s, above the travel's rated 0.500 m/s \(stacker_heavy.xml\)"),
    ({"stacking.layers": 40}, r"leaves each of its 40 passes 18.0 s \(2000 t at 10000 t/h\), less than the 56.6 s"),
    ({"stacking.axis_y": 12.0}, r"the pile's foot would reach y = .* inside the 8 m the rail keeps clear"),
    ({"stacking.axis_x": [0.0, 1.0]}, r"'stacking.axis_x' must span at least 4 grid cells"),
    ({"stacking.grade.file": "grade.csv"}, r"\[stacking.grade\] needs either a 'mean'"),
    ({"path.frame": "world", "path.via_points": [{"t": 0.0, "p": [0.0, 0.0, 0.0]}]},
     r"needs one of a \[path\] of via points, a \[reclaim\] or a \[stacking\], got \[path\] and \[stacking\]"),
])
def test_a_stacking_the_machine_cannot_do_is_refused_naming_the_key(overrides, message, tmp_path):
    (tmp_path / "grade.csv").write_text("t,grade\n0,62\n")
    overrides = {k: (str(tmp_path / v) if k.endswith("file") else v) for k, v in overrides.items()}
    with pytest.raises(SceneError, match=message):
        simulate(load_scene(SCENE, {**SMALL, **overrides}))


@pytest.fixture(scope="module")
def grown():
    """The small pile stacked with its frames kept for a replay, every 10 s."""
    return simulate(load_scene(SCENE, SMALL), pile_frame_period=10.0)


def test_the_replay_shows_the_pile_growing_from_the_bare_yard(grown):
    """Kept for a replay, the pile's frames rebuild it as it grew: less at half time than at the
    end, and at the end the pile the run stacked."""
    from bwr_twin.replay import Recording

    result = grown
    recording = Recording.from_result(result)
    pile = recording.pile
    assert recording.plan.activity == "stacking" and recording.plan.names[0] == "pass 1"

    def heights_until(t: float) -> np.ndarray:
        z = pile.z_start.copy().ravel()
        for i in np.flatnonzero(pile.frame_time <= t):
            z[pile.cells[pile.offsets[i]:pile.offsets[i + 1]]] = pile.heights[pile.offsets[i]:pile.offsets[i + 1]]
        return z.reshape(pile.z_start.shape)

    assert pile.z_start.max() == 0.0
    middle, end = heights_until(360.0), heights_until(result.time[-1])
    assert 0.3 * end.sum() < middle.sum() < 0.7 * end.sum()
    np.testing.assert_allclose(end, result.stacking.z, atol=1e-5)  # float32 frames


def top_grades_until(history, t: float) -> np.ndarray:
    """The (ny, nx) top grades a history's frames give at time t (s)."""
    grade = history.grade_start.copy().ravel()
    for i in np.flatnonzero(history.frame_time <= t):
        frame = slice(history.offsets[i], history.offsets[i + 1])
        grade[history.cells[frame]] = history.grades[frame]
    return grade.reshape(history.z_start.shape)


def test_the_frames_keep_the_top_layers_grade_through_pile_npz(grown, stacked, tmp_path):
    """Each frame keeps the grade of the layer exposed at its cells: rebuilt at the end, it is the
    layers' top grade, NaN on bare ground; pile.npz keeps it, with the grade's name and band, and
    a stacking written without its frames still gives its top grade at the end."""
    from bwr_twin.stockpile.history import PileHistory
    from bwr_twin.stockpile.layers import top_grade

    record, history = grown.stacking, grown.stacking.history
    assert np.isnan(history.grade_start).all() and len(history.grades) == len(history.cells)
    expected = top_grade(record.layer_grade, record.count)
    assert np.isnan(expected).any() and np.isfinite(expected).sum() > 100  # bare ground around a pile
    end = top_grades_until(history, grown.time[-1])
    np.testing.assert_array_equal(end, expected.astype(np.float32))
    middle = top_grades_until(history, 360.0)
    assert np.isfinite(middle).sum() < np.isfinite(end).sum()  # it grows
    write_run(grown, tmp_path / "grown", plots=False)
    read = PileHistory.read(tmp_path / "grown" / "pile.npz", float(grown.time[-1]))
    for name in ("grade_start", "grades", "cells", "heights"):
        np.testing.assert_array_equal(getattr(read, name), getattr(history, name))
    assert (read.grade_name, read.grade_band) == ("Fe %", (61.0, 63.0))
    write_run(stacked, tmp_path / "whole", plots=False)  # no frames: the pile whole at the end
    whole = PileHistory.read(tmp_path / "whole" / "pile.npz", float(stacked.time[-1]))
    np.testing.assert_array_equal(top_grades_until(whole, stacked.time[-1]),
                                  top_grade(stacked.stacking.layer_grade, stacked.stacking.count).astype(np.float32))


def test_the_replay_colours_the_pile_by_the_grade_of_its_top_layer(grown):
    """"Pile colour" grade: every tile's faces are split over the scale's bins by the mean top
    grade of their corners, each bin with faces a mesh in its colour, bare ground in ore, together
    the whole tile; they follow the pile back in time; "ore" shows the ore meshes again."""
    import html

    from test_replay import until

    from bwr_twin.replay import Recording, ReplayServer
    from bwr_twin.replay.pile import ORE_COLOUR

    with ReplayServer(Recording.from_result(grown), port=0) as server:
        player, panel, pile = server.player, server.player.panel, server.view.sites[0].pile
        scale = server.view.grade_scale
        assert panel.pile_colour.options == ("ore", "grade") and panel.pile_colour.value == "ore"
        assert not panel.grade_legend.visible and "Top layer's grade, Fe %" in panel.grade_legend.content
        assert all(html.escape(label) in panel.grade_legend.content for label in scale.labels())

        bins = len(scale.colours) + 1  # and bare ground

        def faces_by_bin() -> np.ndarray:
            """(tiles, bins) the faces each grade mesh draws (none, or a placeholder: one vertex, none)."""
            return np.array([[len(tile.bins[k].faces) if k in tile.bins and len(tile.bins[k].vertices) > 1 else 0
                              for k in range(bins)] for tile in pile._tiles])

        def expected_by_bin() -> np.ndarray:
            rows, cols = np.ix_(pile._grid.rows, pile._grid.cols)
            grade = pile.dug.grade[rows, cols]
            counts = []
            for tile in pile._tiles:
                corners = grade[tile.rows, tile.cols].ravel()[tile._faces]
                mean = np.array([np.nanmean(c) if np.isfinite(c).any() else np.nan for c in corners])
                index = scale.bins(mean)
                counts.append([(index == k).sum() for k in range(len(scale.colours))] + [(index < 0).sum()])
            return np.array(counts)

        player.seek(float(grown.time[-1]))
        until(lambda: pile.dug._applied == len(pile.dug.history.frame_time), "the pile at its end")
        player.colour_pile("grade")
        until(lambda: panel.grade_legend.visible, "the pile coloured by grade")  # shown after the tiles
        for tile in pile._tiles:
            assert tile.bins and all(tile.bins[k].color == [*scale.colours, ORE_COLOUR][k] for k in tile.bins)
            assert not tile._ore.visible and not tile._cut.visible
        end = faces_by_bin()
        assert np.array_equal(end.sum(axis=1), [len(tile._faces) for tile in pile._tiles])  # the whole tile
        np.testing.assert_array_equal(end, expected_by_bin())
        assert (end[:, :-1].sum(axis=0) > 0).sum() >= 5  # the layers' grades spread over the scale

        player.seek(300.0)  # back in time: less pile, and its grades then (the player's thread sends them)
        until(lambda: pile.dug.history.frame_time[pile.dug._applied - 1] <= 300.0
              and np.array_equal(faces_by_bin(), expected_by_bin()), "the grade meshes at 300 s")
        assert faces_by_bin()[:, :-1].sum() < end[:, :-1].sum()

        player.colour_pile("ore")
        until(lambda: pile._tiles[0]._ore.visible and not panel.grade_legend.visible, "the ore colours again")
        assert not pile._grade_root.visible and panel.pile_colour.value == "ore"


def test_the_replay_charts_the_grade_stacked_and_the_grade_reclaimed(stacked, reclaimed, tmp_path):
    """The grade the stream brought, and the grade that passed the belt scale from the first
    discharge on (a reclaim's is NaN before: a chart of the known part alone), from a result and
    from its run directory alike."""
    from bwr_twin.replay import Recording

    result, _ = reclaimed
    write_run(result, tmp_path / "blend", plots=False)
    for recording in (Recording.from_result(result), Recording.from_run_dir(tmp_path / "blend")):
        (chart,) = [chart for chart in charts(recording) if chart.title.startswith("Grade")]
        assert chart.title == "Grade reclaimed, at the belt scale" and recording.grade.name == "Fe %"
        (line,) = chart.lines
        assert np.isfinite(line.values).all() and chart.time[0] >= result.reclaim.grade_out["t"][0] - 1.0
        out = result.reclaim.grade_out["grade"]
        assert out.min() <= line.values.min() and line.values.max() <= out.max()
    (chart,) = [chart for chart in charts(Recording.from_result(stacked)) if chart.title.startswith("Grade")]
    assert chart.title == "Grade stacked, as it arrived"
    np.testing.assert_allclose(chart.lines[0].values, np.interp(chart.time, stacked.time,
                                                                stacked.stacking.series(stacked.time)[0]))


def test_a_reclaim_of_a_plain_pile_keeps_no_grade(tmp_path):
    """A windrow has no layers: its pile.npz holds the heights and their frames alone, as before,
    and its replay has no pile colour to choose."""
    from test_stockpile import SHORT_DIG

    from bwr_twin.replay import Recording, ReplayServer

    dig = simulate(load_scene(SCENES / "heavy_dig_pile.toml", SHORT_DIG), pile_frame_period=5.0)
    write_run(dig, tmp_path / "dig", plots=False)
    with np.load(tmp_path / "dig" / "pile.npz") as pile:
        assert sorted(pile.files) == sorted(["x", "y", "z_start", "z_end", "frame_time", "frame_offsets",
                                             "frame_cells", "frame_heights"])
    recording = Recording.from_run_dir(tmp_path / "dig")
    assert recording.pile.grade_start is None and recording.pile.grades is None and recording.grade is None
    assert not any("Grade" in chart.title for chart in charts(recording))
    with ReplayServer(recording, port=0) as server:
        assert server.view.grade_scale is None and server.player.panel.pile_colour is None


# heavy_stack_and_reclaim on the small pile: one 4 m bench of 10 m.
RECLAIM_STACKED = '''extends = "heavy_stack_and_reclaim"
[stockpile]
surface_file = "stack/pile.npz"
grid_spacing = 0.5
[reclaim]
bench_height = 4.0
bench_length = 10.0
start = [-100.0, 15.0, 5.0]
stop = { benches = 1 }
'''


@pytest.fixture(scope="module")
def reclaimed(stacked, tmp_path_factory):
    """The small stacked pile, written as its run directory, then bench-reclaimed by the heavy
    reclaimer from its pile.npz: one 4 m bench of 10 m."""
    folder = tmp_path_factory.mktemp("blend")
    write_run(stacked, folder / "stack", plots=False)
    (folder / "reclaim.toml").write_text(RECLAIM_STACKED)
    return simulate(load_scene(folder / "reclaim.toml"), pile_frame_period=5.0), folder


def test_a_stacked_pile_reclaimed_balances_its_tonnes_and_grade_exactly(reclaimed):
    """The pile's layers at the start are what they hold at the end, what the buckets carried and
    what spilled, in tonnes and in tonnes x grade, to 1e-9; what left is the reclaim's tonnes."""
    result, _ = reclaimed
    blend = result.metrics["blend"]
    assert abs(blend["balance_relative"]) <= 1e-9 and abs(blend["grade_balance_relative"]) <= 1e-9
    assert blend["tonnes_out_t"] == pytest.approx(result.metrics["reclaim"]["mass_t"], rel=1e-12)
    assert blend["tonnes_out_t"] > 300.0


def test_the_faces_cut_into_a_stacked_pile_slump_with_their_layers(reclaimed):
    """heavy_stack_and_reclaim's 'stockpile.angle_of_repose': the cut faces slump, their layers
    carried along (the balances above hold with them), and no slope stands steeper at the end."""
    result, _ = reclaimed
    pile = result.reclaim
    talus = Talus.of(pile.x[1] - pile.x[0], 37.0)
    assert result.metrics["reclaim"]["slumped_m3"] > 10.0
    assert talus.excess(pile.z_end) <= talus.tolerance


def test_the_grade_that_left_is_the_stacked_grade_blended(reclaimed, stacked):
    """Each bucket carries a mix of the layers it cut through: the grade out lies within what was
    stacked, and varies less than what came in."""
    result, _ = reclaimed
    blend, out = result.metrics["blend"], result.reclaim.grade_out
    assert stacked.stacking.grade.min() <= out["grade"].min() and out["grade"].max() <= stacked.stacking.grade.max()
    assert blend["grade_in_sd"] == pytest.approx(stacked.metrics["stacking"]["grade_in_sd"], rel=1e-12)
    assert blend["grade_out_sd"] < blend["grade_in_sd"] and blend["sd_ratio"] < 1.0
    assert blend["belt_delay_s"] == pytest.approx(40.0 / 4.5)  # the heavy machine's belt scale (mjcf/README.md)
    assert "blended: " in summary_table(result.metrics)


def test_the_run_directory_keeps_the_grade_out_after_the_belt_delay(reclaimed, tmp_path):
    result, _ = reclaimed
    write_run(result, tmp_path / "run")
    assert (tmp_path / "run" / "blend.png").stat().st_size > 10_000
    series = read_timeseries(tmp_path / "run" / "timeseries.csv")
    assert (series.grade.name, series.grade.kind) == ("Fe %", "reclaimed")
    grade = series.grade.values
    first = result.reclaim.grade_out["t"][0]
    assert np.isnan(grade[series.time < first - 1e-9]).all()
    assert grade[np.searchsorted(series.time, first)] == pytest.approx(result.reclaim.grade_out["grade"][0])


@pytest.mark.parametrize("old, new, message", [
    ("grid_spacing = 0.5", "grid_spacing = 0.25",
     (r"a stacked pile is reclaimed on the grid it was stacked on, its layers cell by cell: 'stockpile.grid_spacing' "
      r"must be its 0.5 m, got 0.25 m")),
    ("grid_spacing = 0.5", "grid_spacing = 0.5\nbulk_density = 2000.0",
     r"'stockpile.bulk_density' \(2000 kg/m3\) must be the 2400 kg/m3 its stacked pile was laid at"),
])
def test_a_stacked_pile_on_another_grid_or_density_is_refused(reclaimed, old, new, message):
    _, folder = reclaimed
    (folder / "bad.toml").write_text(RECLAIM_STACKED.replace(old, new))
    with pytest.raises(SceneError, match=message):
        simulate(load_scene(folder / "bad.toml"))


def test_a_stacked_pile_is_named_on_the_command_line_from_any_folder(reclaimed, tmp_path):
    """`--pile` gives a reclaim its pile from the cwd, whatever the scene's own path says (a shipped
    scene's relative path points inside the installed package); it replaces a windrow too."""
    _, folder = reclaimed
    scene = tmp_path / "short.toml"
    scene.write_text(RECLAIM_STACKED.replace('surface_file = "stack/pile.npz"', 'surface_file = "elsewhere/pile.npz"')
                     .replace("stop = { benches = 1 }", "stop = { time = 20.0 }"))
    pile = (folder / "stack" / "pile.npz").relative_to(folder)
    run = subprocess.run([sys.executable, "-m", "bwr_twin.run", str(scene), "--pile", str(pile), "--out", str(tmp_path / "run"),
                          "--no-plots"], capture_output=True, text=True, cwd=folder, timeout=300, check=False)
    assert run.returncode == 0, run.stderr
    metrics = json.loads((tmp_path / "run" / "metrics.json").read_text())
    assert metrics["blend"]["layers"] == 4  # the small stacked pile's
    windrow = load_scene(SCENES / "heavy_bench_reclaim.toml", {"stockpile.surface_file": str(folder / pile)})
    assert windrow.stockpile.windrow is None and windrow.stockpile.surface_file == folder / pile


def test_the_reclaim_of_a_stacked_pile_keeps_the_grade_its_cut_exposes(reclaimed, stacked, tmp_path):
    """At the start each cell's top grade is the stacked pile's; where the wheel cut through a
    layer, the grade below shows, within the grades stacked; pile.npz keeps it."""
    from bwr_twin.stockpile.history import PileHistory
    from bwr_twin.stockpile.layers import top_grade

    result, _ = reclaimed
    history = result.reclaim.history
    record = stacked.stacking
    ix = round((record.x[0] - history.x[0]) / (history.x[1] - history.x[0]))
    iy = round((record.y[0] - history.y[0]) / (history.y[1] - history.y[0]))
    start = np.full(history.z_start.shape, np.nan, np.float32)
    start[iy:iy + len(record.y), ix:ix + len(record.x)] = top_grade(record.layer_grade, record.count)
    np.testing.assert_array_equal(history.grade_start, start)
    end = top_grades_until(history, result.time[-1])
    exposed = (end != start) & np.isfinite(end)
    assert exposed.sum() > 50  # the cut bared other layers
    low, high = np.float32(record.grade.min()), np.float32(record.grade.max())
    assert low <= end[exposed].min() and end[exposed].max() <= high  # a merged layer's lies between its two
    write_run(result, tmp_path / "run", plots=False)
    read = PileHistory.read(tmp_path / "run" / "pile.npz", float(result.time[-1]))
    np.testing.assert_array_equal(read.grades, history.grades)
    assert read.grade_name == "Fe %"
