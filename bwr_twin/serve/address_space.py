"""The OPC UA address space of the twin: `Objects/Reclaimer/...`, the contract of docs/opcua.md.

Every variable is one row of `MACHINE_VARIABLES` or `AXIS_VARIABLES`: its browse name, type,
unit and meaning. The server publishes a variable from the value of the same name in the
readings it is given (`AddressSpace.publish`), so a new machine-level variable is one row here
and one value in the readings. A Double is an analog item of OPC UA Part 8 (AnalogUnitType,
or AnalogItemType without a unit) with its EURange, given to `build` (bwr_twin.sim.ranges).
The rows of `INSTRUMENT_VARIABLES` are served only by a run that has the instrument, those of
`NEIGHBOUR_VARIABLES` and `NEIGHBOUR_AXIS_VARIABLES` only by one with a second machine on the
rail; the scanners' profiles and the faults' states are `bwr_twin.serve.sensing`'s.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from datetime import datetime, timezone

from asyncua import Node, Server, ua

from bwr_twin.model.machine import AXES
from bwr_twin.opcua import nodes
from bwr_twin.opcua.analog import UNITS, add_analog_item, eu_information  # noqa: F401  (UNITS: the contract's)
from bwr_twin.opcua.methods import checked

NAMESPACE_URI = "urn:bwr_twin:reclaimer"
LINEAR, ANGULAR = "linear", "angular"
AXIS_KIND = {"travel": LINEAR, "slew": ANGULAR, "luff": ANGULAR}


@dataclass(frozen=True)
class Variable:
    """One variable of the contract.

    `unit`: a symbol of UNITS, or for an axis variable a (linear, angular) pair of them, or None.
    """

    name: str
    variant: ua.VariantType
    unit: str | tuple[str, str] | None
    meaning: str
    writable: bool = False


D, B, S, U = ua.VariantType.Double, ua.VariantType.Boolean, ua.VariantType.String, ua.VariantType.UInt32

MACHINE_VARIABLES = (
    Variable("SimTime", D, "s", "simulated time of the encoder reading"),
    Variable("ControlPeriod", D, "s", "the control period: the time one Step advances"),
    Variable("PeriodsLeft", U, None, "control periods left on the path; 0 at its end"),
    Variable("Running", B, None, "real-time mode: the clock runs (Start); false in lockstep mode"),
    Variable("Mode", S, None, '"lockstep" or "realtime"'),
    Variable("WatchdogTripped", B, None, "real-time mode: no DriveSetpoint write within the watchdog's "
             "periods; drives at zero until Reset"),
    Variable("Overruns", U, None, "real-time mode: control periods computed later than the next one was due"),
    Variable("ReclaimRate", D, "t/h", "what the bucket wheel reclaims, as the belt scale sees it; 0 without a stockpile"),
)

# Served only when the run has the instrument: a scene with a [stockpile] on a machine whose MJCF
# describes it (docs/sensing.md); published as the twin reads it every control period.
INSTRUMENT_VARIABLES = (
    Variable("BeltScale", D, "t/h", "the belt scale's reading of the boom conveyor: the belt's rate at the "
             "discharge, the transport delay later, with its noise and filter; 0 before the first period"),
    Variable("WheelCurrent", D, "A", "the wheel motor's line current as its drive measures it, with its noise; "
             "0 before the first period"),
    Variable("WindSpeed", D, "m/s", "the anemometer: the wind's speed towards the scene's wind_direction over the "
             "last period (its mean before the first); served when the plant has wind"),
)

# Served only when the run has a [neighbour] (docs/anticollision.md): what the automation hears of
# the other machine on the rail, its latest position report, report_delay late.
NEIGHBOUR_VARIABLES = (
    Variable("NeighbourReportTime", D, "s", "the simulated time at which the neighbour stood where its latest "
             "position report says: SimTime less its report delay"),
)
NEIGHBOUR_AXIS_VARIABLES = (
    Variable("NeighbourPosition", D, ("m", "rad"), "the neighbour's position on this axis, as its latest report "
             "gives it (true at NeighbourReportTime)"),
)

AXIS_VARIABLES = (
    Variable("EncoderPosition", D, ("m", "rad"), "encoder position, quantised to the scene's resolution"),
    Variable("EncoderVelocity", D, ("m/s", "rad/s"), "encoder velocity, as the scene's encoders give it"),
    Variable("ReferencePosition", D, ("m", "rad"), "the path's position at SimTime"),
    Variable("ReferenceVelocity", D, ("m/s", "rad/s"), "the path's velocity at SimTime"),
    Variable("ReferenceAcceleration", D, ("m/s²", "rad/s²"), "the path's acceleration at SimTime"),
    Variable("DriveSetpoint", D, ("N", "N·m"), "drive force the PLC commands, held over the periods advanced after the write",
             writable=True),
    Variable("DriveCommanded", D, ("N", "N·m"), "drive force the PLC commanded over the last period (the setpoint "
             "held), stamped with the period's readings"),
    Variable("DriveApplied", D, ("N", "N·m"), "drive force applied over the last period (within the rating)"),
    Variable("AtLimit", B, None, "limit switch: the joint at or beyond its operating envelope or end stop"),
)

METHODS = {
    "Start": "real-time mode: start the clock",
    "Stop": "real-time mode: stop the clock; the machine freezes",
    "Reset": "back to the path's start: setpoints zero, watchdog and overruns cleared, clock stopped",
    "Step": "Step(n UInt32) -> SimTime: advance n control periods under the current setpoints (not while Running)",
}


def axis_name(axis: str) -> str:
    """'travel' -> 'Travel', the browse name of an axis's object."""
    return axis.capitalize()


def unit_of(variable: Variable, axis: str | None = None) -> str | None:
    """The unit symbol of a variable (of an axis: linear or angular)."""
    if isinstance(variable.unit, tuple):
        return variable.unit[0 if AXIS_KIND[axis] == LINEAR else 1]
    return variable.unit


def node_path(variable: str, axis: str | None = None) -> str:
    """'Reclaimer/Travel/DriveSetpoint': a node's browse path under Objects, as the docs give it."""
    return f"Reclaimer/{axis_name(axis)}/{variable}" if axis else f"Reclaimer/{variable}"


def _initial(variant: ua.VariantType):
    return {D: 0.0, B: False, S: "", U: 0}[variant]


class AddressSpace:
    """The twin's nodes on `server`, and the publishing of readings into them."""

    def __init__(self, server: Server, namespace: int, ranges: Mapping[tuple[str, str | None], tuple[float, float]]):
        self.server, self.namespace, self.ranges = server, namespace, ranges
        self.nodes: dict[tuple[str, str | None], Node] = {}  # (variable, axis or None) -> node
        self.objects: dict[str | None, Node] = {}  # axis -> its object; None -> Objects/Reclaimer

    @classmethod
    async def build(cls, server: Server, methods: Mapping[str, Callable],
                    ranges: Mapping[tuple[str, str | None], tuple[float, float]],
                    instruments: Sequence[str] = (), neighbour: bool = False) -> AddressSpace:
        """Create Objects/Reclaimer with its variables and `methods` (name -> async handler);
        `ranges`: the EURange (low, high) of every Double, by (variable, axis or None);
        `instruments`: the names of the INSTRUMENT_VARIABLES the run has; `neighbour`: whether
        it has a second machine on the rail (NEIGHBOUR_VARIABLES, NEIGHBOUR_AXIS_VARIABLES)."""
        space = cls(server, await server.register_namespace(NAMESPACE_URI), ranges)
        ns = space.namespace
        space.objects[None] = reclaimer = await server.nodes.objects.add_object(ua.NodeId("Reclaimer", ns),
                                                                                ua.QualifiedName("Reclaimer", ns))
        for variable in MACHINE_VARIABLES:
            await space._add_variable(reclaimer, variable, None)
        for variable in INSTRUMENT_VARIABLES:
            if variable.name in instruments:
                await space._add_variable(reclaimer, variable, None)
        for variable in NEIGHBOUR_VARIABLES if neighbour else ():
            await space._add_variable(reclaimer, variable, None)
        for axis in AXES:
            space.objects[axis] = folder = await reclaimer.add_object(ua.NodeId(f"Reclaimer.{axis_name(axis)}", ns),
                                                                      ua.QualifiedName(axis_name(axis), ns))
            for variable in AXIS_VARIABLES + (NEIGHBOUR_AXIS_VARIABLES if neighbour else ()):
                await space._add_variable(folder, variable, axis)
        step_argument = ua.Argument(Name="n", DataType=ua.NodeId(ua.ObjectIds.UInt32), ValueRank=-1,
                                    Description=ua.LocalizedText("control periods to advance, >= 1"))
        sim_time = ua.Argument(Name="SimTime", DataType=ua.NodeId(ua.ObjectIds.Double), ValueRank=-1,
                               Description=ua.LocalizedText("simulated time after the step, s"))
        for name, handler in methods.items():
            inputs, outputs = ([step_argument], [sim_time]) if name == "Step" else ([], [])
            handler = checked(handler, [ua.VariantType(a.DataType.Identifier) for a in inputs], reclaimer.nodeid)
            node = await reclaimer.add_method(ua.NodeId(f"Reclaimer.{name}", ns), ua.QualifiedName(name, ns),
                                              handler, inputs, outputs)
            await node.write_attribute(ua.AttributeIds.Description,
                                       ua.DataValue(ua.Variant(ua.LocalizedText(METHODS[name]))))
        return space

    async def _add_variable(self, parent: Node, variable: Variable, axis: str | None) -> None:
        node_id = node_path(variable.name, axis).replace("/", ".")
        eu_range = self.ranges[variable.name, axis] if variable.variant == D else None
        self.nodes[variable.name, axis] = await self.add_variable(parent, node_id, variable, unit_of(variable, axis),
                                                                  eu_range)

    async def add_variable(self, parent: Node, node_id: str, variable: Variable, unit: str | None,
                           eu_range: tuple[float, float] | None, *, value: object = None,
                           length: int | None = None) -> Node:
        """A variable of the twin's namespace under `parent`, with its Description (the meaning
        and unit) and, with a unit, its EngineeringUnits; a Double an analog item with
        `eu_range`. `length`: a one-dimensional array of that many values (the initial `value`,
        a list), else a scalar (`value`, default zero)."""
        ns = self.namespace
        name = ua.QualifiedName(variable.name, ns)
        initial = _initial(variable.variant) if value is None else value
        if variable.variant == D:
            node = await add_analog_item(parent, ua.NodeId(node_id, ns), name, unit, eu_range, value=initial,
                                         length=length)
        else:
            if length is not None:
                node = await nodes.add_variable(parent, ua.NodeId(node_id, ns), name,
                                                ua.Variant(initial, variable.variant),
                                                ua.ObjectIds.BaseDataVariableType, length=length)
            else:
                node = await parent.add_variable(ua.NodeId(node_id, ns), name, initial, variable.variant)
            if unit:  # the standard property, its browse name in namespace 0
                await node.add_property(ua.NodeId(f"{node_id}.EngineeringUnits", ns),
                                        ua.QualifiedName("EngineeringUnits", 0), eu_information(unit),
                                        ua.VariantType.ExtensionObject, ua.NodeId(ua.ObjectIds.EUInformation))
        meaning = f"{variable.meaning}, {unit}" if unit else variable.meaning
        await node.write_attribute(ua.AttributeIds.Description, ua.DataValue(ua.Variant(ua.LocalizedText(meaning))))
        if variable.writable:
            await node.set_writable()
        return node

    def writable(self) -> list[str]:
        """Browse paths of the nodes a client may write."""
        return [node_path(v.name, a) for v in AXIS_VARIABLES if v.writable for a in AXES] + [
            node_path(v.name) for v in MACHINE_VARIABLES if v.writable]

    async def publish(self, readings: Mapping[str, object]) -> None:
        """Write every variable found in `readings` (name -> value; an axis variable's value a
        (3,) sequence in AXES order), stamped with the wall-clock time."""
        now = datetime.now(timezone.utc)
        write = self.server.write_attribute_value
        for name, value in readings.items():
            if (name, None) in self.nodes:
                variable = _VARIABLES[name]
                await write(self.nodes[name, None].nodeid, _data_value(value, variable.variant, now))
            elif (name, AXES[0]) in self.nodes:
                variant = _VARIABLES[name].variant
                for axis, axis_value in zip(AXES, value):
                    await write(self.nodes[name, axis].nodeid, _data_value(axis_value, variant, now))


_VARIABLES = {v.name: v for v in MACHINE_VARIABLES + INSTRUMENT_VARIABLES + NEIGHBOUR_VARIABLES + AXIS_VARIABLES
              + NEIGHBOUR_AXIS_VARIABLES}
_PYTHON = {D: float, B: bool, S: str, U: int}


def _data_value(value: object, variant: ua.VariantType, now: datetime) -> ua.DataValue:
    return data_value(_PYTHON[variant](value), variant, now)


def data_value(value: object, variant: ua.VariantType, now: datetime) -> ua.DataValue:
    """A value as published: stamped with the wall-clock time `now`, at the source and the server."""
    return ua.DataValue(ua.Variant(value, variant), SourceTimestamp=now, ServerTimestamp=now)
