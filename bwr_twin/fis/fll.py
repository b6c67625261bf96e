"""Write a FuzzySystem in FLL, the fuzzylite language, for an independent engine to evaluate.

fuzzylite's centroid (and its other integral defuzzifiers) sums the aggregated set at the
midpoints of `resolution` equal intervals of the output's range; `bwr_twin.fis.inference`, as
MATLAB's evalfis, sums it at `points` evenly spaced samples that include both ends. The FLL output's
range is therefore the .fis range widened by half a sample step at each end, with resolution =
points: fuzzylite's midpoints are then the very samples evalfis takes, and both engines agree to
rounding (a comment in the file says so). Inputs lock their range (fuzzylite clips them, as the
evaluation here does); an output with nothing fired is the middle of its .fis range, as in MATLAB.

Agreement with pyfuzzylite (its `abs_tolerance` set to 0: by default it ignores firing strengths
below 1e-5) is tested on the shipped rule base, MATLAB's tipper and random systems of every set
type, NOT in antecedents, weights, OR and every norm both engines share, to 1e-15 of the output
range. NOT in a consequent means something else to fuzzylite, and is refused.
"""

from __future__ import annotations

from collections.abc import Iterable

from bwr_twin.errors import SceneError
from bwr_twin.fis.inference import DEFAULT_POINTS
from bwr_twin.fis.system import AND, FuzzySystem, MembershipFunction, check
from bwr_twin.fis.writer import format_number

_NORMS = {"min": "Minimum", "prod": "AlgebraicProduct", "max": "Maximum", "probor": "AlgebraicSum",
          "sum": "UnboundedSum"}
_DEFUZZIFIERS = {"centroid": "Centroid", "bisector": "Bisector", "mom": "MeanOfMaximum",
                 "som": "SmallestOfMaximum", "lom": "LargestOfMaximum"}
# MATLAB's parameter order -> fuzzylite's term and its parameter order (indices into MATLAB's)
_TERMS = {"trimf": ("Triangle", (0, 1, 2)), "trapmf": ("Trapezoid", (0, 1, 2, 3)), "gaussmf": ("Gaussian", (1, 0)),
          "gauss2mf": ("GaussianProduct", (1, 0, 3, 2)), "gbellmf": ("Bell", (2, 0, 1)),
          "sigmf": ("Sigmoid", (1, 0)), "smf": ("SShape", (0, 1)), "zmf": ("ZShape", (0, 1)),
          "pimf": ("PiShape", (0, 1, 2, 3))}


def fll_text(system: FuzzySystem, comments: Iterable[str] = (), points: int = DEFAULT_POINTS) -> str:
    """The system as FLL, its output ranges widened so that fuzzylite samples the `points`
    samples of evalfis (see the module's docstring); `comments` open it as # lines."""
    check(system)
    out = [f"# {line}".rstrip() for comment in comments for line in comment.splitlines()]
    out += [f"# Output ranges are the .fis ranges widened by half of the {points}-sample step at each end:",
            "# fuzzylite's midpoint defuzzification then samples the points MATLAB's evalfis samples.",
            f"Engine: {_name(system.name or 'fuzzy')}"]
    for variable in system.inputs:
        out += [f"InputVariable: {_name(variable.name)}", "  enabled: true",
                f"  range: {format_number(variable.range[0])} {format_number(variable.range[1])}",
                "  lock-range: true"]
        out += [_term(mf) for mf in variable.mfs]
    for variable in system.outputs:
        low, high = variable.range
        half = 0.5 * (high - low) / (points - 1)
        out += [f"OutputVariable: {_name(variable.name)}", "  enabled: true",
                f"  range: {format_number(low - half)} {format_number(high + half)}", "  lock-range: false",
                f"  aggregation: {_NORMS[system.agg_method]}",
                f"  defuzzifier: {_DEFUZZIFIERS[system.defuzz_method]} {points}",
                f"  default: {format_number(0.5 * (low + high))}", "  lock-previous: false"]
        out += [_term(mf) for mf in variable.mfs]
    out += ["RuleBlock: rules", "  enabled: true", f"  conjunction: {_NORMS[system.and_method]}",
            f"  disjunction: {_NORMS[system.or_method]}", f"  implication: {_NORMS[system.imp_method]}",
            "  activation: General"]
    for rule in system.rules:
        conditions = [f"{_name(v.name)} is {'not ' if i < 0 else ''}{_name(v.mfs[abs(i) - 1].name)}"
                      for v, i in zip(system.inputs, rule.antecedent) if i != 0]
        conclusions = [f"{_name(v.name)} is {'not ' if i < 0 else ''}{_name(v.mfs[abs(i) - 1].name)}"
                       for v, i in zip(system.outputs, rule.consequent) if i != 0]
        if not conditions:
            raise system.fail("rules", "a rule with every input 'don't care' fires by itself in a .fis; FLL "
                                       "cannot write a rule without a condition")
        if not conclusions:
            continue  # a rule without a consequent changes no output
        if any(i < 0 for i in rule.consequent):
            raise system.fail("rules", "a rule with NOT in its consequent: fuzzylite reads 'then u is not X' "
                                       "otherwise than MATLAB's 1 - mu, so FLL cannot write it")
        weight = "" if rule.weight == 1.0 else f" with {format_number(rule.weight)}"
        joiner = " and " if rule.connection == AND else " or "
        out.append(f"  rule: if {joiner.join(conditions)} then {' and '.join(conclusions)}{weight}")
    return "\n".join(out) + "\n"


def _term(mf: MembershipFunction) -> str:
    kind, order = _TERMS[mf.type]
    return f"  term: {_name(mf.name)} {kind} " + " ".join(format_number(mf.params[i]) for i in order)


def _name(name: str) -> str:
    """fuzzylite names are words: a name with spaces or symbols cannot be written."""
    if not name.replace("_", "").replace(".", "").isalnum():
        raise SceneError(f"the name {name!r} is not a word (letters, digits, _ and .): FLL cannot name it")
    return name
