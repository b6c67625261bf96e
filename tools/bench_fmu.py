"""Speed of the native FMU against the same run in process, measured in one run.

    python tools/bench_fmu.py [SCENE] [--periods 20000] [--repeat 3]

Exports SCENE (default pid_paper) as the native FMU (FMI 2.0), then times, in pairs, a PD on the
encoders against the reference (examples/fmu_pid.py's gains, no integral) driving:
(a) the FMU from a C host (tests/fmi_host.c, compiled here with cc), one control period a
    communication step: fmi2GetReal of 12 outputs, fmi2SetReal of the three setpoints, fmi2DoStep;
    the loop's time alone, instantiation excluded; no Python in that process;
(b) the twin's own loop in process, a lockstep of one (measure, the reference, advance), the PD in
    numpy.
Prints control periods per second of each and their ratio (target: the FMU at least 5 times the
in-process loop), then, for an importer in Python, the same through FMPy (ctypes), once.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
import zipfile
from pathlib import Path
from xml.etree import ElementTree

import numpy as np

from bwr_twin.config.scene import load_scene
from bwr_twin.export.native_fmu import SOURCE, find_compiler
from bwr_twin.shipped import find_scene
from bwr_twin.sim.lockstep import Lockstep

ROOT = Path(__file__).resolve().parents[1]
HOST = ROOT / "tests" / "fmi_host.c"
AXES = ("Travel", "Slew", "Luff")
KP = np.array([28000.0, 7262500.0, 5000000.0])  # examples/fmu_pid.py's gains, as tests/fmi_host.c has them
KD = np.array([28000.0, 7262500.0, 5000000.0])
HOLD = np.array([0.0, 0.0, 490500.0])


def references(fmu: Path) -> tuple[str, dict[str, int]]:
    with zipfile.ZipFile(fmu) as archive:
        root = ElementTree.fromstring(archive.read("modelDescription.xml"))
    return root.get("guid"), {v.get("name"): int(v.get("valueReference")) for v in root.find("ModelVariables")}


def host_rate(host: Path, unzipped: Path, fmu: Path, periods: int) -> float:
    """Control periods per second of the PD driving the FMU from the C host."""
    guid, refs = references(fmu)
    environment = {**os.environ, "FMU_GUID": guid} | {f"VR_{k.replace('.', '_')}": str(v) for k, v in refs.items()}
    done = subprocess.run([str(host), str(unzipped), "bench", "2", str(periods)], capture_output=True, text=True,
                          env=environment, check=True)
    count, seconds = done.stdout.split("\n")[-2].split()
    return int(count) / float(seconds)


def fmpy_rate(fmu: Path, unzipped: Path, periods: int) -> float:
    """Control periods per second of the same PD driving the FMU through FMPy."""
    from fmpy.fmi2 import FMU2Slave  # an importer's view, for comparison only

    guid, refs = references(fmu)
    slave = FMU2Slave(guid=guid, unzipDirectory=str(unzipped), modelIdentifier="BwrReclaimer", instanceName="bench")
    slave.instantiate()
    slave.setupExperiment(startTime=0.0)
    slave.enterInitializationMode()
    slave.setReal([refs[f"{a}.DisturbanceAmplitude"] for a in AXES], [0.0] * 3)
    slave.exitInitializationMode()
    measured = [refs[f"{a}.{n}"] for n in ("EncoderPosition", "EncoderVelocity", "ReferencePosition",
                                            "ReferenceVelocity") for a in AXES]
    setpoints = [refs[f"{a}.DriveSetpoint"] for a in AXES]
    period = slave.getReal([refs["ControlPeriod"]])[0]
    start = time.perf_counter()
    for k in range(periods):
        q, qd, q_ref, qd_ref = np.array(slave.getReal(measured)).reshape(4, 3)
        slave.setReal(setpoints, list(HOLD + KP * (q_ref - q) + KD * (qd_ref - qd)))
        slave.doStep(currentCommunicationPoint=k * period, communicationStepSize=period)
    elapsed = time.perf_counter() - start
    slave.terminate()
    slave.freeInstance()
    return periods / elapsed


def in_process_rate(scene, periods: int) -> float:
    """Control periods per second of the same PD on the twin's own loop, a lockstep of one."""
    loop = Lockstep([scene], nthread=1)
    start = time.perf_counter()
    for _ in range(periods):
        q, qd = loop.measure()
        q_ref, qd_ref, _ = loop.reference_now()
        loop.advance((HOLD + KP * (q_ref - q[0]) + KD * (qd_ref - qd[0]))[None])
    return periods / (time.perf_counter() - start)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("scene", nargs="?", default="pid_paper")
    parser.add_argument("--periods", type=int, default=20000, help="control periods a measurement (default 20000)")
    parser.add_argument("--repeat", type=int, default=3, help="pairs of measurements (default 3)")
    args = parser.parse_args()
    scene = load_scene(find_scene(args.scene), {"disturbance.amplitude": [0.0, 0.0, 0.0]})
    with tempfile.TemporaryDirectory() as folder:
        fmu, unzipped, host = Path(folder) / "bench.fmu", Path(folder) / "bench", Path(folder) / "fmi_host"
        subprocess.run([sys.executable, "-m", "bwr_twin.export", "fmu", str(scene.path), "--out", str(fmu)],
                       check=True, capture_output=True)
        with zipfile.ZipFile(fmu) as archive:
            archive.extractall(unzipped)
        subprocess.run([find_compiler(), "-std=c11", "-O2", f"-I{SOURCE / 'fmi'}", str(HOST), "-o", str(host), "-ldl",
                        "-lm"], check=True)
        pairs = [(host_rate(host, unzipped, fmu, args.periods), in_process_rate(scene, args.periods))
                 for _ in range(args.repeat)]
        through_fmpy = fmpy_rate(fmu, unzipped, args.periods)
    for number, (native, local) in enumerate(pairs, start=1):
        print(f"pair {number}: native FMU from a C host {native:,.0f} periods/s, in process {local:,.0f} periods/s, "
              f"ratio {native / local:.2f}")
    native, local = (float(np.median(column)) for column in zip(*pairs))
    print(f"{args.scene}, {args.periods} control periods a measurement, median of {args.repeat} pairs: native FMU "
          f"{native:,.0f} periods/s, in process {local:,.0f} periods/s; ratio {native / local:.2f} (target >= 5)")
    print(f"the native FMU through FMPy (ctypes, one period a step): {through_fmpy:,.0f} periods/s, "
          f"{through_fmpy / local:.2f} times the in-process loop")


if __name__ == "__main__":
    main()
