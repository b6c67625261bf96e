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


REAL_MAX = float(np.finfo(np.float32).max)


def as_real(text: str) -> str:
    """The REAL (32-bit) variant of an exported text, for PLCs without LREAL: every LREAL declared
    REAL (DINT_TO_LREAL becoming DINT_TO_REAL). Literals keep their double's digits, which the
    compiler rounds to the nearest REAL; an unrated drive's limit becomes the largest REAL."""
    return (text.replace(lreal(LREAL_MAX), lreal(REAL_MAX)).replace("LREAL", "REAL")
            .replace("64-bit", "32-bit"))


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


def matrix_constant(name: str, values: np.ndarray, comment: str) -> str:
    """A 2-D VAR CONSTANT: ARRAY[0..r-1, 0..c-1] OF LREAL, row by row."""
    rows, columns = values.shape
    return (f"    {name} : ARRAY[0..{rows - 1}, 0..{columns - 1}] OF LREAL := "
            f"{lreal_array(values.ravel())};  (* {comment} *)")


def machine_globals(mass: np.ndarray, gravity: np.ndarray, source: str) -> str:
    """GVL_BwrMachine: the believed machine's closed-form coefficients (bwr_twin.model.dynamics)."""
    return "\n".join([
        "VAR_GLOBAL CONSTANT",
        f"    (* M(q) and the gravity forces of {source} in closed form: every entry is a fixed",
        "       combination of the 15 functions {1, cos slew, sin slew} x {1, cos luff, sin luff,",
        "       cos 2 luff, sin 2 luff}, numbered 5 a + b; identified from the MJCF by the twin and checked",
        "       against MuJoCo. Rows of MASS_COEFFICIENTS: M00, M01, M02, M11, M12, M22. *)",
        matrix_constant("MASS_COEFFICIENTS", mass, "kg, kg m, kg m^2"),
        matrix_constant("GRAVITY_COEFFICIENTS", gravity, "N, N m, N m"),
        "END_VAR",
    ]) + "\n"


# M(q) and bias(q, qd) at the measured state, as bwr_twin.model.dynamics.evaluate computes them:
# the same sums in the same order, so the LREAL result is the twin's to the last bit.
_DYNAMICS_VARIABLES = [
    "    basis : ARRAY[0..14] OF LREAL;",
    "    d_slew : ARRAY[0..14] OF LREAL;  (* d basis / d slew *)",
    "    d_luff : ARRAY[0..14] OF LREAL;",
    "    outer : ARRAY[0..2] OF LREAL;",
    "    outer_d : ARRAY[0..2] OF LREAL;",
    "    inner : ARRAY[0..4] OF LREAL;",
    "    inner_d : ARRAY[0..4] OF LREAL;",
    "    mass : ARRAY[0..2, 0..2] OF LREAL;  (* M(q): kg, kg m, kg m^2 *)",
    "    slope : ARRAY[0..2, 0..2, 0..2] OF LREAL;  (* slope[k, i, j] = dM_ij / dq_k *)",
    "    bias : ARRAY[0..2] OF LREAL;  (* Coriolis, centrifugal and gravity forces: N, N m, N m *)",
    "    entry : LREAL;",
    "    slope_slew : LREAL;",
    "    slope_luff : LREAL;",
    "    sum : LREAL;",
    "    inertial : LREAL;",
    "    a : DINT;",
    "    b : DINT;",
    "    n : DINT;",
    "    row : DINT;",
    "    col : DINT;",
    "    k : DINT;",
    "    i : DINT;",
    "    j : DINT;",
]
_ENTRY_ROWS = (0, 0, 0, 1, 1, 2)  # M's upper entries, as the coefficients' rows hold them
_ENTRY_COLUMNS = (0, 1, 2, 1, 2, 2)
_ENTRY_CONSTANTS = [
    f"    ENTRY_ROW : ARRAY[0..5] OF DINT := [{', '.join(map(str, _ENTRY_ROWS))}];",
    f"    ENTRY_COLUMN : ARRAY[0..5] OF DINT := [{', '.join(map(str, _ENTRY_COLUMNS))}];",
]
_DYNAMICS_STATEMENTS = [
    "(* M(q) and bias(q, qd) at the measured state *)",
    "outer[0] := 1.0; outer[1] := COS(q[1]); outer[2] := SIN(q[1]);",
    "outer_d[0] := 0.0; outer_d[1] := -outer[2]; outer_d[2] := outer[1];",
    "inner[0] := 1.0; inner[1] := COS(q[2]); inner[2] := SIN(q[2]); inner[3] := COS(2.0 * q[2]); "
    "inner[4] := SIN(2.0 * q[2]);",
    "inner_d[0] := 0.0; inner_d[1] := -inner[2]; inner_d[2] := inner[1]; inner_d[3] := -2.0 * inner[4]; "
    "inner_d[4] := 2.0 * inner[3];",
    "FOR a := 0 TO 2 DO",
    "    FOR b := 0 TO 4 DO",
    "        basis[5 * a + b] := outer[a] * inner[b];",
    "        d_slew[5 * a + b] := outer_d[a] * inner[b];",
    "        d_luff[5 * a + b] := outer[a] * inner_d[b];",
    "    END_FOR",
    "END_FOR",
    "FOR k := 0 TO 5 DO",
    "    entry := 0.0; slope_slew := 0.0; slope_luff := 0.0;",
    "    FOR n := 0 TO 14 DO",
    "        entry := entry + MASS_COEFFICIENTS[k, n] * basis[n];",
    "        slope_slew := slope_slew + MASS_COEFFICIENTS[k, n] * d_slew[n];",
    "        slope_luff := slope_luff + MASS_COEFFICIENTS[k, n] * d_luff[n];",
    "    END_FOR",
    "    row := ENTRY_ROW[k]; col := ENTRY_COLUMN[k];",
    "    mass[row, col] := entry; mass[col, row] := entry;",
    "    slope[1, row, col] := slope_slew; slope[1, col, row] := slope_slew;",
    "    slope[2, row, col] := slope_luff; slope[2, col, row] := slope_luff;",
    "END_FOR",
    "FOR i := 0 TO 2 DO",
    "    sum := 0.0;",
    "    FOR n := 0 TO 14 DO",
    "        sum := sum + GRAVITY_COEFFICIENTS[i, n] * basis[n];",
    "    END_FOR",
    "    FOR j := 0 TO 2 DO",
    "        FOR k := 0 TO 2 DO",
    "            sum := sum + (slope[k, i, j] - 0.5 * slope[i, j, k]) * qd[j] * qd[k];",
    "        END_FOR",
    "    END_FOR",
    "    bias[i] := sum;",
    "END_FOR",
]


_TORQUE_STATEMENTS = [
    "(* force = M(q) u + bias(q, qd), each row summed in the twin's order *)",
    "FOR i := 0 TO 2 DO",
    "    inertial := 0.0;",
    "    FOR j := 0 TO 2 DO",
    "        inertial := inertial + mass[i, j] * u[j];",
    "    END_FOR",
    "    force[i] := inertial + bias[i];",
    "END_FOR",
]
_INPUTS = [
    "VAR_INPUT",
    f"    q : ARRAY[0..2] OF LREAL;        (* measured position: m, rad, rad *) {AXES_COMMENT}",
    "    qd : ARRAY[0..2] OF LREAL;       (* measured velocity: m/s, rad/s, rad/s *)",
    "    q_ref : ARRAY[0..2] OF LREAL;    (* reference position: m, rad, rad *)",
    "    qd_ref : ARRAY[0..2] OF LREAL;   (* reference velocity: m/s, rad/s, rad/s *)",
    "    qdd_ref : ARRAY[0..2] OF LREAL;  (* reference acceleration: m/s^2, rad/s^2, rad/s^2 *)",
    "END_VAR",
]


def computed_torque_block(name: str, kp, kd, source: str) -> str:
    """The twin's computed-torque PD (bwr_twin.control.computed_torque) as a FUNCTION_BLOCK."""
    return "\n".join([
        f"FUNCTION_BLOCK {name}",
        f"(* The computed-torque PD of {source}, exported by python -m bwr_twin.export plc.",
        "   force = M(q) u + bias(q, qd), u = qdd_ref + KP (q_ref - q) + KD (qd_ref - qd), with M and bias",
        "   of the believed machine in closed form (GVL_BwrMachine). No state: call it every control period. *)",
        *_INPUTS,
        "VAR_OUTPUT",
        "    force : ARRAY[0..2] OF LREAL;    (* drive force command: N, N m, N m *)",
        "    u : ARRAY[0..2] OF LREAL;        (* acceleration command: m/s^2, rad/s^2, rad/s^2 *)",
        "END_VAR",
        "VAR",
        *_DYNAMICS_VARIABLES,
        "END_VAR",
        "VAR CONSTANT",
        constant("KP", kp, "1/s^2"),
        constant("KD", kd, "1/s"),
        *_ENTRY_CONSTANTS,
        "END_VAR",
        *_DYNAMICS_STATEMENTS,
        "FOR i := 0 TO 2 DO",
        "    u[i] := qdd_ref[i] + (KP[i] * (q_ref[i] - q[i]) + KD[i] * (qd_ref[i] - qd[i]));",
        "END_FOR",
        *_TORQUE_STATEMENTS,
        "END_FUNCTION_BLOCK",
    ]) + "\n"


def surface_globals(values: np.ndarray, centres: np.ndarray, e0: float, scale_e: float, ec0: float,
                    scale_ec: float, source: str) -> str:
    """GVL_BwrFuzzySurface: the rule base's control surface as the twin evaluates it (bwr_twin.control.fuzzy)."""
    n = values.shape[0]
    return "\n".join([
        "VAR_GLOBAL CONSTANT",
        f"    (* The control surface u = FLC(e, ec) of {source}: skfuzzy's Mamdani inference on a {n} x {n}",
        "       grid over the input universes and at the cell centres. Each cell is cut along both diagonals",
        "       into four triangles through the centre, so that the surface's kinks (min-AND, max-aggregation)",
        "       stay on grid lines and cell diagonals; inputs beyond the universes saturate at their ends. *)",
        matrix_constant("SURFACE_VALUES", values, "u at (e_i, ec_j), in the output universe"),
        matrix_constant("SURFACE_CENTRES", centres, "u at the cell centres"),
        f"    SURFACE_E0 : LREAL := {lreal(e0)};  (* the e universe's lower end *)",
        f"    SURFACE_SCALE_E : LREAL := {lreal(scale_e)};  (* cells per unit of e *)",
        f"    SURFACE_EC0 : LREAL := {lreal(ec0)};",
        f"    SURFACE_SCALE_EC : LREAL := {lreal(scale_ec)};",
        f"    SURFACE_CELLS : DINT := {n - 1};  (* cells along each input *)",
        "END_VAR",
    ]) + "\n"


def _grid_cell(coordinate: str, cell: str, fraction: str) -> list[str]:
    """The cell of a grid coordinate on [0, CELLS] and how far into it, saturated at the ends."""
    return [
        f"    IF {coordinate} > 0.0 AND {coordinate} < SURFACE_CELLS THEN",
        f"        {cell} := TRUNC({coordinate}); {fraction} := {coordinate} - DINT_TO_LREAL({cell});",
        f"    ELSIF {coordinate} <= 0.0 THEN",
        f"        {cell} := 0; {fraction} := 0.0;",
        "    ELSE",
        f"        {cell} := SURFACE_CELLS - 1; {fraction} := 1.0;",
        "    END_IF",
    ]


def fuzzy_model_block(name: str, scale_e: float, scale_ec: float, output_gain, feedforward: bool,
                      source: str) -> str:
    """The paper's controller (bwr_twin.control.controller): the fuzzy surface on top of the model."""
    return "\n".join([
        f"FUNCTION_BLOCK {name}",
        f"(* The fuzzy + model-based controller of {source} (Lu's Fig. 5 and 11), exported by",
        "   python -m bwr_twin.export plc. Per axis u = OUTPUT_GAIN FLC(SCALE_E e, SCALE_EC de/dt)",
        "   [+ qdd_ref], e = q_ref - q, the control surface FLC from GVL_BwrFuzzySurface; then",
        "   force = M(q) u + bias(q, qd) with the believed machine of GVL_BwrMachine. No state. *)",
        *_INPUTS,
        "VAR_OUTPUT",
        "    force : ARRAY[0..2] OF LREAL;         (* drive force command: N, N m, N m *)",
        "    u : ARRAY[0..2] OF LREAL;             (* acceleration command: m/s^2, rad/s^2, rad/s^2 *)",
        "    fuzzy_output : ARRAY[0..2] OF LREAL;  (* FLC output, in its output universe *)",
        "END_VAR",
        "VAR",
        *_DYNAMICS_VARIABLES,
        "    grid_e : LREAL;   (* grid coordinates of the scaled inputs *)",
        "    grid_ec : LREAL;",
        "    cell_e : DINT;",
        "    cell_ec : DINT;",
        "    s : LREAL;        (* how far into the cell, along e and ec *)",
        "    t : LREAL;",
        "    v00 : LREAL;",
        "    v10 : LREAL;",
        "    v01 : LREAL;",
        "    v11 : LREAL;",
        "    c2 : LREAL;",
        "    ta : LREAL;       (* the triangle's plane: ta + tb s + tc t *)",
        "    tb : LREAL;",
        "    tc : LREAL;",
        "END_VAR",
        "VAR CONSTANT",
        f"    SCALE_E : LREAL := {lreal(scale_e)};  (* K_e: 1/m, 1/rad *)",
        f"    SCALE_EC : LREAL := {lreal(scale_ec)};  (* K_ec: s/m, s/rad *)",
        constant("OUTPUT_GAIN", output_gain, "K_out: m/s^2, rad/s^2, rad/s^2 per unit of the output universe"),
        f"    FEEDFORWARD : DINT := {int(feedforward)};  (* 1: add the reference acceleration to u *)",
        *_ENTRY_CONSTANTS,
        "END_VAR",
        "FOR j := 0 TO 2 DO",
        "    grid_e := ((q_ref[j] - q[j]) * SCALE_E - SURFACE_E0) * SURFACE_SCALE_E;",
        "    grid_ec := ((qd_ref[j] - qd[j]) * SCALE_EC - SURFACE_EC0) * SURFACE_SCALE_EC;",
        *_grid_cell("grid_e", "cell_e", "s"),
        *_grid_cell("grid_ec", "cell_ec", "t"),
        "    v00 := SURFACE_VALUES[cell_e, cell_ec]; v10 := SURFACE_VALUES[cell_e + 1, cell_ec];",
        "    v01 := SURFACE_VALUES[cell_e, cell_ec + 1]; v11 := SURFACE_VALUES[cell_e + 1, cell_ec + 1];",
        "    c2 := 2.0 * SURFACE_CENTRES[cell_e, cell_ec];",
        "    IF s < t THEN",
        "        IF s + t >= 1.0 THEN",
        "            ta := c2 - v11; tb := v11 - v01; tc := v01 + v11 - c2;",
        "        ELSE",
        "            ta := v00; tb := c2 - v00 - v01; tc := v01 - v00;",
        "        END_IF",
        "    ELSIF s + t >= 1.0 THEN",
        "        ta := c2 - v11; tb := v10 + v11 - c2; tc := v11 - v10;",
        "    ELSE",
        "        ta := v00; tb := v10 - v00; tc := c2 - v00 - v10;",
        "    END_IF",
        "    fuzzy_output[j] := ta + tb * s + tc * t;",
        "    u[j] := fuzzy_output[j] * OUTPUT_GAIN[j];",
        "    IF FEEDFORWARD = 1 THEN",
        "        u[j] := u[j] + qdd_ref[j];",
        "    END_IF",
        "END_FOR",
        *_DYNAMICS_STATEMENTS,
        *_TORQUE_STATEMENTS,
        "END_FUNCTION_BLOCK",
    ]) + "\n"
