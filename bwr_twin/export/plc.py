"""A scene's controller as IEC 61131-3 Structured Text, in a folder the twin marks as its own.

    DIR/FB_BwrPid.st   the function block, its gains and drive ratings as VAR CONSTANT
    DIR/README.md      inputs, outputs, units, the cycle time, how to wire the block

The block's arithmetic is the twin's own, operation for operation, so that the LREAL block gives
the forces the twin's controller gives (tests/test_plc_export.py runs it on a recorded run). Of
the shipped controllers the PID is exported so far; another type is refused in one line.
"""

from __future__ import annotations

from pathlib import Path

from bwr_twin.config.scene import Scene
from bwr_twin.errors import SceneError
from bwr_twin.export.structured_text import pid_block
from bwr_twin.model.machine import Machine
from bwr_twin.results.rundir import staged_directory

EXPORTABLE = ("pid",)
PID_BLOCK = "FB_BwrPid"


def export_plc(scene: Scene, out: Path, *, overwrite: bool = False) -> list[Path]:
    """Write the scene's controller into `out` (replaced only if the twin wrote it, with
    `overwrite`); the files written, as they are named in `out`."""
    if scene.controller.type not in EXPORTABLE:
        raise SceneError(f"{scene.path}: [controller] type {scene.controller.type!r} cannot be exported as PLC "
                         f"code yet (exported: {', '.join(EXPORTABLE)})")
    settings = scene.controller.settings
    limits = Machine(scene.controller_mjcf).drive_limits  # the ratings the twin's PID clips to
    period = scene.simulation.control_period
    text = pid_block(PID_BLOCK, settings.kp, settings.ki, settings.kd, settings.holding_force, limits[:, 0],
                     limits[:, 1], period, scene.path.name)
    files = {f"{PID_BLOCK}.st": text, "README.md": _readme(scene, period)}
    with staged_directory(out, overwrite=overwrite, kind="plc") as staging:
        for name, content in files.items():
            (staging / name).write_text(content, encoding="utf-8")
    return [out / name for name in files]


def _readme(scene: Scene, period: float) -> str:
    return f"""# {PID_BLOCK}: the PID of {scene.path.name}, as IEC 61131-3 Structured Text

Written by `python -m bwr_twin.export plc {scene.path.stem}`. One FUNCTION_BLOCK, LREAL (64-bit)
throughout: the same arithmetic, in the same order, as the twin's controller (bwr_twin.control.pid).

Call it once every control period, {period:g} s (its constant DT): a cycle time other than DT
changes the integral's scale.

| input | units | wire it to |
| --- | --- | --- |
| `q[0..2]` | m, rad, rad | the travel, slew and luff encoders |
| `qd[0..2]` | m/s, rad/s, rad/s | their velocities |
| `q_ref[0..2]` | m, rad, rad | the path's reference position |
| `qd_ref[0..2]` | m/s, rad/s, rad/s | the reference velocity |

| output | units | wire it to |
| --- | --- | --- |
| `force[0..2]` | N, N m, N m | the travel, slew and luff drives' force or torque setpoints |

The gains (KP, KI, KD), the holding force F0 and the drive ratings (LOW, HIGH) are the scene's, as
VAR CONSTANT; a drive without a rating is limited at the largest LREAL. Axis 0 is travel, 1 slew,
2 luff. The integral stops growing while an axis is saturated with its error pushing further.
"""
