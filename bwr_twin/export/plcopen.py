"""The exported blocks as a PLCopen XML project (TC6 v2.01), which CODESYS, TwinCAT and other
IEC 61131-3 tools import: each block a `pou` of type functionBlock with its interface and its ST
body, each global constant list a `globalVars` of one configuration. Written from the same data as
the .st files (bwr_twin.export.structured_text); tests/test_plc_export.py validates it against the
TC6 schema.
"""

from __future__ import annotations

import datetime
from collections.abc import Sequence
from importlib.metadata import version
from xml.etree import ElementTree as ET

from bwr_twin.export.structured_text import Block, GlobalConstants, Var

NAMESPACE = "http://www.plcopen.org/xml/tc6_0201"
XHTML = "http://www.w3.org/1999/xhtml"
CONFIGURATION = "BwrTwin"
_INTERFACE = {"VAR_INPUT": ("inputVars", False), "VAR_OUTPUT": ("outputVars", False), "VAR": ("localVars", False),
              "VAR CONSTANT": ("localVars", True)}


def project_xml(block: Block, constants: Sequence[GlobalConstants], source: str) -> str:
    """The project: `block` as a POU and `constants` as the configuration's global variables."""
    ET.register_namespace("", NAMESPACE)
    ET.register_namespace("xhtml", XHTML)
    project = _element("project")
    now = datetime.datetime.now(datetime.timezone.utc).replace(microsecond=0, tzinfo=None).isoformat()
    _element("fileHeader", project, companyName="bwr_twin", productName="bwr_twin",
             productVersion=version("bwr_twin"), creationDateTime=now,
             contentDescription=f"The controller of {source}, exported by python -m bwr_twin.export plc")
    header = _element("contentHeader", project, name=block.name)
    coordinates = _element("coordinateInfo", header)
    for language in ("fbd", "ld", "sfc"):  # required by the schema, unused by ST
        _element("scaling", _element(language, coordinates), x="1", y="1")
    types = _element("types", project)
    _element("dataTypes", types)
    pou = _element("pou", _element("pous", types), name=block.name, pouType="functionBlock")
    interface = _element("interface", pou)
    for section, variables in block.variables.items():
        tag, constant = _INTERFACE[section]
        _variables(_element(tag, interface, **({"constant": "true"} if constant else {})), variables)
    _text(_element("ST", _element("body", pou)), "\n".join(block.body))
    _text(_element("documentation", pou), block.comment)
    configuration = _element("configuration", _element("configurations", _element("instances", project)),
                             name=CONFIGURATION)
    for table in constants:
        _variables(_element("globalVars", configuration, name=table.name, constant="true"), table.variables)
    ET.indent(project)
    return '<?xml version="1.0" encoding="utf-8"?>\n' + ET.tostring(project, encoding="unicode") + "\n"


def _element(tag: str, parent: ET.Element | None = None, **attributes: str) -> ET.Element:
    name = f"{{{NAMESPACE}}}{tag}"
    return ET.Element(name, attributes) if parent is None else ET.SubElement(parent, name, attributes)


def _text(parent: ET.Element, text: str) -> None:
    """Formatted text, as the schema has it: an XHTML paragraph."""
    ET.SubElement(parent, f"{{{XHTML}}}p").text = text


def _variables(parent: ET.Element, variables: Sequence[Var]) -> None:
    for var in variables:
        element = _element("variable", parent, name=var.name)
        _type(_element("type", element), var)
        if var.value is not None:
            value = _element("initialValue", element)
            if var.dims:
                array = _element("arrayValue", value)
                for literal in var.value:
                    _element("simpleValue", _element("value", array), value=literal)
            else:
                _element("simpleValue", value, value=var.value[0])
        if var.comment:
            _text(_element("documentation", element), var.comment)


def _type(parent: ET.Element, var: Var) -> None:
    if not var.dims:
        _element(var.type, parent)
        return
    array = _element("array", parent)
    for length in var.dims:
        _element("dimension", array, lower="0", upper=str(length - 1))
    _element(var.type, _element("baseType", array))
