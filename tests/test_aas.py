"""The machine as an Asset Administration Shell: `python -m bwr_twin.export aas` writes an AASX
package that basyx-compliance-tool reads without an error, whose submodels hold what their IDTA
templates require, whose Nameplate says what the OPC UA Machinery identification says, and whose
FMU, read back out, FMPy validates and co-simulates in a process of its own; `--check` fails, with
a line naming what is wrong, on a package that lacks a required element or a file, and on a
corrupt one. The package is built once for the module.
"""

import math
import subprocess
import sys
import xml.etree.ElementTree as Et
import zipfile
from pathlib import Path

import pytest
from basyx.aas import model
from basyx.aas.adapter import aasx
from conftest import write_short_scene

from bwr_twin.config.scene import load_scene
from bwr_twin.export.aas_machine import UNKNOWN, nameplate, nameplate_values
from bwr_twin.export.aas_templates import (
    NAMEPLATE,
    SIMULATION_MODELS,
    TECHNICAL_DATA,
    TEMPLATES,
    check_submodel,
)
from bwr_twin.model.machine import Machine

ROOT = Path(__file__).resolve().parents[1]


def python(*arguments, cwd=ROOT) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, *map(str, arguments)], check=False, cwd=cwd, capture_output=True,
                          text=True, timeout=600, env=_environment())


def _environment() -> dict:
    import os

    return os.environ | {"PYTHONPATH": str(ROOT)}


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    return write_short_scene(tmp_path_factory.mktemp("aas_scene"))


@pytest.fixture(scope="module")
def calibration(scene, tmp_path_factory):
    """A real calibration of the scene's machine: the travel's damping fitted to the scene's own run."""
    work = tmp_path_factory.mktemp("calibration")
    assert python("-m", "bwr_twin.run", scene, "--out", work / "log", "--no-plots").returncode == 0
    fitted = python("-m", "bwr_twin.calibrate", "fit", work / "log", "--model", load_scene(scene).machine.mjcf,
                    "--params", "travel_damping", "--out", work / "calibration")
    assert fitted.returncode == 0, fitted.stderr
    return work / "calibration"


@pytest.fixture(scope="module")
def package(scene, calibration, tmp_path_factory):
    out = tmp_path_factory.mktemp("aas") / "reclaimer.aasx"
    result = python("-m", "bwr_twin.export", "aas", scene, "--out", out, "--calibration", calibration)
    assert result.returncode == 0, result.stderr
    return out


def read(path: Path) -> tuple[model.DictIdentifiableStore, aasx.DictSupplementaryFileContainer]:
    store, files = model.DictIdentifiableStore(), aasx.DictSupplementaryFileContainer()
    with aasx.AASXReader(path, failsafe=False) as reader:
        reader.read_into(store, files)
    return store, files


def submodel(store, template) -> model.Submodel:
    (found,) = [s for s in store if isinstance(s, model.Submodel) and s.semantic_id.key[-1].value ==
                template.semantic_id]
    return found


def write(path: Path, store, files) -> None:
    (shell,) = [s for s in store if isinstance(s, model.AssetAdministrationShell)]
    with aasx.AASXWriter(path) as writer:
        writer.write_aas(shell.id, store, files)


def test_the_compliance_tool_finds_no_error_and_the_check_passes(package):
    tool = Path(sys.executable).parent / "aas-compliance-check"
    result = subprocess.run([tool, "d", "--xml", "--aasx", package, "-v"], capture_output=True, text=True, timeout=120,
                            check=False)
    assert "SUCCESS:      Read file" in result.stdout and "FAILED" not in result.stdout, result.stdout
    check = python("-m", "bwr_twin.export", "aas", "--check", package)
    assert check.returncode == 0, check.stderr
    assert "passes" in check.stdout and check.stderr == ""


def test_each_submodel_holds_its_templates_semantic_id_and_required_elements(package):
    store, files = read(package)
    assert NAMEPLATE.semantic_id == "https://admin-shell.io/zvei/nameplate/2/0/Nameplate"
    assert TECHNICAL_DATA.semantic_id == "https://admin-shell.io/ZVEI/TechnicalData/Submodel/1/2"
    assert SIMULATION_MODELS.semantic_id == "https://admin-shell.io/idta/SimulationModels/SimulationModels/1/0"
    for template in TEMPLATES:
        assert check_submodel(submodel(store, template), template) == [], template.name
    models = submodel(store, SIMULATION_MODELS)
    assert {m.id_short for m in models.submodel_element} == {"FMU", "MJCF"}
    fmu = models.get_referable("FMU")
    digital = fmu.get_referable("ModelFile").get_referable("ModelFileVersion").get_referable("DigitalFile")
    assert digital.value in files and digital.value.endswith(".fmu")
    # Inputs, outputs and parameters from the FMU's own model description, with their units.
    ports = fmu.get_referable("Ports")
    inputs = {v.get_referable("VariableName").value: v.get_referable("UnitList").value
              for v in ports.get_referable("Inputs").value if v.id_short.startswith("Variable")}
    assert inputs == {"Travel.DriveSetpoint": "N", "Slew.DriveSetpoint": "N.m", "Luff.DriveSetpoint": "N.m",
                      "WindSpeed": "m/s"}  # the native FMU's: the paper scene is a path
    parameters = [v.get_referable("VariableName").value for v in ports.get_referable("Parameters").value
                  if v.id_short.startswith("Variable")]
    assert "Seed" in parameters
    solver = fmu.get_referable("Environment").get_referable("SimulationTool").get_referable("SolverAndTolerances")
    assert solver.get_referable("FixedStepSize").value == 0.01
    assert "linux64" in fmu.get_referable("Environment").get_referable("OperatingSystem").value or \
        "Linux" in fmu.get_referable("Environment").get_referable("OperatingSystem").value
    assert "native, MuJoCo in C" in fmu.get_referable("Summary").value["en"]  # no Python inside: any FMI host loads it
    # The calibration report rides along with both models.
    documents = [e.value for e in fmu.value if e.id_short.startswith("RefSimDocumentation")]
    assert sorted(Path(d).name for d in documents) == ["calibrated.xml", "calibration.json", "parameters.png",
                                                        "report.html", "residuals.png", "traces.png"]
    assert all(d in files for d in documents)


def test_technical_data_comes_from_the_compiled_model_with_units(package, scene):
    store, _ = read(package)
    machine = Machine(load_scene(scene).machine.mjcf)
    sections = submodel(store, TECHNICAL_DATA).get_referable("TechnicalProperties")
    drives, wheel = sections.get_referable("Drives"), sections.get_referable("BucketWheel")
    assert drives.get_referable("RatedSpeedTravel").value == pytest.approx(machine.rated_speed[0])
    assert wheel.get_referable("WheelDiameter").value == pytest.approx(machine.wheel.diameter)
    concept = drives.get_referable("DriveRatingTravel").semantic_id.resolve(store)
    content = concept.embedded_data_specifications[0].data_specification_content
    assert content.unit == "N" and content.unit_id.key[0].value == "0112/2///62720#UAA235"  # IEC CDD: newton


def test_the_nameplate_says_what_the_opc_ua_identification_says(package, scene):
    store, files = read(package)
    plate = submodel(store, NAMEPLATE)
    nodeset = next(name for name in files if name.endswith("nodeset.xml"))
    opc = {}
    root = Et.fromstring(_bytes(files, nodeset))
    for node in root:
        node_id = node.get("NodeId", "")
        if ".Identification." in node_id:
            name = node_id.rsplit(".", 1)[-1]
            opc[name] = "".join(node.find("{*}Value").itertext()).strip()
    assert opc["Manufacturer"] == plate.get_referable("ManufacturerName").value["en"] == "bwr_twin"
    assert opc["Model"] == plate.get_referable("ManufacturerProductDesignation").value["en"]
    assert opc["SerialNumber"] == plate.get_referable("SerialNumber").value == "BWR-LU-0001"
    assert opc["ProductInstanceUri"] == plate.get_referable("URIOfTheProduct").value
    texts = Machine(load_scene(scene).machine.mjcf).identification
    assert plate.get_referable("YearOfConstruction").value == texts.get("year_of_construction", UNKNOWN)


def _bytes(files, name) -> bytes:
    import io

    buffer = io.BytesIO()
    files.write_file(name, buffer)
    return buffer.getvalue()


def test_the_fmu_read_back_out_is_validated_and_simulated_by_fmpy_alone_in_a_fresh_environment(package, tmp_path,
                                                                                               fmpy_alone):
    fmu = tmp_path / "from_the_package.fmu"
    with zipfile.ZipFile(package) as archive:
        fmu.write_bytes(archive.read("aasx/files/bwr.fmu"))  # named after the machine
    ((samples, periods_left, position),) = fmpy_alone(fmu)
    assert samples == 201 and periods_left == 2001 - 200 and math.isfinite(position)  # the scene's 20 s path


def test_check_fails_on_a_package_without_a_required_element(package, tmp_path):
    store, files = read(package)
    plate = submodel(store, NAMEPLATE)
    plate.submodel_element.remove(plate.get_referable("ManufacturerName"))
    broken = tmp_path / "broken.aasx"
    write(broken, store, files)
    result = python("-m", "bwr_twin.export", "aas", "--check", broken)
    assert result.returncode == 1
    assert ("no ManufacturerName (semanticId 0173-1#02-AAO677#002), which Digital Nameplate (IDTA 02006-2-0) "
            "requires") in result.stderr, result.stderr
    assert result.stderr.count("\n") == 1  # one problem, one line


def test_check_fails_on_a_package_missing_a_file_it_points_at(package, tmp_path):
    store, files = read(package)
    fmu = next(name for name in files if name.endswith(".fmu"))
    files.delete_file(fmu)
    broken = tmp_path / "no_fmu.aasx"
    write(broken, store, files)
    result = python("-m", "bwr_twin.export", "aas", "--check", broken)
    assert result.returncode == 1 and fmu in result.stderr, result.stderr  # the package names a part it lacks


def test_check_fails_on_a_package_that_breaks_the_meta_model(package, tmp_path):
    broken = tmp_path / "bad_id_short.aasx"
    with zipfile.ZipFile(package) as source, zipfile.ZipFile(broken, "w") as copy:
        for item in source.infolist():
            data = source.read(item.filename)
            if item.filename == "aasx/data.xml":  # an idShort with a space: AAS constraint AASd-002
                data = data.replace(b"<aas:idShort>Nameplate</aas:idShort>", b"<aas:idShort>Name plate</aas:idShort>")
            copy.writestr(item, data)
    result = python("-m", "bwr_twin.export", "aas", "--check", broken)
    assert result.returncode == 1 and "AASd-002" in result.stderr and result.stderr.count("\n") == 1, result.stderr


@pytest.mark.parametrize("damage", ["not a zip", "truncated"])
def test_a_corrupt_package_gets_one_line(package, tmp_path, damage):
    bad = tmp_path / "bad.aasx"
    bad.write_bytes(b"no package here" if damage == "not a zip" else package.read_bytes()[: 4096])
    result = python("-m", "bwr_twin.export", "aas", "--check", bad)
    assert result.returncode == 2 and result.stderr.count("\n") == 1 and "Traceback" not in result.stderr
    assert result.stderr.startswith(f"error: --check {bad}:")


def test_overwrite_follows_ownership_and_no_calibration_leaves_the_entry_out(package, scene, tmp_path):
    out = tmp_path / "again.aasx"
    first = python("-m", "bwr_twin.export", "aas", scene, "--out", out)
    assert first.returncode == 0, first.stderr
    store, _ = read(out)
    fmu = submodel(store, SIMULATION_MODELS).get_referable("FMU")
    assert not [e for e in fmu.value if e.id_short.startswith("RefSimDocumentation")]
    refused = python("-m", "bwr_twin.export", "aas", scene, "--out", out)
    assert refused.returncode == 2 and "already exists" in refused.stderr and refused.stderr.count("\n") == 1
    before = out.stat().st_ino
    again = python("-m", "bwr_twin.export", "aas", scene, "--out", out, "--overwrite")
    assert again.returncode == 0, again.stderr
    assert out.stat().st_ino != before  # a new package took its name, whole
    with zipfile.ZipFile(out, "a") as archive:  # the engineer adds a note and keeps the twin's mark
        comment = archive.comment
        archive.writestr("aasx/files/notes.txt", "my notes\n")
        archive.comment = comment
    refused = python("-m", "bwr_twin.export", "aas", scene, "--out", out, "--overwrite")
    assert refused.returncode == 2 and "changed since the twin wrote it" in refused.stderr
    foreign = tmp_path / "foreign.aasx"
    foreign.write_bytes(b"the engineer's own")
    refused = python("-m", "bwr_twin.export", "aas", scene, "--out", foreign, "--overwrite")
    assert refused.returncode == 2 and "not written by the twin" in refused.stderr
    assert foreign.read_bytes() == b"the engineer's own"


def test_a_calibration_of_another_machine_is_refused_before_any_work(scene, calibration, tmp_path):
    other = tmp_path / "other"
    other.mkdir()
    (other / "calibration.json").write_bytes((calibration / "calibration.json").read_bytes())
    (other / "calibrated.xml").write_bytes((ROOT / "mjcf" / "bwr_heavy.xml").read_bytes())
    out = tmp_path / "x.aasx"
    result = python("-m", "bwr_twin.export", "aas", scene, "--out", out, "--calibration", other)
    assert result.returncode == 2 and result.stderr.count("\n") == 1
    assert "a calibration of machine 'bwr_heavy'; the scene's machine is 'bwr'" in result.stderr
    assert not out.exists()


def test_a_bad_calibration_folder_gets_one_line_before_any_work(scene, tmp_path):
    (tmp_path / "calibration.json").write_text("{not json")
    out = tmp_path / "x.aasx"
    result = python("-m", "bwr_twin.export", "aas", scene, "--out", out, "--calibration", tmp_path)
    assert result.returncode == 2 and "calibration.json: not readable JSON" in result.stderr
    assert not out.exists()


def test_a_machine_without_identification_takes_the_documented_placeholders(tmp_path):
    text = (ROOT / "mjcf" / "bwr.xml").read_text()
    stripped = "\n".join(line for line in text.splitlines() if "<text name=" not in line)
    mjcf = tmp_path / "anonymous.xml"
    mjcf.write_text(stripped)
    machine = Machine(mjcf)
    values = nameplate_values(machine)
    assert values["ManufacturerName"] == values["SerialNumber"] == values["YearOfConstruction"] == UNKNOWN
    assert values["ManufacturerProductDesignation"] == "bwr"  # the <mujoco model> name, as OPC UA gives it
    assert check_submodel(nameplate(machine, "urn:test:nameplate"), NAMEPLATE) == []


def test_the_heavy_machines_technical_data_lists_its_scanners_and_instruments():
    from conftest import HEAVY_MJCF

    from bwr_twin.export.aas_elements import Measures
    from bwr_twin.export.aas_machine import technical_data

    machine = Machine(HEAVY_MJCF)
    assert machine.scanners and machine.belt_scale is not None and machine.wheel_motor is not None
    measures = Measures("urn:test:concept")
    data = technical_data(machine, "urn:test:technical", measures)
    assert check_submodel(data, TECHNICAL_DATA) == []
    instruments = data.get_referable("TechnicalProperties").get_referable("Instruments")
    scanner = machine.scanners[0]
    assert instruments.get_referable(f"{scanner.name.capitalize()}Range").value == pytest.approx(scanner.max_range)
    assert instruments.get_referable("WheelMotorVoltage").value == pytest.approx(machine.wheel_motor.voltage)
    volts = measures.concepts["urn:test:concept:WheelMotorVoltage"].embedded_data_specifications[0]
    assert volts.data_specification_content.unit_id.key[0].value == "0112/2///62720#UAA296"  # IEC CDD: volt
