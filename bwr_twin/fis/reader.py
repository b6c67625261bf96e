"""Read MATLAB Fuzzy Logic Toolbox .fis files (type-1 Mamdani) into a FuzzySystem.

The format is INI-like: [System], [Input1].., [Output1].., [Rules]; `Key=Value` lines (spaces
around '=' allowed), strings in single quotes, vectors in brackets, `%` comment lines and blank
lines anywhere. A membership function is `MF1='name':'trimf',[0 5 10]`; a rule is
`1 -2, 3 (0.5) : 1` (input indices, comma, output indices, weight, colon, 1 AND / 2 OR).
Version may be missing; NumInputs, NumOutputs, NumRules and NumMFs, when present, must match what
the file holds; missing methods take MATLAB's defaults (min, max, min, max, centroid).

Every problem is a one-line SceneError 'FILE:LINE: what is wrong (the limit)'.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

from bwr_twin.errors import SceneError, shown_text
from bwr_twin.fis.system import METHODS, FuzzySystem, MembershipFunction, Rule, Variable, check
from bwr_twin.textfile import decode

_NUMBER = r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?"
_NUMBER_RE = re.compile(_NUMBER)
_INT_RE = re.compile(r"[+-]?\d+")
_HEADER_RE = re.compile(r"\[\s*([A-Za-z]+)\s*(\d*)\s*\]")
_STRING_RE = re.compile(r"'([^']*)'")
_MF_RE = re.compile(r"'([^']*)'\s*:\s*'([^']*)'\s*,\s*\[([^\]]*)\]")
_RULE_RE = re.compile(r"([^,]*),([^(]*)\(([^)]*)\)\s*:\s*(\S+)")
_SYSTEM_KEYS = ("Name", "Type", "Version", "NumInputs", "NumOutputs", "NumRules") + tuple(
    m[1] for m in METHODS
)
_VARIABLE_KEYS = ("Name", "Range", "NumMFs", "MF1", "MF2", "...")


@dataclass
class _Section:
    key: str  # 'system', 'input1', 'output2', 'rules'
    title: str  # as written in messages: '[Input1]'
    line: int
    entries: dict[str, tuple[str, str, int]] = field(default_factory=dict)  # lower key -> (key, value, line)
    rules: list[tuple[str, int]] = field(default_factory=list)


def read_fis(path: str | Path) -> FuzzySystem:
    """Read and check a .fis file; every problem is a one-line SceneError naming file and line."""
    path = Path(path)
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        raise SceneError(f"{path}: .fis file not found") from None
    except OSError as exc:
        raise SceneError(f"{path}: cannot read the .fis file: {exc.strerror}") from None
    try:
        text = decode(data)
    except UnicodeDecodeError:
        # MATLAB on Windows writes names in the system code page; latin-1 reads any byte.
        text = data.decode("latin-1").replace("\r\n", "\n")
    return parse_fis(text, path)


def parse_fis(text: str, path: str | Path = "<string>") -> FuzzySystem:
    """Parse .fis text (as read_fis does); `path` only names the source in messages."""
    path = Path(path)
    sections = _split_sections(text, path)
    lines: dict[str, int] = {}

    def fail(line: int, what: str) -> SceneError:
        return SceneError(f"{path}:{line}: {what}")

    system = sections.get("system")
    if system is None:
        first = min((s.line for s in sections.values()), default=1)
        raise fail(first, "missing section [System] (it holds Name, Type, NumInputs, ..., DefuzzMethod)")
    lines["system"] = system.line
    for lower, (key, _, line) in system.entries.items():
        if lower not in {k.lower() for k in _SYSTEM_KEYS}:
            raise fail(line, f"unknown key {key!r} in [System] (known: {', '.join(_SYSTEM_KEYS)})")
        lines[_canonical(key, _SYSTEM_KEYS)] = line

    fis_type = _string(system, "Type", path, required=True)
    if fis_type.lower() != "mamdani":
        line = system.entries["type"][2]
        if fis_type.lower() == "sugeno":
            raise fail(
                line, "Type 'sugeno' is not supported: only type-1 Mamdani systems are (Type='mamdani')"
            )
        raise fail(line, f"unknown Type {fis_type!r} (supported: 'mamdani')")
    name = _string(system, "Name", path, required=False)
    if name is None:
        name = path.stem
    methods = {}
    for attribute, key, allowed in METHODS:
        value = _string(system, key, path, required=False)
        methods[attribute] = allowed[0] if value is None else value.lower()
    counts = {key: _count(system, key, path) for key in ("NumInputs", "NumOutputs", "NumRules")}

    variables = {}
    for kind, count_key in (("input", "NumInputs"), ("output", "NumOutputs")):
        present = sorted(int(k[len(kind) :]) for k in sections if k.startswith(kind))
        declared = counts[count_key]
        n = declared if declared is not None else (present[-1] if present else 0)
        title = kind.capitalize()
        for i in range(1, n + 1):
            if f"{kind}{i}" not in sections:
                if declared is not None:
                    raise fail(
                        system.entries[count_key.lower()][2],
                        f"missing section [{title}{i}] ({count_key}={declared} needs {_span(title, n)})",
                    )
                later = sections[f"{kind}{present[-1]}"]
                raise fail(later.line, f"missing section [{title}{i}] ({later.title} needs [{title}1]..)")
        for i in present:
            if i > n:
                section = sections[f"{kind}{i}"]
                raise fail(section.line, f"section {section.title} but {count_key}={n} (sections 1..{n})")
        variables[kind] = tuple(_variable(sections[f"{kind}{i}"], path, lines) for i in range(1, n + 1))

    rules_section = sections.get("rules")
    if rules_section is None:
        raise fail(
            system.line, "missing section [Rules] (one line a rule, e.g. '1 1, 1 (1) : 1')"
        )
    lines["rules"] = rules_section.line
    if not rules_section.rules:
        raise fail(rules_section.line, "[Rules] holds no rule (at least one, one line a rule, e.g. '1 1, 1 (1) : 1')")
    rules = []
    for r, (text_line, line) in enumerate(rules_section.rules, start=1):
        rules.append(_rule(text_line, line, r, path))
        lines[f"rule{r}"] = line
    if counts["NumRules"] is not None and counts["NumRules"] != len(rules):
        raise fail(
            system.entries["numrules"][2],
            f"NumRules={counts['NumRules']} but [Rules] holds {len(rules)} rules",
        )

    return check(
        FuzzySystem(
            name=name,
            inputs=variables["input"],
            outputs=variables["output"],
            rules=tuple(rules),
            path=path,
            lines=lines,
            **methods,
        )
    )


def _span(title: str, n: int) -> str:
    return f"[{title}1]" if n == 1 else f"[{title}1]..[{title}{n}]"


def _split_sections(text: str, path: Path) -> dict[str, _Section]:
    sections: dict[str, _Section] = {}
    current: _Section | None = None
    for number, raw in enumerate(text.splitlines(), start=1):
        line = raw.strip()
        if not line or line.startswith("%"):
            continue
        if line.startswith("["):
            current = _header(line, number, path)
            if current.key in sections:
                first = sections[current.key].line
                raise SceneError(
                    f"{path}:{number}: section {current.title} appears twice (first on line {first})"
                )
            sections[current.key] = current
            continue
        if current is None:
            raise SceneError(
                f"{path}:{number}: text before the first section: {shown_text(line)} ([System] comes first)"
            )
        if current.key == "rules":
            current.rules.append((line, number))
            continue
        if "=" not in line:
            raise SceneError(f"{path}:{number}: expected Key=Value in {current.title}, got {shown_text(line)}")
        key, value = (part.strip() for part in line.split("=", 1))
        if key.lower() in current.entries:
            first = current.entries[key.lower()][2]
            raise SceneError(
                f"{path}:{number}: key {key!r} appears twice in {current.title} (first on line {first})"
            )
        current.entries[key.lower()] = (key, value, number)
    return sections


def _header(line: str, number: int, path: Path) -> _Section:
    match = _HEADER_RE.fullmatch(line)
    kind = match[1].lower() if match else ""
    index = match[2] if match else ""
    if kind in ("system", "rules") and not index:
        return _Section(kind, f"[{kind.capitalize()}]", number)
    if kind in ("input", "output") and index and int(index) >= 1:
        return _Section(f"{kind}{int(index)}", f"[{kind.capitalize()}{int(index)}]", number)
    raise SceneError(
        f"{path}:{number}: unknown section {shown_text(line)} (known: [System], [Input1].., [Output1].., [Rules])"
    )


def _canonical(key: str, known: tuple[str, ...]) -> str:
    return next((k for k in known if k.lower() == key.lower()), key)


def _string(section: _Section, key: str, path: Path, required: bool) -> str | None:
    entry = section.entries.get(key.lower())
    if entry is None:
        if required:
            raise SceneError(f"{path}:{section.line}: missing key {key} in {section.title}")
        return None
    match = _STRING_RE.fullmatch(entry[1])
    if match is None:
        raise SceneError(
            f"{path}:{entry[2]}: {key} must be a quoted string like '{key.lower()}', got {shown_text(entry[1])}"
        )
    return match[1]


def _count(section: _Section, key: str, path: Path) -> int | None:
    entry = section.entries.get(key.lower())
    if entry is None:
        return None
    if not _INT_RE.fullmatch(entry[1]) or int(entry[1]) < 0:
        raise SceneError(f"{path}:{entry[2]}: {key} must be a whole number >= 0, got {shown_text(entry[1])}")
    return int(entry[1])


def _numbers(text: str, line: int, path: Path, what: str) -> tuple[float, ...]:
    items = [item for item in re.split(r"[\s,;]+", text.strip()) if item]
    for item in items:
        if not _NUMBER_RE.fullmatch(item):
            raise SceneError(f"{path}:{line}: {what}: {shown_text(item)} is not a number")
    return tuple(float(item) for item in items)


def _variable(section: _Section, path: Path, lines: dict[str, int]) -> Variable:
    lines[section.key] = section.line
    mf_entries: dict[int, tuple[str, int]] = {}
    for lower, (key, value, line) in section.entries.items():
        match = re.fullmatch(r"mf(\d+)", lower)
        if match and int(match[1]) >= 1:
            mf_entries[int(match[1])] = (value, line)
        elif lower not in ("name", "range", "nummfs"):
            raise SceneError(
                f"{path}:{line}: unknown key {shown_text(key)} in {section.title} (known: {', '.join(_VARIABLE_KEYS)})"
            )
    name = _string(section, "Name", path, required=True)
    range_entry = section.entries.get("range")
    if range_entry is None:
        raise SceneError(f"{path}:{section.line}: missing key Range in {section.title} (Range=[low high])")
    value, line = range_entry[1], range_entry[2]
    lines[f"{section.key}.range"] = line
    if not (value.startswith("[") and value.endswith("]")):
        raise SceneError(f"{path}:{line}: Range must be [low high], two numbers, got {shown_text(value)}")
    bounds = _numbers(value[1:-1], line, path, "Range must be [low high], two numbers")
    if len(bounds) != 2:
        raise SceneError(
            f"{path}:{line}: Range must be [low high], two numbers, got {len(bounds)}: {shown_text(value)}"
        )

    n = max(mf_entries, default=0)
    for k in range(1, n + 1):
        if k not in mf_entries:
            raise SceneError(
                f"{path}:{mf_entries[n][1]}: MF{k} is missing in {section.title} (MF1..MF{n} expected)"
            )
    declared = _count(section, "NumMFs", path)
    if declared is not None and declared != n:
        line = section.entries["nummfs"][2]
        raise SceneError(f"{path}:{line}: NumMFs={declared} but {section.title} holds {n} MF lines")
    mfs = []
    for k in range(1, n + 1):
        value, line = mf_entries[k]
        lines[f"{section.key}.mf{k}"] = line
        match = _MF_RE.fullmatch(value)
        if match is None:
            raise SceneError(f"{path}:{line}: MF{k} must look like 'name':'trimf',[a b c], got {shown_text(value)}")
        params = _numbers(match[3], line, path, f"MF{k} {match[1]!r} parameters")
        mfs.append(MembershipFunction(name=match[1], type=match[2].strip(), params=params))
    return Variable(name=name, range=(bounds[0], bounds[1]), mfs=tuple(mfs))


def _rule(text: str, line: int, r: int, path: Path) -> Rule:
    match = _RULE_RE.fullmatch(text)
    if match is None:
        raise SceneError(
            f"{path}:{line}: rule {r} must look like '1 2, 1 (1) : 1' "
            "(inputs, outputs (weight) : 1 AND / 2 OR), "
            f"got {shown_text(text)}"
        )
    columns = []
    for part, what in ((match[1], "antecedent"), (match[2], "consequent")):
        items = part.split()
        for item in items:
            if not _INT_RE.fullmatch(item):
                raise SceneError(
                    f"{path}:{line}: rule {r}: {what} index {shown_text(item)} is not a whole number "
                    "(1-based set index, 0 don't care, negative NOT)"
                )
        columns.append(tuple(int(item) for item in items))
    weight_text = match[3].strip()
    if not _NUMBER_RE.fullmatch(weight_text):
        raise SceneError(f"{path}:{line}: rule {r}: weight {shown_text(weight_text)} is not a number (in [0, 1])")
    connection = match[4]
    if connection not in ("1", "2"):
        raise SceneError(f"{path}:{line}: rule {r}: connection {shown_text(connection)} must be 1 (AND) or 2 (OR)")
    return Rule(
        antecedent=columns[0], consequent=columns[1], weight=float(weight_text), connection=int(connection)
    )
