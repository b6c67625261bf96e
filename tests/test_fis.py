"""bwr_twin.fis: MATLAB .fis files read, written, evaluated, converted and plotted.

Checked against scikit-fuzzy (membership functions, defuzzification, its Mamdani machinery),
against MATLAB's published numbers (the tipper example of evalfis, the defuzz example) and
against the project's own fuzzy controller (bwr_twin.control.fuzzy) for the paper's rule base.
"""

from __future__ import annotations

import functools
import itertools
import subprocess
import sys
import warnings
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
import pytest
import skfuzzy as fuzz
from conftest import SCENES

from bwr_twin.control.fuzzy import skfuzzy_compute
from bwr_twin.control.rulebase import RuleBase
from bwr_twin.errors import SceneError
from bwr_twin.fis import membership as mf
from bwr_twin.fis.convert import fis_to_rulebase, rulebase_to_fis, rulebase_toml
from bwr_twin.fis.inference import FisWarning, aggregate, defuzzify, evaluate, firing_strengths
from bwr_twin.fis.reader import parse_fis, read_fis
from bwr_twin.fis.system import (
    AGG_METHODS,
    AND_METHODS,
    IMP_METHODS,
    OR_METHODS,
    FuzzySystem,
    MembershipFunction,
    Rule,
    Variable,
)
from bwr_twin.fis.writer import fis_text, write_fis

TIPPER = Path(__file__).resolve().parent / "assets" / "tipper.fis"
PAPER_TOML = SCENES / "rulebases" / "paper_table2.toml"

# scikit-fuzzy's generators with MATLAB's parameter vectors: skfuzzy takes gaussmf and sigmf
# centre first and splits the vectors into arguments.
SK_MF = {
    "trimf": lambda x, p: fuzz.trimf(x, list(p)),
    "trapmf": lambda x, p: fuzz.trapmf(x, list(p)),
    "gaussmf": lambda x, p: fuzz.gaussmf(x, p[1], p[0]),
    "gauss2mf": lambda x, p: fuzz.gauss2mf(x, p[1], p[0], p[3], p[2]),
    "gbellmf": lambda x, p: fuzz.gbellmf(x, p[0], p[1], p[2]),
    "sigmf": lambda x, p: fuzz.sigmf(x, p[1], p[0]),
    "zmf": lambda x, p: fuzz.zmf(x, p[0], p[1]),
    "smf": lambda x, p: fuzz.smf(x, p[0], p[1]),
    "pimf": lambda x, p: fuzz.pimf(x, *p),
}


def run_cli(*args, cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "bwr_twin.fis", *map(str, args)], capture_output=True, text=True, cwd=cwd
    )


# -- membership functions -------------------------------------------------------------------------

MF_CASES = [
    ("trimf", (0, 5, 10)),
    ("trimf", (2, 2, 8)),  # a == b: left shoulder
    ("trimf", (2, 8, 8)),  # b == c: right shoulder
    ("trimf", (3, 3, 3)),  # a == b == c: 1 at the point only
    ("trapmf", (0, 2, 6, 9)),
    ("trapmf", (0, 0, 1, 3)),  # a == b: the tipper's 'rancid'
    ("trapmf", (7, 9, 10, 10)),  # c == d: the tipper's 'delicious'
    ("trapmf", (2, 5, 5, 8)),  # b == c: a triangle
    ("trapmf", (4, 4, 4, 4)),
    ("gaussmf", (1.5, 5)),
    ("gaussmf", (0.3, -2)),
    ("gauss2mf", (1, 3, 2, 7)),
    ("gauss2mf", (1, 4, 2, 4)),  # c1 == c2
    ("gbellmf", (2, 4, 6)),
    ("gbellmf", (1, 0.5, 3)),
    ("sigmf", (2, 4)),
    ("sigmf", (-3, 5)),
    ("zmf", (3, 7)),
    ("smf", (1, 8)),
    ("pimf", (1, 4, 5, 10)),
    ("pimf", (1, 4, 4, 10)),  # b == c
    ("zmf", (5, 5)),  # a == b: a step (degenerate, see below)
    ("smf", (5, 5)),
    ("pimf", (2, 2, 8, 8)),
]


@pytest.mark.parametrize(("mf_type", "params"), MF_CASES, ids=[f"{t}{list(p)}" for t, p in MF_CASES])
def test_membership_functions_match_skfuzzy(mf_type, params):
    # A dense grid that also holds every parameter exactly, where the pieces meet.
    x = np.union1d(np.linspace(-5.0, 15.0, 4001), np.array(params, dtype=float))
    ours = mf.MF_FUNCTIONS[mf_type](x, params)
    with np.errstate(divide="ignore", invalid="ignore"):
        theirs = SK_MF[mf_type](x, params)
    assert mf.param_problem(mf_type, params) is None
    assert ours.shape == x.shape and np.all((ours >= 0) & (ours <= 1))
    # A degenerate spline (smf or zmf with a == b, pimf with a == b or c == d) is a step; at the
    # step itself skfuzzy divides 0 by 0 (NaN, or 0 where a later piece overwrites it) while
    # MATLAB defines it (next test). Everywhere else the two agree.
    steps = [p for p, q in zip(params[::2], params[1::2]) if mf_type in ("smf", "zmf", "pimf") and p == q]
    compared = ~np.isin(x, steps)
    assert np.isfinite(theirs[compared]).all()
    np.testing.assert_allclose(ours[compared], theirs[compared], rtol=0, atol=1e-12)


def test_degenerate_steps_follow_matlab():
    # Where skfuzzy has no value (a == b for smf and zmf) or refuses the parameters (trapmf with
    # b > c, gauss2mf with c1 > c2, smf and zmf with a > b), MATLAB's functions define one.
    x = np.array([4.99, 5.0, 5.01])
    np.testing.assert_array_equal(mf.smf(x, (5, 5)), [0, 1, 1])  # smf: 1 where x >= (a + b) / 2
    np.testing.assert_array_equal(mf.zmf(x, (5, 5)), [1, 1, 0])  # zmf: 1 where x <= (a + b) / 2
    np.testing.assert_array_equal(mf.smf(x, (6, 4)), [0, 1, 1])
    np.testing.assert_array_equal(mf.zmf(x, (6, 4)), [1, 1, 0])
    np.testing.assert_array_equal(mf.pimf(x, (5, 5, 5, 5)), [0, 1, 0])
    # trapmf [0 6 4 10]: the ramps cross below 1, at x = 5 where both are 5/6.
    assert mf.trapmf([5.0], (0, 6, 4, 10))[0] == pytest.approx(5 / 6, abs=1e-15)
    # gauss2mf [1 6 1 4]: between c2 = 4 and c1 = 6 both halves apply and multiply.
    assert mf.gauss2mf([5.0], (1, 6, 1, 4))[0] == pytest.approx(np.exp(-1.0), abs=1e-15)
    # Shoulders: trimf [0 0 10] is 1 at 0, trapmf [0 0 1 3] is 1 on [0, 1].
    np.testing.assert_array_equal(mf.trimf([-0.1, 0.0, 5.0], (0, 0, 10)), [0, 1, 0.5])
    np.testing.assert_array_equal(mf.trapmf([-0.1, 0.0, 1.0, 2.0], (0, 0, 1, 3)), [0, 1, 1, 0.5])


@pytest.mark.parametrize(
    ("mf_type", "params", "words"),
    [
        ("triangle", (0, 1, 2), "unknown membership function type 'triangle'"),
        ("trimf", (0, 5), "trimf takes 3 parameters [a b c], got 2"),
        ("trimf", (0, 5, 3), "a <= b <= c"),
        ("trapmf", (3, 1, 4, 5), "a <= b and c <= d"),
        ("gaussmf", (0, 5), "sigma != 0"),
        ("gbellmf", (0, 2, 5), "a != 0"),
        ("sigmf", (np.inf, 5), "finite"),
    ],
)
def test_parameter_problems_are_named(mf_type, params, words):
    assert words in mf.param_problem(mf_type, params)


# -- defuzzification --------------------------------------------------------------------------------


def padded_defuzz(y: np.ndarray, values: np.ndarray, method: str) -> float:
    """skfuzzy's defuzz of a sampled set, made to take MATLAB's sums.

    skfuzzy integrates the piecewise-linear set (trapezoids); MATLAB sums the samples. On an even
    grid the trapezoids weigh every interior sample by the step, the two end samples by half of
    it; padding the set with a zero sample beyond each end makes every sample interior, so
    skfuzzy's centroid becomes MATLAB's exactly (and its bisector the continuous version of
    MATLAB's, within one step of it).
    """
    if method in ("centroid", "bisector"):
        dy = y[1] - y[0]
        return fuzz.defuzz(np.r_[y[0] - dy, y, y[-1] + dy], np.r_[0.0, values, 0.0], method)
    return fuzz.defuzz(y, values, method)


def test_defuzzification_matches_skfuzzy():
    rng = np.random.default_rng(3)
    y = np.linspace(0.0, 30.0, 101)  # a non-negative universe: MATLAB's som/lom by magnitude = min/max
    sets = []
    for _ in range(200):
        values = np.zeros_like(y)
        for _ in range(rng.integers(1, 4)):
            a, b, c = np.sort(rng.uniform(-5, 35, 3))
            values = np.maximum(values, np.minimum(rng.uniform(0.05, 1), fuzz.trimf(y, [a, b, c])))
        if rng.random() < 0.3:  # a set that is not zero at the ends
            values = np.maximum(values, rng.uniform(0, 1) * mf.gaussmf(y, (8, rng.uniform(0, 30))))
        sets.append(values)
    sets = np.array(sets)
    sets = sets[sets.sum(axis=1) > 0]
    for method in ("centroid", "bisector", "mom", "som", "lom"):
        ours = defuzzify(y, sets, method)
        theirs = np.array([padded_defuzz(y, values, method) for values in sets])
        # bisector: MATLAB picks the first sample at which the running sum reaches half the total,
        # the continuous bisector lies between the neighbouring samples: within one step.
        tolerance = (y[1] - y[0]) * (1 + 1e-9) if method == "bisector" else 1e-9
        np.testing.assert_allclose(ours, theirs, rtol=0, atol=tolerance, err_msg=method)
    assert np.isnan(defuzzify(y, np.zeros((1, len(y))), "centroid")).all()


def test_defuzzification_matlab_published_example():
    # MATLAB's documentation, "Defuzzification Methods": x = -10:0.1:10,
    # mf = max(0.5 trapmf(x,[-5 -3 2 4]), max(0.9 trapmf(x,[-10 -8 -2 2]), 0.1 trapmf(x,[2 3 8 9]))),
    # published results mom = -5, som = -2, lom = -8: on the plateau [-8, -2] MATLAB's som and lom
    # pick the smallest and largest value in magnitude, not on the axis.
    x = np.arange(-100, 101) / 10.0
    values = np.maximum(
        0.5 * mf.trapmf(x, (-5, -3, 2, 4)),
        np.maximum(0.9 * mf.trapmf(x, (-10, -8, -2, 2)), 0.1 * mf.trapmf(x, (2, 3, 8, 9))),
    )
    published = {"mom": -5.0, "som": -2.0, "lom": -8.0}
    for method, value in published.items():
        assert round(float(defuzzify(x, values, method)[0]), 4) == value, method


# -- inference against scikit-fuzzy ---------------------------------------------------------------


def random_system(rng: np.random.Generator, methods: tuple[str, ...]) -> FuzzySystem:
    """Two or three inputs of mixed set types, one or two outputs, rules with NOT, don't care, OR
    and weights."""

    def variable(name: str, low: float, width: float, types: tuple[str, ...]) -> Variable:
        high = low + width
        sets = []
        for k in range(rng.integers(2, 5)):
            kind = types[rng.integers(len(types))]
            centre = rng.uniform(low, high)
            spread = rng.uniform(0.05, 0.4) * width
            if kind in ("trimf", "trapmf", "zmf", "smf", "pimf"):
                n = len(mf.MF_PARAMS[kind])
                params = np.sort(rng.uniform(low - 0.2 * width, high + 0.2 * width, n))
            elif kind == "gaussmf":
                params = (spread, centre)
            elif kind == "gauss2mf":
                c1, c2 = np.sort(rng.uniform(low, high, 2))
                params = (spread, c1, rng.uniform(0.05, 0.4) * width, c2)
            elif kind == "gbellmf":
                params = (spread, rng.uniform(0.5, 4), centre)
            else:  # sigmf
                params = (rng.choice([-1, 1]) * rng.uniform(2, 20) / width, centre)
            sets.append(MembershipFunction(f"{name}{k + 1}", kind, tuple(float(p) for p in params)))
        return Variable(name, (low, high), tuple(sets))

    inputs = tuple(
        variable(f"in{j + 1}", rng.uniform(-10, 10), rng.uniform(2, 20), tuple(mf.MF_PARAMS))
        for j in range(rng.integers(2, 4))
    )
    # Outputs on non-negative ranges, where MATLAB's som / lom (by magnitude) are skfuzzy's (min / max).
    outputs = tuple(
        variable(f"out{o + 1}", rng.uniform(0, 5), rng.uniform(5, 20), ("trimf", "trapmf", "gaussmf"))
        for o in range(rng.integers(1, 3))
    )
    rules = []
    for _ in range(rng.integers(3, 9)):
        antecedent = tuple(int(rng.integers(-len(v.mfs), len(v.mfs) + 1)) for v in inputs)
        consequent = tuple(int(rng.integers(-len(v.mfs), len(v.mfs) + 1)) for v in outputs)
        weight = 1.0 if rng.random() < 0.5 else float(rng.uniform(0.1, 1))
        rules.append(Rule(antecedent, consequent, weight, int(rng.integers(1, 3))))
    names = ("and_method", "or_method", "imp_method", "agg_method", "defuzz_method")
    return FuzzySystem("random", inputs, outputs, tuple(rules), **dict(zip(names, methods)))


def skfuzzy_mamdani(system: FuzzySystem, row: np.ndarray, points: int) -> list[float]:
    """One row through Mamdani inference built from skfuzzy's parts: its membership functions
    fuzzify and sample the sets, np.fmin / np.fmax combine them, skfuzzy's defuzz concludes."""

    def probor(a, b):
        return a + b - a * b

    def member(mf_: MembershipFunction, x) -> np.ndarray:
        return SK_MF[mf_.type](np.atleast_1d(np.asarray(x, dtype=float)), mf_.params)

    mus = [[member(m, row[j])[0] for m in v.mfs] for j, v in enumerate(system.inputs)]
    strengths = []
    for rule in system.rules:
        values = []
        for j, index in enumerate(rule.antecedent):
            if index > 0:
                values.append(mus[j][index - 1])
            elif index < 0:
                values.append(1.0 - mus[j][-index - 1])
            else:
                values.append(1.0 if rule.connection == 1 else 0.0)
        if rule.connection == 1:
            join = np.fmin if system.and_method == "min" else np.multiply
        else:
            join = np.fmax if system.or_method == "max" else probor
        strengths.append(functools.reduce(join, values) * rule.weight)
    crisp = []
    for o, variable in enumerate(system.outputs):
        y = np.linspace(*variable.range, points)
        total = np.zeros(points)
        for rule, strength in zip(system.rules, strengths):
            index = rule.consequent[o]
            if index == 0:
                continue
            shape = member(variable.mfs[abs(index) - 1], y)
            shape = shape if index > 0 else 1.0 - shape
            implied = np.fmin(strength, shape) if system.imp_method == "min" else strength * shape
            if system.agg_method == "max":
                total = np.fmax(total, implied)
            elif system.agg_method == "sum":
                total = total + implied
            else:
                total = probor(total, implied)
        if total.sum() == 0:
            crisp.append(0.5 * sum(variable.range))  # nothing fired: the middle, as MATLAB
        else:
            crisp.append(padded_defuzz(y, total, system.defuzz_method))
    return crisp


@pytest.mark.parametrize("defuzz_method", ["centroid", "bisector", "mom", "som", "lom"])
def test_inference_matches_skfuzzy(defuzz_method):
    combos = list(itertools.product(AND_METHODS, OR_METHODS, IMP_METHODS, AGG_METHODS))
    for c, combo in enumerate(combos):
        rng = np.random.default_rng(100 * c + len(defuzz_method))
        system = random_system(rng, combo + (defuzz_method,))
        rows = np.column_stack([rng.uniform(*v.range, 25) for v in system.inputs])
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", FisWarning)  # random rules may leave an output unfired
            ours = evaluate(system, rows)
        theirs = np.array([skfuzzy_mamdani(system, row, 101) for row in rows])
        steps = np.array([(v.range[1] - v.range[0]) / 100 for v in system.outputs])
        tolerance = steps * (1 + 1e-9) if defuzz_method == "bisector" else 1e-9  # see padded_defuzz
        assert np.all(np.abs(ours - theirs) <= tolerance), (combo, np.abs(ours - theirs).max())


def test_paper_fis_agrees_with_the_project_controller():
    rule_base = RuleBase.from_toml(PAPER_TOML)
    system = parse_fis(fis_text(rulebase_to_fis(rule_base)), "paper.fis")
    rng = np.random.default_rng(11)
    e, ec = rng.uniform(-3, 3, 150), rng.uniform(-3, 3, 150)
    reference = skfuzzy_compute(rule_base, e, ec)  # what FuzzySurface is built from
    rows = np.column_stack([e, ec])
    points = rule_base.output_points  # 181, the controller's sampling of the output, not evalfis' 101
    ours = evaluate(system, rows, points=points)[:, 0]
    # Same sets, rules and samples; the centroids still differ in how they integrate the set:
    # MATLAB sums the 181 samples, skfuzzy integrates the piecewise-linear set exactly, on the
    # samples plus the points where each clipped set crosses its cut. That costs (1) the end
    # samples, which the integral weighs half: where NB or PB fires, the set is up to 1 at the
    # range end and the centroid moves outwards by up to about
    #   1/2 (mu_0 |y_0 - c| + mu_n |y_n - c|) / sum(mu)  (~0.02 for 181 samples; 0.035 for 101),
    # which is exactly the difference between our centroid and skfuzzy's defuzz of our samples;
    # and (2) the cut crossings between samples (skfuzzy's defuzz of our samples against its
    # control system: measured 5e-4 for 181 samples; allowed 1e-3).
    y, total = aggregate(system, firing_strengths(system, rows), 0, points)
    trapezoids = np.array([fuzz.defuzz(y, values, "centroid") for values in total])
    assert np.abs(trapezoids - reference).max() < 1e-3
    assert np.all(np.abs(ours - reference) <= np.abs(ours - trapezoids) + 1e-3)
    assert np.abs(ours - reference).max() < 0.025
    # Both converge to the same surface: on 10x finer samples the gap shrinks about tenfold.
    fine = evaluate(system, rows, points=10 * (points - 1) + 1)[:, 0]
    assert np.abs(fine - reference).max() < 3e-3


def test_tipper_matches_matlab_published_evalfis():
    system = read_fis(TIPPER)
    assert [v.name for v in system.inputs] == ["service", "food"] and system.outputs[0].name == "tip"
    assert system.inputs[0].mfs[1] == MembershipFunction("good", "gaussmf", (1.5, 5.0))
    assert system.inputs[1].mfs[0] == MembershipFunction("rancid", "trapmf", (0.0, 0.0, 1.0, 3.0))
    assert system.rules[1] == Rule((2, 0), (2,), 1.0, 1)
    # MATLAB's evalfis documentation, examples on fis = readfis("tipper"):
    #   evalfis(fis,[2 1]) -> 7.0169, and for the rows [2 1; 4 5; 7 8] -> 7.0169, 14.4585, 20.3414
    # (published to 4 decimals; evalfis' default of 101 output samples).
    assert round(float(evaluate(system, [2, 1])[0, 0]), 4) == 7.0169
    outputs = evaluate(system, [[2, 1], [4, 5], [7, 8]])
    assert outputs.shape == (3, 1)
    assert [round(float(v), 4) for v in outputs[:, 0]] == [7.0169, 14.4585, 20.3414]


def test_out_of_range_inputs_are_clipped_and_unfired_outputs_take_the_middle():
    tipper = read_fis(TIPPER)
    with pytest.warns(FisWarning, match=r"input 1 'service': 1 of 2 values outside its range \[0, 10\]"):
        clipped = evaluate(tipper, [[12, 3], [10, 3]])
    assert clipped[0, 0] == clipped[1, 0]
    assert np.isnan(evaluate(tipper, [[np.nan, 3]])).all()
    lonely = FuzzySystem(
        "lonely",
        (Variable("x", (0.0, 10.0), (MembershipFunction("low", "trimf", (0.0, 1.0, 2.0)),)),),
        (Variable("y", (2.0, 4.0), (MembershipFunction("any", "trimf", (2.0, 3.0, 4.0)),)),),
        (Rule((1,), (1,)),),
    )
    with pytest.warns(FisWarning, match="no rule fired for 1 of 2 input rows; the output is the middle"):
        result = evaluate(lonely, [[5.0], [1.0]])
    assert result[0, 0] == 3.0  # MATLAB: "the defuzzified value of that output is the midpoint of its range"
    assert result[1, 0] == pytest.approx(3.0)


def test_many_rows_evaluate_in_blocks_exactly_as_one_at_a_time():
    # 250 rows at 20,001 output samples go through evaluate() in three blocks of 99 rows; the
    # reference evaluates each row alone. Out-of-range and NaN rows included.
    methods = [("min", "max", "min", "max", "centroid"), ("prod", "probor", "prod", "sum", "bisector"),
               ("min", "max", "prod", "probor", "mom")]
    for seed, methods in enumerate(methods):
        rng = np.random.default_rng(seed)
        system = random_system(rng, methods)
        rows = np.column_stack([rng.uniform(v.range[0] - 1, v.range[1] + 1, 250) for v in system.inputs])
        rows[7, 0] = np.nan
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", FisWarning)
            together = evaluate(system, rows, points=20_001)
            alone = np.vstack([evaluate(system, row, points=20_001) for row in rows])
        np.testing.assert_array_equal(together, alone)
        assert np.isnan(together[7]).all() and not np.isnan(np.delete(together, 7, axis=0)).any()


# -- reading and writing ----------------------------------------------------------------------------

QUIRKS = (
    "% comments before the first section, and an indented one:\r\n"
    "   % no Version key anywhere; CRLF line ends; spaces and tabs around '='\r\n"
    "\r\n"
    "[System]\r\n"
    "Name='quirks'\r\n"
    "Type = 'mamdani'\r\n"
    "NumInputs=2\r\n"
    "NumOutputs =1\r\n"
    "NumRules= 3\r\n"
    "AndMethod\t=\t'min'\r\n"
    "DefuzzMethod='mom'\r\n"
    "% OrMethod, ImpMethod and AggMethod missing: MATLAB's defaults max, min, max\r\n"
    "\r\n"
    "[Input1]\r\n"
    "Name='a'\r\n"
    "Range=[0 10]\r\n"
    "NumMFs=2\r\n"
    "MF1='lo':'trimf',[0 0 10]\r\n"
    "MF2='hi':'trimf',[0 10 10]\r\n"
    "\r\n"
    "[Input2]\r\n"
    "Name = 'b'\r\n"
    "Range = [0, 10]\r\n"
    "MF1 = 'lo' : 'trimf' , [0 0 10]\r\n"
    "MF2='hi':'trimf',[0 10 10]\r\n"
    "\r\n"
    "[Output1]\r\n"
    "Name='y'\r\n"
    "Range=[0 10]\r\n"
    "NumMFs=2\r\n"
    "MF1='small':'trimf',[0 0 5]\r\n"
    "MF2='big':'trimf',[5 10 10]\r\n"
    "\r\n"
    "[Rules]\r\n"
    "% NOT a is lo (b: don't care) -> small, weight 0.5\r\n"
    "-1 0, 1 (0.5) : 1\r\n"
    "% a is lo OR b is hi -> big\r\n"
    "1 2, 2 (1) : 2\r\n"
    "% a is hi AND b is NOT hi -> y is NOT big, weight 0.25\r\n"
    "2   -2 ,  -2  (0.25)  :  1\r\n"
)


def test_reader_quirks():
    system = parse_fis(QUIRKS, "quirks.fis")
    assert system.name == "quirks"
    assert (system.and_method, system.or_method, system.imp_method, system.agg_method) == (
        "min",
        "max",
        "min",
        "max",
    )
    assert system.defuzz_method == "mom"
    assert system.inputs[1].range == (0.0, 10.0) and system.inputs[1].mfs[0].name == "lo"
    assert system.rules == (
        Rule((-1, 0), (1,), 0.5, 1),
        Rule((1, 2), (2,), 1.0, 2),
        Rule((2, -2), (-2,), 0.25, 1),
    )
    # By hand at a = 2.5, b = 3: a lo 0.75, hi 0.25; b lo 0.7, hi 0.3.
    # Rule 1: NOT 0.75 AND (don't care 1) = 0.25, times 0.5 -> 0.125.
    # Rule 2: 0.75 OR 0.3 = 0.75.   Rule 3: 0.25 AND NOT 0.3 = 0.25, times 0.25 -> 0.0625.
    np.testing.assert_allclose(firing_strengths(system, [2.5, 3.0])[0], [0.125, 0.75, 0.0625], atol=1e-15)
    # The aggregate peaks at 0.75 where 'big' clipped at 0.75 is flat: y >= 8.75, the samples
    # 8.8 .. 10.0 of 101; their mean (mom) is 9.4.
    assert evaluate(system, [2.5, 3.0])[0, 0] == pytest.approx(9.4, abs=1e-12)
    lines = QUIRKS.splitlines()
    assert system.lines["rule3"] == lines.index("2   -2 ,  -2  (0.25)  :  1") + 1
    assert system.lines["input2.mf1"] == lines.index("MF1 = 'lo' : 'trimf' , [0 0 10]") + 1


def test_fis_round_trip(tmp_path):
    tipper = read_fis(TIPPER)
    text = fis_text(tipper)
    again = parse_fis(text, "again.fis")
    assert again == tipper
    assert fis_text(again) == text  # writing is a fixed point
    assert text.startswith("[System]\nName='tipper'\nType='mamdani'\nVersion=2.0\nNumInputs=2\n")
    assert "MF1='poor':'gaussmf',[1.5 0]\n" in text and "\n[Rules]\n1 1, 1 (1) : 2\n" in text

    quirks = parse_fis(QUIRKS, "quirks.fis")
    # Awkward floats read back bit for bit.
    awkward = FuzzySystem(
        "awkward",
        quirks.inputs[:1]
        + (Variable("z", (-1e-16, 1 / 3), (MembershipFunction("g", "gaussmf", (0.1, 2e20)),)),),
        quirks.outputs,
        (Rule((-1, 0), (1,), 0.5, 1), Rule((1, 1), (2,), 1.0, 2), Rule((0, -1), (-2,), 1 / 3, 2)),
        or_method="probor",
        imp_method="prod",
        agg_method="probor",
        defuzz_method="bisector",
    )
    path = tmp_path / "awkward.fis"
    write_fis(awkward, path, comments=["written by a test", "second line"])
    assert path.read_text().startswith("% written by a test\n% second line\n\n[System]\n")
    assert read_fis(path) == awkward
    assert read_fis(path).inputs[1].range == (-1e-16, 1 / 3)


def test_paper_rule_base_round_trips_through_fis(tmp_path):
    rule_base = RuleBase.from_toml(PAPER_TOML)
    system = rulebase_to_fis(rule_base)
    assert system.inputs[0].mfs[0] == MembershipFunction("NB", "trimf", (-3.0, -3.0, -2.0))
    assert system.outputs[0].mfs[-1] == MembershipFunction("PB", "trimf", (3.0, 4.5, 4.5))
    back = fis_to_rulebase(parse_fis(fis_text(system), "paper.fis"))
    assert back == rule_base and back.digest() == rule_base.digest()
    toml = tmp_path / "back.toml"
    toml.write_text(rulebase_toml(back, "paper.fis"))
    assert RuleBase.from_toml(toml).digest() == rule_base.digest()
    assert "converted by `python -m bwr_twin.fis convert` from paper.fis" in toml.read_text()


def _paper_fis_lines() -> list[str]:
    return fis_text(rulebase_to_fis(RuleBase.from_toml(PAPER_TOML))).splitlines()


def _edit(lines: list[str], old: str, new: str | None) -> tuple[str, int]:
    index = lines.index(old)
    edited = lines[:index] + ([] if new is None else [new]) + lines[index + 1 :]
    return "\n".join(edited) + "\n", index + 1


@pytest.mark.parametrize(
    ("old", "new", "words"),
    [
        ("MF2='NM':'trimf',[-3 -2 -1]", "MF2='NM':'gaussmf',[0.5 -2]", "non-triangular sets"),
        ("MF2='NM':'trimf',[-3 -2 -1]", "MF2='NM':'trimf',[-3 -2.1 -1]", "unevenly spaced sets"),
        ("1 1, 1 (1) : 1", "1 1, 1 (0.5) : 1", "weights other than 1"),
        ("1 1, 1 (1) : 1", "1 1, 1 (1) : 2", "OR rules"),
        ("1 1, 1 (1) : 1", "1 0, 1 (1) : 1", "don't care"),
        ("1 2, 1 (1) : 1", "1 1, 1 (1) : 1", "rule 2 repeats the inputs of rule 1"),
        ("ImpMethod='min'", "ImpMethod='prod'", "ImpMethod 'prod'"),
        ("DefuzzMethod='centroid'", "DefuzzMethod='mom'", "DefuzzMethod 'mom'"),
    ],
)
def test_conversion_refuses_what_toml_cannot_express(old, new, words):
    text, line = _edit(_paper_fis_lines(), old, new)
    system = parse_fis(text, "edited.fis")
    with pytest.raises(SceneError) as info:
        fis_to_rulebase(system)
    message = str(info.value)
    assert (
        message.startswith(f"edited.fis:{line}: ") and words in message and "cannot be expressed" in message
    )
    assert "\n" not in message


def test_conversion_refuses_missing_rules_and_three_inputs():
    lines = _paper_fis_lines()
    text, _ = _edit(lines, "NumRules=49", "NumRules=48")
    text, _ = _edit(text.splitlines(), "4 4, 4 (1) : 1", None)
    with pytest.raises(
        SceneError, match=r"1 of the 7x7 rules are missing, the first for input 1 = O and input 2 = O"
    ):
        fis_to_rulebase(parse_fis(text, "gap.fis"))
    three = read_fis(TIPPER)
    three = FuzzySystem(
        three.name,
        three.inputs * 2 + three.inputs[:1],
        three.outputs,
        (),
        path=Path("t.fis"),
        lines={"NumInputs": 9},
    )
    with pytest.raises(SceneError, match=r"^t\.fis:9: 5 inputs cannot be expressed in a TOML rule base"):
        fis_to_rulebase(three)


@pytest.mark.parametrize(
    ("old", "new", "words"),
    [
        ("NumMFs = 2", "NumMFs = 3", "NumMFs=3 but [Input2] holds 2 MF lines"),
        ("1 1, 1 (1) : 2", "1 1, 1 (1.5) : 2", "weight 1.5 is outside [0, 1]"),
        ("1 1, 1 (1) : 2", "1 1, 1 (1) : 3", "connection '3' must be 1 (AND) or 2 (OR)"),
        ("1 1, 1 (1) : 2", "1 1 1 1 2", "must look like '1 2, 1 (1) : 1'"),
        ("1 1, 1 (1) : 2", "1.5 1, 1 (1) : 2", "'1.5' is not a whole number"),
        ("Name = 'food'", "Name = food", "must be a quoted string"),
        ("NumRules = 3", "NumRules = 4", "NumRules=4 but [Rules] holds 3 rules"),
        ("[Output1]", "[Outputs]", "unknown section '[Outputs]'"),
        ("MF1 = 'cheap':'trimf',[0 5 10]", "MF1 = 'cheap':'trimf',[0 15 10]", "trimf needs a <= b <= c"),
        ("Range = [0 30]", "Range = [30 0]", "low < high"),
    ],
)
def test_reader_errors_name_file_and_line(old, new, words):
    text, line = _edit(TIPPER.read_text().splitlines(), old, new)
    with pytest.raises(SceneError) as info:
        parse_fis(text, "bad.fis")
    message = str(info.value)
    assert message.startswith(f"bad.fis:{line}: ") and words in message and "\n" not in message


# -- the command line -------------------------------------------------------------------------------


def test_cli_evaluate_prints_like_evalfis(tmp_path):
    done = run_cli("evaluate", TIPPER, 2, 1, cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    assert done.stdout == "output = 7.0169\n" and done.stderr == ""


def test_cli_evaluates_every_row_of_a_csv_file_or_stdin(tmp_path):
    # MATLAB's published rows (evalfis(fis, [2 1; 4 5; 7 8])), in a file saved by a Windows editor
    # (byte-order mark, CRLF, a quoted header, a blank line) and piped without a header.
    (tmp_path / "points.csv").write_bytes(b'\xef\xbb\xbf"service","food"\r\n2,1\r\n\r\n4, 5\r\n7,8\r\n')
    done = run_cli("evaluate", TIPPER, "--input", "points.csv", cwd=tmp_path)
    assert done.returncode == 0 and done.stderr == "", done.stderr
    assert done.stdout == "service,food,tip\n2,1,7.0169\n4,5,14.4585\n7,8,20.3414\n"
    piped = subprocess.run([sys.executable, "-m", "bwr_twin.fis", "evaluate", str(TIPPER), "--input", "-",
                            "--digits", "2"], input="2,1\n12,3\n", capture_output=True, text=True,
                           cwd=tmp_path)
    assert piped.returncode == 0, piped.stderr
    clipped = evaluate(read_fis(TIPPER), [10, 3])[0, 0]
    assert piped.stdout == f"service,food,tip\n2,1,7.02\n12,3,{clipped:.2f}\n"
    assert piped.stderr.startswith("warning: input 1 'service': 1 of 2 values outside its range [0, 10]")
    assert piped.stderr.count("\n") == 1
    # The converted paper rule base: each row of a thousand as evaluate() gives it alone.
    rng = np.random.default_rng(5)
    rows = rng.uniform(-3, 3, (1000, 2)).tolist()
    (tmp_path / "paper.csv").write_text("e,ec\n" + "".join(f"{e!r},{ec!r}\n" for e, ec in rows))
    done = run_cli("evaluate", PAPER_TOML, "--input", "paper.csv", "--digits", "6", cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    lines = done.stdout.splitlines()
    assert lines[0] == "e,ec,u" and len(lines) == 1001
    system = rulebase_to_fis(RuleBase.from_toml(PAPER_TOML))
    for line, row in zip(lines[1:], rows):
        assert line == f"{row[0]!r},{row[1]!r},{evaluate(system, row)[0, 0]:.6f}"


def test_cli_refuses_a_bad_row_naming_the_file_line_row_and_column(tmp_path):
    (tmp_path / "points.csv").write_text("service,food\n2,1\n\n4,x\n7,8\n")
    done = run_cli("evaluate", TIPPER, "--input", "points.csv", cwd=tmp_path)
    assert done.returncode == 2 and done.stdout == "" and "Traceback" not in done.stderr
    assert done.stderr == ("error: points.csv:4: row 2, column 2: 'x' is not a finite number "
                           "(input 2 'food', range [0 10])\n")
    piped = subprocess.run([sys.executable, "-m", "bwr_twin.fis", "evaluate", str(TIPPER), "--input", "-"],
                           input="2,1\n4,5,6\n", capture_output=True, text=True, cwd=tmp_path)
    assert piped.returncode == 2 and piped.stdout == ""
    assert piped.stderr == ("error: <stdin>:2: row 2 has 3 values; the system has 2 inputs "
                            "('service', 'food'), one value each, separated by commas\n")


def test_cli_convert_round_trip(tmp_path):
    toml = tmp_path / "paper_table2.toml"
    toml.write_bytes(PAPER_TOML.read_bytes())
    done = run_cli("convert", toml.name, "paper.fis", cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    fis = (tmp_path / "paper.fis").read_text()
    assert fis.startswith("% written by bwr_twin.fis\n% Converted by `python -m bwr_twin.fis convert` from "
                          "paper_table2.toml.\n")
    done = run_cli("convert", "paper.fis", "back.toml", cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    assert "paper.fis -> back.toml: 2 inputs, 1 output, 49 rules" in done.stdout
    back = RuleBase.from_toml(tmp_path / "back.toml")
    assert back.digest() == RuleBase.from_toml(PAPER_TOML).digest()
    assert "from paper.fis." in (tmp_path / "back.toml").read_text()


def test_cli_surface_writes_a_png(tmp_path):
    done = run_cli("surface", TIPPER, "--out", "tipper.png", "--grid", 11, cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    picture = (tmp_path / "tipper.png").read_bytes()
    assert picture[:8] == b"\x89PNG\r\n\x1a\n" and len(picture) > 20_000
    # no temporary file left; the manifest beside it records what the twin wrote
    assert sorted(p.name for p in tmp_path.iterdir()) == [".tipper.png.bwr_twin", "tipper.png"]


def test_cli_refuses_unsafe_outputs(tmp_path):
    source = tmp_path / "tipper.fis"
    source.write_bytes(TIPPER.read_bytes())
    before = source.read_bytes()
    (tmp_path / "taken.fis").write_text("keep me\n")
    cases = [
        (("convert", "tipper.fis", "tipper.fis"), "tipper.fis: is the input file itself"),
        (
            ("convert", "tipper.fis", "taken.fis"),
            "taken.fis: already exists; choose another output or pass --overwrite",
        ),
        (
            ("convert", "tipper.fis", "missing/out.fis"),
            "missing/out.fis: the directory missing does not exist",
        ),
        (("convert", "tipper.fis", "out.txt"), "out.txt: unknown output suffix '.txt' (known: .fis, .toml, .fcl, .fll)"),
    ]
    with ThreadPoolExecutor(max_workers=2) as pool:
        results = list(pool.map(lambda case: run_cli(*case[0], cwd=tmp_path), cases))
    for (args, words), done in zip(cases, results):
        assert done.returncode == 2, args
        assert done.stdout == "" and done.stderr.count("\n") == 1 and done.stderr.startswith("error: "), args
        assert words in done.stderr, (args, done.stderr)
    assert source.read_bytes() == before
    assert (tmp_path / "taken.fis").read_text() == "keep me\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["taken.fis", "tipper.fis"]


def test_cli_main_refusals_and_overwrite(tmp_path, capsys, monkeypatch):
    # The same entry point in-process, for the cases beyond the subprocess ones above.
    from bwr_twin.fis.__main__ import main

    monkeypatch.chdir(tmp_path)
    source = tmp_path / "tipper.fis"
    source.write_bytes(TIPPER.read_bytes())
    before = source.read_bytes()
    (tmp_path / "taken.fis").write_text("keep me\n")
    cases = [
        (["convert", "tipper.fis", "./tipper.fis", "--overwrite"], "tipper.fis: is the input file itself"),
        (["convert", "tipper.fis", "out.toml"], "error: tipper.fis:29: input 2 'food' has sets"),
        (["surface", "tipper.fis", "--out", "tipper.fis"], "unknown picture suffix '.fis'"),
        (["evaluate", "tipper.fis", "2"], "the system has 2 inputs ('service', 'food'), got 1 values"),
        (
            ["evaluate", "tipper.fis", "2", "x"],
            "X2 'x' is not a finite number (input 2 'food', range [0 10])",
        ),
        (["evaluate", "nowhere.fis", "2", "1"], "nowhere.fis: .fis file not found"),
    ]
    for args, words in cases:
        assert main(args) == 2, args
        captured = capsys.readouterr()
        assert captured.out == "" and captured.err.count("\n") == 1 and words in captured.err, (
            args,
            captured,
        )
    assert source.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["taken.fis", "tipper.fis"]
    # --overwrite replaces only a file bwr_twin.fis wrote: "keep me" stays, an earlier conversion goes.
    assert main(["convert", "tipper.fis", "taken.fis", "--overwrite"]) == 2
    assert "taken.fis: exists and was not written by bwr_twin.fis; it is left alone" in capsys.readouterr().err
    assert (tmp_path / "taken.fis").read_text() == "keep me\n"
    (tmp_path / "taken.fis").unlink()
    assert main(["convert", "tipper.fis", "taken.fis"]) == 0
    assert main(["convert", "tipper.fis", "taken.fis", "--overwrite"]) == 0
    assert read_fis(tmp_path / "taken.fis") == read_fis(source)
    # Out-of-range inputs are evaluated clipped, with one warning line.
    assert main(["evaluate", "tipper.fis", "12", "3"]) == 0
    captured = capsys.readouterr()
    assert captured.out.endswith("output = " + f"{evaluate(read_fis(source), [10, 3])[0, 0]:.4f}\n")
    assert captured.err.startswith("warning: input 1 'service': 1 of 1 values outside its range [0, 10]")


def _three_inputs(lines: list[str]) -> str:
    text = "\n".join(lines) + "\n"
    text = text.replace("NumInputs = 2", "NumInputs = 3").replace(
        "[Output1]",
        ("[Input3]\nName = 'ambience'\nRange = [0 10]\nMF1 = 'dull':'trimf',[0 0 10]\n\n[Output1]"),
    )
    for rule in ("1 1, 1", "2 0, 2", "3 2, 3"):
        text = text.replace(f"\n{rule} (1)", f"\n{rule.replace(',', ' 0,')} (1)")
    return text


def test_cli_bad_files_exit_2_with_one_line(tmp_path):
    lines = TIPPER.read_text().splitlines()
    output_section = slice(lines.index("[Output1]"), lines.index("MF3 = 'generous':'trimf',[20 25 30]") + 1)
    cases = {  # name: (file text, line the message must name, command, words)
        "unknown_type": (
            *_edit(lines, "MF1 = 'poor':'gaussmf',[1.5 0]", "MF1 = 'poor':'gaussianmf',[1.5 0]"),
            "evaluate",
            "unknown membership function type 'gaussianmf'",
        ),
        "param_count": (
            *_edit(lines, "MF1 = 'cheap':'trimf',[0 5 10]", "MF1 = 'cheap':'trimf',[0 5]"),
            "evaluate",
            "trimf takes 3 parameters [a b c], got 2",
        ),
        "rule_range": (
            *_edit(lines, "3 2, 3 (1) : 2", "3 4, 3 (1) : 2"),
            "evaluate",
            "index 4 for input 2 'food' is out of range",
        ),
        "rule_columns": (
            *_edit(lines, "2 0, 2 (1) : 1", "2 0 1, 2 (1) : 1"),
            "evaluate",
            "rule 2 has 3 antecedent columns, the system has 2 inputs",
        ),
        "missing_section": (
            "\n".join(lines[: output_section.start] + lines[output_section.stop :]) + "\n",
            lines.index("NumOutputs = 1") + 1,
            "evaluate",
            "missing section [Output1]",
        ),
        "not_a_number": (
            *_edit(lines, "Range = [0 10]", "Range = [0 ten]"),
            "evaluate",
            "'ten' is not a number",
        ),
        "unknown_method": (
            *_edit(lines, "AndMethod = 'min'", "AndMethod = 'mean'"),
            "evaluate",
            "AndMethod 'mean' is not supported (supported: min, prod)",
        ),
        "sugeno": (
            *_edit(lines, "Type = 'mamdani'", "Type = 'sugeno'"),
            "evaluate",
            "only type-1 Mamdani systems",
        ),
        "three_inputs": (
            _three_inputs(lines),
            lines.index("NumInputs = 2") + 1,
            "surface",
            "3 inputs: a control surface plots 1 or 2 inputs",
        ),
    }
    for name, (text, _, _, _) in cases.items():
        (tmp_path / f"{name}.fis").write_text(text)

    def run(item):
        name, (_, _, command, _) = item
        extra = ("2", "1") if command == "evaluate" else ("--out", f"{name}.png")
        return run_cli(command, f"{name}.fis", *extra, cwd=tmp_path)

    with ThreadPoolExecutor(max_workers=2) as pool:
        results = list(pool.map(run, cases.items()))
    for (name, (_, line, _, words)), done in zip(cases.items(), results):
        assert done.returncode == 2, (name, done.stdout, done.stderr)
        assert "Traceback" not in done.stderr and done.stdout == "", name
        assert done.stderr.count("\n") == 1, (name, done.stderr)
        assert done.stderr.startswith(f"error: {name}.fis:{line}: "), (name, done.stderr)
        assert words in done.stderr, (name, done.stderr)
    assert not list(tmp_path.glob("*.png"))
    # The three-input file is fine to evaluate; only the surface refuses it.
    assert read_fis(tmp_path / "three_inputs.fis").inputs[2].name == "ambience"
