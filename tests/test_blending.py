"""The pile's physics for stacking and blending: relaxation to the angle of repose, the grade in
layers, deposition at a discharge point, the grade stream, the sqrt(N) blending law and the
tonnes and grade balances through a random sequence of all of them."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from bwr_twin import SceneError
from bwr_twin.config.sections import StockpileSection, WindrowSection
from bwr_twin.pile.relaxation import DEFAULT_TOLERANCE, Talus, relax
from bwr_twin.pile.surface import Surface, windrow
from bwr_twin.stockpile.blending import blend, chevron_pile, slice_grades, stacked_grades
from bwr_twin.stockpile.deposition import discharge, footprint
from bwr_twin.stockpile.grade import Ar1Grade, RecordedGrade
from bwr_twin.stockpile.layers import LayeredPile
from bwr_twin.stockpile.material import Material

IRON_ORE = Material(bulk_density=2400.0, angle_of_repose=37.0)  # as heavy_dig_pile's [stockpile]
SPACING = 0.5  # m


def _windrow(spacing: float = SPACING) -> Surface:
    """A 15 m windrow at 37 deg, 40 m of crest: 103 x 163 cells of 0.5 m."""
    section = WindrowSection(length=40.0, crest_width=10.0, height=15.0, angle_of_repose=37.0, centre=(50.0, 30.0))
    return windrow(section, spacing, Path("test.toml"))


def _assert_within_talus(z: np.ndarray, talus: Talus) -> None:
    """Every pair of neighbours, axial and diagonal, within its talus height plus the tolerance."""
    pairs = {"x": (z[:, 1:], z[:, :-1], talus.axial), "y": (z[1:, :], z[:-1, :], talus.axial),
             "diagonal": (z[1:, 1:], z[:-1, :-1], talus.diagonal), "antidiagonal": (z[1:, :-1], z[:-1, 1:], talus.diagonal)}
    for name, (a, b, limit) in pairs.items():
        assert np.max(np.abs(a - b)) <= limit + talus.tolerance, name


# --- relaxation -----------------------------------------------------------------------------


def test_talus_heights_come_from_the_angle_of_repose_and_the_spacing():
    talus = Talus.of(0.5, 37.0)
    assert talus.axial == pytest.approx(0.5 * math.tan(math.radians(37.0)), rel=1e-15)
    assert talus.diagonal == pytest.approx(math.sqrt(2) * talus.axial, rel=1e-15)
    assert talus.tolerance == DEFAULT_TOLERANCE == 1e-4
    for bad in ((0.5, 0.0), (0.5, 90.0), (0.0, 37.0)):
        with pytest.raises(ValueError):
            Talus.of(*bad)


def test_a_pile_at_its_angle_of_repose_is_left_alone():
    z = _windrow().z.copy()
    before = z.copy()
    relaxed = relax(z, Talus.of(SPACING, 37.0))
    assert (relaxed.rounds, relaxed.converged, relaxed.move_count) == (1, True, 0)
    assert np.array_equal(z, before)


@pytest.mark.parametrize("case", ["vertical face", "bench cut", "random heights"])
def test_relaxation_conserves_the_volume_and_leaves_no_slope_steeper_than_repose(case):
    talus = Talus.of(SPACING, IRON_ORE.angle_of_repose)
    z = _windrow().z.copy()
    if case == "vertical face":  # the whole windrow cut off square: 15 m standing vertical
        z[:, : z.shape[1] // 2] = 0.0
    elif case == "bench cut":  # a 6 m deep, 10 m wide bench taken into the crest with vertical walls
        z[:, 70:90] = np.minimum(z[:, 70:90], 9.0)
    else:
        z = np.random.default_rng(3).uniform(0.0, 10.0, (40, 50))
    volume = z.sum() * SPACING**2
    relaxed = relax(z, talus)
    assert relaxed.converged and relaxed.move_count > 0
    assert z.sum() * SPACING**2 == pytest.approx(volume, rel=1e-12, abs=0)
    assert z.min() >= 0.0  # the yard floor
    _assert_within_talus(z, talus)
    assert talus.excess(z) <= talus.tolerance
    # Slumped to the angle of repose, not flatter: the steepest pairs stand at their talus height.
    assert talus.excess(z) > -talus.tolerance


def test_relaxation_from_the_cells_that_changed_settles_the_whole_pile():
    """A relaxation told which cells changed (a cut's rectangle) visits those and their
    neighbours first, and the avalanche spreads from there: the pile ends as relaxed, with the
    same volume, as one relaxed from every cell."""
    talus = Talus.of(SPACING, IRON_ORE.angle_of_repose)
    cut = _windrow().z.copy()
    cut[20:40, 70:90] = np.minimum(cut[20:40, 70:90], 4.0)  # a deep pocket, vertical walls
    volume = cut.sum()
    seeded, full = cut.copy(), cut.copy()
    local = relax(seeded, talus, region=(20, 39, 70, 89))
    everywhere = relax(full, talus)
    assert local.converged and local.move_count > 0 and talus.excess(seeded) <= talus.tolerance
    assert seeded.sum() == pytest.approx(volume, rel=1e-12, abs=0)
    assert local.moved_volume == pytest.approx(everywhere.moved_volume, rel=1e-2)  # the order differs
    # Another order of visits, another of the many relaxed piles: the same material in the pocket.
    assert seeded[20:40, 70:90].sum() == pytest.approx(full[20:40, 70:90].sum(), rel=1e-2)
    # A region that missed the change leaves the pocket standing: the region is what is looked at.
    missed = cut.copy()
    assert relax(missed, talus, region=(0, 2, 0, 2)).move_count == 0 and np.array_equal(missed, cut)


def test_relaxation_is_deterministic_and_bounded_in_rounds():
    talus = Talus.of(SPACING, IRON_ORE.angle_of_repose)
    face = _windrow().z.copy()
    face[:, : face.shape[1] // 2] = 0.0
    first, second = face.copy(), face.copy()
    relaxed = relax(first, talus)
    assert relax(second, talus) == relaxed and np.array_equal(first, second)
    # A 15 m vertical face on 0.5 m cells, the worst slump a wheel can leave, settles in under
    # 2,000 rounds; a budget cut short says so and leaves the face still too steep.
    assert relaxed.rounds < 2000
    short = face.copy()
    stopped = relax(short, talus, max_rounds=50)
    assert (stopped.rounds, stopped.converged) == (50, False)
    assert talus.excess(short) > talus.tolerance
    assert short.sum() == pytest.approx(face.sum(), rel=1e-12)
    with pytest.raises(ValueError, match="max_rounds"):
        relax(face.copy(), talus, max_rounds=0)


def test_a_tighter_tolerance_holds_its_tighter_bound():
    talus = Talus.of(SPACING, IRON_ORE.angle_of_repose, tolerance=1e-7)
    z = np.zeros((31, 31))
    z[15, 15] = 40.0
    relax(z, talus)
    _assert_within_talus(z, talus)
    assert z.sum() == pytest.approx(40.0, rel=1e-13)


# --- layers --------------------------------------------------------------------------------


def _column(pile: LayeredPile, iy: int, ix: int) -> list[tuple[float, float]]:
    """(thickness, grade) of a column's layers from the floor up."""
    return [(float(t), float(g)) for t, g in zip(pile.thickness[iy, ix, : pile.count[iy, ix]],
                                                   pile.grade[iy, ix, : pile.count[iy, ix]])]


def _small_pile(max_layers: int = 8) -> LayeredPile:
    return LayeredPile(np.arange(5) * SPACING, np.arange(4) * SPACING, max_layers)


def test_a_deposit_thickens_a_top_layer_of_the_same_grade_and_otherwise_lays_a_new_one():
    pile = _small_pile()
    one = np.zeros((4, 5))
    one[1, 2] = 1.0
    pile.deposit(one, 62.0)
    pile.deposit(one * 0.5, 62.0)
    pile.deposit(one * 0.25, 58.0)
    assert _column(pile, 1, 2) == [(1.5, 62.0), (0.25, 58.0)]
    assert pile.z[1, 2] == 1.75 and pile.z.sum() == 1.75
    grades = np.full((4, 5), 60.0)
    pile.deposit(np.full((4, 5), 0.1), grades)  # a grade per cell
    assert _column(pile, 0, 0) == [(0.1, 60.0)]
    with pytest.raises(ValueError, match=">= 0"):
        pile.deposit(-one, 60.0)
    with pytest.raises(ValueError, match="finite"):
        pile.deposit(one, math.nan)


def test_a_cut_takes_layers_from_the_top_down_with_their_grade():
    pile = _small_pile()
    one = np.zeros((4, 5))
    one[2, 3] = 1.0
    for thickness, grade in ((2.0, 60.0), (1.0, 64.0), (0.5, 56.0)):
        pile.deposit(one * thickness, grade)
    heights = pile.z.copy()
    heights[2, 3] = 2.5  # down through the top layer and half of the next
    removed = pile.cut_to(heights)
    area = SPACING**2
    assert removed.total_volume == pytest.approx(1.0 * area, rel=1e-15)
    assert removed.grade == pytest.approx((0.5 * 56.0 + 0.5 * 64.0) / 1.0, rel=1e-15)
    assert removed.volume[2, 3] == removed.total_volume and np.count_nonzero(removed.volume) == 1
    assert _column(pile, 2, 3) == [(2.0, 60.0), (0.5, 64.0)]
    heights[2, 3] = -1.0  # below the yard floor: down to the floor only
    assert pile.cut_to(heights).total_volume == pytest.approx(2.5 * area, rel=1e-15)
    assert pile.count[2, 3] == 0 and pile.z[2, 3] == 0.0
    assert math.isnan(pile.cut_to(heights).grade)  # nothing left to cut


def test_a_full_column_merges_its_two_closest_layers_keeping_the_balance():
    pile = _small_pile(max_layers=4)
    one = np.zeros((4, 5))
    one[0, 0] = 1.0
    for thickness, grade in ((1.0, 60.0), (1.0, 64.0), (0.2, 63.0), (1.0, 58.0), (1.0, 66.0)):
        pile.deposit(one * thickness, grade)
    # 64 and 63 (0.2 m) cost least to merge: 1 x 0.2 / 1.2 x 1^2; the others, 4^2 x 1/2 or more.
    merged = (1.0 * 64.0 + 0.2 * 63.0) / 1.2
    assert _column(pile, 0, 0) == [(1.0, 60.0), (pytest.approx(1.2, rel=1e-15), pytest.approx(merged, rel=1e-15)),
                                   (1.0, 58.0), (1.0, 66.0)]
    assert pile.volume() == pytest.approx(4.2 * SPACING**2, rel=1e-15)
    assert pile.grade_volume() == pytest.approx((60 + 64 + 0.2 * 63 + 58 + 66) * SPACING**2, rel=1e-15)


def test_relaxation_moves_the_top_of_a_column_with_its_grade():
    """A tall column of grade 60 under a cap of grade 70, beside bare ground: each move carries the
    top of a column, as a sheet that keeps its order, onto the next."""
    pile = LayeredPile(np.arange(3) * SPACING, np.arange(1) * SPACING)
    tall = np.array([[3.0, 0.0, 0.0]])
    pile.deposit(tall * 0.9, 60.0)
    pile.deposit(tall * 0.1, 70.0)
    talus = Talus.of(SPACING, IRON_ORE.angle_of_repose, tolerance=1e-9)
    heights = pile.z.copy()
    relaxed = pile.relax(talus)
    relax(heights, talus)
    assert np.array_equal(pile.z, heights)  # the same relaxation as the heights alone
    assert np.allclose(pile.column_heights(), pile.z, rtol=0, atol=1e-12)
    assert relaxed.move_count > 0 and pile.z[0, 2] > 0
    # The cap slid off first, riding on the sheet under it, and went on to the far cell.
    assert {g for column in range(2) for _, g in _column(pile, 0, column)} == {60.0}
    far = _column(pile, 0, 2)
    assert [g for _, g in far] == [60.0, 70.0, 60.0]
    assert far[1][0] == pytest.approx(0.3, rel=1e-12)
    assert pile.grade_volume() == pytest.approx((2.7 * 60 + 0.3 * 70) * SPACING**2, rel=1e-14)


# --- deposition ----------------------------------------------------------------------------


def test_the_footprint_is_bilinear_around_the_point():
    pile = _small_pile()
    weights = footprint(pile, 0.6, 1.1)  # 1.2 and 0.2 spacings beyond the first lines
    assert weights.sum() == pytest.approx(1.0, rel=1e-15)
    assert np.count_nonzero(weights) == 4
    assert weights[2, 1] == pytest.approx(0.8 * 0.8) and weights[3, 2] == pytest.approx(0.2 * 0.2)
    gy, gx = np.meshgrid(pile.y, pile.x, indexing="ij")
    assert (np.sum(weights * gx), np.sum(weights * gy)) == pytest.approx((0.6, 1.1), rel=1e-14)
    assert footprint(pile, 2.0, 1.5)[3, 4] == 1.0  # the last grid lines: the corner cell
    with pytest.raises(ValueError, match="x = 2.1 m lies outside"):
        footprint(pile, 2.1, 1.0)


def test_deposited_at_one_point_a_cone_grows_at_the_angle_of_repose():
    n = 49
    pile = LayeredPile(np.arange(n) * SPACING, np.arange(n) * SPACING)
    talus = Talus.of(SPACING, IRON_ORE.angle_of_repose)
    centre, tonnes = (n - 1) / 2 * SPACING, 0.0
    for period in range(30):  # 2,000 t/h for 30 minutes, a minute at a time, grade changing
        laid = discharge(pile, centre, centre, 2000.0, 60.0, 60.0 + period % 3, IRON_ORE)
        assert laid.relaxed.converged
        tonnes += laid.tonnes
    assert tonnes == pytest.approx(1000.0, rel=1e-14)
    assert pile.volume() == pytest.approx(tonnes / 2.4, rel=1e-12)  # m^3 at 2.4 t/m^3
    assert talus.excess(pile.z) <= talus.tolerance
    tan = math.tan(math.radians(IRON_ORE.angle_of_repose))
    height, middle = pile.z.max(), n // 2
    rays = [(dy, dx) for dy in (-1, 0, 1) for dx in (-1, 0, 1) if (dy, dx) != (0, 0)]
    reaches = []
    for dy, dx in rays:  # the flanks along the grid lines and the diagonals, between 20 and 80 % of the height
        steps = np.arange(middle + 1)
        z = pile.z[middle + dy * steps, middle + dx * steps]
        run = steps * SPACING * math.hypot(dx, dy)
        flank = (z > 0.2 * height) & (z < 0.8 * height)
        assert -np.polyfit(run[flank], z[flank], 1)[0] == pytest.approx(tan, rel=0.01)
        reaches.append(np.mean(run[flank] + z[flank] / tan))  # where the flank meets the floor
    # A regular octagonal pyramid at the angle of repose (bwr_twin.pile.relaxation), its
    # apex a cell across: the flanks meet the floor as far out along the diagonals as the grid
    # lines, and it holds the volume laid.
    reach = np.mean(reaches)
    assert np.ptp(reaches) < 2 * SPACING
    assert pile.volume() == pytest.approx(2 * math.sqrt(2) / 3 * reach**3 * tan, rel=0.05)


def test_a_discharge_refuses_a_negative_rate_and_a_talus_for_another_grid():
    with pytest.raises(ValueError, match="rate"):
        discharge(_small_pile(), 1.0, 1.0, -1.0, 1.0, 60.0, IRON_ORE)
    with pytest.raises(ValueError, match="a grid of 0.25 m, the pile's is 0.5 m"):
        _small_pile().relax(Talus.of(0.25, 37.0))


def test_the_material_comes_from_the_scene():
    section = StockpileSection(bulk_density=2400.0, grid_spacing=0.25, windrow=WindrowSection(10.0, 2.0, 3.0, 38.0, (0.0, 20.0)))
    material = Material.of(section, Path("scene.toml"))
    assert material == Material(2400.0, 38.0)
    assert material.tonnes(material.volume(123.0)) == pytest.approx(123.0, rel=1e-15)
    with pytest.raises(SceneError, match="scene.toml: .*angle_of_repose"):
        Material.of(StockpileSection(bulk_density=2400.0, grid_spacing=0.25, surface_file=Path("survey.npz")), Path("scene.toml"))


# --- the grade stream ----------------------------------------------------------------------


def test_an_ar1_grade_has_its_mean_spread_and_correlation_time():
    stream = Ar1Grade(mean=62.0, sd=1.5, correlation_time=30.0, period=10.0, seed=7)
    values = stream.series(200_000)
    phi = math.exp(-10.0 / 30.0)
    assert stream.phi == pytest.approx(phi)
    # Correlated over 3 periods, 200,000 values weigh as (1 - phi) / (1 + phi) x 200,000 = 33,000
    # independent ones in the mean.
    assert values.mean() == pytest.approx(62.0, abs=4 * 1.5 * math.sqrt((1 + phi) / (1 - phi) / 200_000))
    assert values.std() == pytest.approx(1.5, rel=0.01)
    deviation = values - values.mean()
    for lag in (1, 3):
        correlation = np.mean(deviation[lag:] * deviation[:-lag]) / deviation.var()
        assert correlation == pytest.approx(phi**lag, abs=0.02)
    independent = Ar1Grade(62.0, 1.5, 0.0, 10.0, seed=7).series(200_000)
    assert abs(np.corrcoef(independent[1:], independent[:-1])[0, 1]) < 0.01


def test_an_ar1_grade_is_the_same_for_the_same_seed_however_it_is_asked():
    whole = Ar1Grade(62.0, 1.5, 30.0, 10.0, seed=7).series(10_000)
    asked = Ar1Grade(62.0, 1.5, 30.0, 10.0, seed=7)
    times = np.array([99_995.0, 5.0, 40_960.0, 40_959.0])
    assert asked.at(12.0) == whole[1]  # held over its period
    assert np.array_equal(asked.at(times), whole[[9_999, 0, 4_096, 4_095]])
    assert not np.array_equal(Ar1Grade(62.0, 1.5, 30.0, 10.0, seed=8).series(100), whole[:100])
    with pytest.raises(ValueError, match="t = 0"):
        asked.at(-1.0)


def test_a_recorded_grade_is_a_step_or_a_line_between_its_rows(tmp_path):
    file = tmp_path / "grade.csv"
    file.write_text("t,grade\n0,60\n10,62\n# a comment\n30,58\n")
    step, line = RecordedGrade(file), RecordedGrade(file, interpolation="linear")
    assert [step.at(t) for t in (0.0, 9.9, 10.0, 29.0, 30.0)] == [60.0, 60.0, 62.0, 62.0, 58.0]
    assert list(line.at(np.array([5.0, 20.0, 30.0]))) == [61.0, 60.0, 58.0]
    with pytest.raises(ValueError, match=r"grade.csv: records the grade from t = 0 s to 30 s"):
        step.at(31.0)


@pytest.mark.parametrize("text, message", [
    ("t,grade\n0,60\n10,sixty\n", r"line 3, column 2 \(grade\): 'sixty' is not a finite number"),
    ("0,60\nnan,61\n", r"line 2, column 1 \(t\): 'nan' is not a finite number"),
    ("t,grade\n0,60\n0,61\n", r"line 3, column 1 \(t\): 0 s does not follow 0 s"),
    ("t,grade\n0,60,1\n", r"line 2 must be two numbers t,grade"),
    ("t,grade\n", r"holds no rows"),
])
def test_a_bad_recorded_grade_is_refused_in_one_line_naming_its_place(tmp_path, text, message):
    file = tmp_path / "grade.csv"
    file.write_text(text)
    with pytest.raises(SceneError, match=message) as error:
        RecordedGrade(file)
    assert str(error.value).startswith(str(file)) and "\n" not in str(error.value)
    with pytest.raises(SceneError, match="cannot read"):
        RecordedGrade(tmp_path / "missing.csv")


# --- blending ------------------------------------------------------------------------------


@pytest.mark.parametrize("layers", [16, 32, 64, 128])
def test_a_chevron_pile_of_n_layers_narrows_the_grade_by_sqrt_n(layers):
    result = blend(layers, slices=250, repeats=4, seed=1)  # 1,000 slices: sigma_out within 2.2 %
    assert result.expected * math.sqrt(layers) == pytest.approx(1.0, rel=0.02)  # the grid's layers near equal
    assert result.ratio * math.sqrt(layers) == pytest.approx(1.0, rel=0.15)
    assert result.sigma_in == pytest.approx(1.0, rel=0.02)


def test_merging_layers_changes_no_full_face_slice():
    """A full-face slice takes whole columns: merged layers give it the same tonnes and grade."""
    grades = stacked_grades(24, 40, Ar1Grade(60.0, 1.0, 0.0, 1.0, seed=2))
    roomy, tight = (chevron_pile(grades, 21, 10.0, SPACING, max_layers) for max_layers in (25, 4))
    assert roomy.count.max() == 24 and tight.count.max() == 4
    assert np.allclose(slice_grades(tight), slice_grades(roomy), rtol=1e-13, atol=0)


# --- balances ------------------------------------------------------------------------------


def test_tonnes_and_grade_balance_through_deposits_cuts_and_slumps():
    random = np.random.default_rng(11)
    density = IRON_ORE.bulk_density / 1000.0  # t/m^3
    start = Surface(np.arange(40) * SPACING, np.arange(30) * SPACING, np.zeros((30, 40)))
    start.z[10:20, 10:30] = 2.0  # a block of old ore
    pile = LayeredPile.from_surface(start, grade=61.0, max_layers=6)  # few layers: merges happen
    talus = Talus.of(SPACING, IRON_ORE.angle_of_repose)
    tonnes_in = start.volume() * density
    grade_in = tonnes_in * 61.0
    tonnes_out = grade_out = 0.0
    relaxations = 0
    for step in range(120):
        action = random.choice(["deposit", "cut", "relax"], p=[0.5, 0.3, 0.2])
        if action == "deposit":
            x, y = random.uniform(2.0, 17.5), random.uniform(2.0, 12.5)
            grade = round(random.normal(62.0, 2.0), 1)
            laid = discharge(pile, x, y, random.uniform(500.0, 5000.0), 10.0, grade, IRON_ORE)
            tonnes_in += laid.tonnes
            grade_in += laid.tonnes * grade
            relaxations += 1
            assert laid.relaxed.converged
        elif action == "cut":
            heights = pile.z.copy()
            iy, ix = random.integers(0, 25), random.integers(0, 35)
            region = heights[iy:iy + 6, ix:ix + 6]
            region[:] = np.minimum(region, random.uniform(0.0, 1.0) * region.max())
            removed = pile.cut_to(heights)
            tonnes_out += removed.total_volume * density
            grade_out += removed.grade_volume.sum() * density
        else:
            relaxations += 1
            assert pile.relax(talus).converged
        if action != "cut":
            assert talus.excess(pile.z) <= talus.tolerance
        tonnes_held = pile.volume() * density
        assert tonnes_in == pytest.approx(tonnes_held + tonnes_out, rel=1e-9)
        assert grade_in == pytest.approx(pile.grade_volume() * density + grade_out, rel=1e-9)
        assert np.allclose(pile.z, pile.column_heights(), rtol=0, atol=1e-9)
        assert pile.z.min() >= 0.0 and np.all(pile.count <= 6)
    assert relaxations > 40 and tonnes_out > 0 and pile.count.max() == 6
