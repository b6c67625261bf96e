"""IEC 61131-3 Structured Text from the twin's controllers: the literals, declarations and blocks.

Numbers are LREAL (IEC 61131-3's 64-bit float, the twin's float64) written so that they read back
to the same double: the shortest repr, with the decimal point IEC's real literals require. A drive
without a rating is limited at the largest LREAL, which no finite force reaches: ST has no infinity.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

LREAL_MAX = float(np.finfo(np.float64).max)
AXES_COMMENT = "(* index 0 travel, 1 slew, 2 luff *)"


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


def lreal_array(values: Sequence[float]) -> str:
    return "[" + ", ".join(lreal(v) for v in values) + "]"


def constant(name: str, values: Sequence[float], comment: str) -> str:
    """One VAR CONSTANT line: an ARRAY[0..n-1] OF LREAL and its values, with its units."""
    return f"    {name} : ARRAY[0..{len(values) - 1}] OF LREAL := {lreal_array(values)};  (* {comment} *)"


def pid_block(name: str, kp, ki, kd, holding, low, high, period: float, source: str) -> str:
    """The twin's PID (bwr_twin.control.pid) as a FUNCTION_BLOCK called once a control period."""
    return "\n".join([
        f"FUNCTION_BLOCK {name}",
        f"(* The per-axis PID of {source}, exported by python -m bwr_twin.export plc.",
        "   force = LIMIT(LOW, F0 + KP e + KI integral(e) + KD de/dt, HIGH), e = q_ref - q; the integral",
        "   grows by e * DT each call unless the output is saturated with e pushing further the same way",
        f"   (conditional integration). Call it once every DT = {lreal(period)} s. *)",
        "VAR_INPUT",
        f"    q : ARRAY[0..2] OF LREAL;       (* measured position: m, rad, rad *) {AXES_COMMENT}",
        "    qd : ARRAY[0..2] OF LREAL;      (* measured velocity: m/s, rad/s, rad/s *)",
        "    q_ref : ARRAY[0..2] OF LREAL;   (* reference position: m, rad, rad *)",
        "    qd_ref : ARRAY[0..2] OF LREAL;  (* reference velocity: m/s, rad/s, rad/s *)",
        "END_VAR",
        "VAR_OUTPUT",
        "    force : ARRAY[0..2] OF LREAL;   (* drive force command: N, N m, N m *)",
        "END_VAR",
        "VAR",
        "    integral : ARRAY[0..2] OF LREAL;  (* m s, rad s, rad s *)",
        "    e : LREAL;",
        "    unclipped : LREAL;",
        "    j : DINT;",
        "END_VAR",
        "VAR CONSTANT",
        constant("KP", kp, "N/m, N m/rad, N m/rad"),
        constant("KI", ki, "N/(m s), N m/(rad s), N m/(rad s)"),
        constant("KD", kd, "N s/m, N m s/rad, N m s/rad"),
        constant("F0", holding, "holding force: N, N m, N m"),
        constant("LOW", low, "drive rating, lower: N, N m, N m"),
        constant("HIGH", high, "drive rating, upper: N, N m, N m"),
        f"    DT : LREAL := {lreal(period)};  (* s, the control period *)",
        "END_VAR",
        "FOR j := 0 TO 2 DO",
        "    e := q_ref[j] - q[j];",
        "    unclipped := F0[j] + KP[j] * e + KI[j] * integral[j] + KD[j] * (qd_ref[j] - qd[j]);",
        "    force[j] := MIN(MAX(unclipped, LOW[j]), HIGH[j]);",
        "    IF NOT ((unclipped > HIGH[j] AND e > 0.0) OR (unclipped < LOW[j] AND e < 0.0)) THEN",
        "        integral[j] := integral[j] + e * DT;",
        "    END_IF",
        "END_FOR",
        "END_FUNCTION_BLOCK",
    ]) + "\n"
