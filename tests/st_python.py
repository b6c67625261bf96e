"""Structured Text, parsed by blark (an independent IEC 61131-3 parser), turned into Python.

The tests run the exported function blocks with it: blark's tree of a FUNCTION_BLOCK becomes the
source of a Python class whose `__call__` runs the block's body once, its VAR and VAR_OUTPUT kept
between calls as a PLC keeps them. Only what the exporter writes is translated (LREAL and DINT
scalars and 0-based arrays of any rank, global constants, :=, FOR, IF/ELSIF/ELSE, arithmetic, comparisons, AND/OR/NOT, MIN, MAX,
LIMIT, COS, SIN, ABS, SQRT, TRUNC); anything else raises NotImplementedError naming the node.
Python floats are IEEE doubles, as LREAL: each operation rounds as a PLC's does.
"""

from __future__ import annotations

import math
import re

import numpy as np

from blark import parse_source_code
from blark import transform as tf

_BINARY = {"+": "+", "-": "-", "*": "*", "/": "/", "<": "<", ">": ">", "<=": "<=", ">=": ">=", "=": "==",
           "<>": "!=", "AND": "and", "OR": "or"}
_FUNCTIONS = {"MIN": "min", "MAX": "max", "COS": "_math.cos", "SIN": "_math.sin", "ABS": "abs",
              "SQRT": "_math.sqrt", "TRUNC": "_trunc", "DINT_TO_LREAL": "float", "LIMIT": "_limit"}


def load_block(text: str, global_constants: dict | None = None):
    """The first FUNCTION_BLOCK of the ST `text` as a Python class (instances keep their state);
    names it does not declare are looked up in `global_constants` (`read_global_constants`). A
    block declared in REAL computes in numpy's float32, every literal, input and result rounded
    to single precision as a PLC's REAL is."""
    parsed = parse_source_code(text)
    if parsed.exception is not None:
        raise parsed.exception
    source = parsed.transform()
    block = next(item for item in source.items if isinstance(item, tf.FunctionBlock))
    real = "LREAL" not in text and " REAL" in text
    constants = global_constants or {}
    if real:
        constants = {name: _single(value) for name, value in constants.items()}
    return _Translator(block, constants, real).build()


def _single(value):
    """A constant as a PLC's REAL holds it: float32, in nested lists for arrays."""
    if isinstance(value, list):
        return [_single(v) for v in value]
    return np.float32(value) if isinstance(value, float) else value


_GLOBAL = re.compile(r"^\s*(\w+)\s*:\s*ARRAY\[([^\]]*)\]\s*OF\s+L?REAL\s*:=\s*\[([^\]]*)\];", re.MULTILINE)


_SCALAR = re.compile(r"^\s*(\w+)\s*:\s*(L?REAL|DINT)\s*:=\s*([^;]+);", re.MULTILINE)


def read_global_constants(text: str) -> dict:
    """The LREAL arrays (as nested lists of floats) and LREAL and DINT scalars of a VAR_GLOBAL
    CONSTANT file.

    blark's Earley grammar is ambiguous on a bare list of array elements, and its parse time grows
    with the cube of the list (200 numbers take a minute): the numbers of these long initialisers
    are read here, each literal by Python's float(), the logic that uses them by blark.
    """
    assert "VAR_GLOBAL CONSTANT" in text and text.rstrip().endswith("END_VAR")
    constants = {}
    for name, ranges, values in _GLOBAL.findall(text):
        shape = [int(stop) - int(start) + 1 for start, stop in (r.split("..") for r in ranges.split(","))]
        flat = np.array([float(v) for v in values.split(",")])
        constants[name] = flat.reshape(shape).tolist()
    for name, kind, value in _SCALAR.findall(text):
        constants[name] = int(value) if kind == "DINT" else float(value)
    return constants


class _Translator:
    def __init__(self, block, global_constants: dict, real: bool = False):
        self.block = block
        self.real = real
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
        cast = "_F" if self.real else ""
        lines += [f"        self.{name} = {cast}({name})" if cast else f"        self.{name} = {name}"
                  for name in self.inputs]
        lines += self.statements(self.block.body, 2) or ["        pass"]
        namespace = {"_math": np if self.real else math, "_trunc": int,
                     "_limit": lambda mn, x, mx: min(max(x, mn), mx), "_G": self.global_constants,
                     "_F": (lambda x: [np.float32(v) for v in x] if isinstance(x, list) else np.float32(x))}
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
        return f"_F({value!r})" if self.real else repr(value)

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
            if self.real and name == "float":
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


def load_exported(folder) -> object:
    """A new instance of the function block `python -m bwr_twin.export plc` wrote into `folder`,
    its global constant lists read."""
    from pathlib import Path

    folder = Path(folder)
    constants = {}
    for global_list in sorted(folder.glob("GVL_*.st")):
        constants |= read_global_constants(global_list.read_text())
    (block,) = folder.glob("FB_*.st")
    return load_block(block.read_text(), constants)()


def forces_on(block, result) -> np.ndarray:
    """The block run once a control period on a recorded run's measured and reference states (a
    run recorded every period): its drive forces, (periods, 3). A block with `qdd_ref` gets it."""
    references = [result.q_desired, result.qd_desired]
    if "qdd_ref" in vars(block):
        references.append(result.qdd_desired)
    forces = np.empty_like(result.drive_force_command)
    for k in range(len(result.time)):
        block(list(result.q_measured[k]), list(result.qd_measured[k]), *(list(x[k]) for x in references))
        forces[k] = block.force
    return forces
