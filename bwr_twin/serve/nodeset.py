"""`--nodeset FILE.xml`: the twin's address space as a UA NodeSet2 file, for an engineering tool
or another server to load (asyncua's XmlExporter: every node of the twin's namespace, the
values included, so that EURange and the identification travel with it).

The file's second line marks it as the twin's, `<!-- written by bwr_twin.serve -->`, right after
the XML declaration (bwr_twin.ownership): only such a file is replaced, and only with
--overwrite.
"""

from __future__ import annotations

import xml.etree.ElementTree as Et
from pathlib import Path

from asyncua import Server
from asyncua.common.ua_utils import get_nodes_of_namespace
from asyncua.common.xmlexporter import XmlExporter

from bwr_twin.ownership import NODESET_WRITER, check_output, write_atomically, xml_mark
from bwr_twin.serve import ServeError


async def write_nodeset(server: Server, namespace_uri: str, path: Path, *, overwrite: bool) -> int:
    """Write every node of `namespace_uri` on `server` to `path` (checked again just before);
    the number of nodes written."""
    nodes = await get_nodes_of_namespace(server, [namespace_uri])
    exporter = XmlExporter(server, export_values=True)
    await exporter.build_etree(nodes)
    Et.indent(exporter.etree.getroot())
    body = Et.tostring(exporter.etree.getroot(), encoding="unicode")
    text = f"<?xml version='1.0' encoding='utf-8'?>\n{xml_mark(NODESET_WRITER)}\n{body}\n"
    check_output(path, "nodeset", overwrite=overwrite, option="--nodeset")  # again, just before replacing
    try:
        write_atomically(path, lambda temporary: temporary.write_text(text, encoding="utf-8"), record=True,
                         option="--nodeset")
    except OSError as exc:
        raise ServeError(f"--nodeset {path}: cannot write it ({exc.strerror or exc}); nothing written") from None
    return len(nodes)
