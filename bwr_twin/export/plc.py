"""A scene's controller as IEC 61131-3 Structured Text, in a folder the twin marks as its own.

    DIR/FB_BwrPid.st, FB_BwrComputedTorque.st, FB_BwrFuzzyModel.st or FB_BwrFuzzyRulesModel.st
                            the block, its gains as VAR CONSTANT
    DIR/GVL_BwrFuzzySurface.st   the fuzzy controller's control surface, as the twin evaluates it
    DIR/GVL_BwrFuzzyRules.st     or, with --fuzzy rules, its rule base, inferred from each cycle
    DIR/GVL_BwrMachine.st   the believed machine's M(q) and gravity in closed form (model-based blocks)
    DIR/bwr_twin_plc.xml    the same, as a PLCopen XML (TC6 v2.01) project for CODESYS, TwinCAT, ...
    DIR/README.md           inputs, outputs, units, the cycle time, how to wire the block

The block's arithmetic is the twin's own, operation for operation, so that the LREAL block gives
the forces the twin's controller gives (tests/test_plc_export.py runs it on recorded runs). The PID,
computed torque and the paper's fuzzy + model-based controller are exported; an engineer's own
controller type is refused in one line. The fuzzy part is the twin's table (`fuzzy="table"`), or
skfuzzy's Mamdani inference computed rule by rule each cycle (`fuzzy="rules"`): no table, its
result skfuzzy's to rounding, at some 20 times the table block's operations a cycle.
"""

from __future__ import annotations

import functools
from pathlib import Path

import numpy as np

from bwr_twin.config.scene import Scene
from bwr_twin.control.fuzzy import FuzzySurface, default_grid_points, surface_error
from bwr_twin.control.rulebase import load_rule_base
from bwr_twin.errors import SceneError
from bwr_twin.export.blocks import (
    computed_torque_block,
    fuzzy_model_block,
    fuzzy_rules_model_block,
    machine_globals,
    most_active_sets,
    pid_block,
    rule_globals,
    rules_cost_bound,
    surface_globals,
)
from bwr_twin.export.plcopen import project_xml
from bwr_twin.export.structured_text import (
    LREAL_MAX,
    REAL_MAX,
    Block,
    GlobalConstants,
    as_real,
    block_text,
    check_constants,
    globals_text,
)
from bwr_twin.model.machine import AXES, Machine
from bwr_twin.ownership import check_output
from bwr_twin.results.rundir import staged_directory
from bwr_twin.sim.scaling import check_surface_grid

PID_BLOCK = "FB_BwrPid"
COMPUTED_TORQUE_BLOCK = "FB_BwrComputedTorque"
FUZZY_MODEL_BLOCK = "FB_BwrFuzzyModel"
FUZZY_RULES_BLOCK = "FB_BwrFuzzyRulesModel"
MACHINE_GLOBALS = "GVL_BwrMachine"
SURFACE_GLOBALS = "GVL_BwrFuzzySurface"
RULE_GLOBALS = "GVL_BwrFuzzyRules"
FUZZY_EVALUATIONS = ("table", "rules")  # how a fuzzy block computes its fuzzy part: the surface, or rule by rule
PROJECT = "bwr_twin_plc.xml"  # the same POUs as a PLCopen XML (TC6 v2.01) project


def export_plc(scene: Scene, out: Path, *, real: bool = False, grid: int | None = None, fuzzy: str = "table",
               overwrite: bool = False) -> list[Path]:
    """Write the scene's controller into `out` (replaced only if the twin wrote it, with
    `overwrite`), in LREAL or, with `real`, REAL, a fuzzy controller's surface on the twin's grid
    or on `grid` points per input, or with `fuzzy="rules"` its rule base inferred from each cycle;
    the files written, as they are named in `out`."""
    check_output(out, "plc", overwrite=overwrite, inputs=scene.input_files)  # before any work: a refusal costs nothing
    _check_fuzzy_options(grid, fuzzy)
    notes: list[str] = []  # what the README adds: a table's measured error bound, the rules' cost
    fuzzy_writer = (functools.partial(_fuzzy_model, grid=grid, notes=notes) if fuzzy == "table"
                    else functools.partial(_fuzzy_rules_model, notes=notes))
    writers = {"pid": _pid, "computed_torque": _computed_torque, "fuzzy_model": fuzzy_writer}
    if scene.controller.type not in writers:
        raise SceneError(f"{scene.path}: [controller] type {scene.controller.type!r} cannot be exported as PLC "
                         f"code yet (exported: {', '.join(writers)})")
    if grid is not None and scene.controller.type != "fuzzy_model":
        raise SceneError(f"{scene.path}: --grid sets a fuzzy control surface's table; [controller] type "
                         f"{scene.controller.type!r} has none")
    if fuzzy != "table" and scene.controller.type != "fuzzy_model":
        raise SceneError(f"{scene.path}: --fuzzy {fuzzy} sets how a fuzzy controller infers; [controller] type "
                         f"{scene.controller.type!r} has no fuzzy part")
    machine = Machine(scene.controller_mjcf)
    block, constants = writers[scene.controller.type](scene, machine)
    variables = [(block.name, v) for section in block.variables.values() for v in section]
    variables += [(c.name, v) for c in constants for v in c.variables]
    check_constants(f"{scene.path}: [controller]", variables, real)
    _check_gains(f"{scene.path}: [controller]", variables, machine, real)
    files = {f"{block.name}.st": block_text(block)}
    files |= {f"{c.name}.st": globals_text(c) for c in constants}
    files[PROJECT] = project_xml(block, constants, scene.path.name)
    files["README.md"] = _readme(scene, block.name, scene.simulation.control_period) + "".join(notes)
    if real:
        files = {name: as_real(text) for name, text in files.items()}
        files["README.md"] += _REAL_NOTE
    with staged_directory(out, overwrite=overwrite, kind="plc") as staging:
        for name, content in files.items():
            (staging / name).write_text(content, encoding="utf-8")
    return [out / name for name in files]


def _check_gains(where: str, variables, machine: Machine, real: bool) -> None:
    """SceneError naming the first gain whose product the block's arithmetic cannot hold: KP
    times the largest position error the envelope allows, KD times twice the rated speed (the
    reference and the axis at full speed opposite ways). A type holds the constant, yet the PLC
    would compute infinity from it."""
    largest = REAL_MAX if real else LREAL_MAX
    reach = {"KP": np.ptp(machine.envelope, axis=1), "KD": 2.0 * machine.rated_speed}
    for owner, var in variables:
        if var.name not in reach or var.value is None:
            continue
        for j, literal in enumerate(var.value):
            product = abs(float(literal)) * float(reach[var.name][j])
            if np.isfinite(reach[var.name][j]) and not product <= largest:
                times = "the envelope's span" if var.name == "KP" else "twice the rated speed"
                raise SceneError(f"{where}: the constant {owner}.{var.name}[{j}] = {literal} times {times} of the "
                                 f"{AXES[j]} ({float(reach[var.name][j]):.4g}) overflows {'REAL' if real else 'LREAL'} "
                                 f"(largest {largest:.3g}): the block would compute infinity")


def _check_fuzzy_options(grid: int | None, fuzzy: str) -> None:
    if fuzzy not in FUZZY_EVALUATIONS:
        raise SceneError(f"--fuzzy {fuzzy}: not one of {', '.join(FUZZY_EVALUATIONS)}")
    if fuzzy == "rules" and grid is not None:
        raise SceneError(f"--grid {grid} sizes the control surface's table; --fuzzy rules infers without one")


def _pid(scene: Scene, believed: Machine) -> tuple[Block, list[GlobalConstants]]:
    settings, limits = scene.controller.settings, believed.drive_limits  # the ratings the twin's PID clips to
    return pid_block(PID_BLOCK, settings.kp, settings.ki, settings.kd, settings.holding_force, limits[:, 0],
                     limits[:, 1], scene.simulation.control_period, scene.path.name), []


def _machine(believed: Machine) -> GlobalConstants:
    dynamics = believed.dynamics  # a machine outside the contract's closed form is refused here
    return machine_globals(MACHINE_GLOBALS, dynamics.mass, dynamics.gravity, believed.path.name)


def _computed_torque(scene: Scene, believed: Machine) -> tuple[Block, list[GlobalConstants]]:
    settings = scene.controller.settings
    return computed_torque_block(COMPUTED_TORQUE_BLOCK, settings.kp, settings.kd, scene.path.name), [_machine(believed)]


def _fuzzy_model(scene: Scene, believed: Machine, grid: int | None,
                 notes: list[str]) -> tuple[Block, list[GlobalConstants]]:
    settings = scene.controller.settings
    rule_base = load_rule_base(settings.rule_base)
    if grid is None:
        surface = FuzzySurface.load(rule_base)  # the table the twin's controller reads
    else:
        surface = _surface_on(rule_base, grid, default_grid_points(rule_base), notes)
    _, e0, scale_e, ec0, scale_ec, _ = surface.kernel
    block = fuzzy_model_block(FUZZY_MODEL_BLOCK, settings.input_scale_e, settings.input_scale_ec, settings.output_gain,
                              settings.acceleration_feedforward, scene.path.name)
    table = surface_globals(SURFACE_GLOBALS, surface.values, surface.centres, e0, scale_e, ec0, scale_ec,
                            settings.rule_base.name)
    return block, [table, _machine(believed)]


def _fuzzy_rules_model(scene: Scene, believed: Machine, notes: list[str]) -> tuple[Block, list[GlobalConstants]]:
    settings = scene.controller.settings
    rule_base = load_rule_base(settings.rule_base)
    block = fuzzy_rules_model_block(FUZZY_RULES_BLOCK, settings.input_scale_e, settings.input_scale_ec,
                                    settings.output_gain, settings.acceleration_feedforward, len(rule_base.sets),
                                    scene.path.name)
    notes.append(_rules_cost_note(rule_base))
    return block, [rule_globals(RULE_GLOBALS, rule_base, settings.rule_base.name), _machine(believed)]


def _rules_cost_note(rule_base) -> str:
    """The README's statement of what the rules cost a call, from the rule base's size."""
    n, points, active = len(rule_base.sets), rule_base.output_points, most_active_sets(len(rule_base.sets))
    arithmetic, comparisons = rules_cost_bound(n, points)
    return f"""
What it costs: with --fuzzy rules the block infers every call, for each of the 3 axes, the {2 * n}
memberships of its two inputs, the {n * n} rules (a MIN and a MAX each) and the centroid over the
{points} output samples and at most {2 * active} cut points, each point's membership the largest of at
most {active} active output sets. That is at most {arithmetic:,} LREAL arithmetic operations and
{comparisons:,} comparisons a call for the loop over the axes (the fuzzy part and u), where the
table block's loop does about 30 an axis; the model-based rest, the same in both, some 840 more.
docs/plc_export.md gives the counts measured on the paper's run and their time at an assumed cost
an operation.
"""


ERROR_POINTS = 20_000  # random inputs a table of another grid is measured on (about 5 s)


def _surface_on(rule_base, grid: int, twins: int, notes: list[str]) -> FuzzySurface:
    """The surface on `grid` points per input, and a README note of its measured error bound."""
    check_surface_grid(grid, 2 * (len(rule_base.sets) - 1))  # before a point is inferred
    try:
        surface = FuzzySurface.load(rule_base, grid_points=grid)
    except ValueError as exc:
        raise SceneError(f"--grid {grid}: {exc}") from None
    largest, _ = surface_error(surface, ERROR_POINTS)
    width = rule_base.output_range[1] - rule_base.output_range[0]
    notes.append(f"""
The control surface is tabled on {grid} x {grid} points (--grid), not the twin's {twins} x {twins}: the
block's forces differ from the twin's by the table. Its largest difference from skfuzzy's Mamdani
inference, on {ERROR_POINTS:,} random inputs, is {largest:.4g} ({100 * largest / width:.3g} % of the output range).
""")
    return surface


_REAL_NOTE = """
This is the REAL (32-bit) variant: every number and operation rounds to single precision, so the
forces differ from the LREAL block's by the rounding (docs/plc_export.md gives the measured difference).
"""

_TWINS = "the same arithmetic, in the same order, as the twin's controller ({})"
_DESCRIPTIONS = {  # block: (what it is, whose arithmetic, how to use it)
    PID_BLOCK: ("the per-axis PID", _TWINS.format("bwr_twin.control.pid"),
                "Call it once every control period, {period:g} s (its constant DT): a cycle time other than DT "
                "changes the integral's scale. The gains (KP, KI, KD), the holding force F0 and the drive ratings "
                "(LOW, HIGH) are the scene's, as VAR CONSTANT; a drive without a rating is limited at the largest "
                "LREAL. The integral stops growing while an axis is saturated with its error pushing further."),
    COMPUTED_TORQUE_BLOCK: ("the computed-torque PD", _TWINS.format("bwr_twin.control.computed_torque"),
                            "It holds no state; the twin calls it every {period:g} s. KP (1/s^2) and KD (1/s) are "
                            "the scene's, as VAR CONSTANT; M(q) and the bias forces come from GVL_BwrMachine.st, "
                            "the believed machine's closed form: add that global variable list to the project "
                            "with the block. The block does not clip: the drives' own limits do."),
    FUZZY_MODEL_BLOCK: ("the fuzzy + model-based controller", _TWINS.format("bwr_twin.control.controller"),
                        "It holds no state; the twin calls it every {period:g} s. The input scales SCALE_E, "
                        "SCALE_EC and the output gains are the scene's, as VAR CONSTANT. The control surface is "
                        "GVL_BwrFuzzySurface.st, the table the twin itself evaluates (skfuzzy's Mamdani inference "
                        "on a grid, four triangles a cell); M(q) and the bias forces come from GVL_BwrMachine.st. "
                        "Add both global variable lists to the project with the block. The block does not clip: "
                        "the drives' own limits do."),
    FUZZY_RULES_BLOCK: ("the rule-by-rule fuzzy + model-based controller",
                        "the model-based part is the twin's controller's arithmetic in the same order "
                        "(bwr_twin.control.controller), the fuzzy part skfuzzy's Mamdani inference "
                        "(bwr_twin.control.fuzzy.skfuzzy_compute) where the twin reads a table",
                        "It holds no state; the twin calls it every {period:g} s. The input scales SCALE_E, "
                        "SCALE_EC and the output gains are the scene's, as VAR CONSTANT. The fuzzy part holds no "
                        "table: each call it infers from the rule base, GVL_BwrFuzzyRules.st (the sets' triangles, "
                        "the rule table, the universes), rule by rule as skfuzzy does: the scaled inputs clipped to "
                        "their universes, each rule's min-AND, max accumulation per output set, and the centroid "
                        "over the output universe's samples and the points where the sets cross their "
                        "activations. Its fuzzy_output is skfuzzy's to rounding, where the table block differs by "
                        "up to the table's error. M(q) and the bias forces come from GVL_BwrMachine.st. Add both "
                        "global variable lists to the project with the block. The block does not clip: the "
                        "drives' own limits do."),
}


def _readme(scene: Scene, block: str, period: float) -> str:
    what, origin, notes = _DESCRIPTIONS[block]
    inputs = [("q[0..2]", "m, rad, rad", "the travel, slew and luff encoders"),
              ("qd[0..2]", "m/s, rad/s, rad/s", "their velocities"),
              ("q_ref[0..2]", "m, rad, rad", "the path's reference position"),
              ("qd_ref[0..2]", "m/s, rad/s, rad/s", "the reference velocity")]
    if block != PID_BLOCK:
        inputs.append(("qdd_ref[0..2]", "m/s^2, rad/s^2, rad/s^2", "the reference acceleration"))
    rows = "\n".join(f"| `{name}` | {units} | {wire} |" for name, units, wire in inputs)
    options = " --fuzzy rules" if block == FUZZY_RULES_BLOCK else ""
    return f"""# {block}: {what} of {scene.path.name}, as IEC 61131-3 Structured Text

Written by `python -m bwr_twin.export plc {scene.path.stem}{options}`. LREAL (64-bit) throughout: {origin}.
Axis 0 is travel, 1 slew, 2 luff.

| input | units | wire it to |
| --- | --- | --- |
{rows}

| output | units | wire it to |
| --- | --- | --- |
| `force[0..2]` | N, N m, N m | the travel, slew and luff drives' force or torque setpoints |

{notes.format(period=period)}

`{PROJECT}` holds the same block and global constant lists as a PLCopen XML (TC6 v2.01) project:
import it with your IEC 61131-3 tool's PLCopen XML import instead of adding the .st files by hand.
"""
