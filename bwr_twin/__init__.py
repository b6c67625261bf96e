"""bwr_twin: a MuJoCo digital twin of a bucket wheel reclaimer under fuzzy, model-based control.

Data flow: machine (MJCF, kinematics) -> trajectory -> controller -> simulation -> results
-> plots, replay and batch runs.
"""

from bwr_twin.errors import (
    BwrError,
    EnvelopeError,
    ModelError,
    SceneError,
    SimulationError,
    UnreachableError,
)
from bwr_twin.machine import AXES, Machine

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
