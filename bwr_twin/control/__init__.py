"""Control: the controller slot (interface, registry), the paper's fuzzy + model-based controller
(rule base, surface, belief), and the PID and computed-torque baselines.

An engineer's own controller derives from `Controller` (docs/controllers.md), an engineer's own
reclaim rate loop from `RateControl` (docs/reclaiming.md)."""

from bwr_twin.control.interface import Controller, ControllerContext, SettingsError
from bwr_twin.control.rate import RateControl, RateSignals

__all__ = ["Controller", "ControllerContext", "RateControl", "RateSignals", "SettingsError"]
