"""The alarms a SCADA client subscribes to on Objects/Reclaimer (or on the Server object): a
limit switch that closes and opens again (OffNormalAlarmType, one condition per axis), and the
watchdog's trip and its clearing by Reset (TripAlarmType).

Each change of a condition is one event of its type, with the condition's fields as OPC UA
Part 9 gives them (ConditionId, ActiveState, Retain, Severity, SourceNode, InputNode, Message).
The conditions are not nodes of the address space (Part 9 allows that): they need no
acknowledgement, and arrive acknowledged.

ConditionRefresh and ConditionRefresh2 (Part 9, 5.5.7 and 5.5.8; called on ConditionType) are
served here, not by asyncua: a RefreshStartEvent to every event monitored item of the
subscription (or the one named), whatever its filter, then each active condition again, as its
last event (its Retain true), to the monitored items of the Reclaimer or the Server object whose
filter it meets, then a RefreshEndEvent as the start went.
"""

from __future__ import annotations

import uuid
from collections.abc import Mapping
from datetime import datetime, timezone

from asyncua import ua
from asyncua.server.event_generator import EventGenerator

from bwr_twin.model.machine import AXES
from bwr_twin.serve.address_space import AddressSpace, axis_name
from bwr_twin.serve.methods import checked, status

# OPC UA severities run 1-1000; 601-800 is medium-high, 801-1000 high.
LIMIT_SEVERITY = 700  # a joint reached its envelope or end stop: the PLC should stop pushing it
WATCHDOG_SEVERITY = 900  # the drives were cut: the machine does not follow the PLC until Reset
# OPC UA Part 9's condition classes: the process (a joint's travel), the system (its PLC link).
PROCESS_CLASS, SYSTEM_CLASS = ua.ObjectIds.ProcessConditionClassType, ua.ObjectIds.SystemConditionClassType


class Alarms:
    """The conditions of the twin and the events of their changes."""

    def __init__(self, space: AddressSpace, conditions: dict[tuple[str, str | None], EventGenerator],
                 subscriptions):
        self.space = space
        self._conditions = conditions  # (input variable, axis or None) -> the condition's event generator
        self._active = {key: False for key in conditions}
        self._subscriptions = subscriptions  # asyncua's: events go to the Server object's subscribers too
        self._brackets: dict[int, object] = {}  # RefreshStartEventType, RefreshEndEventType -> the event sent

    @classmethod
    async def build(cls, space: AddressSpace) -> Alarms:
        """The conditions' event generators, emitting on Objects/Reclaimer; the Reclaimer a
        notifier of the Server object, its axes its event sources."""
        server = space.server
        reclaimer = space.objects[None]
        await server.nodes.server.add_reference(reclaimer.nodeid, ua.ObjectIds.HasNotifier)
        conditions = {}
        for index, axis in enumerate(AXES):
            await reclaimer.add_reference(space.objects[axis].nodeid, ua.ObjectIds.HasEventSource)
            conditions["AtLimit", axis] = await _generator(
                space, ua.ObjectIds.OffNormalAlarmType, first=index == 0, source=space.objects[axis],
                input_node=space.nodes["AtLimit", axis], condition=f"Reclaimer.{axis_name(axis)}.LimitAlarm",
                name="LimitAlarm", severity=LIMIT_SEVERITY, condition_class=(PROCESS_CLASS, "Process"))
        conditions["WatchdogTripped", None] = await _generator(
            space, ua.ObjectIds.TripAlarmType, first=True, source=reclaimer,
            input_node=space.nodes["WatchdogTripped", None], condition="Reclaimer.WatchdogAlarm",
            name="WatchdogAlarm", severity=WATCHDOG_SEVERITY, condition_class=(SYSTEM_CLASS, "System"))
        alarms = cls(space, conditions, server.iserver.isession.subscription_service)
        for event_type in (ua.ObjectIds.RefreshStartEventType, ua.ObjectIds.RefreshEndEventType):
            bracket = EventGenerator(server.iserver.isession)
            await bracket.init(event_type, add_generates_event=False)  # from the Server object
            alarms._brackets[event_type] = bracket.event
        condition_type, integer_id = ua.NodeId(ua.ObjectIds.ConditionType), ua.VariantType.UInt32
        for method, inputs in ((ua.ObjectIds.ConditionType_ConditionRefresh, [integer_id]),
                               (ua.ObjectIds.ConditionType_ConditionRefresh2, [integer_id, integer_id])):
            server.iserver.isession.add_method_callback(ua.NodeId(method),
                                                        checked(alarms.refresh, inputs, condition_type))
        return alarms

    async def refresh(self, parent, subscription: ua.Variant, monitored_item: ua.Variant | None = None):
        """ConditionRefresh(SubscriptionId), ConditionRefresh2(SubscriptionId, MonitoredItemId).

        The subscription's event items are read from asyncua's monitored item service, as its own
        (unbound) ConditionRefresh reads them: asyncua offers no public way to reach one item."""
        found = self._subscriptions.subscriptions.get(subscription.Value)
        if found is None:
            return status(ua.StatusCodes.BadSubscriptionIdInvalid)
        items = found.monitored_item_srv
        notifiers = {mid: node for node, mids in items._monitored_events.items() for mid in mids}
        if monitored_item is not None:
            if monitored_item.Value not in notifiers:
                return status(ua.StatusCodes.BadMonitoredItemIdInvalid)
            notifiers = {monitored_item.Value: notifiers[monitored_item.Value]}
        if not notifiers:
            return status(ua.StatusCodes.BadNothingToDo)
        sources = {self.space.objects[None].nodeid, ua.NodeId(ua.ObjectIds.Server)}
        await self._bracket(items, notifiers, ua.ObjectIds.RefreshStartEventType)
        for key, active in self._active.items():
            if active:
                event = self._conditions[key].event
                for mid, node in notifiers.items():
                    if node in sources:
                        await items._trigger_event(event, mid)  # only where the item's filter takes it
        await self._bracket(items, notifiers, ua.ObjectIds.RefreshEndEventType)
        return []

    async def _bracket(self, items, notifiers: Mapping[int, ua.NodeId], event_type: int) -> None:
        """One RefreshStart or RefreshEnd event, a copy to each monitored item, past its filter."""
        event, now = self._brackets[event_type], datetime.now(timezone.utc)
        event.EventId, event.Time, event.ReceiveTime = uuid.uuid4().bytes, now, now
        event.Message = ua.LocalizedText("ConditionRefresh " + ("started" if event_type ==
                                                                ua.ObjectIds.RefreshStartEventType else "ended"))
        for mid in notifiers:
            item = items._monitored_items[mid]
            fields = ua.EventFieldList(ClientHandle=item.client_handle,
                                       EventFields=event.to_event_fields(item.filter.SelectClauses))
            await items.isub.enqueue_event(mid, fields, item.queue_size)

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
        if self._active[key] == active:
            return
        self._active[key] = active
        generator = self._conditions[key]
        event, now = generator.event, datetime.now(timezone.utc)
        # The Time of the event is the transition's (asyncua types a TransitionTime field wrongly).
        for field, value in {"Retain": active, "ActiveState": ua.LocalizedText("Active" if active else "Inactive"),
                             "ActiveState/Id": active}.items():
            setattr(event, field, value)
        await generator.trigger(time_attr=now, message=_message(key, active, sim_time))
        reclaimer = event.emitting_node  # asyncua delivers an event to the subscribers of one node
        event.emitting_node = ua.NodeId(ua.ObjectIds.Server)
        try:
            await self._subscriptions.trigger_event(event)
        finally:
            event.emitting_node = reclaimer


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


async def _generator(space: AddressSpace, event_type: int, *, first: bool, source, input_node, condition: str,
                     name: str, severity: int, condition_class: tuple[int, str]) -> EventGenerator:
    """An event generator of `event_type` on Objects/Reclaimer for one condition; `first`: the
    first of its type, which adds the Reclaimer's GeneratesEvent reference to the type."""
    generator = EventGenerator(space.server.iserver.isession)
    await generator.init(event_type, emitting_node=space.objects[None], add_generates_event=first)
    class_id, class_name = condition_class
    fields = {
        "NodeId": ua.NodeId(condition, space.namespace), "ConditionName": name,
        "SourceNode": source.nodeid, "SourceName": (await source.read_browse_name()).Name,
        "InputNode": input_node.nodeid, "Severity": severity, "LastSeverity": severity,
        "ConditionClassId": ua.NodeId(class_id), "ConditionClassName": ua.LocalizedText(class_name),
        "Quality": ua.StatusCode(ua.StatusCodes.Good), "BranchId": ua.NodeId(),
        "EnabledState": ua.LocalizedText("Enabled"), "EnabledState/Id": True,
        "AckedState": ua.LocalizedText("Acknowledged"), "AckedState/Id": True,
        "Retain": False, "ActiveState": ua.LocalizedText("Inactive"), "ActiveState/Id": False,
    }
    for field, value in fields.items():
        setattr(generator.event, field, value)
    return generator
