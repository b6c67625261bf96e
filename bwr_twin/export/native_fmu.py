"""A path scene as a native co-simulation FMU, FMI 2.0 or 3.0: the reclaimer in C over MuJoCo's
C library, no Python inside (docs/fmu.md).

    reclaimer.fmu
        modelDescription.xml        every variable with its unit (bwr_twin.export.fmu_variables)
        binaries/linux64/           BwrReclaimer.so and the mujoco wheel's libmujoco.so.* beside it
          (FMI 3.0: x86_64-linux/)  (rpath $ORIGIN), compiled here with the system's C compiler
        sources/                    the C source (bwr_twin/export/native), its variables.h, the FMI
                                    headers; FMI 3.0: buildDescription.xml
        resources/model.mjb         the plant's compiled model, as MuJoCo saved it
        resources/path.bin          the path, a row of 9 float64 per control period
        resources/plant.txt         the run's numbers and the variables' start values
        resources/<machine>.xml     the machine's MJCF, as the engineer wrote it (for reading)

The model is stored as MJB, not MJCF: the twin's plant compiles the machine with the edits of
bwr_twin/model/spec.py (payloads, timestep, no visual geoms) and sets per-run fields (friction
loss) after compiling; MuJoCo's own save of that compiled model is the same model bit for bit,
which a re-parsed XML need not be. An MJB loads only in the MuJoCo version that saved it: the FMU
carries that library for Linux, and a build for another platform links the same version.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import tempfile
import uuid
import zipfile
from pathlib import Path
from xml.etree.ElementTree import Element, SubElement, indent, tostring

import mujoco
import numpy as np

from bwr_twin.config.scene import Scene
from bwr_twin.errors import SceneError
from bwr_twin.export.fmu_variables import PARAMETERS, UNITS, Variable, native_variables
from bwr_twin.model.machine import Machine
from bwr_twin.ownership import FMU_WRITER, check_output, write_atomically
from bwr_twin.sim.parameters import RunParameters
from bwr_twin.sim.tracking import PathTracking
from bwr_twin.sim.twin import limit_switch_bounds

MODEL_IDENTIFIER = "BwrReclaimer"
SOURCE = Path(__file__).with_name("native")  # reclaimer.c/h, fmi2.c, fmi3.c and fmi/ (the FMI headers)
PLATFORM = {2: "linux64", 3: "x86_64-linux"}  # the binaries folder of 64-bit Linux in each FMI version
FMI_HEADERS = {2: ("fmi2Functions.h", "fmi2FunctionTypes.h", "fmi2TypesPlatform.h"),
               3: ("fmi3Functions.h", "fmi3FunctionTypes.h", "fmi3PlatformTypes.h")}
INT32_MAX = 2**31 - 1


class CompilerMissing(SceneError):
    """No C compiler on this machine: the native FMU cannot be built."""


def native_obstacle(scene: Scene) -> str | None:
    """Why the native FMU cannot carry `scene` (its C side steps the machine on a path under
    drives, encoders, disturbances, friction and wind, nothing more), or None if it can."""
    parts = (("stockpile", "a stockpile (the wheel's cut, the belt and its instruments)"),
             ("reclaim", "a bench reclaim and its rate loop"), ("stacking", "stacking"),
             ("neighbour", "a neighbour on the rail"), ("interlock", "an anti-collision interlock"),
             ("faults", "scheduled faults"))
    found = [what for name, what in parts if getattr(scene, name)]
    if scene.trajectory is None and not found:
        found.append("no via-point path")
    return f"the scene has {' and '.join(found)}, which only the Python FMU carries" if found else None


def find_compiler() -> str:
    """The C compiler: $CC, else cc or gcc on the PATH. Raises CompilerMissing."""
    for name in (os.environ.get("CC"), "cc", "gcc"):
        if name and shutil.which(name):
            return shutil.which(name)
    raise CompilerMissing("no C compiler found (cc or gcc on the PATH, or $CC): the native FMU is compiled on this "
                          "machine; install one (Debian: apt-get install gcc)")


def mujoco_library() -> tuple[Path, Path]:
    """The mujoco wheel's include folder and its libmujoco.so.*."""
    package = Path(mujoco.__file__).parent
    libraries = sorted(package.glob("libmujoco.so.*"))
    if not libraries or not (package / "include" / "mujoco" / "mujoco.h").is_file():
        raise SceneError(f"{package}: the mujoco package ships no libmujoco.so.* and include/mujoco/mujoco.h to "
                         "build the native FMU against")
    return package / "include", libraries[0]


def export_native_fmu(scene: Scene, out: Path, *, fmi: int = 2, overwrite: bool = False) -> Path:
    """Write `scene` as the native FMU `out` (FMI `fmi`, 2 or 3); returns `out`. Raises
    CompilerMissing without a C compiler, SceneError for a scene it cannot carry."""
    check_output(out, "fmu", overwrite=overwrite, inputs=scene.input_files)  # before any work
    obstacle = native_obstacle(scene)
    if obstacle:
        raise SceneError(f"{scene.path}: {obstacle}")
    compiler = find_compiler()
    include, library = mujoco_library()
    with tempfile.TemporaryDirectory(prefix="bwr_twin_fmu_") as folder:
        root = Path(folder) / "fmu"
        resources, sources, binaries = root / "resources", root / "sources", root / "binaries" / PLATFORM[fmi]
        for path in (resources, sources, binaries):
            path.mkdir(parents=True)
        samples, period, variables = _write_resources(scene, resources)
        _copy_sources(sources, fmi)
        guid = _guid(resources, sources, fmi)
        (sources / "variables.h").write_text(variables_header(variables, guid), encoding="utf-8")
        files = ["reclaimer.c", f"fmi{fmi}.c"]
        description = model_description(variables, guid, samples, period, fmi, files)
        (root / "modelDescription.xml").write_bytes(description)
        if fmi == 3:
            (sources / "buildDescription.xml").write_bytes(build_description(files, library))
        _compile(compiler, sources, files, include, library, binaries / f"{MODEL_IDENTIFIER}.so")
        built = Path(folder) / "built.fmu"
        with zipfile.ZipFile(built, "w", zipfile.ZIP_DEFLATED) as archive:
            for path in sorted(root.rglob("*")):
                if path.is_file():
                    archive.write(path, path.relative_to(root).as_posix())
            archive.comment = FMU_WRITER.encode()
        check_output(out, "fmu", overwrite=overwrite, inputs=scene.input_files)  # again, just before replacing
        write_atomically(out, lambda partial: shutil.copyfile(built, partial), record=True)
    return out


def _write_resources(scene: Scene, resources: Path) -> tuple[int, float, tuple[Variable, ...]]:
    """model.mjb, path.bin, plant.txt and the machine's MJCF into `resources`: the control periods,
    the period (s), and the variables with their start values."""
    sim = scene.simulation
    period = sim.control_period
    machine = Machine(scene.machine.mjcf, payloads=scene.plant.payload)
    tracking = PathTracking(scene, machine, period)
    parameters = RunParameters.of([scene])
    model = machine.physics_model(sim.timestep)  # as bwr_twin.sim.plant.Plant compiles it
    if not np.isnan(parameters.frictionloss[0]).any():  # the plant's per-run friction loss
        model.dof_frictionloss[:3] = parameters.frictionloss[0]
    mujoco.mj_saveModel(model, str(resources / "model.mjb"), None)
    shutil.copyfile(scene.machine.mjcf, resources / scene.machine.mjcf.name)
    rows = np.stack(tracking.rows, axis=1).reshape(tracking.samples, 9)  # (samples, position|velocity|acceleration x 3)
    rows.astype("<f8").tofile(resources / "path.bin")

    windy = bool(parameters.windy[0])
    heading = parameters.wind_direction[0]
    direction = np.array([np.cos(heading), np.sin(heading), 0.0])  # as the plant computes it
    low, high = limit_switch_bounds(machine)
    ids = list(machine.actuator_ids)
    numbers = {
        "period": [period], "substeps": [round(period / sim.timestep)],  # as the plant rounds it
        "actuators": ids, "gear": machine.model.actuator_gear[ids, 0].tolist(), "start": list(tracking.start),
        "low": low, "high": high, "wind_direction": direction.tolist(),
        "velocity_estimated": [int(parameters.velocity_estimated[0])],
        "velocity_filter": [float(parameters.velocity_filter[0])],
    }
    starts: dict[str, float] = {f"{axis}.DriveSetpoint": 0.0 for axis in ("Travel", "Slew", "Luff")}
    starts["WindSpeed"] = float(parameters.wind_speed[0])
    # a still-air run has the file's density, as the plant leaves it (docs/fmu.md)
    starts["AirDensity"] = float(parameters.air_density[0]) if windy else float(model.opt.density)
    for name, key, index, _, _ in PARAMETERS:
        table, field = key.split(".")
        value = getattr(getattr(scene, table), field)
        starts[name] = value if index is None else float(value[index])
    if not 0 <= starts["Seed"] <= INT32_MAX:
        raise SceneError(f"{scene.path}: [simulation] seed {starts['Seed']}: the FMU's Seed is a 32-bit integer, "
                         f"0 to {INT32_MAX}")
    lines = [f"{name} {' '.join(repr(float(v)) if isinstance(v, float) else str(v) for v in values)}"
             for name, values in numbers.items()]
    variables = native_variables(starts)
    lines += [f"value {v.vr} {v.start!r}" for v in variables if v.start is not None]
    (resources / "plant.txt").write_text("\n".join(lines) + "\n", encoding="utf-8")
    return tracking.samples, period, variables


def _copy_sources(sources: Path, fmi: int) -> None:
    for name in ("reclaimer.c", "reclaimer.h", f"fmi{fmi}.c"):
        shutil.copyfile(SOURCE / name, sources / name)
    for name in FMI_HEADERS[fmi]:
        shutil.copyfile(SOURCE / "fmi" / name, sources / name)


def _guid(resources: Path, sources: Path, fmi: int) -> str:
    """The same FMU, the same GUID: a digest of what it holds."""
    digest = hashlib.sha256(str(fmi).encode())
    for path in sorted([*resources.iterdir(), *sources.iterdir()]):
        digest.update(path.name.encode() + path.read_bytes())
    return "{" + str(uuid.UUID(bytes=digest.digest()[:16])) + "}"


def variables_header(variables: tuple[Variable, ...], guid: str) -> str:
    """sources/variables.h: the variable table as the C code reads it."""
    groups: dict[str, int] = {}
    for v in variables:
        groups.setdefault(v.group, v.vr)
    kinds = {"input": "i", "output": "o", "parameter": "p", "calculatedParameter": "c", "independent": "t"}
    minimum = [repr(float(v.minimum[0])) if v.minimum else "-1e308" for v in variables]
    names = ", ".join(f'"{v.name}"' for v in variables)
    return "\n".join([
        "/* Written by python -m bwr_twin.export fmu from bwr_twin/export/fmu_variables.py: do not edit. */",
        "#ifndef VARIABLES_H", "#define VARIABLES_H", "",
        f'#define MODEL_GUID "{guid}"',
        f"#define VARIABLE_COUNT {len(variables)}",
        *(f"#define VR_{group} {vr}" for group, vr in groups.items()), "",
        "#ifdef VARIABLE_TABLES /* the value references' types (r Real, i Integer, b Boolean), kinds (i input,",
        "                          o output, p fixed parameter, c calculated parameter, t time), least values, names */",
        f'static const char VARIABLE_TYPE[] = "{"".join(v.type[0].lower() for v in variables)}";',
        f'static const char VARIABLE_KIND[] = "{"".join(kinds[v.causality] for v in variables)}";',
        f"static const double VARIABLE_MIN[] = {{{', '.join(minimum)}}};",
        f'static const char VARIABLE_MIN_OPEN[] = "{"".join("1" if v.minimum and v.minimum[1] else "0" for v in variables)}";',
        f"static const char *const VARIABLE_NAME[] = {{{names}}};",
        "#endif", "", "#endif", ""])


def _unit_definitions(parent: Element, variables: tuple[Variable, ...]) -> None:
    definitions = SubElement(parent, "UnitDefinitions")
    for name in sorted({v.unit for v in variables if v.unit}):
        exponents = dict(UNITS[name])
        factor = exponents.pop("factor", None)
        attributes = {k: str(v) for k, v in exponents.items()} | ({"factor": repr(factor)} if factor else {})
        SubElement(SubElement(definitions, "Unit", name=name), "BaseUnit", attributes)


def _described(v: Variable) -> str:
    return f"{v.description}, {v.unit}" if v.unit else v.description


def model_description(variables: tuple[Variable, ...], guid: str, samples: int, period: float, fmi: int,
                      files: list[str]) -> bytes:
    """modelDescription.xml of FMI `fmi` (2 or 3)."""
    common = {"modelName": MODEL_IDENTIFIER, "description": "Bucket wheel reclaimer (travel, slew, luff) under drive "
              "forces from the importer; native, MuJoCo in C", "generationTool": "bwr_twin",
              "variableNamingConvention": "structured"}
    if fmi == 2:
        root = Element("fmiModelDescription", fmiVersion="2.0", guid=guid, numberOfEventIndicators="0", **common)
        cosim = SubElement(root, "CoSimulation", modelIdentifier=MODEL_IDENTIFIER,
                           canHandleVariableCommunicationStepSize="true", canNotUseMemoryManagementFunctions="true",
                           canBeInstantiatedOnlyOncePerProcess="false")
        listed = SubElement(cosim, "SourceFiles")
        for name in files:
            SubElement(listed, "File", name=name)
    else:
        root = Element("fmiModelDescription", fmiVersion="3.0", instantiationToken=guid, **common)
        SubElement(root, "CoSimulation", modelIdentifier=MODEL_IDENTIFIER, canHandleVariableCommunicationStepSize="true",
                   hasEventMode="false", providesIntermediateUpdate="false", canReturnEarlyAfterIntermediateUpdate="false")
    _unit_definitions(root, variables)
    categories = SubElement(root, "LogCategories")
    SubElement(categories, "Category", name="logStatusError", description="a call refused, with its reason")
    SubElement(categories, "Category", name="logEvents", description="what the FMU did (with logging on)")
    SubElement(root, "DefaultExperiment", startTime="0", stopTime=repr(samples * period), stepSize=repr(period))
    listing = SubElement(root, "ModelVariables")
    for v in variables:
        attributes = {"name": v.name, "valueReference": str(v.vr), "causality": v.causality,
                      "variability": v.variability, "description": _described(v)}
        if v.causality in ("output", "calculatedParameter"):
            attributes["initial"] = "calculated"
        elif v.causality == "parameter":
            attributes["initial"] = "exact"
        typed: dict[str, str] = {}
        if v.unit:
            typed["unit"] = v.unit
        if v.start is not None:
            typed["start"] = repr(v.start) if v.type == "Real" else str(int(v.start))
        if v.minimum:
            typed["min"] = repr(v.minimum[0]) if v.type == "Real" else str(int(v.minimum[0]))
        if fmi == 2:
            SubElement(SubElement(listing, "ScalarVariable", attributes), v.type, typed)
        else:
            kind = {"Real": "Float64", "Integer": "Int32", "Boolean": "Boolean"}[v.type]
            SubElement(listing, kind, attributes | typed)
    structure = SubElement(root, "ModelStructure")
    outputs = [v for v in variables if v.causality == "output"]
    unknowns = [v for v in variables if v.causality in ("output", "calculatedParameter")]
    if fmi == 2:  # by index, 1-based, in the order of ModelVariables
        SubElement(structure, "Outputs").extend(Element("Unknown", index=str(v.vr + 1)) for v in outputs)
        SubElement(structure, "InitialUnknowns").extend(Element("Unknown", index=str(v.vr + 1)) for v in unknowns)
    else:
        for v in outputs:
            SubElement(structure, "Output", valueReference=str(v.vr))
        for v in unknowns:
            SubElement(structure, "InitialUnknown", valueReference=str(v.vr))
    indent(root)
    return tostring(root, encoding="UTF-8", xml_declaration=True)


def build_description(files: list[str], library: Path) -> bytes:
    """sources/buildDescription.xml (FMI 3.0): the files to compile and the library to link."""
    root = Element("fmiBuildDescription", fmiVersion="3.0")
    configuration = SubElement(root, "BuildConfiguration", modelIdentifier=MODEL_IDENTIFIER,
                               description="C11; link MuJoCo's library of the version in the Library element")
    files_set = SubElement(configuration, "SourceFileSet", language="C11")
    for name in files:
        SubElement(files_set, "SourceFile", name=name)
    SubElement(configuration, "Library", name="mujoco", version=library.name.partition(".so.")[2], external="true",
               description="MuJoCo's C library (mujoco/mujoco.h), the version that saved resources/model.mjb")
    indent(root)
    return tostring(root, encoding="UTF-8", xml_declaration=True)


def _compile(compiler: str, sources: Path, files: list[str], include: Path, library: Path, target: Path) -> None:
    """Compile the FMU's library with MuJoCo's beside it, found there at run time ($ORIGIN)."""
    shutil.copyfile(library, target.parent / library.name)  # the name is the library's soname
    command = [compiler, "-std=c11", "-O2", "-fPIC", "-shared", "-fvisibility=hidden", "-Wall",
               f"-I{sources}", f"-I{include}", *(str(sources / name) for name in files), "-o", str(target),
               f"-L{target.parent}", f"-l:{library.name}", "-Wl,-rpath,$ORIGIN", "-lm"]
    done = subprocess.run(command, capture_output=True, text=True, check=False)
    if done.returncode != 0:
        raise SceneError(f"{compiler}: the native FMU does not compile: {done.stderr.strip().splitlines()[-1:]}")
