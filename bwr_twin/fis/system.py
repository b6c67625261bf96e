"""A type-1 Mamdani fuzzy inference system as plain, frozen data, and its checks.

The fields follow MATLAB's .fis file one to one, so that reading and writing are lossless:
membership function indices in rules count from 1, 0 is "don't care" (or "no consequent") and a
negative index is NOT. `check` refuses everything the inference and the writer could not honour,
naming the file and line the problem came from when the system was read from a file.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

from bwr_twin.errors import SceneError, shown_items
from bwr_twin.fis.membership import param_problem

AND_METHODS = ("min", "prod")
OR_METHODS = ("max", "probor")
IMP_METHODS = ("min", "prod")
AGG_METHODS = ("max", "sum", "probor")
DEFUZZ_METHODS = ("centroid", "bisector", "mom", "som", "lom")
AND, OR = 1, 2  # a rule's connection, as the .fis file writes it
# The largest magnitude of a range's end or a set's parameter. An output range is sampled and its
# centroid is a sum of samples times memberships: of ±1.7e308 the width alone overflows, and every
# output would read as "no rule fired". Within ±1e100 the width, up to 1,000,000 samples of it and
# their sums stay finite, far beyond any physical universe.
MAX_MAGNITUDE = 1e100
_WIDTHS = {"gaussmf": (0,), "gauss2mf": (0, 2), "gbellmf": (0,)}  # the parameters squared or divided by

# (attribute, .fis key, allowed values)
METHODS = (
    ("and_method", "AndMethod", AND_METHODS),
    ("or_method", "OrMethod", OR_METHODS),
    ("imp_method", "ImpMethod", IMP_METHODS),
    ("agg_method", "AggMethod", AGG_METHODS),
    ("defuzz_method", "DefuzzMethod", DEFUZZ_METHODS),
)


@dataclass(frozen=True)
class MembershipFunction:
    """One fuzzy set: its name, MATLAB type (e.g. 'trimf') and parameters in MATLAB's order."""

    name: str
    type: str
    params: tuple[float, ...]


@dataclass(frozen=True)
class Variable:
    """An input or output: its name, universe (low, high) and fuzzy sets."""

    name: str
    range: tuple[float, float]
    mfs: tuple[MembershipFunction, ...]


@dataclass(frozen=True)
class Rule:
    """IF inputs THEN outputs, one index per input and per output (1-based; 0 don't care; < 0 NOT).

    weight in [0, 1] scales the firing strength; connection 1 joins the antecedents with AND,
    2 with OR.
    """

    antecedent: tuple[int, ...]
    consequent: tuple[int, ...]
    weight: float = 1.0
    connection: int = AND


@dataclass(frozen=True)
class FuzzySystem:
    """A Mamdani system. `path` and `lines` record where it was read from (not compared).

    `lines` maps places in the file to line numbers, for messages: 'system', 'NumInputs',
    'AndMethod', ..., 'input1', 'input1.range', 'input1.mf2', 'output1', 'rules', 'rule3'.
    """

    name: str
    inputs: tuple[Variable, ...]
    outputs: tuple[Variable, ...]
    rules: tuple[Rule, ...]
    and_method: str = "min"
    or_method: str = "max"
    imp_method: str = "min"
    agg_method: str = "max"
    defuzz_method: str = "centroid"
    path: Path | None = field(default=None, compare=False)
    lines: Mapping[str, int] = field(default_factory=dict, compare=False, repr=False)

    def where(self, place: str = "system") -> str:
        """'FILE:LINE' of a place in the source file, or the best that is known of it."""
        source = str(self.path) if self.path is not None else f"fuzzy system {self.name!r}"
        fallback = "rules" if place.startswith("rule") else place.split(".")[0]
        for key in (place, fallback, "system"):
            if key in self.lines:
                return f"{source}:{self.lines[key]}"
        return source

    def fail(self, place: str, what: str) -> SceneError:
        """A SceneError 'FILE:LINE: what' for a problem at a place of the file."""
        return SceneError(f"{self.where(place)}: {what}")


def variable_label(kind: str, index: int, variable: Variable) -> str:
    """'input 1 'service'': how messages name a variable (index 1-based)."""
    return f"{kind} {index} {variable.name!r}"


def check(system: FuzzySystem) -> FuzzySystem:
    """The system itself if the inference and the .fis writer can honour it; else a SceneError.

    Checks the methods, that there is at least one input and one output, the names (non-empty,
    no quote or line break: the .fis format has no escapes; a variable's sets distinct), the ranges
    (finite, low < high, within ±MAX_MAGNITUDE), every membership function (type, parameter count
    and conditions, within ±MAX_MAGNITUDE) and every rule (column counts,
    indices within the sets, weight in [0, 1], connection 1 or 2).
    """
    for attribute, key, allowed in METHODS:
        value = getattr(system, attribute)
        if value not in allowed:
            raise system.fail(key, f"{key} {value!r} is not supported (supported: {', '.join(allowed)})")
    _check_name(system, "system", "the system's Name", system.name, allow_empty=True)
    if not system.inputs:
        raise system.fail("NumInputs", "the system has no inputs (needs at least 1 [Input1] section)")
    if not system.outputs:
        raise system.fail("NumOutputs", "the system has no outputs (needs at least 1 [Output1] section)")
    for kind, variables in (("input", system.inputs), ("output", system.outputs)):
        for i, variable in enumerate(variables, start=1):
            _check_variable(system, kind, i, variable)
    for r, rule in enumerate(system.rules, start=1):
        _check_rule(system, r, rule)
    return system


def _check_name(system: FuzzySystem, place: str, label: str, name: str, allow_empty: bool = False) -> None:
    if not isinstance(name, str) or (not name and not allow_empty):
        raise system.fail(place, f"{label} must be a non-empty string, got {name!r}")
    if "'" in name or "\n" in name or "\r" in name:
        raise system.fail(
            place, f"{label} {name!r} contains a quote or line break (a .fis file cannot hold it)"
        )


def _check_variable(system: FuzzySystem, kind: str, i: int, variable: Variable) -> None:
    place = f"{kind}{i}"
    label = f"{kind} {i}"
    _check_name(system, place, f"{label}'s Name", variable.name)
    low, high = (float(v) for v in variable.range)
    if not (math.isfinite(low) and math.isfinite(high) and low < high):
        raise system.fail(
            f"{place}.range",
            f"{label} {variable.name!r}: Range must be [low high], finite, low < high, "
            f"got [{low:g} {high:g}]",
        )
    if max(abs(low), abs(high)) > MAX_MAGNITUDE:
        raise system.fail(
            f"{place}.range",
            f"{label} {variable.name!r}: Range [{low:g} {high:g}] is beyond ±{MAX_MAGNITUDE:g} (its samples "
            "and their centroid would overflow)",
        )
    if not variable.mfs:
        raise system.fail(place, f"{label} {variable.name!r} has no membership functions (needs MF1=...)")
    names: dict[str, int] = {}
    for k, mf in enumerate(variable.mfs, start=1):
        where = f"{place}.mf{k}"
        _check_name(system, where, f"MF{k} of {label} {variable.name!r}", mf.name)
        if mf.name in names:
            raise system.fail(
                where, f"MF{k} {mf.name!r} of {label} {variable.name!r}: the name of MF{names[mf.name]} too "
                "(each set of a variable has its own name)"
            )
        names[mf.name] = k
        problem = param_problem(mf.type, mf.params)
        if not problem and any(abs(float(v)) > MAX_MAGNITUDE for v in mf.params):
            problem = f"parameters beyond ±{MAX_MAGNITUDE:g}, got {shown_items(mf.params, '{:g}'.format)}"
        widths = [float(mf.params[i]) for i in _WIDTHS.get(mf.type, ())]
        if not problem and any(0 < abs(w) < 1 / MAX_MAGNITUDE for w in widths):
            problem = (f"{mf.type} width {min(widths, key=abs):g} is narrower than {1 / MAX_MAGNITUDE:g} (its square "
                       "would be 0)")
        if problem:
            raise system.fail(where, f"MF{k} {mf.name!r} of {label} {variable.name!r}: {problem}")


def _check_rule(system: FuzzySystem, r: int, rule: Rule) -> None:
    place = f"rule{r}"
    for kind, indices, variables in (
        ("antecedent", rule.antecedent, system.inputs),
        ("consequent", rule.consequent, system.outputs),
    ):
        noun = "inputs" if kind == "antecedent" else "outputs"
        if len(indices) != len(variables):
            raise system.fail(
                place,
                f"rule {r} has {len(indices)} {kind} columns, the system has {len(variables)} {noun} "
                "(one column per variable)",
            )
        for j, (index, variable) in enumerate(zip(indices, variables), start=1):
            n = len(variable.mfs)
            if not isinstance(index, int) or isinstance(index, bool) or abs(index) > n:
                raise system.fail(
                    place,
                    f"rule {r}: index {index} for {noun[:-1]} {j} {variable.name!r} is out of range "
                    f"(it has {n} membership functions: -{n}..{n}, 0 = don't care, negative = NOT)",
                )
    weight = float(rule.weight)
    if not 0.0 <= weight <= 1.0:
        raise system.fail(place, f"rule {r}: weight {weight:g} is outside [0, 1]")
    if rule.connection not in (AND, OR):
        raise system.fail(place, f"rule {r}: connection {rule.connection!r} must be 1 (AND) or 2 (OR)")
