"""The fuzzy rule base (paper Sec. 3, Table 2), its skfuzzy definition and the compiled surface."""

import dataclasses
import json

import numpy as np
import pytest
from conftest import SCENES

from bwr_twin.control.fuzzy import (
    CACHE_ENV,
    TARGET_GRID_POINTS,
    FuzzySurface,
    build_control_system,
    default_cache_dir,
    default_grid_points,
    skfuzzy_compute,
)
from bwr_twin.control.rulebase import RuleBase
from bwr_twin.errors import SceneError

PAPER_FILE = SCENES / "rulebases" / "paper_table2.toml"
TABLE_2 = """\
NB NB NM NM NS NS O
NB NM NM NS NS O  PS
NM NM NS NS O  PS PS
NM NS NS O  PS PS PM
NS NS O  PS PS PM PM
NS O  PS PS PM PM PB
O  PS PS PM PM PB PB"""
SMALL_GRID = 25  # 4 cells per set spacing: enough to test caching in well under a second


@pytest.fixture(scope="module")
def rule_base() -> RuleBase:
    return RuleBase.from_toml(PAPER_FILE)


@pytest.fixture(scope="module")
def surface(rule_base, tmp_path_factory) -> FuzzySurface:
    # Built afresh (about 15 s) so that the test covers the build, not a stale cache file.
    return FuzzySurface.load(rule_base, cache_dir=tmp_path_factory.mktemp("fuzzy_cache"))


# -- the rule base ------------------------------------------------------------------------------


def test_paper_rule_base_is_table_2(rule_base):
    assert rule_base.sets == ("NB", "NM", "NS", "O", "PS", "PM", "PB")
    assert rule_base.rules == tuple(tuple(line.split()) for line in TABLE_2.splitlines())
    assert rule_base.e_range == rule_base.ec_range == (-3.0, 3.0)
    assert rule_base.output_range == (-4.5, 4.5)
    assert (rule_base.and_method, rule_base.aggregation, rule_base.defuzzify) == ("min", "max", "centroid")
    digest = rule_base.digest()
    assert len(digest) == 64 and digest == RuleBase.from_toml(PAPER_FILE).digest()


def test_digest_follows_content_not_comments(rule_base, tmp_path):
    bare = tmp_path / "bare.toml"
    lines = [line.split("#")[0].rstrip() for line in PAPER_FILE.read_text().splitlines()]
    bare.write_text("\n".join(line for line in lines if line) + "\n")
    assert RuleBase.from_toml(bare).digest() == rule_base.digest()

    rules = [list(row) for row in rule_base.rules]
    rules[3][3] = "PS"
    changed = dataclasses.replace(rule_base, rules=tuple(tuple(row) for row in rules))
    assert changed.digest() != rule_base.digest()
    assert dataclasses.replace(rule_base, output_range=(-4.0, 4.0)).digest() != rule_base.digest()


def test_skfuzzy_definition(rule_base):
    from skfuzzy import control as ctrl

    system, e, ec, u = build_control_system(rule_base)
    rules = list(system.rules)
    assert len(rules) == 49 and all(r.and_func is np.fmin for r in rules)
    assert u.defuzzify_method == "centroid"
    # The sets are skfuzzy's own evenly spaced automf(7) triangles.
    for var in (e, ec, u):
        reference = ctrl.Antecedent(var.universe, "ref")
        reference.automf(names=list(rule_base.sets))
        for name in rule_base.sets:
            np.testing.assert_array_equal(var[name].mf, reference[name].mf)
    # Table 2, read back from the skfuzzy rules: "IF e is NB AND ec is PB THEN u is O".
    first = {str(t.label) for t in rules[6].antecedent_terms}
    assert first == {"NB", "PB"} and rules[6].consequent[0].term.label == "O"


# -- the compiled surface against skfuzzy ---------------------------------------------------------


def test_surface_matches_skfuzzy(rule_base, surface):
    assert surface.values.shape == (TARGET_GRID_POINTS, TARGET_GRID_POINTS)
    rng = np.random.default_rng(20240611)
    e = rng.uniform(-3.0, 3.0, 1000)
    ec = rng.uniform(-3.0, 3.0, 1000)
    reference = skfuzzy_compute(rule_base, e, ec)  # one compute() call on the arrays
    assert np.abs(surface.evaluate(e, ec) - reference).max() <= 0.01
    # At the grid points the surface is skfuzzy's value itself.
    k = rng.integers(0, TARGET_GRID_POINTS, (2, 50))
    nodes = skfuzzy_compute(rule_base, surface.grid_e[k[0]], surface.grid_ec[k[1]])
    at_nodes = surface.evaluate(surface.grid_e[k[0]], surface.grid_ec[k[1]])
    np.testing.assert_allclose(at_nodes, nodes, atol=1e-12)
    # A scalar call agrees with the array call.
    assert skfuzzy_compute(rule_base, e[0], ec[0]) == pytest.approx(reference[0], abs=1e-12)


def test_fast_path_equals_vectorised(surface):
    rng = np.random.default_rng(3)
    e = rng.uniform(-4.0, 4.0, (400, 3))
    ec = rng.uniform(-4.0, 4.0, (400, 3))
    expected = surface.evaluate(e, ec)
    out = np.empty(3)
    via_evaluate = np.empty(3)
    for k in range(len(e)):
        assert surface.evaluate_into(e[k], ec[k], out) is out
        np.testing.assert_allclose(out, expected[k], atol=1e-12)
        surface.evaluate(e[k], ec[k], out=via_evaluate)
        np.testing.assert_allclose(via_evaluate, expected[k], atol=1e-12)


def test_outside_the_universe_is_clipped(rule_base, surface):
    e = np.array([-7.0, 3.5, 0.4, -np.inf, np.inf, 10.0])
    ec = np.array([0.3, -1.2, 9.0, 1.0, -np.inf, -10.0])
    clipped = surface.evaluate(np.clip(e, -3, 3), np.clip(ec, -3, 3))
    np.testing.assert_array_equal(surface.evaluate(e, ec), clipped)
    out = np.empty(3)
    np.testing.assert_array_equal(surface.evaluate_into(e[:3], ec[:3], out), clipped[:3])
    # skfuzzy saturates the same way.
    np.testing.assert_allclose(skfuzzy_compute(rule_base, e[:3], ec[:3]), clipped[:3], atol=0.01)


def test_nan_in_gives_nan_out(surface):
    e = np.array([np.nan, 0.5, 1.0])
    ec = np.array([0.2, np.nan, 1.0])
    result = surface.evaluate(e, ec)
    assert np.isnan(result[:2]).all() and np.isfinite(result[2])
    out = np.empty(3)
    surface.evaluate_into(e, ec, out)
    assert np.isnan(out[:2]).all() and out[2] == result[2]


def test_table_2_is_odd_symmetric(rule_base, surface):
    rng = np.random.default_rng(11)
    e = rng.uniform(-3.0, 3.0, 2000)
    ec = rng.uniform(-3.0, 3.0, 2000)
    np.testing.assert_allclose(surface.evaluate(-e, -ec), -surface.evaluate(e, ec), atol=0.01)
    assert abs(float(surface.evaluate(0.0, 0.0))) < 1e-9
    assert abs(skfuzzy_compute(rule_base, 0.0, 0.0)) < 1e-9
    # The sign follows the error: a positive error and error rate ask for a positive output.
    assert float(surface.evaluate(1.0, 1.0)) > 0 and float(surface.evaluate(3.0, 3.0)) == pytest.approx(
        float(surface.values[-1, -1])
    )


def test_evaluate_keeps_shapes(surface):
    grid = surface.evaluate(surface.grid_e[:, None], surface.grid_ec[None, :])
    np.testing.assert_allclose(grid, surface.values, atol=1e-12)
    assert surface.evaluate(0.5, 0.5).shape == ()
    out = np.empty((2, 2))
    assert surface.evaluate(np.zeros((2, 2)), 0.1, out=out) is out
    with pytest.raises(ValueError, match="shape"):
        surface.evaluate(np.zeros(3), np.zeros(3), out=np.empty(4))


# -- the cache ------------------------------------------------------------------------------------


def test_cache_is_written_once_and_reused(rule_base, tmp_path, monkeypatch):
    monkeypatch.setenv(CACHE_ENV, str(tmp_path))
    first = FuzzySurface.load(rule_base, grid_points=SMALL_GRID)
    assert first.built and first.cache_path is not None and first.cache_path.parent == tmp_path
    assert [p.name for p in tmp_path.iterdir()] == [first.cache_path.name]  # no temporary file left

    def no_rebuild(*args, **kwargs):
        raise AssertionError("the cache file should have been used")

    monkeypatch.setattr("bwr_twin.control.fuzzy.compute_grid", no_rebuild)
    second = FuzzySurface.load(rule_base, grid_points=SMALL_GRID)
    assert not second.built and second.cache_path == first.cache_path
    np.testing.assert_array_equal(second.values, first.values)
    np.testing.assert_array_equal(second.centres, first.centres)


def test_changed_rule_base_gets_its_own_cache_file(rule_base, tmp_path):
    first = FuzzySurface.load(rule_base, cache_dir=tmp_path, grid_points=SMALL_GRID)
    rules = [list(row) for row in rule_base.rules]
    rules[0][0] = "NM"
    changed = dataclasses.replace(rule_base, rules=tuple(tuple(row) for row in rules))
    second = FuzzySurface.load(changed, cache_dir=tmp_path, grid_points=SMALL_GRID)
    assert second.built and second.cache_path != first.cache_path
    assert rule_base.digest()[:24] in first.cache_path.name
    assert changed.digest()[:24] in second.cache_path.name
    assert second.values[0, 0] > first.values[0, 0]  # NM pulls the corner away from NB


def test_broken_cache_file_is_rebuilt(rule_base, tmp_path):
    first = FuzzySurface.load(rule_base, cache_dir=tmp_path, grid_points=SMALL_GRID)
    first.cache_path.write_bytes(b"half a file")
    again = FuzzySurface.load(rule_base, cache_dir=tmp_path, grid_points=SMALL_GRID)
    assert again.built
    np.testing.assert_array_equal(again.values, first.values)
    assert not FuzzySurface.load(rule_base, cache_dir=tmp_path, grid_points=SMALL_GRID).built


def test_cache_dir_resolution(tmp_path, monkeypatch):
    monkeypatch.setenv(CACHE_ENV, str(tmp_path / "own"))
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert default_cache_dir() == tmp_path / "own"
    monkeypatch.delenv(CACHE_ENV)
    assert default_cache_dir() == tmp_path / "xdg" / "bwr_twin"
    monkeypatch.delenv("XDG_CACHE_HOME")
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    assert default_cache_dir() == tmp_path / "home" / ".cache" / "bwr_twin"


@pytest.mark.parametrize("count", [2, 6])
def test_any_number_of_sets_gets_a_grid_that_fits(count, tmp_path):
    """An even number of sets once crashed the default grid (145 points fit 7 sets only)."""
    names = [f"S{i}" for i in range(count)]
    rows = [[names[min(count - 1, max(0, i + j - count // 2))] for j in range(count)] for i in range(count)]
    rules = ",\n".join(f"  {json.dumps(row)}" for row in rows)
    path = tmp_path / "rules.toml"
    text = PAPER_FILE.read_text()
    start, end = text.index("sets ="), text.index("[universe]")
    path.write_text(text[:start] + f"sets = {names}\nrules = [\n{rules},\n]\n\n" + text[end:])
    rule_base = RuleBase.from_toml(path)
    points = default_grid_points(rule_base)
    assert (points - 1) % (2 * (count - 1)) == 0 and abs(points - TARGET_GRID_POINTS) <= count
    surface = FuzzySurface.load(rule_base, cache_dir=tmp_path)
    assert surface.values.shape == (points, points)
    e, ec = np.array([-2.9, -0.7, 0.0, 1.3]), np.array([2.1, -0.2, 0.0, -2.8])
    np.testing.assert_allclose(surface.evaluate(e, ec), skfuzzy_compute(rule_base, e, ec), atol=0.02)


def test_grid_points_must_fit_the_sets(rule_base, tmp_path):
    with pytest.raises(ValueError, match="grid_points"):
        FuzzySurface.load(rule_base, cache_dir=tmp_path, grid_points=100)


# -- bad rule base files --------------------------------------------------------------------------

ROW_O = '["NM", "NS", "NS", "O",  "PS", "PS", "PM"],  # e = O'
ROW_PS = '["NS", "NS", "O",  "PS", "PS", "PM", "PM"],  # e = PS'
ROW_PB = '["O",  "PS", "PS", "PM", "PM", "PB", "PB"],  # e = PB'


@pytest.mark.parametrize(
    "old, new, key, what",
    [
        ("sets = [", "speed = 3\nsets = [", "speed", "unknown key"),
        ("and = ", "or = 1\nand = ", "inference.or", "unknown key"),
        ("e = [-3.0, 3.0]", 'e = "wide"', "universe.e", "[low, high]"),
        ("output = [-4.5, 4.5]", "output = [4.5, -4.5]", "universe.output", "low must be below high"),
        ("ec = [-3.0, 3.0]", "ec = [1.0, 1.0]", "universe.ec", "low must be below high"),
        (ROW_PB, "", "rules", "7x7"),
        (ROW_O, '["NM", "NS", "NS", "O", "PS", "PS"],', "rules", "row 4 (e = O) has 6 entries"),
        (ROW_PS, '["NS", "NS", "ZE", "PS", "PS", "PM", "PM"],', "rules", "row 5 (e = PS) column 3 (ec = NS)"),
        (ROW_PS, '["NS", "NS", 0, "PS", "PS", "PM", "PM"],', "rules", "unknown set 0"),
        ('sets = ["NB", "NM", "NS", "O", "PS", "PM", "PB"]', "sets = 7", "sets", "list of names"),
        ("input_points = 601", "input_points = 600", "membership.input_points", "k * 12 + 1"),
        ("output_points = 181", 'output_points = "fine"', "membership.output_points", "integer"),
        ('and = "min"', 'and = "product"', "inference.and", "not supported"),
        ('defuzzify = "centroid"', "defuzzify = 2", "inference.defuzzify", "string"),
    ],
)
def test_bad_rule_base_names_file_and_key(tmp_path, old, new, key, what):
    text = PAPER_FILE.read_text()
    assert old in text
    bad = tmp_path / "bad_rules.toml"
    bad.write_text(text.replace(old, new, 1))
    with pytest.raises(SceneError) as info:
        RuleBase.from_toml(bad)
    message = str(info.value)
    assert "\n" not in message
    assert str(bad) in message and f"'{key}'" in message and what in message


def test_unreadable_rule_base_files(tmp_path):
    with pytest.raises(SceneError, match="not found"):
        RuleBase.from_toml(tmp_path / "missing.toml")
    broken = tmp_path / "broken.toml"
    broken.write_text("sets = [\n")
    with pytest.raises(SceneError, match="malformed TOML") as info:
        RuleBase.from_toml(broken)
    assert str(broken) in str(info.value)
    empty = tmp_path / "empty.toml"
    empty.write_text("")
    with pytest.raises(SceneError, match="missing key 'sets'"):
        RuleBase.from_toml(empty)
