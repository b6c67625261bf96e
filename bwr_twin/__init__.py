"""bwr_twin: a MuJoCo digital twin of a bucket wheel reclaimer under fuzzy, model-based control.

The package is built in layers (bwr_twin.layers), lowest first; each imports only from itself and
the layers before it:

    errors; units, values, textfile, signals, progress, arguments, exposure, shipped, ownership,
    streams -> arrays, tomlfile (files checked) -> model (MJCF machine, kinematics, its parts)
    -> control (control laws, rule base)
    -> fis (.fis files) -> config (scene and sweep files, plug-ins) -> pile (the pile's shape)
    -> planning (trajectory, bench and stacking plans) -> stockpile (material, digging, stacking)
    -> sensing, collision -> sim (plant, the lockstep loop and its stages, twin) -> results (run directories,
    plots) -> run -> batch, compare, gym, replay, serve -> export (FMU, PLC, AAS) -> tune
"""

from bwr_twin.errors import (
    BwrError,
    EnvelopeError,
    ModelError,
    SceneError,
    SimulationError,
    UnreachableError,
)
from bwr_twin.model.machine import AXES, Machine

__all__ = [
    "AXES",
    "BwrError",
    "EnvelopeError",
    "Machine",
    "ModelError",
    "SceneError",
    "SimulationError",
    "UnreachableError",
]
