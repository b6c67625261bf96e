"""Control: the controller slot (interface), the paper's fuzzy + model-based controller (rule
base, surface, belief), the PID and computed-torque baselines, and the reclaim rate loops.

An engineer's own controller derives from `Controller` (docs/controllers.md), an engineer's own
reclaim rate loop from `RateControl` (docs/reclaiming.md); a scene names either by a string that
bwr_twin.config.plugins resolves."""

from bwr_twin.control.interface import Controller, ControllerContext, SettingsError
from bwr_twin.control.rate import RateControl, RateSignals, WheelCalibration

__all__ = ["Controller", "ControllerContext", "RateControl", "RateSignals", "SettingsError", "WheelCalibration"]
