"""IEC 61131-3 function blocks as data, and their Structured Text.

A `Block` is what a POU holds: its variables by section (`Var`: name, type, array lengths, initial
value, comment) and its body as ST statements. The same data gives the `.st` file here and the
PLCopen XML project (bwr_twin.export.plcopen), so the two cannot disagree.

Numbers are LREAL (IEC 61131-3's 64-bit float, the twin's float64) written so that they read back
to the same double: the shortest repr, with the decimal point IEC's real literals require. A drive
without a rating is limited at the largest LREAL, which no finite force reaches: ST has no infinity.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from bwr_twin.errors import SceneError

LREAL_MAX = float(np.finfo(np.float64).max)
REAL_MAX = float(np.finfo(np.float32).max)
LREAL_TINY = float(np.finfo(np.float64).tiny)  # the smallest normal LREAL: below it, a denormal or 0
REAL_TINY = float(np.finfo(np.float32).tiny)  # the smallest normal REAL, 1.18e-38
SECTIONS = ("VAR_INPUT", "VAR_OUTPUT", "VAR", "VAR CONSTANT")


def lreal(value: float) -> str:
    """An LREAL literal that reads back to the same double: 28000.0, -1.5E-05, 1.7976931348623157E+308."""
    value = float(value)
    if not np.isfinite(value):
        value = LREAL_MAX if value > 0 else -LREAL_MAX
    text = repr(value).upper()
    mantissa, _, exponent = text.partition("E")
    if "." not in mantissa:
        mantissa += ".0"
    return f"{mantissa}E{exponent}" if exponent else mantissa


def as_real(text: str) -> str:
    """The REAL (32-bit) variant of an exported text, for PLCs without LREAL: every LREAL declared
    REAL (DINT_TO_LREAL becoming DINT_TO_REAL). Literals keep their double's digits, which the
    compiler rounds to the nearest REAL; an unrated drive's limit becomes the largest REAL."""
    return (text.replace(lreal(LREAL_MAX), lreal(REAL_MAX)).replace("LREAL", "REAL")
            .replace("64-bit", "32-bit"))


def check_constants(where: str, variables: Sequence[tuple[str, Var]], real: bool) -> None:
    """SceneError naming the first constant that its type cannot hold: beyond the largest REAL
    (with `real`), or nonzero below the smallest normal number (a denormal, which PLCs flush to 0
    or trap on). The largest LREAL, an unrated drive's limit, becomes the largest REAL as it should."""
    kind, largest, tiny = ("REAL", REAL_MAX, REAL_TINY) if real else ("LREAL", LREAL_MAX, LREAL_TINY)
    for owner, var in variables:
        if var.type != "LREAL" or var.value is None:
            continue
        for i, literal in enumerate(var.value):
            value = abs(float(literal))
            if value == LREAL_MAX:
                continue  # ST's infinity, an unrated drive's limit
            if value > largest or 0 < value < tiny:
                index = f"[{i}]" if var.dims else ""
                raise SceneError(f"{where}: the constant {owner}.{var.name}{index} = {literal} lies outside {kind}'s "
                                 f"range (magnitudes {tiny:.3g} to {largest:.3g}, or 0): the PLC cannot hold it")


@dataclass(frozen=True)
class Var:
    """One variable: `dims` the lengths of a 0-based array (empty: a scalar), `value` its initial
    value as ST literals (one per element, row by row; None: none)."""

    name: str
    type: str = "LREAL"
    dims: tuple[int, ...] = ()
    value: tuple[str, ...] | None = None
    comment: str = ""


def reals(name: str, values, comment: str = "") -> Var:
    """An LREAL constant, scalar or array of any rank, from numbers."""
    array = np.asarray(values, dtype=float)
    return Var(name, "LREAL", array.shape, tuple(lreal(v) for v in array.ravel()), comment)


def integers(name: str, values: Sequence[int] | int, comment: str = "") -> Var:
    array = np.asarray(values, dtype=np.int64)
    return Var(name, "DINT", array.shape, tuple(str(int(v)) for v in array.ravel()), comment)


@dataclass(frozen=True)
class Block:
    """A FUNCTION_BLOCK: its variables by section (keys of SECTIONS) and its ST body."""

    name: str
    comment: str
    variables: dict[str, tuple[Var, ...]]
    body: tuple[str, ...]


@dataclass(frozen=True)
class GlobalConstants:
    """A global variable list of constants (VAR_GLOBAL CONSTANT), the blocks' large tables."""

    name: str
    comment: str
    variables: tuple[Var, ...]


def type_text(var: Var) -> str:
    if not var.dims:
        return var.type
    return f"ARRAY[{', '.join(f'0..{n - 1}' for n in var.dims)}] OF {var.type}"


def declaration(var: Var) -> str:
    value = ""
    if var.value is not None:
        value = f" := {var.value[0]}" if not var.dims else f" := [{', '.join(var.value)}]"
    comment = f"  (* {var.comment} *)" if var.comment else ""
    return f"    {var.name} : {type_text(var)}{value};{comment}"


def block_text(block: Block) -> str:
    """The block as an .st file."""
    lines = [f"FUNCTION_BLOCK {block.name}", _comment(block.comment)]
    for section in SECTIONS:
        if block.variables.get(section):
            lines += [section] + [declaration(v) for v in block.variables[section]] + ["END_VAR"]
    return "\n".join(lines + list(block.body) + ["END_FUNCTION_BLOCK"]) + "\n"


def globals_text(constants: GlobalConstants) -> str:
    """The list as an .st file (a GVL, as TwinCAT and CODESYS call it)."""
    lines = ["VAR_GLOBAL CONSTANT", "    " + _comment(constants.comment).replace("\n", "\n    ")]
    return "\n".join(lines + [declaration(v) for v in constants.variables] + ["END_VAR"]) + "\n"


def _comment(text: str) -> str:
    return "(* " + text.replace("\n", "\n   ") + " *)"
