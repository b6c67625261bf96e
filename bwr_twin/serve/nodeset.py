"""`--nodeset FILE.xml`: the twin's address space as a UA NodeSet2 file, for an engineering tool
or another server to load (asyncua's XmlExporter: every node of the twin's namespace, the
values included, so that EURange and the identification travel with it).

Two things asyncua's exporter leaves out, which other stacks need, are put right here: an
ExtensionObject's TypeId names the DataType's "Default XML" encoding node (a Range i=885, an
EUInformation i=888, an Argument i=297), not the DataType itself, which a reader such as
node-opcua cannot decode (it loads the value as null); and the file names its model and the
model it requires, OPC UA's own, in `<Models>` (OPC UA Part 6, F.2). The file validates
against the OPC Foundation's UANodeSet.xsd.

The file's second line marks it as the twin's, `<!-- written by bwr_twin.serve -->`, right after
the XML declaration (bwr_twin.ownership): only such a file is replaced, and only with
--overwrite.
"""

from __future__ import annotations

import xml.etree.ElementTree as Et
from importlib.metadata import version
from pathlib import Path

from asyncua import Server, ua
from asyncua.common.ua_utils import get_nodes_of_namespace
from asyncua.common.xmlexporter import XmlExporter

from bwr_twin.ownership import NODESET_WRITER, check_output, write_atomically, xml_mark
from bwr_twin.serve import ServeError

UA_MODEL = "http://opcfoundation.org/UA/"
XML_ENCODING = "Default XML"  # the browse name of a DataType's XML encoding node (Part 6, 5.3.1.1)


async def write_nodeset(server: Server, namespace_uri: str, path: Path, *, overwrite: bool) -> int:
    """Write every node of `namespace_uri` on `server` to `path` (checked again just before);
    the number of nodes written."""
    nodes = await get_nodes_of_namespace(server, [namespace_uri])
    exporter = XmlExporter(server, export_values=True)
    await exporter.build_etree(nodes)
    root = exporter.etree.getroot()
    await _name_xml_encodings(server, root)
    await _add_models(server, root, namespace_uri)
    Et.indent(root)
    body = Et.tostring(root, encoding="unicode")
    text = f"<?xml version='1.0' encoding='utf-8'?>\n{xml_mark(NODESET_WRITER)}\n{body}\n"
    check_output(path, "nodeset", overwrite=overwrite, option="--nodeset")  # again, just before replacing
    try:
        write_atomically(path, lambda temporary: temporary.write_text(text, encoding="utf-8"), record=True,
                         option="--nodeset")
    except OSError as exc:
        raise ServeError(f"--nodeset {path}: cannot write it ({exc.strerror or exc}); nothing written") from None
    return len(nodes)


async def _name_xml_encodings(server: Server, root: Et.Element) -> None:
    """Replace each ExtensionObject's TypeId, a DataType as asyncua writes it, by that DataType's
    Default XML encoding node, found on `server` by its HasEncoding reference."""
    encodings: dict[str, str] = {}
    for extension_object in root.iter("uax:ExtensionObject"):  # asyncua writes its tags as prefixed names
        identifier = _child(_child(extension_object, "uax:TypeId"), "uax:Identifier")
        data_type = identifier.text.strip()
        if data_type not in encodings:
            references = await server.get_node(ua.NodeId.from_string(data_type)).get_references(
                ua.ObjectIds.HasEncoding, ua.BrowseDirection.Forward)
            xml = [ref.NodeId for ref in references if ref.BrowseName.Name == XML_ENCODING]
            if not xml:
                raise ServeError(f"--nodeset: the data type {data_type} has no {XML_ENCODING!r} encoding to name "
                                 "in the file; nothing written")
            encodings[data_type] = xml[0].to_string()
        identifier.text = encodings[data_type]


def _child(element: Et.Element, tag: str) -> Et.Element:
    """The child of `element` with the literal `tag` (ElementPath would read its prefix as one)."""
    return next(child for child in element if child.tag == tag)


async def _add_models(server: Server, root: Et.Element, namespace_uri: str) -> None:
    """`<Models>`, where the schema puts it (after NamespaceUris): the twin's model, version the
    package's, requiring OPC UA's own model as `server` has it."""
    metadata = server.get_node(ua.NodeId(ua.ObjectIds.OPCUANamespaceMetadata))
    ua_version = await (await metadata.get_child("NamespaceVersion")).read_value()
    ua_date = await (await metadata.get_child("NamespacePublicationDate")).read_value()
    models = Et.Element("Models")
    model = Et.SubElement(models, "Model", ModelUri=namespace_uri, Version=version("bwr_twin"))
    Et.SubElement(model, "RequiredModel", ModelUri=UA_MODEL, Version=ua_version,
                  PublicationDate=ua_date.strftime("%Y-%m-%dT%H:%M:%SZ"))
    after = [index for index, child in enumerate(root) if child.tag in ("NamespaceUris", "ServerUris")]
    root.insert(after[-1] + 1 if after else 0, models)
