"""The twin's controllers as IEC 61131-3 function blocks (bwr_twin.export.structured_text's data).

Each block's arithmetic is the twin's own, operation for operation and in the same order, so that
in LREAL it gives the twin's forces to the last bit (tests/test_plc_export.py); the rules block's
fuzzy part is skfuzzy's instead, where the twin reads a table:
- `pid_block`: bwr_twin.control.pid;
- `computed_torque_block`: bwr_twin.control.computed_torque, over the closed-form model;
- `fuzzy_model_block`: the paper's controller (bwr_twin.control.controller), its control surface
  interpolated as bwr_twin.control.fuzzy does, over the same model;
- `fuzzy_rules_model_block`: the same controller, its fuzzy part inferred rule by rule each call
  as skfuzzy infers it (bwr_twin.control.fuzzy.skfuzzy_compute), to rounding.
The model-based blocks read global constant lists: `machine_globals`, M(q) and gravity in closed
form (bwr_twin.model.dynamics), and `surface_globals`, the control surface's table, or
`rule_globals`, the rule base's sets, rules and universes.
"""

from __future__ import annotations

import numpy as np

from bwr_twin.control.rulebase import RuleBase
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


def _fuzzy_model(name: str, comment: str, fuzzy_variables: tuple[Var, ...], fuzzy_statements: tuple[str, ...],
                 scale_e: float, scale_ec: float, output_gain, feedforward: bool) -> Block:
    """The paper's controller around a fuzzy part: `fuzzy_statements` set fuzzy_output[j] of axis j
    (over `fuzzy_variables`); the output gain, the feed-forward and the model are every variant's."""
    return Block(name, comment, {
        "VAR_INPUT": (_Q, _QD, _Q_REF, _QD_REF, _QDD_REF),
        "VAR_OUTPUT": (_FORCE, _U, Var("fuzzy_output", dims=(3,), comment="FLC output, in its output universe")),
        "VAR": (*_DYNAMICS_VARIABLES, *fuzzy_variables),
        "VAR CONSTANT": (reals("SCALE_E", scale_e, "K_e: 1/m, 1/rad"), reals("SCALE_EC", scale_ec, "K_ec: s/m, s/rad"),
                         reals("OUTPUT_GAIN", output_gain,
                               "K_out: m/s^2, rad/s^2, rad/s^2 per unit of the output universe"),
                         integers("FEEDFORWARD", int(feedforward), "1: add the reference acceleration to u"),
                         *_ENTRY_CONSTANTS),
    }, (
        "FOR j := 0 TO 2 DO",
        *fuzzy_statements,
        "    u[j] := fuzzy_output[j] * OUTPUT_GAIN[j];",
        "    IF FEEDFORWARD = 1 THEN",
        "        u[j] := u[j] + qdd_ref[j];",
        "    END_IF",
        "END_FOR",
        *_DYNAMICS_STATEMENTS,
        *_TORQUE_STATEMENTS,
    ))


def fuzzy_model_block(name: str, scale_e: float, scale_ec: float, output_gain, feedforward: bool,
                      source: str) -> Block:
    """The paper's controller: the fuzzy surface on top of the model."""
    return _fuzzy_model(name, (
        f"The fuzzy + model-based controller of {source} (Lu's Fig. 5 and 11), exported by\n"
        "python -m bwr_twin.export plc. Per axis u = OUTPUT_GAIN FLC(SCALE_E e, SCALE_EC de/dt)\n"
        "[+ qdd_ref], e = q_ref - q, the control surface FLC from GVL_BwrFuzzySurface; then\n"
        "force = M(q) u + bias(q, qd) with the believed machine of GVL_BwrMachine. No state."), (
        Var("grid_e", comment="grid coordinates of the scaled inputs"), Var("grid_ec"),
        Var("cell_e", "DINT"), Var("cell_ec", "DINT"),
        Var("s", comment="how far into the cell, along e and ec"), Var("t"),
        *(Var(corner) for corner in ("v00", "v10", "v01", "v11", "c2")),
        Var("ta", comment="the triangle's plane: ta + tb s + tc t"), Var("tb"), Var("tc"),
    ), (
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
    ), scale_e, scale_ec, output_gain, feedforward)


def rule_globals(name: str, rule_base: RuleBase, source: str) -> GlobalConstants:
    """The rule base's own numbers, from which the rules block infers each cycle."""
    n = len(rule_base.sets)
    table = [[rule_base.sets.index(out) for out in row] for row in rule_base.rules]
    ranges = {"E": rule_base.e_range, "EC": rule_base.ec_range, "OUTPUT": rule_base.output_range}
    return GlobalConstants(name, (
        f"The Mamdani rule base of {source}: {n} triangular sets on each universe ({', '.join(rule_base.sets)}),\n"
        f"{n} x {n} rules 'IF e is set i AND ec is set k THEN u is FUZZY_RULES[i, k]', min-AND, max\n"
        "accumulation and centroid defuzzification over FUZZY_OUTPUT_POINTS samples of the output\n"
        "universe, as skfuzzy computes them."), (
        integers("FUZZY_SET_COUNT", n, "sets on each universe, lowest first"),
        *(reals(f"FUZZY_{axis}_SETS", rule_base.term_abcs(*bounds),
                "each set's triangle (a, b, c): feet a and c, peak b") for axis, bounds in ranges.items()),
        integers("FUZZY_RULES", table, "the output set of e's set i and ec's set k"),
        *(reals(f"FUZZY_{axis}_RANGE", bounds, "the universe: low, high") for axis, bounds in ranges.items()),
        integers("FUZZY_OUTPUT_POINTS", rule_base.output_points, "samples of the output universe, ends included"),
    ))


def _corners(sets: str, index: str) -> str:
    """The triangle `sets`[index, 0..2] into foot_low, peak, foot_high."""
    return f"foot_low := {sets}[{index}, 0]; peak := {sets}[{index}, 1]; foot_high := {sets}[{index}, 2];"


def _membership(point: str, sets: str, index: str, result: str, indent: str) -> tuple[str, ...]:
    """`result` := the membership of `point` in the triangle `sets`[index, 0..2], as skfuzzy's trimf
    computes it (a shoulder set, foot_low = peak or peak = foot_high, has no slope on that side)."""
    return tuple(indent + line for line in (
        _corners(sets, index),
        f"IF {point} < peak THEN",
        f"    IF {point} > foot_low THEN",
        f"        {result} := ({point} - foot_low) / (peak - foot_low);",
        "    ELSE",
        f"        {result} := 0.0;",
        "    END_IF",
        f"ELSIF {point} > peak THEN",
        f"    IF {point} < foot_high THEN",
        f"        {result} := (foot_high - {point}) / (foot_high - peak);",
        "    ELSE",
        f"        {result} := 0.0;",
        "    END_IF",
        "ELSE",
        f"    {result} := 1.0;",
        "END_IF",
    ))


def _fuzzify(error: str, scale: str, universe: str, memberships: str) -> tuple[str, ...]:
    """The memberships of a scaled input in its universe's sets, the input clipped to the universe
    first (skfuzzy's clip_to_bounds)."""
    return (
        f"    (* the memberships of {scale} {error}, clipped to its universe as skfuzzy's clip_to_bounds does *)",
        f"    scaled := LIMIT(FUZZY_{universe}_RANGE[0], {error} * {scale}, FUZZY_{universe}_RANGE[1]);",
        "    FOR k := 0 TO FUZZY_SET_COUNT - 1 DO",
        *_membership("scaled", f"FUZZY_{universe}_SETS", "k", f"{memberships}[k]", "        "),
        "    END_FOR",
    )


_RULE_STATEMENTS = (
    "    (* every rule: the min of its two memberships, the max of these for each output set *)",
    "    FOR k := 0 TO FUZZY_SET_COUNT - 1 DO",
    "        activation[k] := 0.0;",
    "    END_FOR",
    "    FOR i := 0 TO FUZZY_SET_COUNT - 1 DO",
    "        FOR k := 0 TO FUZZY_SET_COUNT - 1 DO",
    "            output_set := FUZZY_RULES[i, k];",
    "            activation[output_set] := MAX(activation[output_set], MIN(e_membership[i], ec_membership[k]));",
    "        END_FOR",
    "    END_FOR",
)
# skfuzzy adds to the output samples the points where an output set's triangle crosses its
# activation; only those strictly inside matter (at 0 and 1 they are the set's feet and peak,
# which are samples). At most two a set, and they come nearly in order: an insertion sort.
_CUT_STATEMENTS = (
    "    (* the active output sets, and where each one's triangle crosses its activation *)",
    "    active_count := 0; cut_count := 0;",
    "    FOR k := 0 TO FUZZY_SET_COUNT - 1 DO",
    "        IF activation[k] > 0.0 THEN",
    "            active[active_count] := k; active_count := active_count + 1;",
    "            IF activation[k] < 1.0 THEN",
    f"                {_corners('FUZZY_OUTPUT_SETS', 'k')}",
    "                IF foot_low < peak THEN",
    "                    cuts[cut_count] := foot_low + activation[k] * (peak - foot_low);",
    "                    cut_count := cut_count + 1;",
    "                END_IF",
    "                IF peak < foot_high THEN",
    "                    cuts[cut_count] := foot_high - activation[k] * (foot_high - peak);",
    "                    cut_count := cut_count + 1;",
    "                END_IF",
    "            END_IF",
    "        END_IF",
    "    END_FOR",
    "    (* sorted by insertion: a few points, nearly in order *)",
    "    FOR k := 1 TO cut_count - 1 DO",
    "        cut := cuts[k]; slot := k;",
    "        FOR i := 1 TO k DO",
    "            IF cuts[slot - 1] <= cut THEN",
    "                EXIT;",
    "            END_IF",
    "            cuts[slot] := cuts[slot - 1]; slot := slot - 1;",
    "        END_FOR",
    "        cuts[slot] := cut;",
    "    END_FOR",
    "    cuts[cut_count] := FUZZY_OUTPUT_RANGE[1];  (* the walk's sentinel: every cut lies below it *)",
)
_ACCUMULATE = "moment_sum := moment_sum + moment * area; area_sum := area_sum + area;"
# skfuzzy's centroid, term for term: the aggregated membership linear between neighbouring points,
# each segment a rectangle, a triangle or a trapezoid, a segment of no width (a point skfuzzy's
# np.union1d would have dropped as a duplicate) or under zero membership adding nothing.
_SEGMENT_STATEMENTS = (
    "        IF point <> previous_point THEN",
    "            IF membership = previous_membership THEN",
    "                IF membership > 0.0 THEN",
    "                    moment := 0.5 * (previous_point + point);",
    "                    area := (point - previous_point) * previous_membership;",
    f"                    {_ACCUMULATE}",
    "                END_IF",
    "            ELSE",
    "                IF previous_membership = 0.0 THEN",
    f"                    moment := {lreal(2.0 / 3.0)} * (point - previous_point) + previous_point;",
    "                    area := 0.5 * (point - previous_point) * membership;",
    "                ELSIF membership = 0.0 THEN",
    f"                    moment := {lreal(1.0 / 3.0)} * (point - previous_point) + previous_point;",
    "                    area := 0.5 * (point - previous_point) * previous_membership;",
    "                ELSE",
    f"                    moment := {lreal(2.0 / 3.0)} * (point - previous_point)"
    " * (membership + 0.5 * previous_membership) / (previous_membership + membership) + previous_point;",
    "                    area := 0.5 * (point - previous_point) * (previous_membership + membership);",
    "                END_IF",
    f"                {_ACCUMULATE}",
    "            END_IF",
    "        END_IF",
)
_CENTROID_STATEMENTS = (
    "    (* the centroid over the output samples (as np.linspace places them) merged with the cuts *)",
    "    spacing := (FUZZY_OUTPUT_RANGE[1] - FUZZY_OUTPUT_RANGE[0]) / DINT_TO_LREAL(FUZZY_OUTPUT_POINTS - 1);",
    "    sample := FUZZY_OUTPUT_RANGE[0]; sample_index := 0; cut_index := 0;",
    "    previous_point := sample; previous_membership := 0.0;  (* the first point's segment has no width *)",
    "    moment_sum := 0.0; area_sum := 0.0;",
    "    FOR n := 0 TO FUZZY_OUTPUT_POINTS + cut_count - 1 DO",
    "        IF cuts[cut_index] < sample THEN",
    "            point := cuts[cut_index]; cut_index := cut_index + 1;",
    "        ELSE",
    "            point := sample; sample_index := sample_index + 1;",
    "            IF sample_index < FUZZY_OUTPUT_POINTS - 1 THEN",
    "                sample := DINT_TO_LREAL(sample_index) * spacing + FUZZY_OUTPUT_RANGE[0];",
    "            ELSE",
    "                sample := FUZZY_OUTPUT_RANGE[1];",
    "            END_IF",
    "        END_IF",
    "        membership := 0.0;  (* max over the active sets of MIN(activation, the set's membership) *)",
    "        FOR k := 0 TO active_count - 1 DO",
    "            output_set := active[k];",
    *_membership("point", "FUZZY_OUTPUT_SETS", "output_set", "set_membership", "            "),
    "            membership := MAX(membership, MIN(activation[output_set], set_membership));",
    "        END_FOR",
    *_SEGMENT_STATEMENTS,
    "        previous_point := point; previous_membership := membership;",
    "    END_FOR",
    "    fuzzy_output[j] := moment_sum / area_sum;  (* area_sum > 0: some rule fires at 0.5 or more *)",
)


def fuzzy_rules_model_block(name: str, scale_e: float, scale_ec: float, output_gain, feedforward: bool,
                            set_count: int, source: str) -> Block:
    """The paper's controller with its fuzzy part inferred rule by rule each cycle, as skfuzzy
    infers it, instead of read from the control surface's table."""
    sets = (set_count,)
    return _fuzzy_model(name, (
        f"The fuzzy + model-based controller of {source} (Lu's Fig. 5 and 11), exported by\n"
        "python -m bwr_twin.export plc --fuzzy rules. Per axis\n"
        "u = OUTPUT_GAIN FLC(SCALE_E e, SCALE_EC de/dt) [+ qdd_ref], e = q_ref - q, FLC the Mamdani\n"
        "inference of GVL_BwrFuzzyRules computed rule by rule each call as skfuzzy computes it; then\n"
        "force = M(q) u + bias(q, qd) with the believed machine of GVL_BwrMachine. No state."), (
        Var("scaled", comment="an input scaled and clipped to its universe"),
        Var("foot_low", comment="a set's triangle"), Var("peak"), Var("foot_high"),
        Var("e_membership", dims=sets, comment="of the scaled e in each of its sets"),
        Var("ec_membership", dims=sets),
        Var("activation", dims=sets, comment="of each output set: the max of its rules' min-AND"),
        Var("active", "DINT", sets, comment="the output sets with activation > 0"), Var("active_count", "DINT"),
        Var("output_set", "DINT"),
        Var("cuts", dims=(2 * set_count + 1,), comment="where the output sets cross their activations, sorted"),
        Var("cut_count", "DINT"), Var("cut"), Var("slot", "DINT"),
        Var("spacing", comment="the output samples' spacing"), Var("sample"), Var("sample_index", "DINT"),
        Var("cut_index", "DINT"), Var("point", comment="the centroid's current point and its membership"),
        Var("membership"), Var("set_membership"), Var("previous_point"), Var("previous_membership"),
        Var("moment"), Var("area"), Var("moment_sum"), Var("area_sum"),
    ), (
        *_fuzzify("(q_ref[j] - q[j])", "SCALE_E", "E", "e_membership"),
        *_fuzzify("(qd_ref[j] - qd[j])", "SCALE_EC", "EC", "ec_membership"),
        *_RULE_STATEMENTS,
        *_CUT_STATEMENTS,
        *_CENTROID_STATEMENTS,
    ), scale_e, scale_ec, output_gain, feedforward)


def most_active_sets(set_count: int) -> int:
    """How many output sets a rule base's inference can activate at once. The sets are triangles
    with their feet at the neighbours' peaks (RuleBase.term_abcs), so an input lies strictly
    inside at most two of a universe's sets: at most four rules fire."""
    return min(4, set_count)


def rules_cost_bound(set_count: int, output_points: int) -> tuple[int, int]:
    """At most how many LREAL arithmetic operations (+, -, *, /, DINT_TO_LREAL) and comparisons
    (MIN and MAX one each, LIMIT two) the rules block's loop over the axes (its fuzzy part, and u
    from it) does a call: each statement's worst branch, with `most_active_sets` active output
    sets cutting their triangles at two points each, and a point strictly inside two triangles
    at most."""
    n, points = set_count, output_points
    active = most_active_sets(n)
    cuts = 2 * active
    walked = points + cuts
    arithmetic = (2 * (2 + 2 * 3)  # each input scaled; its two memberships inside a triangle
                  + 3 * cuts  # the cut points
                  + 3 + 3 * points  # the samples' spacing, and each sample
                  + walked * (2 * 3 + 15)  # each point's memberships inside a triangle, its segment's trapezoid
                  + 1  # the centroid
                  + 2)  # u, with the feed-forward
    comparisons = (2 * (2 + 3 * n)  # each input clipped, tested against every set's triangle
                   + 2 * n * n  # every rule's MIN and MAX
                   + n + 3 * active  # the active sets; whether and where they cut
                   + cuts * (cuts - 1) // 2  # the insertion sort
                   + walked * (1 + 5 * active + 4))  # the merge; each active set's membership, MIN, MAX; the segment
    return 3 * arithmetic, 3 * comparisons
