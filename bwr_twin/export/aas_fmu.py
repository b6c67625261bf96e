"""What an FMU says of itself: its FMI version, model identifier, variables and default
experiment from its modelDescription.xml, and its platforms from its binaries/ folders. Read
from the archive alone, so that any FMU the twin exports is described the same way, whatever
built it (FMI 2.0 or 3.0)."""

from __future__ import annotations

import xml.etree.ElementTree as Et
import zipfile
from dataclasses import dataclass
from pathlib import Path

from bwr_twin.errors import BwrError

# FMI 3.0's variable elements, by the type name a reader expects (FMI 2.0 nests one in a ScalarVariable).
_FMI3_TYPES = {"Float64": "Real", "Float32": "Real", "Int32": "Integer", "Int64": "Integer", "Boolean": "Boolean",
               "String": "String", "Enumeration": "Enumeration"}


@dataclass(frozen=True)
class Variable:
    name: str
    causality: str  # input, output, parameter
    type: str  # Real, Integer, Boolean, String, Enumeration
    unit: str  # "" without one
    description: str
    start: str  # "" without one


@dataclass(frozen=True)
class FmuDescription:
    fmi_version: str
    model_name: str
    model_identifier: str
    generation_tool: str
    description: str
    step_size: float | None  # s, the default experiment's
    stop_time: float | None  # s
    variables: tuple[Variable, ...]
    platforms: tuple[str, ...]  # the folders under binaries/, e.g. linux64, x86_64-linux

    def of(self, causality: str) -> tuple[Variable, ...]:
        return tuple(v for v in self.variables if v.causality == causality)


def read_fmu(path: Path) -> FmuDescription:
    """The FMU `path` as it describes itself; BwrError naming the file if it is not an FMU."""
    try:
        with zipfile.ZipFile(path) as archive:
            root = Et.fromstring(archive.read("modelDescription.xml"))
            names = archive.namelist()
    except (OSError, zipfile.BadZipFile, KeyError, Et.ParseError) as exc:
        raise BwrError(f"{path}: not an FMU with a readable modelDescription.xml ({exc})") from None
    version = root.get("fmiVersion", "")
    kind = root.find("CoSimulation")
    experiment = root.find("DefaultExperiment")
    platforms = sorted({name.split("/")[1] for name in names
                        if name.startswith("binaries/") and name.count("/") >= 2 and not name.endswith("/")})
    return FmuDescription(
        fmi_version=version, model_name=root.get("modelName", ""),
        model_identifier=kind.get("modelIdentifier", "") if kind is not None else "",
        generation_tool=root.get("generationTool", ""), description=root.get("description", ""),
        step_size=_number(experiment, "stepSize"), stop_time=_number(experiment, "stopTime"),
        variables=tuple(_variables(root, version)), platforms=tuple(platforms))


def _number(element, key: str) -> float | None:
    value = element.get(key) if element is not None else None
    return float(value) if value is not None else None


def _variables(root, version: str):
    variables = root.find("ModelVariables")
    if variables is None:
        return
    for element in variables:
        if version.startswith("2"):
            typed = next(iter(element), None)
            kind = typed.tag if typed is not None else ""
        else:
            typed, kind = element, _FMI3_TYPES.get(element.tag, element.tag)
        causality = element.get("causality", "local")
        if causality in ("input", "output", "parameter"):
            yield Variable(element.get("name", ""), causality, kind, typed.get("unit", "") if typed is not None else "",
                           element.get("description", ""), typed.get("start", "") if typed is not None else "")
