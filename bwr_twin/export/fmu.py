"""A scene as the Python FMU: FMI 2.0 co-simulation, built with pythonfmu (bwr_twin.export.fmu_slave
is its model). `python -m bwr_twin.export fmu` writes it for the scenes the native FMU
(bwr_twin.export.native_fmu) does not carry: a stockpile, stacking, a neighbour, an interlock, faults.

    reclaimer.fmu
        modelDescription.xml          every variable with its unit and description (fmu_slave.VARIABLES)
        binaries/linux64, win64       pythonfmu's FMI library, which runs the model in Python
        resources/fmu_slave.py        the model: one run of the scene, stepped by the importer
        resources/scene.toml          the scene, its tables as the twin read them, its files beside it
        resources/*.xml, *.toml, ...  the machine's MJCF and every other file the scene reads
        resources/pythonfmu/          pythonfmu's Python side

The importing machine needs Python with `bwr_twin` installed (docs/fmu.md). The archive's comment
is the twin's mark: an existing .fmu is replaced only with --overwrite, if the twin wrote it and it is
unchanged since (the manifest beside it, bwr_twin.ownership), and only whole.
"""

from __future__ import annotations

import shutil
import tempfile
import zipfile
from pathlib import Path

from bwr_twin.config.scene import Scene
from bwr_twin.config.scene_toml import scene_toml
from bwr_twin.errors import SceneError
from bwr_twin.export import fmu_slave
from bwr_twin.ownership import FMU_WRITER, check_output, write_atomically


def export_fmu(scene: Scene, out: Path, *, overwrite: bool = False) -> Path:
    """Write the scene as the FMU `out` (an .fmu file the twin wrote, unchanged since, is replaced
    with `overwrite`); returns `out`."""
    check_output(out, "fmu", overwrite=overwrite, inputs=scene.input_files)  # before any work: a refusal costs nothing
    from pythonfmu.builder import FmuBuilder  # imported here: the twin's other commands never need it

    with tempfile.TemporaryDirectory(prefix="bwr_twin_fmu_") as folder:
        resources = Path(folder) / "resources"
        resources.mkdir()
        _pack_scene(scene, resources)
        script = Path(folder) / Path(fmu_slave.__file__).name
        shutil.copyfile(fmu_slave.__file__, script)
        built = Path(folder) / "built.fmu"
        FmuBuilder.build_FMU(script, dest=built, project_files=sorted(resources.iterdir()),
                             needsExecutionTool="true", canHandleVariableCommunicationStepSize="true")
        with zipfile.ZipFile(built, "a") as archive:
            archive.comment = FMU_WRITER.encode()
        check_output(out, "fmu", overwrite=overwrite, inputs=scene.input_files)  # again, just before anything is replaced
        write_atomically(out, lambda partial: shutil.copyfile(built, partial), record=True)
    return out


def _pack_scene(scene: Scene, resources: Path) -> None:
    """resources/scene.toml, with each file the scene reads copied beside it under its own name."""
    names: dict[Path, str] = {}
    for source in scene.input_files[1:]:  # [0] is the scene file itself, written anew below
        source = source.resolve()
        if source in names:
            continue
        if source.suffix.lower() == ".xml" and "<include" in source.read_text(encoding="utf-8", errors="replace"):
            raise SceneError(f"{source}: includes other MJCF files; the FMU packs a machine in one file "
                             "(write it out whole, e.g. with mujoco.MjSpec.from_file(...).to_xml())")
        name = source.name if source.name not in names.values() else f"{len(names)}_{source.name}"
        names[source] = name
        shutil.copyfile(source, resources / name)
    text = scene_toml(scene, f"{scene.path.name}, packed by python -m bwr_twin.export fmu")
    for source, name in names.items():  # an absolute path, or a "file.py:Class" reference
        text = text.replace(f'"{source}"', f'"{name}"').replace(f'"{source}:', f'"{name}:')
    (resources / fmu_slave.SCENE_FILE).write_text(text, encoding="utf-8")
