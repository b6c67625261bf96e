"""The alarms a SCADA client subscribes to on Objects/Reclaimer (or on the Server object): a
limit switch that closes and opens again (OffNormalAlarmType, one condition per axis), and the
watchdog's trip and its clearing by Reset (TripAlarmType). Their events, and ConditionRefresh,
are bwr_twin.opcua.conditions'.
"""

from __future__ import annotations

from collections.abc import Mapping

from asyncua import ua

from bwr_twin.model.machine import AXES
from bwr_twin.opcua.conditions import Conditions
from bwr_twin.serve.address_space import AddressSpace, axis_name

# OPC UA severities run 1-1000; 601-800 is medium-high, 801-1000 high.
LIMIT_SEVERITY = 700  # a joint reached its envelope or end stop: the PLC should stop pushing it
WATCHDOG_SEVERITY = 900  # the drives were cut: the machine does not follow the PLC until Reset
# OPC UA Part 9's condition classes: the process (a joint's travel), the system (its PLC link).
PROCESS_CLASS, SYSTEM_CLASS = ua.ObjectIds.ProcessConditionClassType, ua.ObjectIds.SystemConditionClassType


class Alarms:
    """The conditions of the twin and the events of their changes."""

    def __init__(self, space: AddressSpace, conditions: Conditions):
        self.space = space
        self.conditions = conditions  # keyed (input variable, axis or None)

    @classmethod
    async def build(cls, space: AddressSpace) -> Alarms:
        """The conditions, emitted on Objects/Reclaimer; the Reclaimer a notifier of the Server
        object, its axes its event sources."""
        reclaimer = space.objects[None]
        conditions = await Conditions.build(space.server, reclaimer)
        for index, axis in enumerate(AXES):
            await reclaimer.add_reference(space.objects[axis].nodeid, ua.ObjectIds.HasEventSource)
            await conditions.add(
                ("AtLimit", axis), ua.ObjectIds.OffNormalAlarmType, first=index == 0, source=space.objects[axis],
                input_node=space.nodes["AtLimit", axis],
                condition=ua.NodeId(f"Reclaimer.{axis_name(axis)}.LimitAlarm", space.namespace),
                name="LimitAlarm", severity=LIMIT_SEVERITY, condition_class=(PROCESS_CLASS, "Process"))
        await conditions.add(
            ("WatchdogTripped", None), ua.ObjectIds.TripAlarmType, first=True, source=reclaimer,
            input_node=space.nodes["WatchdogTripped", None],
            condition=ua.NodeId("Reclaimer.WatchdogAlarm", space.namespace), name="WatchdogAlarm",
            severity=WATCHDOG_SEVERITY, condition_class=(SYSTEM_CLASS, "System"))
        return cls(space, conditions)

    async def publish(self, readings: Mapping[str, object]) -> None:
        """Raise or clear the conditions that `readings` change: each limit switch that changed
        since the last publication, in order (`LimitSwitches`: (axis index, at the limit,
        SimTime)), then AtLimit and WatchdogTripped as they read now."""
        for index, at_limit, sim_time in readings.get("LimitSwitches", ()):
            await self._change(("AtLimit", AXES[index]), at_limit, sim_time)
        sim_time = float(readings.get("SimTime", 0.0))
        if "AtLimit" in readings:
            for axis, at_limit in zip(AXES, readings["AtLimit"]):
                await self._change(("AtLimit", axis), bool(at_limit), sim_time)
        if "WatchdogTripped" in readings:
            await self._change(("WatchdogTripped", None), bool(readings["WatchdogTripped"]), sim_time)

    async def _change(self, key, active: bool, sim_time: float) -> None:
        await self.conditions.change(key, active, _message(key, active, sim_time))


def _message(key, active: bool, sim_time: float) -> str:
    variable, axis = key
    at = f"at SimTime {sim_time:.2f} s"
    if variable == "AtLimit":
        if active:
            return (f"{axis_name(axis)}: limit switch closed {at}: the joint at or beyond its operating envelope "
                    "or end stop")
        return f"{axis_name(axis)}: limit switch open again {at}"
    if active:
        return (f"watchdog tripped {at}: no DriveSetpoint write within the watchdog's periods; drives at zero "
                "until Reset")
    return f"watchdog cleared by Reset {at}"
