"""The reclaimer as OPC 40001-1 (OPC UA for Machinery) describes a machine: found in the
`Objects/Machines` folder, named by its `Identification` add-in, its state and operation mode
told by the `MachineryItemState` and `MachineryOperationMode` state machines in its
`MachineryBuildingBlocks` folder.

asyncua ships no Machinery (nor DI) NodeSet2, and no installed package does: the few types the
twin serves are modelled here, in the twin's own namespace, with the specification's browse
names, supertypes, state names and state numbers (docs/opcua.md says what that means for a
client). Node ids follow the browse paths, as everywhere in the twin's namespace.
"""

from __future__ import annotations

from collections.abc import Mapping
from urllib.parse import quote

from asyncua import Node, ua

from bwr_twin.model.machine import Machine
from bwr_twin.opcua import nodes
from bwr_twin.serve import LOCKSTEP
from bwr_twin.serve.address_space import AddressSpace

LT, STRING = ua.VariantType.LocalizedText, ua.VariantType.String
# MachineryItemIdentificationType's properties (OPC 40001-1, 8.3; names from OPC 10000-100 DI)
# that the twin serves: (browse name, type, mandatory), and the MJCF text each comes from.
IDENTIFICATION = (("Manufacturer", LT, True), ("Model", LT, False), ("SerialNumber", STRING, True),
                  ("ProductInstanceUri", STRING, True))
MJCF_TEXT = {"Manufacturer": "manufacturer", "Model": "model", "SerialNumber": "serial_number"}
# State names and StateNumbers of OPC 40001-1, 12.2 and 13.2.
ITEM_STATES = {"NotAvailable": 0, "OutOfService": 1, "NotExecuting": 2, "Executing": 3}
OPERATION_MODES = {"None": 0, "Maintenance": 1, "Setup": 2, "Processing": 3}
STATE_MACHINES = {  # instance browse name -> (its type, the type's states, description)
    "MachineryItemState": ("MachineryItemState_StateMachineType", ITEM_STATES,
                           "State machine representing the state of a machinery item"),
    "MachineryOperationMode": ("MachineryOperationModeStateMachineType", OPERATION_MODES,
                               "State machine representing the operation mode of a MachineryItem"),
}
OPERATION_MODE = "Processing"  # the twin has no setup or maintenance mode: it serves a production run


def item_state(*, mode: str, running: bool, started: bool, done: bool, diverged: bool, tripped: bool) -> str:
    """The MachineryItemState of the twin (docs/opcua.md): OutOfService once the watchdog tripped
    or the run diverged (until Reset); Executing while the real-time clock runs, or in lockstep
    mode from the first Step to the path's end (time stands still between Steps, the job does
    not); NotExecuting otherwise."""
    if diverged or tripped:
        return "OutOfService"
    if running or (mode == LOCKSTEP and started and not done):
        return "Executing"
    return "NotExecuting"


class Machinery:
    """The Machinery building blocks of Objects/Reclaimer, and the publishing of its state."""

    def __init__(self, space: AddressSpace, current: dict[str, Node], states: dict[str, dict[str, ua.NodeId]]):
        self.space = space
        self._current = current  # state machine -> its CurrentState variable
        self._states = states  # state machine -> state name -> the state's node in its type
        self._published: dict[str, str] = {}

    @classmethod
    async def build(cls, space: AddressSpace, machine: Machine) -> Machinery:
        """Add the types, Objects/Machines and the reclaimer's building blocks, identified from
        `machine`'s MJCF; the operation mode Processing, the state NotExecuting."""
        server, ns = space.server, space.namespace
        types, states = await _add_types(server, ns)
        reclaimer = space.objects[None]
        machines = await nodes.add_object(server.nodes.objects, ua.NodeId("Machines", ns),
                                          ua.QualifiedName("Machines", ns), ua.ObjectIds.FolderType,
                                          reference=ua.ObjectIds.Organizes,
                                          description="the machines of this server (OPC 40001-1, 9)")
        await machines.add_reference(reclaimer.nodeid, ua.ObjectIds.Organizes)
        identification = await nodes.add_object(reclaimer, ua.NodeId("Reclaimer.Identification", ns),
                                                ua.QualifiedName("Identification", ns),
                                                types["MachineIdentificationType"], reference=ua.ObjectIds.HasAddIn,
                                                description="the machine's nameplate, from its MJCF")
        values = identification_values(machine)
        for name, variant, _ in IDENTIFICATION:
            value = ua.LocalizedText(values[name]) if variant == LT else values[name]
            await nodes.add_property(identification, ua.NodeId(f"Reclaimer.Identification.{name}", ns),
                                     ua.QualifiedName(name, ns), ua.Variant(value, variant))
        blocks = await nodes.add_object(reclaimer, ua.NodeId("Reclaimer.MachineryBuildingBlocks", ns),
                                        ua.QualifiedName("MachineryBuildingBlocks", ns), ua.ObjectIds.FolderType,
                                        description="the Machinery building blocks the reclaimer implements")
        await blocks.add_reference(identification.nodeid, ua.ObjectIds.HasAddIn)  # also directly on the machine
        current = {}
        for instance, (type_name, _, description) in STATE_MACHINES.items():
            path = f"Reclaimer.MachineryBuildingBlocks.{instance}"
            state_machine = await nodes.add_object(blocks, ua.NodeId(path, ns), ua.QualifiedName(instance, ns),
                                                   types[type_name], reference=ua.ObjectIds.HasAddIn,
                                                   description=description)
            current[instance] = variable = await nodes.add_variable(
                state_machine, ua.NodeId(f"{path}.CurrentState", ns), ua.QualifiedName("CurrentState", 0),
                ua.Variant(ua.LocalizedText(""), LT), ua.ObjectIds.FiniteStateVariableType)
            await nodes.add_property(variable, ua.NodeId(f"{path}.CurrentState.Id", ns), ua.QualifiedName("Id", 0),
                                     ua.Variant(ua.NodeId(), ua.VariantType.NodeId))
            await nodes.add_property(variable, ua.NodeId(f"{path}.CurrentState.Number", ns),
                                     ua.QualifiedName("Number", 0), ua.Variant(0, ua.VariantType.UInt32))
        machinery = cls(space, current, states)
        await machinery._write("MachineryOperationMode", OPERATION_MODE)
        await machinery._write("MachineryItemState", "NotExecuting")
        return machinery

    async def publish(self, readings: Mapping[str, object]) -> None:
        """Write the MachineryItemState of `readings` if it changed."""
        state = readings.get("MachineryItemState")
        if state is not None and state != self._published["MachineryItemState"]:
            await self._write("MachineryItemState", state)

    async def _write(self, instance: str, state: str) -> None:
        _, numbers, _ = STATE_MACHINES[instance]
        variable, write = self._current[instance].nodeid, self.space.server.write_attribute_value
        await write(variable, ua.DataValue(ua.Variant(ua.LocalizedText(state), LT)))
        await write(ua.NodeId(f"{variable.Identifier}.Id", variable.NamespaceIndex),
                    ua.DataValue(ua.Variant(self._states[instance][state], ua.VariantType.NodeId)))
        await write(ua.NodeId(f"{variable.Identifier}.Number", variable.NamespaceIndex),
                    ua.DataValue(ua.Variant(numbers[state], ua.VariantType.UInt32)))
        self._published[instance] = state


def identification_values(machine: Machine) -> dict[str, str]:
    """Browse name -> value of the Identification properties: the MJCF's `<custom><text>`
    entries; without them the `<mujoco model>` name as Model and empty Manufacturer and
    SerialNumber. The ProductInstanceUri joins the model name and the serial number."""
    texts = machine.identification
    values = {name: texts.get(key, machine.name if name == "Model" else "") for name, key in MJCF_TEXT.items()}
    model, serial = quote(machine.name, safe=""), quote(values["SerialNumber"], safe="")
    values["ProductInstanceUri"] = f"urn:bwr_twin:{model}:{serial}"
    return values


async def _add_types(server, ns: int) -> tuple[dict[str, ua.NodeId], dict[str, dict[str, ua.NodeId]]]:
    """The ObjectTypes the building blocks are instances of: browse name -> node id; and each
    state machine's states: instance -> state name -> the StateType object in its type."""
    folder_type = server.get_node(ua.ObjectIds.FolderType)
    item = await folder_type.add_object_type(ua.NodeId("MachineryItemIdentificationType", ns),
                                             ua.QualifiedName("MachineryItemIdentificationType", ns))
    await item.write_attribute(ua.AttributeIds.IsAbstract, ua.DataValue(ua.Variant(True)))
    for name, variant, mandatory in IDENTIFICATION:
        empty = ua.LocalizedText("") if variant == LT else ""
        declaration = await nodes.add_property(item, ua.NodeId(f"MachineryItemIdentificationType.{name}", ns),
                                               ua.QualifiedName(name, ns), ua.Variant(empty, variant))
        await declaration.set_modelling_rule(mandatory)
    machine = await item.add_object_type(ua.NodeId("MachineIdentificationType", ns),
                                         ua.QualifiedName("MachineIdentificationType", ns))
    types = {"MachineryItemIdentificationType": item.nodeid, "MachineIdentificationType": machine.nodeid}
    states = {}
    finite_state_machine = server.get_node(ua.ObjectIds.FiniteStateMachineType)
    for instance, (type_name, numbers, description) in STATE_MACHINES.items():
        node = await finite_state_machine.add_object_type(ua.NodeId(type_name, ns), ua.QualifiedName(type_name, ns))
        await node.write_attribute(ua.AttributeIds.Description, ua.DataValue(ua.Variant(ua.LocalizedText(description))))
        types[type_name], states[instance] = node.nodeid, {}
        for state, number in numbers.items():
            state_node = await nodes.add_object(node, ua.NodeId(f"{type_name}.{state}", ns),
                                                ua.QualifiedName(state, ns), ua.ObjectIds.StateType)
            await nodes.add_property(state_node, ua.NodeId(f"{type_name}.{state}.StateNumber", ns),
                                     ua.QualifiedName("StateNumber", 0), ua.Variant(number, ua.VariantType.UInt32))
            states[instance][state] = state_node.nodeid
    return types, states
