"""The FMU's variables, one table for both FMUs the twin exports (docs/fmu.md): the native FMU
(bwr_twin.export.native_fmu) writes its model description and its C header from it, the Python
one (bwr_twin.export.fmu_slave) registers its variables from it. Named as the OPC UA address
space names them."""

from __future__ import annotations

from dataclasses import dataclass

from bwr_twin.sim.twin import MEASURED

AXES = ("Travel", "Slew", "Luff")

# FMI 2.0 unit definitions (fmi2Unit): the SI base-unit exponents of each unit the variables carry.
UNITS = {
    "m": {"m": 1}, "rad": {"rad": 1}, "s": {"s": 1},
    "m/s": {"m": 1, "s": -1}, "rad/s": {"rad": 1, "s": -1},
    "m/s2": {"m": 1, "s": -2}, "rad/s2": {"rad": 1, "s": -2},
    "N": {"kg": 1, "m": 1, "s": -2}, "N.m": {"kg": 1, "m": 2, "s": -2},
    "t/h": {"kg": 1, "s": -1, "factor": 1000 / 3600}, "A": {"A": 1}, "1": {}, "kg/m3": {"kg": 1, "m": -3},
}


@dataclass(frozen=True)
class Signal:
    """One variable per axis (`per_axis`) or of the machine: its name, unit (linear, angular) and meaning."""

    name: str
    unit: tuple[str, str] | str | None
    meaning: str
    per_axis: bool = True


OUTPUTS = (
    Signal("EncoderPosition", ("m", "rad"), "encoder position, quantised to the scene's resolution"),
    Signal("EncoderVelocity", ("m/s", "rad/s"), "encoder velocity, as the scene's encoders give it"),
    Signal("ReferencePosition", ("m", "rad"), "the path's position at the step's end"),
    Signal("ReferenceVelocity", ("m/s", "rad/s"), "the path's velocity at the step's end"),
    Signal("ReferenceAcceleration", ("m/s2", "rad/s2"), "the path's acceleration at the step's end"),
    Signal("DriveApplied", ("N", "N.m"), "drive force applied over the last period (within the drive's rating)"),
)
assert [s.name for s in OUTPUTS] == [*MEASURED, "DriveApplied"], "in the order the twin gives them"
SWITCHES = Signal("AtLimit", None, "limit switch: the joint at or beyond its operating envelope or end stop")
RECLAIM_RATE = Signal("ReclaimRate", "t/h", "what the bucket wheel reclaims, on the belt at the discharge", False)
# The machine's instruments, where its MJCF describes them (docs/sensing.md): late and noisy.
BELT_SCALE = Signal("BeltScale", "t/h", "the belt scale's reading: the rate the belt transport delay ago, "
                    "with the scale's noise and filter", False)
WHEEL_CURRENT = Signal("WheelCurrent", "A", "the wheel motor's current as its drive measures it", False)
# A second machine on the rail, where the scene has a [neighbour] (docs/anticollision.md): what the
# automation hears of it, its latest position report.
NEIGHBOUR_POSITION = Signal("NeighbourPosition", ("m", "rad"), "the neighbour's position as its latest report "
                            "gives it, true at NeighbourReportTime")
NEIGHBOUR_REPORT_TIME = Signal("NeighbourReportTime", "s", "the simulated time at which the neighbour stood where its "
                               "latest report says: the time less its report delay", False)
# A bench reclaim's rate loop, replaceable by the importer's: its trim, and whether it is used.
TRIM = Signal("SlewSpeedTrim", "1", "the bench plan's slew speed law times this, within the scene's "
              "trim_limits, while SlewSpeedTrimFromInput is true", False)
TRIM_FROM_INPUT = Signal("SlewSpeedTrimFromInput", None, "true: SlewSpeedTrim trims the slew speed; "
                         "false: the scene's own rate loop does", False)
SETPOINT = Signal("DriveSetpoint", ("N", "N.m"), "drive force the controller commands, held over the step")
# Scene keys an importer may set before initialisation, each (FMI name, scene key, axis index or None, unit).
PARAMETERS = (
    ("Seed", "simulation.seed", None, None, "seed of the disturbance forces' random stream"),
    *((f"{axis}.DisturbanceAmplitude", "disturbance.amplitude", i, ("N", "N.m")[i > 0],
       "amplitude of the uniform random disturbance force") for i, axis in enumerate(AXES)),
    ("DisturbanceHoldTime", "disturbance.hold_time", None, "s", "how long each random disturbance is held"),
    *((f"{axis}.EncoderResolution", "encoders.resolution", i, ("m", "rad")[i > 0],
       "the encoder's count, what its position is quantised to") for i, axis in enumerate(AXES)),
)


def axis_unit(signal: Signal, index: int) -> str | None:
    """The unit of a per-axis signal on axis `index` (0 travel: linear; slew and luff: angular)."""
    return signal.unit[0 if index == 0 else 1] if isinstance(signal.unit, tuple) else signal.unit



# The native FMU's own: the wind comes from the importer (the scene's gusts do not apply), and the
# air density that makes it act. Its other variables are the ones above.
WIND_SPEED = Signal("WindSpeed", "m/s", "the wind's speed along the scene's wind direction, held over the step; "
                    "it acts on the machine's wind areas while AirDensity > 0", False)
AIR_DENSITY = ("AirDensity", "kg/m3", ("density of the air the wind and the machine's motion act through; 0: no "
                                        "air drag, as the twin's still-air runs"))
DISTURBANCE = Signal("DisturbanceForce", ("N", "N.m"), "the random disturbance force on the joint over the last "
                     "period: the world's, which the automation does not measure")
PERIODS_LEFT = "control periods left on the path; 0 at its end"
CONTROL_PERIOD = "the control period: a communication step is a whole number of them"
# The least value of a parameter (the bound, and whether the bound itself is refused), by the
# name after its axis: the FMU refuses a value beyond it, as the scene file would.
MINIMUM = {"Seed": (0, False), "DisturbanceAmplitude": (0.0, False), "DisturbanceHoldTime": (0.0, True),
           "EncoderResolution": (0.0, True), "AirDensity": (0.0, False)}


@dataclass(frozen=True)
class Variable:
    """One scalar variable of the native FMU. `group` names it for the C code (VR_<group> is the
    value reference of its first axis); `type` is FMI 2.0's (Real, Integer, Boolean)."""

    name: str
    vr: int
    type: str
    causality: str  # input, output, parameter, calculatedParameter, independent
    unit: str | None
    description: str
    group: str
    start: float | None = None
    minimum: tuple[float, bool] | None = None

    @property
    def variability(self) -> str:
        if self.causality in ("parameter", "calculatedParameter"):
            return "fixed"
        return "continuous" if self.type == "Real" else "discrete"


def _group(name: str) -> str:
    """EncoderPosition -> ENCODER_POSITION."""
    return "".join(f"_{c}" if c.isupper() and i else c for i, c in enumerate(name)).upper()


def native_variables(starts: dict[str, float]) -> tuple[Variable, ...]:
    """The native FMU's variables in value-reference order; `starts` gives each input's and
    parameter's start value by its name."""
    rows: list[tuple] = []
    for i, axis in enumerate(AXES):
        rows.append((f"{axis}.{SETPOINT.name}", "Real", "input", axis_unit(SETPOINT, i), SETPOINT.meaning, SETPOINT.name))
    rows.append((WIND_SPEED.name, "Real", "input", WIND_SPEED.unit, WIND_SPEED.meaning, WIND_SPEED.name))
    for signal in OUTPUTS:
        for i, axis in enumerate(AXES):
            rows.append((f"{axis}.{signal.name}", "Real", "output", axis_unit(signal, i), signal.meaning, signal.name))
    for i, axis in enumerate(AXES):
        rows.append((f"{axis}.{DISTURBANCE.name}", "Real", "output", axis_unit(DISTURBANCE, i), DISTURBANCE.meaning,
                     DISTURBANCE.name))
    for axis in AXES:
        rows.append((f"{axis}.{SWITCHES.name}", "Boolean", "output", None, SWITCHES.meaning, SWITCHES.name))
    rows.append(("PeriodsLeft", "Integer", "output", None, PERIODS_LEFT, "PeriodsLeft"))
    rows.append(("ControlPeriod", "Real", "calculatedParameter", "s", CONTROL_PERIOD, "ControlPeriod"))
    rows.append(("time", "Real", "independent", "s", "the simulated time, k control periods", "Time"))
    for name, _, _, unit, meaning in (*PARAMETERS, (AIR_DENSITY[0], None, None, *AIR_DENSITY[1:])):
        short = name.rpartition(".")[2]
        rows.append((name, "Integer" if unit is None else "Real", "parameter", unit, meaning, short))
    variables = []
    for vr, (name, kind, causality, unit, meaning, group) in enumerate(rows):
        given = causality in ("input", "parameter")
        variables.append(Variable(name, vr, kind, causality, unit, meaning, _group(group),
                                  start=starts[name] if given else None,
                                  minimum=MINIMUM.get(name.rpartition(".")[2]) if causality == "parameter" else None))
    return tuple(variables)
