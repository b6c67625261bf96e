"""Control: the controller slot (interface, registry), the paper's fuzzy + model-based controller
(rule base, surface, belief), and the PID and computed-torque baselines.

An engineer's own controller derives from `Controller` (docs/controllers.md)."""

from bwr_twin.control.interface import Controller, ControllerContext, SettingsError

__all__ = ["Controller", "ControllerContext", "SettingsError"]
