"""bwr_twin: a MuJoCo digital twin of a bucket wheel reclaimer under fuzzy, model-based control.

The sub-packages follow the data flow:

    config (scene and sweep files) -> model (MJCF machine, kinematics) -> planning (trajectory)
    -> control (fuzzy surface, belief, control law) -> sim (plant, encoders, lockstep loop)
    -> results (records, metrics, run directories, plots) -> batch, replay
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
