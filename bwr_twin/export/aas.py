"""A scene's machine as an Asset Administration Shell (IEC 63278) in an AASX package, written
with the Eclipse BaSyx Python SDK, and the check of such a package.

    reclaimer.aasx
        one shell for the machine, its asset the Nameplate's product URI, with the submodels
            Nameplate                 Digital Nameplate, IDTA 02006-2-0 (bwr_twin.export.aas_machine)
            TechnicalData             Technical Data, IDTA 02003-1-2
            SimulationModels          Provision of Simulation Models, IDTA 02005-1-0: the FMU and the MJCF
            ControlSoftware           the PLC package and its interface table (bwr_twin.export.aas_models)
            OperationalDataEndpoints  the OPC UA endpoint and its NodeSet2
        /aasx/files/...               the FMU (<model name>.fmu), MJCF, PLC files, NodeSet2, calibration report

The FMU, the PLC package and the NodeSet2 are made by their own exporters (export_scene_fmu,
export_plc, the server's address space through bwr_twin.serve.nodeset) and described from the
files they wrote. The archive's comment is the twin's mark (bwr_twin.ownership): an existing
.aasx is replaced only with --overwrite, if the twin wrote it and it is unchanged since.
"""

from __future__ import annotations

import asyncio
import json
import logging
import shutil
import tempfile
import zipfile
from pathlib import Path
from urllib.parse import quote
from xml.etree import ElementTree

from bwr_twin.config.scene import Scene
from bwr_twin.errors import BwrError, SceneError
from bwr_twin.ownership import AAS_WRITER, check_output, write_atomically

FILES = "/aasx/files"  # where the package keeps the files its File elements point at
CALIBRATION_FILE = "calibration.json"
CALIBRATED_MJCF = "calibrated.xml"  # beside it, as `python -m bwr_twin.calibrate fit` writes them
CONTENT_TYPES = {".json": "application/json", ".md": "text/markdown", ".html": "text/html", ".pdf": "application/pdf",
                 ".png": "image/png", ".csv": "text/csv", ".txt": "text/plain", ".xml": "application/xml",
                 ".st": "text/plain", ".svg": "image/svg+xml"}


def export_aas(scene: Scene, out: Path, *, overwrite: bool = False, calibration: Path | None = None) -> Path:
    """Write the AASX package `out` for `scene` (replaced, with `overwrite`, only if the twin wrote
    it); `calibration`, a folder holding calibration.json and its report, rides along. Returns `out`."""
    report = _calibration_files(calibration) if calibration is not None else []
    check_output(out, "aas", overwrite=overwrite, inputs=(*scene.input_files, *report))  # a refusal costs nothing
    from basyx.aas import model
    from basyx.aas.adapter import aasx

    from bwr_twin.export.aas_elements import Measures, id_short
    from bwr_twin.export.aas_fmu import read_fmu
    from bwr_twin.export.aas_machine import nameplate, nameplate_values, technical_data
    from bwr_twin.export.aas_models import control_software, endpoints, simulation_models
    from bwr_twin.export.plc import PROJECT, export_plc
    from bwr_twin.export.scene_fmu import export_scene_fmu
    from bwr_twin.model.machine import Machine
    from bwr_twin.serve.address_space import NAMESPACE_URI
    from bwr_twin.serve.cli import DEFAULT_ENDPOINT

    machine = Machine(scene.machine.mjcf)
    if calibration is not None:
        _check_calibrated_machine(calibration, machine.name)
    values = nameplate_values(machine)
    uri = values["URIOfTheProduct"]  # the asset: the product instance the OPC UA server names
    shell_id = f"urn:bwr_twin:aas:{quote(machine.name, safe='')}:{quote(values['SerialNumber'], safe='')}"
    with tempfile.TemporaryDirectory(prefix="bwr_twin_aas_") as folder:
        work = Path(folder)
        plc = export_plc(scene, work / "plc")  # first: a controller it cannot export is refused before the FMU's build
        fmu, _ = export_scene_fmu(scene, work / f"{machine.name}.fmu")  # the FMU `export fmu` writes
        nodeset = work / "nodeset.xml"
        asyncio.run(_write_nodeset(scene, nodeset))
        files = aasx.DictSupplementaryFileContainer()

        def pack(source: Path, name: str | None = None) -> str:
            with source.open("rb") as f:
                return files.add_file(f"{FILES}/{name or source.name}", f,
                                      CONTENT_TYPES.get(source.suffix.lower(), "application/octet-stream"))

        fmu_path, mjcf_path = pack(fmu), pack(scene.machine.mjcf)
        documentation = [(pack(source, f"calibration/{source.name}"),
                          CONTENT_TYPES.get(source.suffix.lower(), "application/octet-stream")) for source in report]
        sources = [pack(path, f"plc/{path.name}") for path in plc if path.suffix == ".st"]
        plcopen = next(path for path in plc if path.name == PROJECT)
        measures = Measures(f"{shell_id}:concept")
        submodels = [
            nameplate(machine, f"{shell_id}:submodel:Nameplate"),
            technical_data(machine, f"{shell_id}:submodel:TechnicalData", measures),
            simulation_models(f"{shell_id}:submodel:SimulationModels", read_fmu(fmu), fmu_path, mjcf_path,
                              documentation),
            control_software(f"{shell_id}:submodel:ControlSoftware", scene.controller.type, sources,
                             pack(plcopen, f"plc/{plcopen.name}"), plcopen),
            endpoints(f"{shell_id}:submodel:OperationalDataEndpoints", DEFAULT_ENDPOINT, NAMESPACE_URI,
                      pack(nodeset)),
        ]
        shell = model.AssetAdministrationShell(
            model.AssetInformation(model.AssetKind.INSTANCE, global_asset_id=uri), shell_id,
            id_short=id_short(machine.name), submodel={model.ModelReference.from_referable(s) for s in submodels})
        store = model.DictIdentifiableStore([shell, *submodels, *measures.concepts.values()])
        built = work / "built.aasx"
        with aasx.AASXWriter(built) as writer:
            writer.write_aas(shell_id, store, files)  # with the concept descriptions its semantic ids name
        with zipfile.ZipFile(built, "a") as archive:
            archive.comment = AAS_WRITER.encode()
        check_output(out, "aas", overwrite=overwrite, inputs=(*scene.input_files, *report))  # again, before replacing
        write_atomically(out, lambda partial: shutil.copyfile(built, partial), record=True)
    return out


async def _write_nodeset(scene: Scene, path: Path) -> None:
    """The NodeSet2 of the address space `python -m bwr_twin.serve SCENE` serves, built as the
    server builds it, written by bwr_twin.serve.nodeset."""
    from asyncua import Server

    from bwr_twin.serve import DEFAULT_WATCHDOG_PERIODS, LOCKSTEP
    from bwr_twin.serve.address_space import NAMESPACE_URI
    from bwr_twin.serve.clock import Clock
    from bwr_twin.serve.nodeset import write_nodeset
    from bwr_twin.serve.server import build_address_space
    from bwr_twin.sim.twin import Twin

    logging.getLogger("asyncua").setLevel(logging.CRITICAL)
    server = Server()
    await server.init()
    clock = Clock(Twin(scene), mode=LOCKSTEP, speed=1.0, watchdog_periods=DEFAULT_WATCHDOG_PERIODS, log=lambda _: None)
    await build_address_space(server, clock)
    await write_nodeset(server, NAMESPACE_URI, path, overwrite=False)


def _calibration_files(folder: Path) -> list[Path]:
    """The files of a calibration report's folder (its top level), which must hold a readable
    calibration.json; SceneError naming the folder or file otherwise."""
    if not folder.is_dir():
        raise SceneError(f"--calibration {folder}: not a folder (give the folder that holds {CALIBRATION_FILE})")
    calibration = folder / CALIBRATION_FILE
    try:
        json.loads(calibration.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise SceneError(f"--calibration {folder}: holds no {CALIBRATION_FILE}") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise SceneError(f"--calibration {calibration}: not readable JSON ({exc})") from None
    return sorted(path for path in folder.iterdir() if path.is_file() and not path.name.startswith("."))


def _check_calibrated_machine(folder: Path, name: str) -> None:
    """SceneError if the calibration in `folder` is of another machine than `name` (its
    calibrated MJCF's model name), before any work."""
    calibrated = folder / CALIBRATED_MJCF
    if not calibrated.is_file():
        return  # a report without the MJCF: nothing tells its machine
    try:
        fitted = ElementTree.parse(calibrated).getroot().get("model", "")
    except (OSError, ElementTree.ParseError) as exc:
        raise SceneError(f"--calibration {calibrated}: not readable MJCF ({exc})") from None
    if fitted != name:
        raise SceneError(f"--calibration {folder}: a calibration of machine {fitted!r}; the scene's machine is "
                         f"{name!r}: give its own calibration, or the scene the calibrated MJCF")


def check_aas(path: Path) -> list[str]:
    """Every way the package `path` falls short, one line each (none: it passes): the AAS
    meta-model and package as basyx-compliance-tool reads them, then each submodel against its
    template (bwr_twin.export.aas_templates), and every File element against the package's files.
    BwrError, one line, if `path` is no AASX package at all."""
    if not path.is_file():
        raise BwrError(f"--check {path}: no such file")
    if not zipfile.is_zipfile(path):
        raise BwrError(f"--check {path}: not an AASX package (not a zip archive)")
    try:
        from aas_compliance_tool import compliance_check_aasx
        from aas_compliance_tool.state_manager import ComplianceToolStateManager, Status
    except ImportError:
        raise BwrError("--check needs basyx-compliance-tool (pip install 'bwr_twin[dev]')") from None
    from bwr_twin.export.aas_templates import TEMPLATES, check_submodel, semantic_key

    manager = ComplianceToolStateManager()
    try:
        store, files, _ = compliance_check_aasx.check_deserialization(str(path), manager)
    except Exception as exc:  # noqa: BLE001 - a corrupt package breaks the reader in many ways: each is one line
        raise BwrError(f"--check {path}: not a readable AASX package ({type(exc).__name__}: {exc})") from None
    problems = [f"{path}: {manager.steps[i].name}: {' '.join(record.getMessage().split())}"
                for i in range(len(manager.steps)) for record in manager.get_error_logs_from_step(i)]
    if manager.status not in (Status.SUCCESS, Status.SUCCESS_WITH_WARNINGS) and not problems:
        problems.append(f"{path}: basyx-compliance-tool: {manager.status.name}")
    if problems:
        return problems
    from basyx.aas import model

    shells = [item for item in store if isinstance(item, model.AssetAdministrationShell)]
    if len(shells) != 1:
        return [f"{path}: holds {len(shells)} asset administration shells, not one"]
    submodels = [item for item in store if isinstance(item, model.Submodel)]
    for template in TEMPLATES:
        found = [s for s in submodels if semantic_key(s) == template.semantic_id]
        if not found:
            problems.append(f"{path}: no {template.name} submodel (semanticId {template.semantic_id})")
        for submodel in found:
            problems += [f"{path}: {line}" for line in check_submodel(submodel, template)]
    for submodel in submodels:
        for element in _walk(submodel.submodel_element):
            if isinstance(element, model.File) and element.value not in files:
                problems.append(f"{path}: submodel {submodel.id_short}: {element.id_short} points at "
                                f"{element.value}, which the package does not hold")
    return problems


def _walk(elements):
    from basyx.aas import model

    for element in elements:
        yield element
        if isinstance(element, (model.SubmodelElementCollection, model.SubmodelElementList)):
            yield from _walk(element.value)
