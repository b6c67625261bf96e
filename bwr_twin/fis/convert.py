"""Convert between a FuzzySystem (.fis) and the project's TOML rule base (RuleBase).

A RuleBase is a special Mamdani system: inputs e and ec and one output, all three with the same
set names, each set a triangle (trimf) of `RuleBase.term_abcs` (evenly spaced, feet at the
neighbouring peaks, shoulders at the range ends), one AND rule of weight 1 for every pair of
input sets, min AND, min implication (skfuzzy clips), max aggregation and centroid. Anything
else in a .fis has no place in the TOML file and is refused with a one-line SceneError naming
it. The TOML's input_points and output_points are skfuzzy's sampling, which a .fis does not hold:
converting to .fis drops them (a comment says which they were) and converting back writes
RuleBase's defaults for that number of sets.

`fis_rule_base` reads a .fis file as the fuzzy_model controller's rule base; importing this module
adds it to bwr_twin.control.rulebase.READERS, so that the rule base knows nothing of .fis.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

from bwr_twin.control.rulebase import READERS, RuleBase
from bwr_twin.errors import SceneError
from bwr_twin.fis.fcl import fcl_text, read_fcl
from bwr_twin.fis.fll import fll_text
from bwr_twin.fis.reader import read_fis
from bwr_twin.fis.system import AND, FuzzySystem, MembershipFunction, Rule, Variable, check
from bwr_twin.fis.writer import fis_text, format_number
from bwr_twin.textfile import read_text
from bwr_twin.tomlfile import toml_value

SUFFIXES = (".fis", ".toml", ".fcl")  # what convert reads
OUTPUT_SUFFIXES = SUFFIXES + (".fll",)  # and writes: FLL for fuzzylite (bwr_twin.fis.fll)
INPUT_NAMES = ("e", "ec")
OUTPUT_NAME = "u"  # bwr_twin.control.fuzzy names the output u
_DEFAULT_POINTS = (601, 181)  # RuleBase's input_points, output_points
_TOLERANCE = 1e-9  # of a range's width: how far a set's feet and peak may be from term_abcs (float noise)
# What the TOML rule base fixes, as (FuzzySystem attribute, .fis key, value, TOML key).
_FIXED_METHODS = (
    ("and_method", "AndMethod", "min", "inference.and"),
    ("imp_method", "ImpMethod", "min", "none: skfuzzy clips the output sets, i.e. min"),
    ("agg_method", "AggMethod", "max", "inference.aggregation"),
    ("defuzz_method", "DefuzzMethod", "centroid", "inference.defuzzify"),
)


def rulebase_to_fis(rule_base: RuleBase, name: str | None = None) -> FuzzySystem:
    """The rule base as a Mamdani FuzzySystem: inputs e, ec, output u, trimf sets of term_abcs."""
    name = name if name is not None else (rule_base.path.stem if rule_base.path else "rulebase")

    def variable(var_name: str, bounds: tuple[float, float]) -> Variable:
        abcs = rule_base.term_abcs(*bounds)
        mfs = tuple(MembershipFunction(s, "trimf", abc) for s, abc in zip(rule_base.sets, abcs))
        return Variable(var_name, (float(bounds[0]), float(bounds[1])), mfs)

    index = {s: k + 1 for k, s in enumerate(rule_base.sets)}
    rules = tuple(
        Rule(antecedent=(i + 1, j + 1), consequent=(index[out],), weight=1.0, connection=AND)
        for i, row in enumerate(rule_base.rules)
        for j, out in enumerate(row)
    )
    return check(
        FuzzySystem(
            name=name,
            inputs=(
                variable(INPUT_NAMES[0], rule_base.e_range),
                variable(INPUT_NAMES[1], rule_base.ec_range),
            ),
            outputs=(variable(OUTPUT_NAME, rule_base.output_range),),
            rules=rules,
            and_method=rule_base.and_method,
            or_method="max",
            imp_method="min",
            agg_method=rule_base.aggregation,
            defuzz_method=rule_base.defuzzify,
        )
    )


def fis_to_rulebase(system: FuzzySystem) -> RuleBase:
    """The FuzzySystem as a RuleBase, or a SceneError naming the first thing the TOML cannot express.

    OrMethod is not checked: with no OR rules (which are refused) it has no effect.
    """
    check(system)
    cannot = "cannot be expressed in a TOML rule base"
    if len(system.inputs) != 2:
        raise system.fail("NumInputs", f"{len(system.inputs)} inputs {cannot} (it has exactly 2, e and ec)")
    if len(system.outputs) != 1:
        raise system.fail("NumOutputs", f"{len(system.outputs)} outputs {cannot} (it has exactly 1)")
    for attribute, key, value, toml_key in _FIXED_METHODS:
        if getattr(system, attribute) != value:
            raise system.fail(
                key, f"{key} {getattr(system, attribute)!r} {cannot} (it uses {value!r}; {toml_key})"
            )

    variables = (
        ("input", 1, system.inputs[0]),
        ("input", 2, system.inputs[1]),
        ("output", 1, system.outputs[0]),
    )
    sets = tuple(mf.name for mf in system.inputs[0].mfs)
    if len(sets) < 2 or len(set(sets)) != len(sets):
        raise system.fail("input1", f"input 1 sets {list(sets)} {cannot} (it needs 2 or more distinct names)")
    for kind, i, variable in variables:
        names = tuple(mf.name for mf in variable.mfs)
        if names != sets:
            raise system.fail(
                f"{kind}{i}",
                f"{kind} {i} {variable.name!r} has sets {list(names)}, input 1 has {list(sets)}: "
                f"different sets {cannot} (e, ec and the output share one list, lowest first)",
            )
    probe = RuleBase(sets=sets, rules=(), e_range=(0.0, 1.0), ec_range=(0.0, 1.0), output_range=(0.0, 1.0))
    for kind, i, variable in variables:
        low, high = variable.range
        tolerance = _TOLERANCE * (high - low)
        for k, (mf, abc) in enumerate(zip(variable.mfs, probe.term_abcs(low, high)), start=1):
            place = f"{kind}{i}.mf{k}"
            if mf.type != "trimf":
                raise system.fail(
                    place,
                    f"MF{k} {mf.name!r} of {kind} {i} {variable.name!r} is {mf.type}: non-triangular sets "
                    f"{cannot} (trimf only)",
                )
            if any(abs(p - q) > tolerance for p, q in zip(mf.params, abc)):
                expected = "[" + " ".join(format_number(v) for v in abc) + "]"
                got = "[" + " ".join(format_number(v) for v in mf.params) + "]"
                raise system.fail(
                    place,
                    f"MF{k} {mf.name!r} of {kind} {i} {variable.name!r} is trimf {got}: unevenly spaced sets "
                    f"{cannot} (evenly spaced over [{low:g} {high:g}] it would be {expected})",
                )

    n = len(sets)
    table: dict[tuple[int, int], tuple[int, int]] = {}  # (input sets) -> (rule, output set)
    for r, rule in enumerate(system.rules, start=1):
        place = f"rule{r}"
        if rule.connection != AND:
            raise system.fail(place, f"rule {r} is an OR rule: OR rules {cannot} (AND only)")
        if rule.weight != 1.0:
            raise system.fail(place, f"rule {r} has weight {rule.weight:g}: weights other than 1 {cannot}")
        if any(i <= 0 for i in rule.antecedent + rule.consequent):
            raise system.fail(
                place,
                f"rule {r} uses a 0 (don't care) or negative (NOT) index: {cannot} (one set per input "
                "and for the output)",
            )
        key = (rule.antecedent[0], rule.antecedent[1])
        if key in table:
            raise system.fail(
                place,
                f"rule {r} repeats the inputs of rule {table[key][0]}: {cannot} (one rule per pair of sets)",
            )
        table[key] = (r, rule.consequent[0])
    missing = [(i, j) for i in range(1, n + 1) for j in range(1, n + 1) if (i, j) not in table]
    if missing:
        i, j = missing[0]
        raise system.fail(
            "rules",
            f"{len(missing)} of the {n}x{n} rules are missing, the first for input 1 = {sets[i - 1]} and "
            f"input 2 = {sets[j - 1]}: an incomplete rule table {cannot} (a rule for every pair)",
        )
    rules = tuple(tuple(sets[table[(i, j)][1] - 1] for j in range(1, n + 1)) for i in range(1, n + 1))
    step = 2 * (n - 1)  # RuleBase needs points - 1 to be a multiple of this
    input_points, output_points = (max(1, round((p - 1) / step)) * step + 1 for p in _DEFAULT_POINTS)
    return RuleBase(
        sets=sets,
        rules=rules,
        e_range=tuple(float(v) for v in system.inputs[0].range),
        ec_range=tuple(float(v) for v in system.inputs[1].range),
        output_range=tuple(float(v) for v in system.outputs[0].range),
        input_points=input_points,
        output_points=output_points,
    )


def rulebase_toml(rule_base: RuleBase, source: str, system: FuzzySystem | None = None) -> str:
    """A TOML rule base file, its comments naming the file it was converted from."""
    names = [json.dumps(s, ensure_ascii=False) for s in rule_base.sets]
    width = max(len(name) for name in names) + 2  # a quoted name and its ', ': the columns line up
    out = [
        "# A bwr_twin fuzzy rule base (read by bwr_twin.control.rulebase.RuleBase.from_toml),",
        f"# converted by `python -m bwr_twin.fis convert` from {source}.",
    ]
    if system is not None:
        e, ec, u = system.inputs[0].name, system.inputs[1].name, system.outputs[0].name
        out.append(f"# There: input 1 {e!r} is e, input 2 {ec!r} is ec, output {u!r} is the output.")
    out += [
        "",
        "# The set names of e, ec and the output, lowest first.",
        f"sets = [{', '.join(names)}]",
        "",
        "# One row per set of e, one column per set of ec; each entry is the output's set.",
        "rules = [",
        "  # ec: " + "".join(s.ljust(width) for s in rule_base.sets).rstrip(),
    ]
    for set_name, row in zip(rule_base.sets, rule_base.rules):
        cells = "".join((json.dumps(s, ensure_ascii=False) + ",").ljust(width) for s in row).rstrip()[:-1]
        out.append(f"  [{cells}],  # e = {set_name}")
    out += [
        "]",
        "",
        "[universe]",
        f"e = [{toml_value(float(rule_base.e_range[0]))}, {toml_value(float(rule_base.e_range[1]))}]",
        f"ec = [{toml_value(float(rule_base.ec_range[0]))}, {toml_value(float(rule_base.ec_range[1]))}]",
        f"output = [{toml_value(float(rule_base.output_range[0]))}, {toml_value(float(rule_base.output_range[1]))}]",
        "",
        "[membership]",
        "# Evenly spaced triangles (RuleBase.term_abcs), as the sets of the source were.",
        f'shape = "{rule_base.shape}"',
    ]
    if system is not None:
        out.append("# A .fis file holds no sample counts: RuleBase's defaults for this number of sets.")
    out += [
        f"input_points = {rule_base.input_points}",
        f"output_points = {rule_base.output_points}",
        "",
        "[inference]",
        f'and = "{rule_base.and_method}"',
        f'aggregation = "{rule_base.aggregation}"',
        f'defuzzify = "{rule_base.defuzzify}"',
    ]
    return "\n".join(out) + "\n"


def fis_rule_base(path: Path) -> RuleBase:
    """A .fis file as the fuzzy_model controller's rule base, if a RuleBase can express it (two
    inputs, evenly spaced triangular sets, a full rule table, min/max/centroid)."""
    try:
        return fis_to_rulebase(read_fis(path))
    except SceneError as exc:
        raise SceneError(f"{exc} (as a rule base of the fuzzy_model controller: docs/fis.md)") from None


READERS[".fis"] = fis_rule_base


def load_system(path: str | Path) -> FuzzySystem:
    """A .fis or .fcl file, or a TOML rule base converted to a FuzzySystem (by the suffix)."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".fis":
        return read_fis(path)
    if suffix == ".fcl":
        return read_fcl(path)
    if suffix == ".toml":
        rule_base = _toml_rule_base(path)
        return rulebase_to_fis(rule_base, name=path.stem)
    raise SceneError(f"{path}: unknown input suffix {path.suffix!r} (known: {', '.join(SUFFIXES)})")


def _toml_rule_base(path: Path) -> RuleBase:
    """RuleBase.from_toml, with the line of the offending key added to its message where it can."""
    try:
        return RuleBase.from_toml(path)
    except SceneError as exc:
        raise SceneError(_with_line(str(exc), path)) from None


def output_text(system: FuzzySystem, out: Path, source: str) -> str:
    """What `convert` writes to `out`: .fis, FCL or FLL text, or a TOML rule base (refusing what it
    cannot hold)."""
    suffix = out.suffix.lower()
    converted = f"Converted by `python -m bwr_twin.fis convert` from {source}."
    if suffix == ".fcl":
        return fcl_text(system, [converted])
    if suffix == ".fll":
        return fll_text(system, [converted])
    if suffix == ".fis":
        comments = [f"Converted by `python -m bwr_twin.fis convert` from {source}."]
        if Path(source).suffix.lower() == ".toml":
            rule_base = _toml_rule_base(Path(source))
            comments.append(
                f"The rule base evaluated e and ec on {rule_base.input_points} samples and the output on "
                f"{rule_base.output_points} (skfuzzy); a .fis holds no sample counts (evalfis uses 101)."
            )
        return fis_text(system, comments)
    if suffix == ".toml":
        return rulebase_toml(fis_to_rulebase(system), source, system)
    raise SceneError(f"{out}: unknown output suffix {out.suffix!r} (known: {', '.join(OUTPUT_SUFFIXES)})")


def _with_line(message: str, path: Path) -> str:
    prefix = f"{path}: "
    if not message.startswith(prefix):
        return message
    rest = message[len(prefix) :]
    decode = re.search(r"\(at line (\d+), column (\d+)\)", rest)
    if decode:
        return f"{path}:{decode[1]}: {rest[: decode.start()].rstrip()} (column {decode[2]})"
    key = re.match(r"(?:key|missing key) '([^']+)'", rest)
    if key is None:
        return message
    try:
        text = read_text(path)
    except (OSError, UnicodeDecodeError):
        return message
    return f"{path}:{_toml_key_line(text, key[1])}: {rest}"


def _toml_key_line(text: str, dotted: str) -> int:
    """The line defining a dotted key (or else its table's header, or else 1): for messages only."""
    parts = dotted.split(".")
    table, header = "", None
    for number, raw in enumerate(text.splitlines(), start=1):
        line = raw.split("#", 1)[0].strip()
        match = re.fullmatch(r"\[\s*([^\]]+?)\s*\]", line)
        if match:
            table = match[1]
            if table == parts[0]:
                header = number
            continue
        if table == ".".join(parts[:-1]) and re.match(rf"{re.escape(parts[-1])}\s*=", line):
            return number
    return header or 1
