"""The rule base as IEC 61131-7 FCL and as fuzzylite's FLL: FCL round trips keep every number,
what FCL cannot hold is refused in one line, and an independent engine (pyfuzzylite, a test
dependency only: it is GPL) reading the FLL agrees with `bwr_twin.fis` evaluate."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import fuzzylite as fl
import numpy as np
import pytest
from conftest import SCENES
from test_fis import TIPPER, random_system, run_cli

from bwr_twin.errors import SceneError
from bwr_twin.fis.convert import load_system
from bwr_twin.fis.fcl import fcl_text, parse_fcl
from bwr_twin.fis.fll import fll_text
from bwr_twin.fis.inference import evaluate
from bwr_twin.fis.system import FuzzySystem, MembershipFunction, Rule, Variable

PAPER_TOML = SCENES / "rulebases" / "paper_table2.toml"


def polyline_system() -> FuzzySystem:
    """Everything FCL's extended level holds: triangles and trapezoids with shoulders, awkward
    numbers, weights, NOT, don't care, OR, two outputs, every method FCL names."""
    tri = lambda name, *p: MembershipFunction(name, "trimf", tuple(p))  # noqa: E731
    trap = lambda name, *p: MembershipFunction(name, "trapmf", tuple(p))  # noqa: E731
    inputs = (Variable("speed", (-0.1, 2.0 / 3.0), (tri("low", -0.1, -0.1, 0.3), trap("high", 0.1, 0.35, 2.0 / 3.0, 2.0 / 3.0))),
              Variable("load", (0.0, 1e-3), (tri("light", 0.0, 0.0, 7e-4), tri("heavy", 1e-4, 1e-3, 1e-3))))
    outputs = (Variable("force", (-5.5, 5.5), (tri("back", -5.5, -5.5, 0.0), tri("hold", -2.0, 0.0, 2.0),
                                                tri("ahead", 0.0, 5.5, 5.5))),
               Variable("trim", (0.25, 1.0), (trap("slow", 0.25, 0.25, 0.4, 0.7), tri("fast", 0.5, 1.0, 1.0))))
    rules = (Rule((1, 0), (3, 1)), Rule((-2, 2), (1, 0), 0.375), Rule((2, 1), (2, 2), 1.0, 2), Rule((1, -1), (0, 2)))
    return FuzzySystem("polylines", inputs, outputs, rules, and_method="prod", or_method="probor",
                       imp_method="prod", agg_method="probor", defuzz_method="bisector")


@pytest.mark.parametrize("system", [load_system(PAPER_TOML), polyline_system()], ids=["paper_table2", "polylines"])
def test_fcl_round_trip_keeps_every_number(system):
    text = fcl_text(system, ["a comment"])
    back = parse_fcl(text, Path("x.fcl"))
    assert back == system  # names, every float bit for bit, rules, methods
    assert "FUNCTION_BLOCK" in text and "RULEBLOCK" in text and ("COG;" in text or "COA;" in text)
    assert "Beyond FCL's basic conformance level" in text  # triangular outputs are beyond singletons


def test_fcl_through_convert_and_back(tmp_path):
    """.toml -> .fcl -> .fis -> .fcl through the command line: the two FCL files say the same."""
    for args in ((PAPER_TOML, "a.fcl"), ("a.fcl", "a.fis"), ("a.fis", "b.fcl")):
        result = run_cli("convert", *args, cwd=tmp_path)
        assert result.returncode == 0, result.stderr
    a, b = ((tmp_path / name).read_text().splitlines() for name in ("a.fcl", "b.fcl"))
    assert a[0] == b[0] == "(* written by bwr_twin.fis *)"
    assert a[2:] == b[2:]  # all but the line naming the source
    assert load_system(tmp_path / "a.fis") == load_system(PAPER_TOML)


def test_what_fcl_cannot_hold_is_refused_in_one_line(tmp_path):
    result = run_cli("convert", TIPPER, "t.fcl", cwd=tmp_path)
    assert result.returncode == 2
    assert result.stderr.count("\n") == 1 and "Traceback" not in result.stderr
    assert f"{TIPPER}:24" in result.stderr and "gaussmf" in result.stderr and "trimf, trapmf" in result.stderr
    assert not list(tmp_path.iterdir())
    with pytest.raises(SceneError, match="not an IEC 61131 identifier"):
        fcl_text(dataclasses.replace(polyline_system(), name="has space"))


@pytest.mark.parametrize("text, words", [
    ("FUNCTION_BLOCK f\nVAR_INPUT x : REAL; END_VAR\nFUZZIFY x\n  RANGE := (0 .. 1);\n  TERM a := 3;\nEND_FUZZIFY\n",
     ":5: set 'a' is a singleton"),
    ("FUNCTION_BLOCK f\nVAR_INPUT x : REAL; END_VAR\nFUZZIFY x\n  TERM a := (0, 1) (1, 1);\nEND_FUZZIFY\n",
     ":4: set 'a' has points of degrees (1.0, 1.0)"),
    ("FUNCTION_BLOCK f\nVAR_INPUT x : REAL; END_VAR\nFUZZ x\n", ":3: unknown section 'FUZZ'"),
    ("FUNCTION_BLOCK f\nVAR_INPUT x : REAL; END_VAR\n", ":2: the file ends before END_FUNCTION_BLOCK"),
])
def test_bad_fcl_names_the_line(tmp_path, text, words):
    path = tmp_path / "bad.fcl"
    path.write_text(text)
    result = run_cli("evaluate", path, "0.5", cwd=tmp_path)
    assert result.returncode == 2 and "Traceback" not in result.stderr
    assert f"{path}{words}" in result.stderr, result.stderr


def test_fcl_written_by_hand_is_not_overwritten(tmp_path):
    mine = tmp_path / "mine.fcl"
    mine.write_text("(* my notes: once written by bwr_twin.fis, edited since *)\nFUNCTION_BLOCK x\n")
    result = run_cli("convert", PAPER_TOML, mine, "--overwrite", cwd=tmp_path)
    assert result.returncode == 2 and "not written by bwr_twin.fis" in result.stderr
    assert mine.read_text().startswith("(* my notes")


def fuzzylite_outputs(system: FuzzySystem, x: np.ndarray) -> np.ndarray:
    fl.lib.abs_tolerance = 0.0  # fuzzylite ignores firing strengths below 1e-5 by default; evalfis does not
    engine = fl.FllImporter().from_string(fll_text(system))
    out = np.empty((len(x), len(system.outputs)))
    inputs = [engine.input_variable(v.name) for v in system.inputs]
    outputs = [engine.output_variable(v.name) for v in system.outputs]
    for k, row in enumerate(x):
        for variable, value in zip(inputs, row):
            variable.value = float(value)
        engine.process()
        out[k] = [v.value for v in outputs]
    return out


def random_inputs(system: FuzzySystem, n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return np.column_stack([rng.uniform(*v.range, n) for v in system.inputs])


@pytest.mark.parametrize("system, n", [(load_system(PAPER_TOML), 10_000), (load_system(TIPPER), 2_000)],
                         ids=["paper_table2", "tipper"])
def test_fll_read_by_fuzzylite_agrees_with_evaluate(system, n):
    x = random_inputs(system, n, seed=3)
    width = np.array([v.range[1] - v.range[0] for v in system.outputs])
    error = np.abs(fuzzylite_outputs(system, x) - evaluate(system, x, warn=False)) / width
    assert error.max() <= 1e-6


@pytest.mark.parametrize("seed", range(6))
def test_fll_of_random_systems(seed):
    """Every set type, NOT in antecedents, don't care, OR, weights and every norm .fis and fuzzylite
    share; rules without a condition (which fire by themselves in a .fis) and NOT in a consequent
    are what FLL refuses."""
    rng = np.random.default_rng(seed)
    methods = (("min", "prod")[seed % 2], ("max", "probor")[seed // 2 % 2], ("min", "prod")[seed // 3 % 2],
               ("max", "sum", "probor")[seed % 3], "centroid")
    system = random_system(rng, methods)
    rules = tuple(dataclasses.replace(r, consequent=tuple(abs(i) for i in r.consequent))
                  for r in system.rules if any(r.antecedent))
    system = dataclasses.replace(system, rules=rules)
    x = random_inputs(system, 300, seed)
    width = np.array([v.range[1] - v.range[0] for v in system.outputs])
    assert np.abs(fuzzylite_outputs(system, x) - evaluate(system, x, warn=False)).max() / width.min() <= 1e-6
    negated = dataclasses.replace(system, rules=(dataclasses.replace(rules[0], consequent=tuple(
        -max(i, 1) for i in rules[0].consequent)),) + rules[1:])
    with pytest.raises(SceneError, match="NOT in its consequent"):
        fll_text(negated)
