"""The IDTA submodel templates the twin's Asset Administration Shell follows, and the check of a
submodel against one: its semantic id, and every element the template requires (cardinality One
or OneToMany), found by semantic id, with a value.

    Digital Nameplate                IDTA 02006-2-0
    Technical Data                   IDTA 02003-1-2
    Provision of Simulation Models   IDTA 02005-1-0

The Control software and Operational data endpoints submodels have no IDTA template; the twin's
own (`CONTROL_SOFTWARE`, `ENDPOINTS`) name what they must hold, checked the same way. Only the
elements the twin writes or a template requires are listed (docs/aas.md).
"""

from __future__ import annotations

from dataclasses import dataclass

from basyx.aas import model


@dataclass(frozen=True)
class Entry:
    """One element of a template: its idShort, whether the template requires it, what it holds."""

    id_short: str
    required: bool
    children: tuple[Entry, ...] = ()


def need(id_short: str, *children: Entry) -> Entry:
    return Entry(id_short, True, children)


def may(id_short: str, *children: Entry) -> Entry:
    return Entry(id_short, False, children)


@dataclass(frozen=True)
class Template:
    """A submodel template: its name and number, its semantic id, each element's semantic id by
    idShort, and the tree of its elements."""

    name: str
    number: str
    semantic_id: str
    ids: dict[str, str]
    elements: tuple[Entry, ...]

    def id(self, id_short: str) -> str:
        return self.ids[id_short]


_CONTACT = "https://admin-shell.io/zvei/nameplate/1/0/ContactInformations/ContactInformation"
NAMEPLATE = Template(
    "Digital Nameplate", "IDTA 02006-2-0", "https://admin-shell.io/zvei/nameplate/2/0/Nameplate",
    {"URIOfTheProduct": "0173-1#02-AAY811#001", "ManufacturerName": "0173-1#02-AAO677#002",
     "ManufacturerProductDesignation": "0173-1#02-AAW338#001", "ContactInformation": _CONTACT,
     "NationalCode": "0173-1#02-AAO134#002", "CityTown": "0173-1#02-AAO132#002", "Street": "0173-1#02-AAO128#002",
     "Zipcode": "0173-1#02-AAO129#002", "ManufacturerProductFamily": "0173-1#02-AAU731#001",
     "ManufacturerProductType": "0173-1#02-AAO057#002", "SerialNumber": "0173-1#02-AAM556#002",
     "YearOfConstruction": "0173-1#02-AAP906#001"},
    (need("URIOfTheProduct"), need("ManufacturerName"), need("ManufacturerProductDesignation"),
     need("ContactInformation", need("NationalCode"), need("CityTown"), need("Street"), need("Zipcode")),
     may("ManufacturerProductFamily"), may("ManufacturerProductType"), may("SerialNumber"),
     need("YearOfConstruction")))

_TD = "https://admin-shell.io/ZVEI/TechnicalData/{}/1/1"
TECHNICAL_DATA = Template(
    "Technical Data", "IDTA 02003-1-2", "https://admin-shell.io/ZVEI/TechnicalData/Submodel/1/2",
    {"GeneralInformation": _TD.format("GeneralInformation"), "ManufacturerName": "0173-1#02-AAO677#002",
     "ManufacturerProductDesignation": "0173-1#02-AAW338#001", "ManufacturerArticleNumber": "0173-1#02-AAO676#003",
     "ManufacturerOrderCode": "0173-1#02-AAO227#002", "TechnicalProperties": _TD.format("TechnicalProperties"),
     "MainSection": _TD.format("MainSection"), "FurtherInformation": _TD.format("FurtherInformation"),
     "TextStatement": _TD.format("TextStatement"), "ValidDate": _TD.format("ValidDate"),
     # a property no dictionary defines yet (the template's own id for one)
     "SemanticIdNotAvailable": "https://admin-shell.io/SemanticIdNotAvailable/1/1"},
    (need("GeneralInformation", need("ManufacturerName"), need("ManufacturerProductDesignation"),
          need("ManufacturerArticleNumber"), need("ManufacturerOrderCode")),
     need("TechnicalProperties"), may("FurtherInformation", may("TextStatement"), need("ValidDate"))))

_SIM = "https://admin-shell.io/idta/SimulationModels/{}/1/0"
_SIM_ELEMENTS = ("SimulationModel", "Summary", "SimPurpose", "PosSimPurpose", "TypeOfModel", "ScopeOfModel",
                 "LicenseModel", "EngineeringDomain", "Environment", "OperatingSystem", "ToolEnvironment",
                 "SimulationTool", "SimToolName", "SolverAndTolerances", "StepSizeControlNeeded", "FixedStepSize",
                 "StiffSolverNeeded", "SolverIncluded", "RefSimDocumentation", "ModelFile", "ModelFileType",
                 "ModelFileVersion", "ModelVersionId", "DigitalFile", "ParamMethod", "InitStateMethod",
                 "DefaultSimTime", "SimModManufacturerInformation", "Ports", "PortsConnector", "PortConnectorName",
                 "Variable", "VariableName", "Range", "VariableType", "VariableDescription", "UnitList",
                 "VariableCausality")
SIMULATION_MODELS = Template(
    "Provision of Simulation Models", "IDTA 02005-1-0", _SIM.format("SimulationModels"),
    {name: _SIM.format(name) for name in _SIM_ELEMENTS} | {"Company": "0173-1#02-AAW001#001",
                                                           "Language": "0173-1#02-AAO895#003"},
    (may("SimulationModel",
         need("SimPurpose", need("PosSimPurpose")), need("ScopeOfModel"),
         need("ModelFile", need("ModelFileVersion", need("ModelVersionId"), need("DigitalFile"))),
         need("ParamMethod"), need("InitStateMethod"),
         may("Environment", need("OperatingSystem"),
             need("SimulationTool", need("SimToolName"),
                  need("SolverAndTolerances", need("StepSizeControlNeeded"), need("StiffSolverNeeded"),
                       need("SolverIncluded")))),
         may("SimModManufacturerInformation", need("Company"), need("Language")),
         may("Ports", may("PortsConnector", need("PortConnectorName"),
                          may("Variable", need("VariableName"), need("VariableType"), need("UnitList"),
                              need("VariableCausality"))))),))

_TWIN = "urn:bwr_twin:aas:{}:1:0"  # the twin's own semantic ids, where no template or dictionary has one
CONTROL_SOFTWARE = Template(
    "Control software", "bwr_twin", _TWIN.format("ControlSoftware"),
    {name: _TWIN.format(name) for name in ("ControllerType", "StructuredText", "PLCopenXML", "Interface", "Signal",
                                          "SignalName", "Direction", "DataType", "Unit", "Description")},
    (need("ControllerType"), need("StructuredText"), need("PLCopenXML"),
     need("Interface", need("Signal", need("SignalName"), need("Direction"), need("DataType")))))
ENDPOINTS = Template(
    "Operational data endpoints", "bwr_twin", _TWIN.format("OperationalDataEndpoints"),
    {name: _TWIN.format(name) for name in ("OpcUaEndpoint", "NamespaceUri", "NodeSet", "SecurityNote")},
    (need("OpcUaEndpoint"), need("NamespaceUri"), need("NodeSet")))

TEMPLATES = (NAMEPLATE, TECHNICAL_DATA, SIMULATION_MODELS, CONTROL_SOFTWARE, ENDPOINTS)


def semantic_key(element: model.HasSemantics) -> str | None:
    """The value of an element's semantic id (its last key), or None without one."""
    reference = element.semantic_id
    return reference.key[-1].value if reference is not None and reference.key else None


def check_submodel(submodel: model.Submodel, template: Template) -> list[str]:
    """One line per way `submodel` falls short of `template`: a wrong semantic id, a required
    element missing, or one present without a value."""
    where = f"submodel {submodel.id_short}"
    if semantic_key(submodel) != template.semantic_id:
        return [f"{where}: semanticId {semantic_key(submodel)!r}, but {template.name} ({template.number}) "
                f"is {template.semantic_id!r}"]
    return _check(list(submodel.submodel_element), template.elements, template, where)


def _check(elements: list, entries: tuple[Entry, ...], template: Template, where: str) -> list[str]:
    problems = []
    for entry in entries:
        wanted = template.id(entry.id_short)
        found = [e for e in elements if semantic_key(e) == wanted]
        if not found and entry.required:
            problems.append(f"{where}: no {entry.id_short} (semanticId {wanted}), which {template.name} "
                            f"({template.number}) requires")
        for element in found:
            inside = f"{where}/{element.id_short}"
            if entry.children:
                problems += _check(list(_children(element)), entry.children, template, inside)
            elif entry.required and not _has_value(element):
                problems.append(f"{inside}: has no value, which {template.name} ({template.number}) requires")
    return problems


def _children(element) -> list:
    if isinstance(element, (model.SubmodelElementCollection, model.SubmodelElementList)):
        return list(element.value)
    return []


def _has_value(element) -> bool:
    if isinstance(element, model.MultiLanguageProperty):
        return element.value is not None and any(text.strip() for text in element.value.values())
    if isinstance(element, (model.SubmodelElementCollection, model.SubmodelElementList)):
        return len(element.value) > 0
    value = getattr(element, "value", None)
    return value is not None and str(value).strip() != ""
