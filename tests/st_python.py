"""Structured Text, parsed by blark (an independent IEC 61131-3 parser), turned into Python.

The tests run the exported function blocks with it: blark's tree of a FUNCTION_BLOCK becomes the
source of a Python class whose `__call__` runs the block's body once, its VAR and VAR_OUTPUT kept
between calls as a PLC keeps them. Only what the exporter writes is translated (LREAL and DINT
scalars and 0-based arrays of any rank, global constants, :=, FOR, EXIT, IF/ELSIF/ELSE, arithmetic, comparisons, AND/OR/NOT, MIN, MAX,
LIMIT, COS, SIN, ABS, SQRT, TRUNC); anything else raises NotImplementedError naming the node.
Python floats are IEEE doubles, as LREAL: each operation rounds as a PLC's does. AND and OR
evaluate both sides, as IEC 61131-3's do (AND_THEN and OR_ELSE are the short-circuit ones).
"""

from __future__ import annotations

import math
import operator
import re

import numpy as np

from blark import parse_source_code
from blark import transform as tf

_BINARY = {"+": "+", "-": "-", "*": "*", "/": "/", "<": "<", ">": ">", "<=": "<=", ">=": ">=", "=": "==",
           "<>": "!=", "AND": "&", "OR": "|"}
_FUNCTIONS = {"MIN": "min", "MAX": "max", "COS": "_math.cos", "SIN": "_math.sin", "ABS": "abs",
              "SQRT": "_math.sqrt", "TRUNC": "_trunc", "DINT_TO_LREAL": "float", "LIMIT": "_limit"}


def load_block(text: str, global_constants: dict | None = None, number: type | None = None):
    """The first FUNCTION_BLOCK of the ST `text` as a Python class (instances keep their state);
    names it does not declare are looked up in `global_constants` (`read_global_constants`). A
    block declared in REAL computes in numpy's float32, every literal, input and result rounded
    to single precision as a PLC's REAL is. `number`, a float subclass, holds an LREAL block's
    numbers instead of float (every literal, input, constant and function result made one): one
    that counts the operations done on it, say."""
    parsed = parse_source_code(text)
    if parsed.exception is not None:
        raise parsed.exception
    source = parsed.transform()
    block = next(item for item in source.items if isinstance(item, tf.FunctionBlock))
    if "LREAL" not in text and " REAL" in text:
        number = np.float32
    constants = global_constants or {}
    if number is not None:
        constants = {name: _as_number(value, number) for name, value in constants.items()}
    return _Translator(block, constants, number).build()


def _as_number(value, number: type):
    """A constant held as `number`, in nested lists for arrays; DINTs stay int."""
    if isinstance(value, list):
        return [_as_number(v, number) for v in value]
    return number(value) if isinstance(value, float) else value


class _Results:
    """math's functions, their results held as `number`."""

    def __init__(self, number: type):
        self.number = number

    def __getattr__(self, name: str):
        function = getattr(math, name)
        return lambda *args: self.number(function(*args))


_GLOBAL = re.compile(r"^\s*(\w+)\s*:\s*ARRAY\[([^\]]*)\]\s*OF\s+(L?REAL|DINT)\s*:=\s*\[([^\]]*)\];", re.MULTILINE)


_SCALAR = re.compile(r"^\s*(\w+)\s*:\s*(L?REAL|DINT)\s*:=\s*([^;]+);", re.MULTILINE)


def read_global_constants(text: str) -> dict:
    """The LREAL and DINT arrays (as nested lists of floats or ints) and scalars of a VAR_GLOBAL
    CONSTANT file.

    blark's Earley grammar is ambiguous on a bare list of array elements, and its parse time grows
    with the cube of the list (200 numbers take a minute): the numbers of these long initialisers
    are read here, each literal by Python's float(), the logic that uses them by blark.
    """
    assert "VAR_GLOBAL CONSTANT" in text and text.rstrip().endswith("END_VAR")
    constants = {}
    for name, ranges, kind, values in _GLOBAL.findall(text):
        shape = [int(stop) - int(start) + 1 for start, stop in (r.split("..") for r in ranges.split(","))]
        flat = np.array([int(v) if kind == "DINT" else float(v) for v in values.split(",")])
        constants[name] = flat.reshape(shape).tolist()
    for name, kind, value in _SCALAR.findall(text):
        constants[name] = int(value) if kind == "DINT" else float(value)
    return constants


class _Translator:
    def __init__(self, block, global_constants: dict, number: type | None = None):
        self.block = block
        self.number = number  # None: Python's float
        self.global_constants = global_constants
        self.declared: set[str] = set()
        self.inputs: list[str] = []
        self.state: list[str] = []  # outputs and locals: attributes of the instance
        self.init: list[str] = []

    def build(self):
        for declarations in self.block.declarations:
            for item in declarations.items:
                names = [str(v.variable.name) for v in item.variables]
                self.declared.update(names)
                value = self.initial(item.init)
                for name in names:
                    if isinstance(declarations, tf.InputDeclarations):
                        self.inputs.append(name)
                    self.state.append(name)
                    self.init.append(f"        self.{name} = {value}")
        lines = ["class Block:", "    def __init__(self):"] + (self.init or ["        pass"])
        lines += ["    def __call__(self, " + ", ".join(self.inputs) + "):"]
        lines += [f"        self.{name} = _F({name})" if self.number else f"        self.{name} = {name}"
                  for name in self.inputs]
        lines += self.statements(self.block.body, 2) or ["        pass"]
        number = self.number
        functions = math if number is None else np if number is np.float32 else _Results(number)
        namespace = {"_math": functions, "_trunc": int,
                     "_limit": lambda mn, x, mx: min(max(x, mn), mx), "_G": self.global_constants,
                     "_F": (lambda x: [number(v) for v in x] if isinstance(x, list) else number(x))}
        exec(compile("\n".join(lines), f"<{self.block.name}>", "exec"), namespace)
        return namespace["Block"]

    def initial(self, init) -> str:
        if isinstance(init, tf.ArrayTypeInitialization):
            lengths = [int(str(r.stop.value)) - int(str(r.start.value)) + 1 for r in init.spec.subranges]
            zero = "0" if str(init.spec.type.type_name) == "DINT" else self.real_literal(0.0)
            if init.value is None:
                nested = f"[{zero}] * {lengths[-1]}"
                for length in reversed(lengths[:-1]):
                    nested = f"[{nested} for _ in range({length})]"
                return nested
            if len(lengths) != 1:
                raise NotImplementedError("an initialised array of more than one dimension")
            return "[" + ", ".join(self.expression(e) for e in _flat(init.value)) + "]"
        if isinstance(init, tf.TypeInitialization):
            if init.value is not None:
                return self.expression(init.value)
            return "0" if str(init.spec.type) == "DINT" else self.real_literal(0.0)
        raise NotImplementedError(type(init).__name__)

    def real_literal(self, value: float) -> str:
        return f"_F({value!r})" if self.number else repr(value)

    def statements(self, statement_list, depth: int) -> list[str]:
        pad = "    " * depth
        out = []
        for statement in statement_list.statements if statement_list is not None else ():
            if isinstance(statement, tf.AssignmentStatement):
                (target,) = statement.variables
                out.append(f"{pad}{self.expression(target)} = {self.expression(statement.expression)}")
            elif isinstance(statement, tf.ForStatement):
                control = self.expression(statement.control)
                step = self.expression(statement.step) if statement.step is not None else "1"
                out.append(f"{pad}for {control} in range({self.expression(statement.from_)}, "
                           f"{self.expression(statement.to)} + 1, {step}):")
                out += self.statements(statement.statements, depth + 1) or [f"{pad}    pass"]
            elif isinstance(statement, tf.IfStatement):
                out.append(f"{pad}if {self.expression(statement.if_expression)}:")
                out += self.statements(statement.statements, depth + 1) or [f"{pad}    pass"]
                for clause in statement.else_ifs:
                    out.append(f"{pad}elif {self.expression(clause.if_expression)}:")
                    out += self.statements(clause.statements, depth + 1) or [f"{pad}    pass"]
                if statement.else_clause is not None:
                    out.append(f"{pad}else:")
                    out += self.statements(statement.else_clause.statements, depth + 1) or [f"{pad}    pass"]
            elif isinstance(statement, tf.ExitStatement):
                out.append(f"{pad}break")
            else:
                raise NotImplementedError(type(statement).__name__)
        return out

    def expression(self, node) -> str:
        if isinstance(node, tf.Real):
            return self.real_literal(float(str(node.value)))
        if isinstance(node, tf.Integer):
            return str(int(str(node.value)))
        if isinstance(node, tf.SimpleVariable):
            if str(node.name) not in self.declared:
                if str(node.name) not in self.global_constants:
                    raise NameError(f"{node.name} is neither declared nor a global constant")
                return f"_G[{str(node.name)!r}]"
            return f"self.{node.name}"
        if isinstance(node, tf.MultiElementVariable):
            (subscripts,) = node.elements
            index = "][".join(self.expression(s) for s in subscripts.subscripts)
            return f"{self.expression(node.name)}[{index}]"
        if isinstance(node, tf.ParenthesizedExpression):
            return f"({self.expression(node.expr)})"
        if isinstance(node, tf.UnaryOperation):
            op = "not " if str(node.op).upper() == "NOT" else str(node.op)
            return f"({op}{self.expression(node.expr)})"
        if isinstance(node, tf.BinaryOperation):
            return f"({self.expression(node.left)} {_BINARY[str(node.op).upper()]} {self.expression(node.right)})"
        if isinstance(node, tf.FunctionCall):
            name = _FUNCTIONS[str(node.name.name).upper().replace("_TO_REAL", "_TO_LREAL")]
            if self.number and name == "float":
                name = "_F"
            return f"{name}(" + ", ".join(self.expression(p.value) for p in node.parameters) + ")"
        raise NotImplementedError(type(node).__name__)


def _flat(initialization) -> list:
    """blark nests an initialiser's later elements: [a, b, c] is a, then [b, c] without brackets."""
    out = []
    for element in initialization.elements:
        inner = element.element
        out += _flat(inner) if isinstance(inner, tf.ArrayInitialization) else [inner]
    return out


def load_exported(folder, number: type | None = None) -> object:
    """A new instance of the function block `python -m bwr_twin.export plc` wrote into `folder`,
    its global constant lists read (`number`: as `load_block`'s)."""
    from pathlib import Path

    folder = Path(folder)
    constants = {}
    for global_list in sorted(folder.glob("GVL_*.st")):
        constants |= read_global_constants(global_list.read_text())
    (block,) = folder.glob("FB_*.st")
    return load_block(block.read_text(), constants, number)()


def forces_on(block, result) -> np.ndarray:
    """The block run once a control period on a recorded run's measured and reference states (a
    run recorded every period): its drive forces, (periods, 3). A block with `qdd_ref` gets it."""
    return outputs_on(block, result)["force"]


def outputs_on(block, result, names=("force",), periods=None) -> dict[str, np.ndarray]:
    """The block run on a recorded run's measured and reference states at `periods` (indices
    into the record, in order; every period by default): each of its variables `names` after each
    call, (len(periods), *shape), in float64."""
    periods = range(len(result.time)) if periods is None else periods
    references = [result.q_desired, result.qd_desired]
    if "qdd_ref" in vars(block):
        references.append(result.qdd_desired)
    outputs = {name: np.empty((len(periods), *np.shape(getattr(block, name)))) for name in names}
    for row, k in enumerate(periods):
        block(list(result.q_measured[k]), list(result.qd_measured[k]), *(list(x[k]) for x in references))
        for name, values in outputs.items():
            values[row] = getattr(block, name)
    return outputs


def counting_real() -> type:
    """A float subclass for `load_block`'s `number` that counts, in its dict `counts`, the
    operations done on it: "arithmetic" (+, -, *, /, negation, ABS, DINT_TO_LREAL, TRUNC), of
    them "divisions", and "comparisons" (<, <=, >, >=, =, <>; MIN and MAX one each, LIMIT two).
    Functions such as COS are not counted."""
    counts = {"arithmetic": 0, "divisions": 0, "comparisons": 0}

    class Counted(float):
        def __new__(cls, value=0.0):
            if isinstance(value, int):  # DINT_TO_LREAL
                counts["arithmetic"] += 1
            return super().__new__(cls, value)

        def __int__(self):  # TRUNC
            counts["arithmetic"] += 1
            return int(float(self))

        __hash__ = float.__hash__

    def arithmetic(operation, kind="arithmetic"):
        def counted(*operands):
            counts["arithmetic"] += 1
            if kind != "arithmetic":
                counts[kind] += 1
            return Counted(operation(*map(float, operands)))
        return counted

    def comparison(operation):
        def counted(left, right):
            counts["comparisons"] += 1
            return operation(float(left), float(right))
        return counted

    for name in ("add", "sub", "mul", "truediv"):
        forward, kind = getattr(operator, name), "divisions" if name == "truediv" else "arithmetic"
        setattr(Counted, f"__{name}__", arithmetic(forward, kind))
        setattr(Counted, f"__r{name}__", arithmetic(lambda a, b, forward=forward: forward(b, a), kind))
    for name in ("neg", "abs"):
        setattr(Counted, f"__{name}__", arithmetic(getattr(operator, name)))
    for name in ("lt", "le", "gt", "ge", "eq", "ne"):
        setattr(Counted, f"__{name}__", comparison(getattr(operator, name)))
    Counted.counts = counts
    return Counted
