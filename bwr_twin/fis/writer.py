"""Write a FuzzySystem as a MATLAB Fuzzy Logic Toolbox .fis file, laid out as MATLAB's writefis does.

Numbers are written in the shortest form that reads back to the same float (10, 1.5, 1e-16), so
that reading the file gives an equal FuzzySystem; MATLAB reads them all.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from pathlib import Path

from bwr_twin.fis.system import METHODS, FuzzySystem, Rule, check


def format_number(value: float) -> str:
    """A float as MATLAB-style text that reads back exactly: 10 (not 10.0), 1.5, -0.25, 1e-16."""
    value = float(value)
    if value.is_integer() and abs(value) < 1e15:
        return str(int(value))
    return repr(value)


def format_vector(values: Sequence[float]) -> str:
    """'[0 5 10]': a MATLAB row vector."""
    return "[" + " ".join(format_number(v) for v in values) + "]"


def format_rule(rule: Rule) -> str:
    """'1 -2, 3 (0.5) : 1': antecedent indices, comma, consequent indices, (weight), : connection."""
    antecedent = " ".join(str(i) for i in rule.antecedent)
    consequent = " ".join(str(i) for i in rule.consequent)
    return f"{antecedent}, {consequent} ({format_number(rule.weight)}) : {rule.connection}"


def fis_text(system: FuzzySystem, comments: Iterable[str] = ()) -> str:
    """The .fis file's text; `comments` become '%' lines at the top. Checks the system first."""
    check(system)
    out = [f"% {line}".rstrip() for comment in comments for line in comment.splitlines()]
    if out:
        out.append("")
    out += [
        "[System]",
        f"Name='{system.name}'",
        "Type='mamdani'",
        "Version=2.0",
        f"NumInputs={len(system.inputs)}",
        f"NumOutputs={len(system.outputs)}",
        f"NumRules={len(system.rules)}",
    ]
    out += [f"{key}='{getattr(system, attribute)}'" for attribute, key, _ in METHODS]
    for title, variables in (("Input", system.inputs), ("Output", system.outputs)):
        for i, variable in enumerate(variables, start=1):
            out += [
                "",
                f"[{title}{i}]",
                f"Name='{variable.name}'",
                f"Range={format_vector(variable.range)}",
                f"NumMFs={len(variable.mfs)}",
            ]
            out += [
                f"MF{k}='{mf.name}':'{mf.type}',{format_vector(mf.params)}"
                for k, mf in enumerate(variable.mfs, start=1)
            ]
    out += ["", "[Rules]"]
    out += [format_rule(rule) for rule in system.rules]
    return "\n".join(out) + "\n"


def write_fis(system: FuzzySystem, path: str | Path, comments: Iterable[str] = ()) -> None:
    """Write the .fis file atomically (a temporary file renamed into place); replaces `path`."""
    from bwr_twin.ownership import write_atomically

    text = fis_text(system, comments)
    write_atomically(Path(path), lambda temporary: temporary.write_text(text, encoding="utf-8"))
