"""The exported PLC blocks against the twin's own controller: docs/plc_export.md's table.

    python tools/plc_equality.py [SCENE ...]

Each scene is run once, recorded every control period; its controller is exported in LREAL and in
REAL, each block is parsed by blark and run (tests/st_python.py) on the recorded measured and
reference states, and its forces are compared with the forces the twin commanded: LREAL as the
largest relative difference, REAL as the largest difference over each axis's force range.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from st_python import forces_on, load_exported  # noqa: E402

from bwr_twin.config.scene import load_scene  # noqa: E402
from bwr_twin.export.plc import export_plc  # noqa: E402
from bwr_twin.shipped import SCENES  # noqa: E402
from bwr_twin.sim.lockstep import simulate  # noqa: E402

DEFAULT = ("pid_paper", "computed_torque_paper", "paper_individual_gains", "computed_torque_heavy", "heavy_reclaim")


def exported_forces(scene, result, folder: Path, real: bool) -> np.ndarray:
    export_plc(scene, folder, real=real)
    return forces_on(load_exported(folder), result)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("scenes", nargs="*", default=DEFAULT)
    args = parser.parse_args()
    print("| scene | periods | LREAL, largest relative difference | REAL, largest difference / force range "
          "(travel, slew, luff) | REAL block run in |")
    print("| --- | --- | --- | --- | --- |")
    for name in args.scenes:
        period = load_scene(SCENES / f"{name}.toml").simulation.control_period
        scene = load_scene(SCENES / f"{name}.toml", {"simulation.record_period": period})
        result = simulate(scene)
        twin = result.drive_force_command
        with tempfile.TemporaryDirectory() as tmp:
            double = exported_forces(scene, result, Path(tmp) / "lreal", real=False)
            started = time.perf_counter()
            single = exported_forces(scene, result, Path(tmp) / "real", real=True)
            took = time.perf_counter() - started
        relative = np.max(np.abs(double - twin) / np.maximum(np.abs(twin), 1e-300))
        of_range = np.abs(single - twin).max(axis=0) / np.ptp(twin, axis=0)
        print(f"| `{name}` | {len(result.time):,} | {relative:.1e} | "
              f"{', '.join(f'{v:.1e}' for v in of_range)} | {took:.1f} s |")


if __name__ == "__main__":
    main()
