"""IEC 61131-7 Fuzzy Control Language (FCL): write a FuzzySystem as a FUNCTION_BLOCK, read it back.

    FUNCTION_BLOCK tipper
    VAR_INPUT service : REAL; END_VAR        VAR_OUTPUT tip : REAL; END_VAR
    FUZZIFY service  RANGE := (0 .. 10);  TERM poor := (0, 0) (5, 1) (10, 0);  END_FUZZIFY
    DEFUZZIFY tip  TERM ... ;  METHOD : COG;  DEFAULT := 15;  RANGE := (0 .. 30);  END_DEFUZZIFY
    RULEBLOCK rules  AND : MIN;  OR : MAX;  ACT : MIN;  ACCU : MAX;
        RULE 1 : IF service IS poor OR food IS rancid THEN tip IS cheap;  END_RULEBLOCK
    END_FUNCTION_BLOCK

A set is the standard's polyline of (value, degree) points: a trimf [a b c] is (a, 0) (b, 1)
(c, 0), a trapmf [a b c d] four points, even where two coincide (a shoulder at the range's end), so
that reading it back gives the same parameters. Numbers are written so that they read back to the
same float: a round trip .fis -> .fcl -> .fis keeps every number.

The standard's basic conformance level has input sets of at most 3 points, singleton output sets,
AND = MIN, ACCU = MAX and COGS. A system that needs more (triangular output sets and COG, as every
Mamdani .fis has; trapezoids; weights; NOT; OR) is written at the extended level, and a comment at
the top of the block names what goes beyond the basic one. An input's RANGE inside FUZZIFY (which
the standard gives DEFUZZIFY only) is an extension too, as jFuzzyLogic writes it: without it the
inputs' universes, which the evaluation clips to, would be lost. Sets without a polyline (Gaussian,
bell, sigmoid, S, Z, pi) and NOT in a consequent have no FCL form: such a system is refused with a
one-line SceneError, as is a name that is not an IEC identifier.

`read_fcl` reads what `fcl_text` writes and the same language written by hand: keywords in any
case, (* comments *), free layout; every problem is a SceneError 'FILE:LINE: what'.
"""

from __future__ import annotations

import re
from collections.abc import Iterable
from pathlib import Path

from bwr_twin.errors import SceneError, shown_items
from bwr_twin.fis.system import AND, OR, FuzzySystem, MembershipFunction, Rule, Variable, check
from bwr_twin.fis.writer import format_number
from bwr_twin.textfile import read_text

# (FuzzySystem attribute, FCL keyword, {fis method: FCL method})
_METHODS = (
    ("and_method", "AND", {"min": "MIN", "prod": "PROD"}),
    ("or_method", "OR", {"max": "MAX", "probor": "ASUM"}),
    ("imp_method", "ACT", {"min": "MIN", "prod": "PROD"}),
    ("agg_method", "ACCU", {"max": "MAX", "probor": "ASUM"}),
)
_DEFUZZIFY = {"centroid": "COG", "bisector": "COA", "som": "LM", "lom": "RM"}
_POLYLINE_DEGREES = {"trimf": (0.0, 1.0, 0.0), "trapmf": (0.0, 1.0, 1.0, 0.0)}
_IDENTIFIER = re.compile(r"[A-Za-z_][A-Za-z0-9_]*\Z")
_KEYWORDS = {"IF", "THEN", "IS", "AND", "OR", "NOT", "WITH", "RULE", "TERM", "RANGE", "METHOD", "DEFAULT",
             "ACT", "ACCU", "REAL", "VAR_INPUT", "VAR_OUTPUT", "END_VAR", "FUZZIFY", "DEFUZZIFY", "RULEBLOCK"}


def fcl_text(system: FuzzySystem, comments: Iterable[str] = ()) -> str:
    """The system as an FCL FUNCTION_BLOCK; `comments` open it as (* *) lines. A system FCL cannot
    hold is a SceneError naming what."""
    check(system)
    _check_fcl(system)
    extended = _beyond_basic(system)
    out = [f"(* {line} *)" for comment in comments for line in comment.splitlines()]
    out.append(f"FUNCTION_BLOCK {system.name}")
    if extended:
        out.append("(* Beyond FCL's basic conformance level (IEC 61131-7 extended level): "
                   + "; ".join(extended) + ". *)")
    for title, variables in (("VAR_INPUT", system.inputs), ("VAR_OUTPUT", system.outputs)):
        out += ["", title] + [f"    {v.name} : REAL;" for v in variables] + ["END_VAR"]
    for variable in system.inputs:
        out += ["", f"FUZZIFY {variable.name}", f"    RANGE := ({_range(variable)});"]
        out += [_term(mf) for mf in variable.mfs] + ["END_FUZZIFY"]
    for variable in system.outputs:
        middle = 0.5 * (variable.range[0] + variable.range[1])  # MATLAB's output when no rule fires
        out += ["", f"DEFUZZIFY {variable.name}"] + [_term(mf) for mf in variable.mfs]
        out += [f"    METHOD : {_DEFUZZIFY[system.defuzz_method]};", f"    DEFAULT := {format_number(middle)};",
                f"    RANGE := ({_range(variable)});", "END_DEFUZZIFY"]
    out += ["", "RULEBLOCK rules"]
    out += [f"    {keyword} : {names[getattr(system, attribute)]};" for attribute, keyword, names in _METHODS]
    out += [f"    RULE {r} : {_rule(system, rule)};" for r, rule in enumerate(system.rules, start=1)]
    out += ["END_RULEBLOCK", "", "END_FUNCTION_BLOCK"]
    return "\n".join(out) + "\n"


def _check_fcl(system: FuzzySystem) -> None:
    def identifier(place: str, label: str, name: str) -> None:
        if not _IDENTIFIER.match(name) or name.upper() in _KEYWORDS:
            raise system.fail(place, f"{label} {name!r} is not an IEC 61131 identifier (letters, digits and _, "
                                     "not a keyword): FCL cannot name it")

    identifier("system", "the system's name", system.name)
    if system.defuzz_method not in _DEFUZZIFY:
        raise system.fail("DefuzzMethod", f"DefuzzMethod {system.defuzz_method!r} has no FCL form (FCL has "
                                          f"{', '.join(_DEFUZZIFY)}: COG, COA, LM, RM)")
    if system.agg_method not in _METHODS[3][2]:
        raise system.fail("AggMethod", f"AggMethod {system.agg_method!r} has no FCL form (FCL's ACCU of a "
                                       "Mamdani .fis: max as MAX, probor as ASUM)")
    for kind, variables in (("input", system.inputs), ("output", system.outputs)):
        for i, variable in enumerate(variables, start=1):
            identifier(f"{kind}{i}", f"{kind} {i}'s name", variable.name)
            for k, mf in enumerate(variable.mfs, start=1):
                identifier(f"{kind}{i}.mf{k}", f"set {k} of {kind} {i} {variable.name!r}", mf.name)
                if mf.type not in _POLYLINE_DEGREES:
                    raise system.fail(f"{kind}{i}.mf{k}", f"set {mf.name!r} of {kind} {i} {variable.name!r} is a "
                                      f"{mf.type}: FCL holds only polylines (trimf, trapmf)")
    for r, rule in enumerate(system.rules, start=1):
        if any(i < 0 for i in rule.consequent):
            raise system.fail(f"rule{r}", f"rule {r} has NOT in its consequent, which FCL cannot write")
        if not any(rule.antecedent) or not any(rule.consequent):
            raise system.fail(f"rule{r}", f"rule {r} has no antecedent or no consequent: FCL cannot write it")


def _beyond_basic(system: FuzzySystem) -> list[str]:
    notes = []
    if any(len(_POLYLINE_DEGREES[mf.type]) > 3 for v in system.inputs for mf in v.mfs):
        notes.append("input sets of 4 points")
    notes.append("input RANGE in FUZZIFY")
    notes.append("output sets that are polylines, not singletons")
    notes.append(f"METHOD {_DEFUZZIFY[system.defuzz_method]}, not COGS")
    if system.and_method != "min" or system.agg_method != "max":
        notes.append("AND or ACCU other than MIN, MAX")
    if any(r.weight != 1.0 for r in system.rules):
        notes.append("rule weights (WITH)")
    if any(i < 0 for r in system.rules for i in r.antecedent):
        notes.append("NOT")
    return notes


def _range(variable: Variable) -> str:
    return f"{format_number(variable.range[0])} .. {format_number(variable.range[1])}"


def _term(mf: MembershipFunction) -> str:
    points = " ".join(f"({format_number(x)}, {format_number(d)})"
                      for x, d in zip(mf.params, _POLYLINE_DEGREES[mf.type]))
    return f"    TERM {mf.name} := {points};"


def _rule(system: FuzzySystem, rule: Rule) -> str:
    joiner = " AND " if rule.connection == AND else " OR "
    conditions = [f"{v.name} IS {'NOT ' if i < 0 else ''}{v.mfs[abs(i) - 1].name}"
                  for v, i in zip(system.inputs, rule.antecedent) if i != 0]
    conclusions = [f"{v.name} IS {v.mfs[i - 1].name}" for v, i in zip(system.outputs, rule.consequent) if i != 0]
    weight = "" if rule.weight == 1.0 else f" WITH {format_number(rule.weight)}"
    return f"IF {joiner.join(conditions)} THEN {', '.join(conclusions)}{weight}"


# -- reading --------------------------------------------------------------------------------

_TOKEN = re.compile(r"\(\*.*?\*\)|(?P<number>[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?)|(?P<word>[A-Za-z_]\w*)"
                    r"|(?P<symbol>:=|\.\.|[();:,])|(?P<space>\s+)|(?P<bad>.)", re.DOTALL)


class _Tokens:
    """The FCL text as (kind, text, line) tokens, comments and spaces dropped."""

    def __init__(self, text: str, path: Path):
        self.path = path
        self.items: list[tuple[str, str, int]] = []
        line = 1
        for match in _TOKEN.finditer(text):
            kind = match.lastgroup
            if kind == "bad":
                raise SceneError(f"{path}:{line}: unexpected character {match[0]!r}")
            if kind in ("number", "word", "symbol"):
                self.items.append((kind, match[0], line))
            line += match[0].count("\n")
        self.at = 0

    def fail(self, what: str) -> SceneError:
        return SceneError(f"{self.path}:{self.line()}: {what}")

    def peek(self) -> str:
        return self.items[self.at][1].upper() if self.at < len(self.items) else ""

    def line(self) -> int:
        return self.items[min(self.at, len(self.items) - 1)][2] if self.items else 1

    def take(self, expected: str | None = None, kind: str | None = None) -> str:
        if self.at >= len(self.items):
            raise self.fail(f"the file ends before END_FUNCTION_BLOCK ({expected or kind} expected)")
        token_kind, text, _ = self.items[self.at]
        if (expected is not None and text.upper() != expected) or (kind is not None and token_kind != kind):
            raise self.fail(f"expected {expected or kind}, found {text!r}")
        self.at += 1
        return text

    def number(self) -> float:
        return float(self.take(kind="number"))


def read_fcl(path: str | Path) -> FuzzySystem:
    """Read and check an FCL file's (first) FUNCTION_BLOCK as a Mamdani FuzzySystem."""
    path = Path(path)
    try:
        text = read_text(path)
    except FileNotFoundError:
        raise SceneError(f"{path}: .fcl file not found") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise SceneError(f"{path}: cannot read the .fcl file: {exc}") from None
    return parse_fcl(text, path)


def parse_fcl(text: str, path: Path) -> FuzzySystem:
    tokens = _Tokens(text, path)
    lines: dict[str, int] = {"system": tokens.line()}
    tokens.take("FUNCTION_BLOCK")
    name = tokens.take(kind="word")
    declared: dict[str, list[str]] = {"VAR_INPUT": [], "VAR_OUTPUT": []}
    first_lines: dict[str, int] = {}  # where each variable was declared
    sets: dict[str, tuple[tuple[float, float] | None, list[MembershipFunction], int]] = {}
    methods = {"and_method": "min", "or_method": "max", "imp_method": "min", "agg_method": "max",
               "defuzz_method": "centroid"}
    rule_texts: list[tuple[list, list, float, int, int]] = []
    while tokens.peek() != "END_FUNCTION_BLOCK":
        section = tokens.take(kind="word").upper()
        if section in declared:
            while tokens.peek() != "END_VAR":
                line = tokens.line()
                variable = tokens.take(kind="word")
                if variable in first_lines:
                    raise tokens.fail(f"variable {variable!r} is declared twice (first on line "
                                      f"{first_lines[variable]}); each input and output is declared once")
                first_lines[variable] = line
                declared[section].append(variable)
                tokens.take(":")
                tokens.take(kind="word")
                tokens.take(";")
            tokens.take("END_VAR")
        elif section in ("FUZZIFY", "DEFUZZIFY"):
            line = tokens.line()
            variable = tokens.take(kind="word")
            if variable in sets:
                raise tokens.fail(f"{section} {variable} appears twice (first on line {sets[variable][2]})")
            sets[variable] = _read_sets(tokens, section, methods) + (line,)
        elif section == "RULEBLOCK":
            tokens.take(kind="word")
            lines["rules"] = tokens.line()
            count = len(rule_texts)
            _read_rules(tokens, methods, rule_texts)
            if len(rule_texts) == count:
                raise SceneError(f"{path}:{lines['rules']}: the RULEBLOCK holds no RULE (at least one: "
                                 "RULE 1 : IF e IS zero THEN u IS zero;)")
        else:
            raise tokens.fail(f"unknown section {section!r} (FCL has VAR_INPUT, VAR_OUTPUT, FUZZIFY, DEFUZZIFY, "
                              "RULEBLOCK)")
    if not rule_texts:
        raise SceneError(f"{path}:{lines['system']}: the FUNCTION_BLOCK has no RULEBLOCK (at least one rule)")
    variables = {}
    for kind, title in (("input", "VAR_INPUT"), ("output", "VAR_OUTPUT")):
        for i, variable in enumerate(declared[title], start=1):
            if variable not in sets:
                raise SceneError(f"{path}:{lines['system']}: {kind} {variable!r} has no "
                                 f"{'FUZZIFY' if kind == 'input' else 'DEFUZZIFY'} block")
            var_range, mfs, line = sets[variable]
            lines[f"{kind}{i}"] = line
            if var_range is None:
                raise SceneError(f"{path}:{line}: {variable!r} has no RANGE := (low .. high)")
            variables[variable] = (kind, i, Variable(variable, var_range, tuple(mfs)))
    inputs = tuple(v for kind, _, v in variables.values() if kind == "input")
    outputs = tuple(v for kind, _, v in variables.values() if kind == "output")
    rules = []
    for r, (conditions, conclusions, weight, connection, line) in enumerate(rule_texts, start=1):
        lines[f"rule{r}"] = line
        antecedent, consequent = [0] * len(inputs), [0] * len(outputs)
        for target, clauses, side in ((antecedent, conditions, "input"), (consequent, conclusions, "output")):
            for variable, negated, term in clauses:
                kind, i, found = variables.get(variable, (None, 0, None))
                names = [mf.name for mf in found.mfs] if found else []
                if found is None or term not in names:
                    raise SceneError(f"{path}:{line}: rule {r}: {variable} IS {term}: no such variable or set")
                if kind != side:
                    raise SceneError(f"{path}:{line}: rule {r}: {variable!r} is an {kind}, on the wrong side of THEN")
                if negated and side == "output":
                    raise SceneError(f"{path}:{line}: rule {r}: NOT in a consequent has no .fis form")
                target[i - 1] = -(names.index(term) + 1) if negated else names.index(term) + 1
        rules.append(Rule(tuple(antecedent), tuple(consequent), weight, connection))
    return check(FuzzySystem(name, inputs, outputs, tuple(rules), path=path, lines=lines, **methods))


def _read_sets(tokens: _Tokens, section: str, methods: dict) -> tuple:
    var_range, mfs = None, []
    terms: dict[str, int] = {}  # each set's line
    end = f"END_{section}"
    while tokens.peek() != end:
        key = tokens.take(kind="word").upper()
        if key == "TERM":
            line = tokens.line()
            name = tokens.take(kind="word")
            if name in terms:
                raise tokens.fail(f"TERM {name} appears twice in this {section} (first on line {terms[name]}); "
                                  "a rule could not tell them apart")
            terms[name] = line
            tokens.take(":=")
            if tokens.peek() != "(":
                raise tokens.fail(f"set {name!r} is a singleton or a variable: a .fis set is a triangle or a "
                                  "trapezoid, written as its points (x, degree)")
            points = []
            while tokens.peek() == "(":
                tokens.take("(")
                x = tokens.number()
                tokens.take(",")
                points.append((x, tokens.number()))
                tokens.take(")")
            degrees = tuple(d for _, d in points)
            kind = next((k for k, d in _POLYLINE_DEGREES.items() if d == degrees), None)
            if kind is None:
                raise tokens.fail(f"set {name!r} has points of degrees {shown_items(degrees)}: the .fis sets are "
                                  "a triangle (0, 1, 0) or a trapezoid (0, 1, 1, 0); singletons and other "
                                  "polylines have none")
            mfs.append(MembershipFunction(name, kind, tuple(x for x, _ in points)))
        elif key == "RANGE":
            tokens.take(":=")
            tokens.take("(")
            low = tokens.number()
            tokens.take("..")
            var_range = (low, tokens.number())
            tokens.take(")")
        elif key == "METHOD" and section == "DEFUZZIFY":
            tokens.take(":")
            method = tokens.take(kind="word").upper()
            inverse = {v: k for k, v in _DEFUZZIFY.items()}
            if method not in inverse:
                raise tokens.fail(f"METHOD {method} has no .fis form (known: {', '.join(inverse)})")
            methods["defuzz_method"] = inverse[method]
        elif key == "DEFAULT" and section == "DEFUZZIFY":
            tokens.take(":=")
            tokens.number()  # a .fis output with nothing fired is the middle of its range
        else:
            raise tokens.fail(f"unknown entry {key!r} in {section}")
        tokens.take(";")
    tokens.take(end)
    return var_range, mfs


def _read_rules(tokens: _Tokens, methods: dict, rule_texts: list) -> None:
    keywords = {keyword: (attribute, {v: k for k, v in names.items()}) for attribute, keyword, names in _METHODS}
    while tokens.peek() != "END_RULEBLOCK":
        key = tokens.take(kind="word").upper()
        if key in keywords:
            attribute, names = keywords[key]
            tokens.take(":")
            method = tokens.take(kind="word").upper()
            if method not in names:
                raise tokens.fail(f"{key} : {method} has no .fis form (known: {', '.join(names)})")
            methods[attribute] = names[method]
        elif key == "RULE":
            line = tokens.line()
            tokens.take(kind="number")
            tokens.take(":")
            tokens.take("IF")
            conditions, connection = [_clause(tokens)], AND
            while tokens.peek() in ("AND", "OR"):
                joiner = AND if tokens.take(kind="word").upper() == "AND" else OR
                if len(conditions) > 1 and joiner != connection:
                    raise tokens.fail("a rule mixes AND and OR: a .fis rule has one connection")
                connection = joiner
                conditions.append(_clause(tokens))
            tokens.take("THEN")
            conclusions = [_clause(tokens)]
            while tokens.peek() == ",":
                tokens.take(",")
                conclusions.append(_clause(tokens))
            weight = 1.0
            if tokens.peek() == "WITH":
                tokens.take("WITH")
                weight = tokens.number()
            rule_texts.append((conditions, conclusions, weight, connection, line))
        else:
            raise tokens.fail(f"unknown entry {key!r} in RULEBLOCK")
        tokens.take(";")
    tokens.take("END_RULEBLOCK")


def _clause(tokens: _Tokens) -> tuple[str, bool, str]:
    variable = tokens.take(kind="word")
    tokens.take("IS")
    negated = tokens.peek() == "NOT"
    if negated:
        tokens.take("NOT")
    return variable, negated, tokens.take(kind="word")
