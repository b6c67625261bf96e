"""Speed of the twin's FMU in FMPy against the same run in process, measured in one run.

    python tools/bench_fmu.py [SCENE] [--periods 5000] [--repeat 3]

Exports SCENE (default pid_paper) as an FMU, then times, in pairs, the PID of examples/fmu_pid.py
driving (a) the FMU in FMPy, one control period a communication step (read 12 outputs, write
three setpoints, fmi2DoStep), and (b) the twin's own loop in process, a lockstep of one (measure,
the reference, advance). Prints control periods per second of each, and their ratio
(target: the FMU at least 0.5 times the in-process loop).
"""

from __future__ import annotations

import argparse
import importlib.util
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave

from bwr_twin.config.scene import load_scene
from bwr_twin.shipped import find_scene
from bwr_twin.sim.lockstep import Lockstep

ROOT = Path(__file__).resolve().parents[1]
_spec = importlib.util.spec_from_file_location("fmu_pid", ROOT / "examples" / "fmu_pid.py")
fmu_pid = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(fmu_pid)


def fmu_rate(path: Path, periods: int) -> float:
    """Control periods per second of the PID co-simulating the FMU in FMPy (instantiation excluded)."""
    description = read_model_description(str(path))
    refs = {v.name: v.valueReference for v in description.modelVariables}
    unzipped = extract(str(path))
    fmu = FMU2Slave(guid=description.guid, unzipDirectory=unzipped,
                    modelIdentifier=description.coSimulation.modelIdentifier, instanceName="bench")
    fmu.instantiate()
    fmu.setupExperiment(startTime=0.0)
    fmu.enterInitializationMode()
    fmu.exitInitializationMode()
    measured = [refs[f"{a}.{n}"] for n in ("EncoderPosition", "EncoderVelocity", "ReferencePosition",
                                            "ReferenceVelocity") for a in fmu_pid.AXES]
    setpoints = [refs[f"{a}.DriveSetpoint"] for a in fmu_pid.AXES]
    period = fmu.getReal([refs["ControlPeriod"]])[0]
    pid = fmu_pid.Pid(period)
    start = time.perf_counter()
    for k in range(periods):
        values = np.array(fmu.getReal(measured))
        fmu.setReal(setpoints, list(pid(*values.reshape(4, 3))))
        fmu.doStep(currentCommunicationPoint=k * period, communicationStepSize=period)
    elapsed = time.perf_counter() - start
    fmu.terminate()
    fmu.freeInstance()
    shutil.rmtree(unzipped, ignore_errors=True)
    return periods / elapsed


def in_process_rate(scene, periods: int) -> float:
    """Control periods per second of the same PID on the twin's own loop, a lockstep of one."""
    loop = Lockstep([scene], nthread=1)
    pid = fmu_pid.Pid(loop.period)
    start = time.perf_counter()
    for _ in range(periods):
        q, qd = loop.measure()
        q_ref, qd_ref, _ = loop.reference_now()
        loop.advance(pid(q[0], qd[0], q_ref[0], qd_ref[0])[None])
    return periods / (time.perf_counter() - start)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("scene", nargs="?", default="pid_paper")
    parser.add_argument("--periods", type=int, default=5000, help="control periods a measurement (default 5000)")
    parser.add_argument("--repeat", type=int, default=3, help="pairs of measurements (default 3)")
    args = parser.parse_args()
    scene = load_scene(find_scene(args.scene))
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "bench.fmu"
        subprocess.run([sys.executable, "-m", "bwr_twin.export", "fmu", str(scene.path), "--out", str(path)],
                       check=True, capture_output=True)
        pairs = [(fmu_rate(path, args.periods), in_process_rate(scene, args.periods)) for _ in range(args.repeat)]
    for number, (fmu, local) in enumerate(pairs, start=1):
        print(f"pair {number}: FMU in FMPy {fmu:,.0f} periods/s, in process {local:,.0f} periods/s, "
              f"ratio {fmu / local:.2f}")
    fmu, local = (float(np.median(column)) for column in zip(*pairs))
    print(f"{args.scene}, {args.periods} control periods a measurement, median of {args.repeat} pairs: "
          f"FMU {fmu:,.0f} periods/s, in process {local:,.0f} periods/s; ratio {fmu / local:.2f} (target >= 0.5)")


if __name__ == "__main__":
    main()
    fmu_pid.exit_now()  # as the example does: docs/fmu.md, known limits
