"""The parameters a log can fit, each with its bounds from physics and from the MJCF's ratings,
the element and field of the MJCF it changes, and the test motion that determines it.

Names: `AXIS_damping` (viscous, N s/m or N m s/rad), `AXIS_frictionloss` (Coulomb, N or N m),
`AXIS_armature` (reflected drive inertia, kg or kg m^2), `BODY_mass` (kg), `BODY_x` (m, the
body's position along its parent's x: along the boom for the boom's bodies), `AXIS_lag` (s, the
drive's time lag), `AXIS_offset` (m or rad, the encoder's offset). Each writes into the MjSpec
through bwr_twin.model.spec.set_field; a lag and an offset change the signals, not the model.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import mujoco
import numpy as np

from bwr_twin.errors import BwrError
from bwr_twin.model.machine import AXES, Machine

DEFAULT_KINDS = ("damping", "frictionloss", "armature")  # fitted when --params names none
JOINT_KINDS = ("damping", "frictionloss", "armature")
SIGNAL_KINDS = ("lag", "offset")
BODY_KINDS = ("mass", "x")
MAX_LAG = 2.0  # s: a drive slower than this is not a lag but a fault
MASS_RANGE = (0.25, 4.0)  # times the file's mass: any larger error is a wrong file, not a calibration
POSITION_RANGE = 0.25  # of the distance from the parent's origin either way, at least 1 m

# The motion that determines each kind of parameter, for what the log could not.
MOTIONS = {
    "damping": "speed steps both ways at several speeds on {axis}, held long enough to settle",
    "frictionloss": "speed steps both ways on {axis}, including slow speeds and starts from rest",
    "armature": "hard accelerations and decelerations of {axis} within its drive rating",
    "mass": "slew and luff at several angles, holding each, so that gravity's moment changes",
    "x": "luff at several angles with the slew held, and slew at several luff angles",
    "lag": "fast force reversals on {axis}",
    "offset": "{axis} at rest at several known positions",
}
UNITS = {"damping": ("N s/m", "N m s/rad", "N m s/rad"), "frictionloss": ("N", "N m", "N m"),
         "armature": ("kg", "kg m^2", "kg m^2"), "lag": ("s", "s", "s"), "offset": ("m", "rad", "rad")}


@dataclass(frozen=True)
class Knob:
    """One parameter a fit may change."""

    name: str
    kind: str  # a JOINT_KINDS, BODY_KINDS or SIGNAL_KINDS entry
    element: str  # the joint (or axis) or body it belongs to
    axis: int | None  # the axis index for joint and signal kinds
    nominal: float
    low: float
    high: float
    unit: str

    @property
    def motion(self) -> str:
        """The test motion that would determine it."""
        return MOTIONS[self.kind].format(axis=self.element)

    def modify(self, spec: mujoco.MjSpec, value: float) -> None:
        """Write `value` into the spec (nothing for a signal's parameter)."""
        from bwr_twin.model.spec import set_field

        if self.kind == "damping":  # MuJoCo's damping is a polynomial in the speed: its linear term
            polynomial = list(spec.joint(self.element).damping)
            polynomial[0] = float(value)
            set_field(spec, "joint", self.element, "damping", polynomial)
        elif self.kind in JOINT_KINDS:
            set_field(spec, "joint", self.element, self.kind, float(value))
        elif self.kind == "mass":
            set_field(spec, "body", self.element, "mass", float(value))
        elif self.kind == "x":
            pos = list(spec.body(self.element).pos)
            pos[0] = float(value)
            set_field(spec, "body", self.element, "pos", pos)


def catalogue(machine: Machine, names: Sequence[str] | None) -> list[Knob]:
    """The knobs named (default: every axis's DEFAULT_KINDS), with their nominal values from the
    machine's file and their bounds. Raises BwrError naming a parameter the machine lacks."""
    if not names:
        names = [f"{axis}_{kind}" for axis in AXES for kind in DEFAULT_KINDS]
    knobs = []
    for given in names:
        name, _, bounds = given.partition("=")
        element, _, kind = name.rpartition("_")
        if not element or kind not in JOINT_KINDS + BODY_KINDS + SIGNAL_KINDS:
            raise BwrError(f"--params: '{name}' is not a parameter; give AXIS_KIND ({', '.join(JOINT_KINDS + SIGNAL_KINDS)}) "
                           f"or BODY_KIND ({', '.join(BODY_KINDS)}), e.g. slew_damping or boom_counterweight_mass")
        knob = _knob(machine, name, element, kind)
        knobs.append(_bounded(knob, bounds) if bounds else knob)
    if len({k.name for k in knobs}) != len(knobs):
        raise BwrError("--params: a parameter is named twice")
    return knobs


def _bounded(knob: Knob, text: str) -> Knob:
    """The knob with the engineer's bounds `LOW:HIGH`, which must lie within physics' (its own)."""
    try:
        low, high = (float(v) for v in text.split(":"))
    except ValueError:
        raise BwrError(f"--params: '{knob.name}={text}': bounds are LOW:HIGH, two numbers") from None
    if not (np.isfinite(low) and np.isfinite(high) and low < high):
        raise BwrError(f"--params: '{knob.name}={text}': bounds need LOW < HIGH, both finite")
    if low < knob.low or high > knob.high:
        raise BwrError(f"--params: '{knob.name}={text}': outside what physics and the MJCF's ratings allow, "
                       f"{knob.low:.6g} to {knob.high:.6g} {knob.unit}")
    if not low <= knob.nominal <= high:
        raise BwrError(f"--params: '{knob.name}={text}': the MJCF's value {knob.nominal:.6g} {knob.unit} lies "
                       "outside them; the fit starts from it")
    return Knob(knob.name, knob.kind, knob.element, knob.axis, knob.nominal, low, high, knob.unit)


def _knob(machine: Machine, name: str, element: str, kind: str) -> Knob:
    model = machine.model
    if kind in JOINT_KINDS + SIGNAL_KINDS:
        if element not in AXES:
            raise BwrError(f"--params: '{name}': '{element}' is not an axis ({', '.join(AXES)})")
        axis = AXES.index(element)
        dof = model.jnt_dofadr[machine.joint_ids[axis]]
        rating = float(np.max(np.abs(machine.drive_limits[axis])))
        unit = UNITS[kind][axis]
        if kind == "damping":  # at most all the drive's rating spent at its rated speed
            speed = machine.rated_speed[axis] if np.isfinite(machine.rated_speed[axis]) else 1.0
            return Knob(name, kind, element, axis, float(model.dof_damping[dof]), 0.0, _finite(rating) / speed, unit)
        if kind == "frictionloss":  # a friction beyond the drive's rating and the axis never moves
            return Knob(name, kind, element, axis, float(model.dof_frictionloss[dof]), 0.0, _finite(rating), unit)
        if kind == "armature":  # a drive reflecting more than the axis's own inertia is another machine
            return Knob(name, kind, element, axis, float(model.dof_armature[dof]), 0.0,
                        _inertia(model, int(dof)), unit)
        if kind == "lag":
            return Knob(name, kind, element, axis, 0.0, 0.0, MAX_LAG, unit)
        half = 0.5 if axis == 0 else 0.05  # m, rad: an encoder set up wrong by more is not an offset
        return Knob(name, kind, element, axis, 0.0, -half, half, unit)
    body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, element)
    if body < 0:
        raise BwrError(f"--params: '{name}': the model has no body '{element}'")
    if kind == "mass":
        mass = float(model.body_mass[body])
        if mass <= 0:
            raise BwrError(f"--params: '{name}': the body '{element}' has no mass to fit")
        return Knob(name, kind, element, None, mass, MASS_RANGE[0] * mass, MASS_RANGE[1] * mass, "kg")
    x = float(model.body_pos[body, 0])
    reach = max(POSITION_RANGE * abs(x), 1.0)
    return Knob(name, kind, element, None, x, x - reach, x + reach, "m")


def _finite(rating: float) -> float:
    """A drive without a rating is bounded as one of 1e9 (N or N m): beyond any reclaimer."""
    return rating if np.isfinite(rating) else 1e9


def _inertia(model: mujoco.MjModel, dof: int) -> float:
    """The diagonal of the mass matrix at the model's reference pose for one dof."""
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    full = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, data, full)
    return float(full[dof, dof])
