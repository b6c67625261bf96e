"""Which FMU a scene gets: the native one (C over MuJoCo's C library, no Python inside) where it
carries the scene, else the Python one, which needs Python with bwr_twin where it runs
(docs/fmu.md). `export fmu` and `export aas` both ask here, so both ship the same FMU."""

from __future__ import annotations

from pathlib import Path

from bwr_twin.config.scene import Scene
from bwr_twin.errors import SceneError
from bwr_twin.export.native_fmu import export_native_fmu, native_obstacle


def export_scene_fmu(scene: Scene, out: Path, *, fmi: int = 2, overwrite: bool = False) -> tuple[Path, str | None]:
    """Write the scene's FMU to `out`; returns it and, for the Python FMU, what keeps the native
    one from carrying the scene (None: the native FMU). FMI 3.0 is the native FMU's alone: a
    scene it cannot carry is refused for it (SceneError)."""
    obstacle = native_obstacle(scene)
    if obstacle is None:
        return export_native_fmu(scene, out, fmi=fmi, overwrite=overwrite), None
    if fmi == 3:
        raise SceneError(f"{scene.path}: --fmi 3 is the native FMU's, but {obstacle} (FMI 2.0)")
    from bwr_twin.export.fmu import export_fmu  # imported here: pythonfmu only for the scenes that need it

    return export_fmu(scene, out, overwrite=overwrite), obstacle
