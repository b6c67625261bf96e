"""Nodes that asyncua's shortcuts do not make: an object or variable of a given type definition,
under a given reference, with the node id the twin chooses and none of the type's children
instantiated (the twin adds the ones it serves, under node ids that follow their browse paths).
"""

from __future__ import annotations

from asyncua import Node, ua

_READ = ua.AccessLevel.CurrentRead.mask


async def add_object(parent: Node, node_id: ua.NodeId, name: ua.QualifiedName, type_definition: int | ua.NodeId, *,
                     reference: int = ua.ObjectIds.HasComponent, description: str | None = None) -> Node:
    """An object of `type_definition` under `parent`, referenced by `reference`."""
    attributes = ua.ObjectAttributes(DisplayName=ua.LocalizedText(name.Name),
                                     Description=ua.LocalizedText(description or name.Name), EventNotifier=0)
    return await _add(parent, node_id, name, ua.NodeClass.Object, type_definition, reference, attributes)


async def add_variable(parent: Node, node_id: ua.NodeId, name: ua.QualifiedName, value: ua.Variant,
                       type_definition: int | ua.NodeId, *, reference: int = ua.ObjectIds.HasComponent,
                       data_type: int | None = None, description: str | None = None,
                       length: int | None = None) -> Node:
    """A read-only variable of `type_definition` holding `value`: a scalar, or with `length` a
    one-dimensional array of that many values; its DataType the variant's built-in type unless
    `data_type` (a structure's, say) is given."""
    shape = ({"ValueRank": ua.ValueRank.Scalar} if length is None else
             {"ValueRank": ua.ValueRank.OneDimension, "ArrayDimensions": [length]})
    attributes = ua.VariableAttributes(
        DisplayName=ua.LocalizedText(name.Name), Description=ua.LocalizedText(description or name.Name),
        Value=value, DataType=ua.NodeId(data_type or value.VariantType.value), **shape,
        AccessLevel=_READ, UserAccessLevel=_READ)
    return await _add(parent, node_id, name, ua.NodeClass.Variable, type_definition, reference, attributes)


async def add_property(parent: Node, node_id: ua.NodeId, name: ua.QualifiedName, value: ua.Variant, *,
                       data_type: int | None = None) -> Node:
    """A property (PropertyType, by HasProperty) of `parent`."""
    return await add_variable(parent, node_id, name, value, ua.ObjectIds.PropertyType,
                              reference=ua.ObjectIds.HasProperty, data_type=data_type)


async def _add(parent: Node, node_id: ua.NodeId, name: ua.QualifiedName, node_class: ua.NodeClass,
               type_definition: int | ua.NodeId, reference: int, attributes) -> Node:
    item = ua.AddNodesItem(ParentNodeId=parent.nodeid, ReferenceTypeId=ua.NodeId(reference),
                           RequestedNewNodeId=node_id, BrowseName=name, NodeClass=node_class,
                           NodeAttributes=attributes, TypeDefinition=_node_id(type_definition))
    (result,) = await parent.session.add_nodes([item])
    result.StatusCode.check()
    return Node(parent.session, result.AddedNodeId)


def _node_id(node: int | ua.NodeId) -> ua.NodeId:
    """A node id of namespace 0's ObjectIds number, or the node id itself."""
    return node if isinstance(node, ua.NodeId) else ua.NodeId(node)
