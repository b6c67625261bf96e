"""OPC UA Part 8's analog items: a Double with a physical meaning, typed AnalogUnitType (with a
unit) or AnalogItemType (without), its EngineeringUnits from UNECE Recommendation 20 and its
EURange, the range its value is expected to stay within."""

from __future__ import annotations

from asyncua import Node, ua

from bwr_twin.opcua import nodes

UNECE_URI = "http://www.opcfoundation.org/UA/units/un/cefact"  # OPC UA Part 8: UNECE Recommendation 20 codes

# Unit symbol -> (UNECE common code, description).
UNITS = {
    "m": ("MTR", "metre"),
    "rad": ("C81", "radian"),
    "m/s": ("MTS", "metre per second"),
    "rad/s": ("2A", "radian per second"),
    "m/s²": ("MSK", "metre per second squared"),
    "rad/s²": ("2B", "radian per second squared"),
    "N": ("NEW", "newton"),
    "N·m": ("NU", "newton metre"),
    "s": ("SEC", "second"),
    "t/h": ("E18", "tonne per hour"),
    "A": ("AMP", "ampere"),
    "%": ("P1", "percent"),
}
# OPC UA Part 8's variable types of a Double with a physical meaning: with its unit (i=17497,
# "AnalogUnitItemType" in some texts) or without (AnalogItemType); both carry EURange.
ANALOG_UNIT_TYPE, ANALOG_ITEM_TYPE = ua.ObjectIds.AnalogUnitType, ua.ObjectIds.AnalogItemType


def eu_information(symbol: str) -> ua.EUInformation:
    """EUInformation of a unit symbol of UNITS, UnitId from its UNECE code (OPC UA Part 8, 5.6.3)."""
    code, description = UNITS[symbol]
    unit_id = 0
    for character in code:
        unit_id = unit_id << 8 | ord(character)
    return ua.EUInformation(NamespaceUri=UNECE_URI, UnitId=unit_id, DisplayName=ua.LocalizedText(symbol),
                            Description=ua.LocalizedText(description))


async def add_analog_item(parent: Node, node_id: ua.NodeId, name: ua.QualifiedName, unit: str | None,
                          eu_range: tuple[float, float], *, value: object = 0.0, length: int | None = None) -> Node:
    """A read-only Double analog item under `parent`, with its EngineeringUnits (if `unit`, a
    symbol of UNITS) and its EURange (low, high); the properties' node ids extend `node_id`'s
    string and their browse names are namespace 0's. `length`: a one-dimensional array of that
    many values (the initial `value`, a list), else a scalar."""
    node = await nodes.add_variable(parent, node_id, name, ua.Variant(value, ua.VariantType.Double),
                                    ANALOG_UNIT_TYPE if unit else ANALOG_ITEM_TYPE, length=length)
    ns, path = node_id.NamespaceIndex, node_id.Identifier
    if unit:
        await node.add_property(ua.NodeId(f"{path}.EngineeringUnits", ns), ua.QualifiedName("EngineeringUnits", 0),
                                eu_information(unit), ua.VariantType.ExtensionObject,
                                ua.NodeId(ua.ObjectIds.EUInformation))
    low, high = eu_range
    await nodes.add_property(node, ua.NodeId(f"{path}.EURange", ns), ua.QualifiedName("EURange", 0),
                             ua.Variant(ua.Range(Low=low, High=high)), data_type=ua.ObjectIds.Range)
    return node
