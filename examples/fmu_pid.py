"""Co-simulate the twin's FMU with FMPy under a controller written here: a per-axis PID with the
luff's holding torque, one control period a communication step.

    python -m bwr_twin.export fmu pid_paper --out reclaimer.fmu
    python examples/fmu_pid.py reclaimer.fmu [--periods 2000] [--seed 7] [--save trace.npz]

Prints the largest encoder error per axis over the periods it ran; --save writes the encoder
positions, the references and the forces, (periods, 3) each, in SI units.
"""

import argparse
import os
import shutil
import sys

import numpy as np
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave

AXES = ("Travel", "Slew", "Luff")
KP = np.array([28000.0, 7262500.0, 5000000.0])  # N/m, N m/rad, N m/rad: pid_paper's gains, 2 rad/s
KI = np.array([14000.0, 3631250.0, 2500000.0])  # N/(m s), N m/(rad s), N m/(rad s)
KD = np.array([28000.0, 7262500.0, 5000000.0])  # N s/m, N m s/rad, N m s/rad
HOLD = np.array([0.0, 0.0, 490500.0])  # N, N m, N m: the luff's static gravity torque


class Pid:
    """force = HOLD + KP e + KI integral(e) + KD de/dt, e = q_ref - q, per axis (SI units)."""

    def __init__(self, period: float):
        self.period, self.integral = period, np.zeros(3)

    def __call__(self, q, qd, q_ref, qd_ref) -> np.ndarray:
        error = q_ref - q
        force = HOLD + KP * error + KI * self.integral + KD * (qd_ref - qd)
        self.integral += error * self.period
        return force


def co_simulate(fmu_path: str, periods: int, seed: int | None = None) -> dict[str, np.ndarray]:
    """Run the FMU for `periods` control periods under the PID: encoder positions, references and
    forces, (periods, 3) each, as the controller saw and commanded them."""
    description = read_model_description(fmu_path)
    refs = {v.name: v.valueReference for v in description.modelVariables}

    def axes(name):
        return [refs[f"{axis}.{name}"] for axis in AXES]

    measured = axes("EncoderPosition") + axes("EncoderVelocity") + axes("ReferencePosition") + axes(
        "ReferenceVelocity")
    unzipped = extract(fmu_path)
    fmu = FMU2Slave(guid=description.guid, unzipDirectory=unzipped,
                    modelIdentifier=description.coSimulation.modelIdentifier, instanceName="reclaimer")
    try:
        fmu.instantiate()
        fmu.setupExperiment(startTime=0.0)
        fmu.enterInitializationMode()
        if seed is not None:
            fmu.setInteger([refs["Seed"]], [seed])
        fmu.exitInitializationMode()
        period = fmu.getReal([refs["ControlPeriod"]])[0]
        pid = Pid(period)
        trace = {name: np.empty((periods, 3)) for name in ("q", "q_ref", "force")}
        for k in range(periods):
            values = np.array(fmu.getReal(measured))
            q, qd, q_ref, qd_ref = values[0:3], values[3:6], values[6:9], values[9:12]
            force = pid(q, qd, q_ref, qd_ref)
            fmu.setReal(axes("DriveSetpoint"), list(force))
            fmu.doStep(currentCommunicationPoint=k * period, communicationStepSize=period)
            trace["q"][k], trace["q_ref"][k], trace["force"][k] = q, q_ref, force
        fmu.terminate()
        fmu.freeInstance()
    finally:
        shutil.rmtree(unzipped, ignore_errors=True)
    return trace


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("fmu", help="an FMU written by python -m bwr_twin.export fmu")
    parser.add_argument("--periods", type=int, default=2000, help="control periods to run (default 2000)")
    parser.add_argument("--seed", type=int, help="the disturbance seed (the FMU's Seed parameter)")
    parser.add_argument("--save", help="write the trace to this .npz file")
    args = parser.parse_args()
    trace = co_simulate(args.fmu, args.periods, args.seed)
    if args.save:
        np.savez(args.save, **trace)
    worst = np.abs(trace["q_ref"] - trace["q"]).max(axis=0)
    print(f"largest encoder error over {args.periods} periods: travel {worst[0] * 1e3:.2f} mm, "
          f"slew {worst[1]:.5f} rad, luff {worst[2]:.5f} rad")


def exit_now(status: int = 0) -> None:
    """End the process without its C libraries' exit handlers. A process that ran pythonfmu's
    library may find its heap corrupted at exit (an abort in a finaliser, after all work is
    done: docs/fmu.md, known limits); everything is written and flushed before this."""
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(status)


if __name__ == "__main__":
    main()
    exit_now()
