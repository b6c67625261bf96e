"""OPC UA Part 9 conditions emitted on one object of a server, and ConditionRefresh.

Each change of a condition is one event of its type, with the condition's fields as Part 9 gives
them (ConditionId, ActiveState, Retain, Severity, SourceNode, InputNode, Message). The
conditions are not nodes of the address space (Part 9 allows that): they need no
acknowledgement, and arrive acknowledged. An event goes to the subscribers of the emitting
object and to those of the Server object (asyncua delivers an event to the subscribers of one
node only).

ConditionRefresh and ConditionRefresh2 (Part 9, 5.5.7 and 5.5.8; called on ConditionType) are
served here, not by asyncua: a RefreshStartEvent to every event monitored item of the
subscription (or the one named), whatever its filter, then each active condition again, as its
last event (its Retain true), to the monitored items of the emitting or the Server object whose
filter it meets, then a RefreshEndEvent as the start went.
"""

from __future__ import annotations

import uuid
from collections.abc import Hashable, Mapping
from datetime import datetime, timezone

from asyncua import Node, Server, ua
from asyncua.server.event_generator import EventGenerator

from bwr_twin.opcua.methods import checked, status


class Conditions:
    """The conditions of a server emitted on `emitting`, by key, and the events of their changes."""

    def __init__(self, server: Server, emitting: Node):
        self.server, self.emitting = server, emitting
        self._conditions: dict[Hashable, EventGenerator] = {}
        self._active: dict[Hashable, bool] = {}
        self._subscriptions = server.iserver.isession.subscription_service  # for the Server object's subscribers
        self._brackets: dict[int, object] = {}  # RefreshStartEventType, RefreshEndEventType -> the event sent

    @classmethod
    async def build(cls, server: Server, emitting: Node) -> Conditions:
        """No conditions yet; `emitting` a notifier of the Server object, ConditionRefresh served."""
        await server.nodes.server.add_reference(emitting.nodeid, ua.ObjectIds.HasNotifier)
        conditions = cls(server, emitting)
        for event_type in (ua.ObjectIds.RefreshStartEventType, ua.ObjectIds.RefreshEndEventType):
            bracket = EventGenerator(server.iserver.isession)
            await bracket.init(event_type, add_generates_event=False)  # from the Server object
            conditions._brackets[event_type] = bracket.event
        condition_type, integer_id = ua.NodeId(ua.ObjectIds.ConditionType), ua.VariantType.UInt32
        for method, inputs in ((ua.ObjectIds.ConditionType_ConditionRefresh, [integer_id]),
                               (ua.ObjectIds.ConditionType_ConditionRefresh2, [integer_id, integer_id])):
            server.iserver.isession.add_method_callback(ua.NodeId(method),
                                                        checked(conditions.refresh, inputs, condition_type))
        return conditions

    async def add(self, key: Hashable, event_type: int | ua.NodeId, *, first: bool, source: Node, condition: ua.NodeId,
                  name: str, severity: int, condition_class: tuple[int, str], input_node: Node | None = None,
                  fields: Mapping[str, object] = {}) -> None:
        """A condition of `event_type`, inactive; `first`: the first of its type, which adds the
        emitting object's GeneratesEvent reference to the type. `fields`: more of the event's
        fields, a subtype's own."""
        generator = EventGenerator(self.server.iserver.isession)
        await generator.init(event_type, emitting_node=self.emitting, add_generates_event=first)
        class_id, class_name = condition_class
        values = {
            "NodeId": condition, "ConditionName": name,
            "SourceNode": source.nodeid, "SourceName": (await source.read_browse_name()).Name,
            "InputNode": input_node.nodeid if input_node is not None else ua.NodeId(), "Severity": severity,
            "LastSeverity": severity, "ConditionClassId": ua.NodeId(class_id),
            "ConditionClassName": ua.LocalizedText(class_name),
            "Quality": ua.StatusCode(ua.StatusCodes.Good), "BranchId": ua.NodeId(),
            "EnabledState": ua.LocalizedText("Enabled"), "EnabledState/Id": True,
            "AckedState": ua.LocalizedText("Acknowledged"), "AckedState/Id": True,
            "Retain": False, "ActiveState": ua.LocalizedText("Inactive"), "ActiveState/Id": False, **fields,
        }
        for field, value in values.items():
            setattr(generator.event, field, value)
        self._conditions[key], self._active[key] = generator, False

    def active(self, key: Hashable) -> bool:
        return self._active[key]

    async def change(self, key: Hashable, active: bool, message: str, fields: Mapping[str, object] = {}) -> None:
        """Raise or clear a condition with `message` (and new values of `fields`); nothing if it
        already is so."""
        if self._active[key] == active:
            return
        self._active[key] = active
        generator = self._conditions[key]
        event, now = generator.event, datetime.now(timezone.utc)
        # The Time of the event is the transition's (asyncua types a TransitionTime field wrongly).
        for field, value in {"Retain": active, "ActiveState": ua.LocalizedText("Active" if active else "Inactive"),
                             "ActiveState/Id": active, **fields}.items():
            setattr(event, field, value)
        await generator.trigger(time_attr=now, message=message)
        emitting = event.emitting_node  # asyncua delivers an event to the subscribers of one node
        event.emitting_node = ua.NodeId(ua.ObjectIds.Server)
        try:
            await self._subscriptions.trigger_event(event)
        finally:
            event.emitting_node = emitting

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
        sources = {self.emitting.nodeid, ua.NodeId(ua.ObjectIds.Server)}
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
