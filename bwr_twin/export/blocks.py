"""The twin's controllers as IEC 61131-3 function blocks (bwr_twin.export.structured_text's data).

Each block's arithmetic is the twin's own, operation for operation and in the same order, so that
in LREAL it gives the twin's forces to the last bit (tests/test_plc_export.py):
- `pid_block`: bwr_twin.control.pid;
- `computed_torque_block`: bwr_twin.control.computed_torque, over the closed-form model;
- `fuzzy_model_block`: the paper's controller (bwr_twin.control.controller), its control surface
  interpolated as bwr_twin.control.fuzzy does, over the same model.
The model-based blocks read two global constant lists: `machine_globals`, M(q) and gravity in
closed form (bwr_twin.model.dynamics), and `surface_globals`, the control surface's table.
"""

from __future__ import annotations

import numpy as np

from bwr_twin.export.structured_text import Block, GlobalConstants, Var, integers, lreal, reals

AXES = "index 0 travel, 1 slew, 2 luff"
_Q = Var("q", dims=(3,), comment=f"measured position: m, rad, rad; {AXES}")
_QD = Var("qd", dims=(3,), comment="measured velocity: m/s, rad/s, rad/s")
_Q_REF = Var("q_ref", dims=(3,), comment="reference position: m, rad, rad")
_QD_REF = Var("qd_ref", dims=(3,), comment="reference velocity: m/s, rad/s, rad/s")
_QDD_REF = Var("qdd_ref", dims=(3,), comment="reference acceleration: m/s^2, rad/s^2, rad/s^2")
_FORCE = Var("force", dims=(3,), comment="drive force command: N, N m, N m")
_U = Var("u", dims=(3,), comment="acceleration command: m/s^2, rad/s^2, rad/s^2")


def pid_block(name: str, kp, ki, kd, holding, low, high, period: float, source: str) -> Block:
    """The twin's PID as a FUNCTION_BLOCK called once a control period."""
    return Block(name, (
        f"The per-axis PID of {source}, exported by python -m bwr_twin.export plc.\n"
        "force = LIMIT(LOW, F0 + KP e + KI integral(e) + KD de/dt, HIGH), e = q_ref - q; the integral\n"
        "grows by e * DT each call unless the output is saturated with e pushing further the same way\n"
        f"(conditional integration). Call it once every DT = {lreal(period)} s."), {
        "VAR_INPUT": (_Q, _QD, _Q_REF, _QD_REF),
        "VAR_OUTPUT": (_FORCE,),
        "VAR": (Var("integral", dims=(3,), comment="m s, rad s, rad s"), Var("e"), Var("unclipped"), Var("j", "DINT")),
        "VAR CONSTANT": (reals("KP", kp, "N/m, N m/rad, N m/rad"), reals("KI", ki, "N/(m s), N m/(rad s), N m/(rad s)"),
                         reals("KD", kd, "N s/m, N m s/rad, N m s/rad"), reals("F0", holding, "holding force: N, N m, N m"),
                         reals("LOW", low, "drive rating, lower: N, N m, N m"),
                         reals("HIGH", high, "drive rating, upper: N, N m, N m"),
                         reals("DT", period, "s, the control period")),
    }, (
        "FOR j := 0 TO 2 DO",
        "    e := q_ref[j] - q[j];",
        "    unclipped := F0[j] + KP[j] * e + KI[j] * integral[j] + KD[j] * (qd_ref[j] - qd[j]);",
        "    force[j] := MIN(MAX(unclipped, LOW[j]), HIGH[j]);",
        "    IF NOT ((unclipped > HIGH[j] AND e > 0.0) OR (unclipped < LOW[j] AND e < 0.0)) THEN",
        "        integral[j] := integral[j] + e * DT;",
        "    END_IF",
        "END_FOR",
    ))


def machine_globals(name: str, mass: np.ndarray, gravity: np.ndarray, source: str) -> GlobalConstants:
    """The believed machine's closed-form coefficients."""
    return GlobalConstants(name, (
        f"M(q) and the gravity forces of {source} in closed form: every entry is a fixed\n"
        "combination of the 15 functions {1, cos slew, sin slew} x {1, cos luff, sin luff,\n"
        "cos 2 luff, sin 2 luff}, numbered 5 a + b; identified from the MJCF by the twin and checked\n"
        "against MuJoCo. Rows of MASS_COEFFICIENTS: M00, M01, M02, M11, M12, M22."), (
        reals("MASS_COEFFICIENTS", mass, "kg, kg m, kg m^2"),
        reals("GRAVITY_COEFFICIENTS", gravity, "N, N m, N m"),
    ))


def surface_globals(name: str, values: np.ndarray, centres: np.ndarray, e0: float, scale_e: float, ec0: float,
                    scale_ec: float, source: str) -> GlobalConstants:
    """The rule base's control surface as the twin evaluates it."""
    n = values.shape[0]
    return GlobalConstants(name, (
        f"The control surface u = FLC(e, ec) of {source}: skfuzzy's Mamdani inference on a {n} x {n}\n"
        "grid over the input universes and at the cell centres. Each cell is cut along both diagonals\n"
        "into four triangles through the centre, so that the surface's kinks (min-AND, max-aggregation)\n"
        "stay on grid lines and cell diagonals; inputs beyond the universes saturate at their ends."), (
        reals("SURFACE_VALUES", values, "u at (e_i, ec_j), in the output universe"),
        reals("SURFACE_CENTRES", centres, "u at the cell centres"),
        reals("SURFACE_E0", e0, "the e universe's lower end"),
        reals("SURFACE_SCALE_E", scale_e, "cells per unit of e"),
        reals("SURFACE_EC0", ec0),
        reals("SURFACE_SCALE_EC", scale_ec),
        integers("SURFACE_CELLS", n - 1, "cells along each input"),
    ))


# M(q) and bias(q, qd) at the measured state, as bwr_twin.model.dynamics.evaluate computes them:
# the same sums in the same order, so the LREAL result is the twin's to the last bit.
_DYNAMICS_VARIABLES = (
    Var("basis", dims=(15,)), Var("d_slew", dims=(15,), comment="d basis / d slew"), Var("d_luff", dims=(15,)),
    Var("outer", dims=(3,)), Var("outer_d", dims=(3,)), Var("inner", dims=(5,)), Var("inner_d", dims=(5,)),
    Var("mass", dims=(3, 3), comment="M(q): kg, kg m, kg m^2"),
    Var("slope", dims=(3, 3, 3), comment="slope[k, i, j] = dM_ij / dq_k"),
    Var("bias", dims=(3,), comment="Coriolis, centrifugal and gravity forces: N, N m, N m"),
    Var("entry"), Var("slope_slew"), Var("slope_luff"), Var("sum"), Var("inertial"),
    *(Var(index, "DINT") for index in ("a", "b", "n", "row", "col", "k", "i", "j")),
)
_ENTRY_CONSTANTS = (  # M's upper entries, as the coefficients' rows hold them
    integers("ENTRY_ROW", (0, 0, 0, 1, 1, 2)),
    integers("ENTRY_COLUMN", (0, 1, 2, 1, 2, 2)),
)
_DYNAMICS_STATEMENTS = (
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
)
_TORQUE_STATEMENTS = (
    "(* force = M(q) u + bias(q, qd), each row summed in the twin's order *)",
    "FOR i := 0 TO 2 DO",
    "    inertial := 0.0;",
    "    FOR j := 0 TO 2 DO",
    "        inertial := inertial + mass[i, j] * u[j];",
    "    END_FOR",
    "    force[i] := inertial + bias[i];",
    "END_FOR",
)


def computed_torque_block(name: str, kp, kd, source: str) -> Block:
    """The twin's computed-torque PD as a FUNCTION_BLOCK."""
    return Block(name, (
        f"The computed-torque PD of {source}, exported by python -m bwr_twin.export plc.\n"
        "force = M(q) u + bias(q, qd), u = qdd_ref + KP (q_ref - q) + KD (qd_ref - qd), with M and bias\n"
        "of the believed machine in closed form (GVL_BwrMachine). No state: call it every control period."), {
        "VAR_INPUT": (_Q, _QD, _Q_REF, _QD_REF, _QDD_REF),
        "VAR_OUTPUT": (_FORCE, _U),
        "VAR": _DYNAMICS_VARIABLES,
        "VAR CONSTANT": (reals("KP", kp, "1/s^2"), reals("KD", kd, "1/s"), *_ENTRY_CONSTANTS),
    }, (
        *_DYNAMICS_STATEMENTS,
        "FOR i := 0 TO 2 DO",
        "    u[i] := qdd_ref[i] + (KP[i] * (q_ref[i] - q[i]) + KD[i] * (qd_ref[i] - qd[i]));",
        "END_FOR",
        *_TORQUE_STATEMENTS,
    ))


def _grid_cell(coordinate: str, cell: str, fraction: str) -> tuple[str, ...]:
    """The cell of a grid coordinate on [0, CELLS] and how far into it, saturated at the ends."""
    return (
        f"    IF {coordinate} > 0.0 AND {coordinate} < SURFACE_CELLS THEN",
        f"        {cell} := TRUNC({coordinate}); {fraction} := {coordinate} - DINT_TO_LREAL({cell});",
        f"    ELSIF {coordinate} <= 0.0 THEN",
        f"        {cell} := 0; {fraction} := 0.0;",
        "    ELSE",
        f"        {cell} := SURFACE_CELLS - 1; {fraction} := 1.0;",
        "    END_IF",
    )


def fuzzy_model_block(name: str, scale_e: float, scale_ec: float, output_gain, feedforward: bool,
                      source: str) -> Block:
    """The paper's controller: the fuzzy surface on top of the model."""
    return Block(name, (
        f"The fuzzy + model-based controller of {source} (Lu's Fig. 5 and 11), exported by\n"
        "python -m bwr_twin.export plc. Per axis u = OUTPUT_GAIN FLC(SCALE_E e, SCALE_EC de/dt)\n"
        "[+ qdd_ref], e = q_ref - q, the control surface FLC from GVL_BwrFuzzySurface; then\n"
        "force = M(q) u + bias(q, qd) with the believed machine of GVL_BwrMachine. No state."), {
        "VAR_INPUT": (_Q, _QD, _Q_REF, _QD_REF, _QDD_REF),
        "VAR_OUTPUT": (_FORCE, _U, Var("fuzzy_output", dims=(3,), comment="FLC output, in its output universe")),
        "VAR": (*_DYNAMICS_VARIABLES,
                Var("grid_e", comment="grid coordinates of the scaled inputs"), Var("grid_ec"),
                Var("cell_e", "DINT"), Var("cell_ec", "DINT"),
                Var("s", comment="how far into the cell, along e and ec"), Var("t"),
                *(Var(corner) for corner in ("v00", "v10", "v01", "v11", "c2")),
                Var("ta", comment="the triangle's plane: ta + tb s + tc t"), Var("tb"), Var("tc")),
        "VAR CONSTANT": (reals("SCALE_E", scale_e, "K_e: 1/m, 1/rad"), reals("SCALE_EC", scale_ec, "K_ec: s/m, s/rad"),
                         reals("OUTPUT_GAIN", output_gain,
                               "K_out: m/s^2, rad/s^2, rad/s^2 per unit of the output universe"),
                         integers("FEEDFORWARD", int(feedforward), "1: add the reference acceleration to u"),
                         *_ENTRY_CONSTANTS),
    }, (
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
    ))
