"""The submodels of what the twin hands over besides the machine: Provision of Simulation Models
(IDTA 02005-1-0) with the FMU and the MJCF, Control software with the PLC package and its
interface table, and the Operational data endpoints with the OPC UA endpoint and its NodeSet2.
Each takes the files as they sit in the package (`/aasx/files/...`), and describes them from
the files themselves: the FMU from its modelDescription.xml and binaries/, the PLC block's
interface from its PLCopen XML."""

from __future__ import annotations

import xml.etree.ElementTree as Et
from importlib.metadata import version
from pathlib import Path

from basyx.aas import model

from bwr_twin.export.aas_elements import collection, file, prop, reference, text
from bwr_twin.export.aas_fmu import FmuDescription
from bwr_twin.export.aas_templates import CONTROL_SOFTWARE, ENDPOINTS, SIMULATION_MODELS

FMU_TYPE = "application/x-fmu"  # no registered media type; the FMI project's usual one
_PLCOPEN = "{http://www.plcopen.org/xml/tc6_0201}"
_DOC = "{http://www.w3.org/1999/xhtml}p"
# FMI causality -> the template's VariableCausality (a parameter is set before the run: an input)
_CAUSALITY = {"input": "Input", "output": "Output", "parameter": "Input"}
_PLATFORMS = {"linux64": "Linux 64-bit", "x86_64-linux": "Linux 64-bit", "win64": "Windows 64-bit",
              "x86_64-windows": "Windows 64-bit", "darwin64": "macOS 64-bit", "x86_64-darwin": "macOS 64-bit",
              "aarch64-darwin": "macOS ARM 64-bit"}
LICENCE = "free"  # the template's LicenseModel: the twin's models cost nothing to use


def simulation_models(submodel_id: str, fmu: FmuDescription, fmu_path: str, mjcf_path: str,
                      documentation: list[tuple[str, str]]) -> model.Submodel:
    """One SimulationModel for the FMU and one for the MJCF; `documentation` (package path,
    content type) is the calibration report's files, given to both as RefSimDocumentation."""
    models = [_fmu_model(fmu, fmu_path, documentation), _mjcf_model(mjcf_path, documentation)]
    return model.Submodel(submodel_id, id_short="SimulationModels",
                          semantic_id=reference(SIMULATION_MODELS.semantic_id), submodel_element=models,
                          kind=model.ModellingKind.INSTANCE)


def _fmu_model(fmu: FmuDescription, path: str, documentation) -> model.SubmodelElementCollection:
    t = SIMULATION_MODELS
    step = fmu.step_size
    tool = collection(t, "SimulationTool", prop(t, "SimToolName", f"any FMI {fmu.fmi_version} co-simulation importer"),
                      collection(t, "SolverAndTolerances",
                                 prop(t, "StepSizeControlNeeded", False, value_type=model.datatypes.Boolean),
                                 prop(t, "FixedStepSize", step, value_type=model.datatypes.Double)
                                 if step is not None else None,
                                 prop(t, "StiffSolverNeeded", False, value_type=model.datatypes.Boolean),
                                 prop(t, "SolverIncluded", True, value_type=model.datatypes.Boolean)))
    environment = collection(t, "Environment",
                             prop(t, "OperatingSystem", ", ".join(_PLATFORMS.get(p, p) for p in fmu.platforms)),
                             *(prop(t, "ToolEnvironment", f"binaries/{p}", as_name=f"ToolEnvironment{i:02d}")
                               for i, p in enumerate(fmu.platforms, 1)),
                             tool)
    ports = collection(t, "Ports", *(collection(t, "PortsConnector", prop(t, "PortConnectorName", causality),
                                                *(_variable(v, i) for i, v in enumerate(fmu.of(causality), 1)),
                                                as_name=f"{causality.capitalize()}s")
                                     for causality in ("input", "output", "parameter") if fmu.of(causality)))
    summary = (f"{fmu.description or fmu.model_name}: FMI {fmu.fmi_version} co-simulation FMU "
               f"{fmu.model_identifier}, made by {fmu.generation_tool or 'an unnamed tool'}")
    return collection(
        t, "SimulationModel",
        text(t, "Summary", summary),
        collection(t, "SimPurpose", prop(t, "PosSimPurpose", "Control design", as_name="PosSimPurpose01"),
                   prop(t, "PosSimPurpose", "Virtual commissioning", as_name="PosSimPurpose02")),
        prop(t, "TypeOfModel", "Nonlinear model"), prop(t, "ScopeOfModel", "Dynamics"),
        prop(t, "LicenseModel", LICENCE), prop(t, "EngineeringDomain", "Control Engineering"),
        environment, *_documentation(documentation),
        collection(t, "ModelFile", prop(t, "ModelFileType", f"FMI {fmu.fmi_version}, Co-Simulation, "
                                        f"{', '.join(fmu.platforms)}"),
                   collection(t, "ModelFileVersion", prop(t, "ModelVersionId", version("bwr_twin")),
                              file(t, "DigitalFile", path, FMU_TYPE))),
        prop(t, "ParamMethod", "pre-parameterized"), prop(t, "InitStateMethod", "integrated in model"),
        prop(t, "DefaultSimTime", fmu.stop_time, value_type=model.datatypes.Double) if fmu.stop_time else None,
        ports, as_name="FMU")


def _variable(variable, index: int) -> model.SubmodelElementCollection:
    t = SIMULATION_MODELS
    return collection(t, "Variable", prop(t, "VariableName", variable.name), prop(t, "VariableType", variable.type),
                      text(t, "VariableDescription", variable.description) if variable.description else None,
                      prop(t, "UnitList", variable.unit or "-"),
                      prop(t, "VariableCausality", _CAUSALITY[variable.causality]),
                      as_name=f"Variable{index:02d}")


def _mjcf_model(path: str, documentation) -> model.SubmodelElementCollection:
    t = SIMULATION_MODELS
    tool = collection(t, "SimulationTool", prop(t, "SimToolName", f"MuJoCo {version('mujoco')}"),
                      collection(t, "SolverAndTolerances",
                                 prop(t, "StepSizeControlNeeded", False, value_type=model.datatypes.Boolean),
                                 prop(t, "StiffSolverNeeded", False, value_type=model.datatypes.Boolean),
                                 prop(t, "SolverIncluded", False, value_type=model.datatypes.Boolean)))
    return collection(
        t, "SimulationModel",
        text(t, "Summary", "The machine as a MuJoCo MJCF model: bodies, joints (travel, slew, luff), drives, "
                           "envelope, bucket wheel and instruments; its timestep is the file's <option timestep>"),
        collection(t, "SimPurpose", prop(t, "PosSimPurpose", "System dynamics", as_name="PosSimPurpose01"),
                   prop(t, "PosSimPurpose", "Control design", as_name="PosSimPurpose02")),
        prop(t, "TypeOfModel", "Nonlinear model"), prop(t, "ScopeOfModel", "Kinematics", as_name="ScopeOfModel01"),
        prop(t, "ScopeOfModel", "Dynamics", as_name="ScopeOfModel02"),
        prop(t, "ScopeOfModel", "Geometry", as_name="ScopeOfModel03"), prop(t, "LicenseModel", LICENCE),
        collection(t, "Environment", prop(t, "OperatingSystem", "any MuJoCo runs on"), tool),
        *_documentation(documentation),
        collection(t, "ModelFile", prop(t, "ModelFileType", "MuJoCo MJCF (XML)"),
                   collection(t, "ModelFileVersion", prop(t, "ModelVersionId", version("bwr_twin")),
                              file(t, "DigitalFile", path, "application/xml"))),
        prop(t, "ParamMethod", "pre-parameterized"), prop(t, "InitStateMethod", "integrated in model"),
        as_name="MJCF")


def _documentation(documentation) -> list[model.File]:
    return [file(SIMULATION_MODELS, "RefSimDocumentation", path, kind, as_name=f"RefSimDocumentation{i:02d}")
            for i, (path, kind) in enumerate(documentation, 1)]


def control_software(submodel_id: str, controller: str, structured_text: list[str], plcopen_path: str,
                     plcopen: Path) -> model.Submodel:
    """The PLC package: its Structured Text files, its PLCopen XML project, and the interface
    table of its function block, read from that project."""
    t = CONTROL_SOFTWARE
    sources = [file(t, "StructuredText", path, "text/plain", as_name=f"StructuredText{i:02d}")
               for i, path in enumerate(structured_text, 1)]
    signals = [collection(t, "Signal", prop(t, "SignalName", name), prop(t, "Direction", direction),
                          prop(t, "DataType", kind), text(t, "Description", description) if description else None,
                          as_name=f"Signal{i:02d}")
               for i, (name, direction, kind, description) in enumerate(plc_interface(plcopen), 1)]
    elements = [prop(t, "ControllerType", controller), *sources, file(t, "PLCopenXML", plcopen_path, "application/xml"),
                collection(t, "Interface", *signals)]
    return model.Submodel(submodel_id, id_short="ControlSoftware", semantic_id=reference(t.semantic_id),
                          submodel_element=elements, kind=model.ModellingKind.INSTANCE)


def plc_interface(project: Path) -> list[tuple[str, str, str, str]]:
    """(name, Input/Output, IEC type, description) of the first function block's inputs and
    outputs in a PLCopen XML project."""
    root = Et.parse(project).getroot()
    pou = root.find(f".//{_PLCOPEN}pou")
    rows = []
    for section, direction in (("inputVars", "Input"), ("outputVars", "Output")):
        for variable in pou.findall(f"{_PLCOPEN}interface/{_PLCOPEN}{section}/{_PLCOPEN}variable"):
            rows.append((variable.get("name"), direction, _iec_type(variable.find(f"{_PLCOPEN}type")),
                         "".join(variable.find(f".//{_DOC}").itertext()) if variable.find(f".//{_DOC}") is not None
                         else ""))
    return rows


def _iec_type(element) -> str:
    array = element.find(f"{_PLCOPEN}array")
    if array is None:
        return next(iter(element)).tag.removeprefix(_PLCOPEN)
    dimension = array.find(f"{_PLCOPEN}dimension")
    base = next(iter(array.find(f"{_PLCOPEN}baseType"))).tag.removeprefix(_PLCOPEN)
    return f"ARRAY[{dimension.get('lower')}..{dimension.get('upper')}] OF {base}"


def endpoints(submodel_id: str, endpoint: str, namespace: str, nodeset_path: str) -> model.Submodel:
    t = ENDPOINTS
    elements = [prop(t, "OpcUaEndpoint", endpoint), prop(t, "NamespaceUri", namespace),
                file(t, "NodeSet", nodeset_path, "application/xml"),
                text(t, "SecurityNote", "python -m bwr_twin.serve SCENE serves it; on any address but loopback "
                                        "it needs --users and --certificate (docs/opcua.md)")]
    return model.Submodel(submodel_id, id_short="OperationalDataEndpoints", semantic_id=reference(t.semantic_id),
                          submodel_element=elements, kind=model.ModellingKind.INSTANCE)

