"""FMPy sessions on an FMU the twin exported, run as their own process by tests/test_fmu.py (an
importer's process: it loads and unloads pythonfmu's library as Simulink or OMSimulator would).

    python tests/fmu_checks.py FMU reset PERIODS      traces before and after fmi2Reset, as JSON
    python tests/fmu_checks.py FMU bad-step           a step of 1.5 periods, then a whole one
    python tests/fmu_checks.py FMU outputs PERIODS NAME...
                                                      the named Real outputs after each of PERIODS
                                                      steps of one period, the setpoints at 0
    python tests/fmu_checks.py FMU trim PERIODS CHUNK [TRIM]
                                                      a bench reclaim stepped CHUNK periods at a time, its
                                                      slew trimmed by TRIM (else the scene's rate loop):
                                                      the slew reference velocity after each step

Each prints one JSON line; FMPy's logger prints the FMU's messages before it.
"""

import importlib.util
import json
import sys
from pathlib import Path

import numpy as np
from fmpy import extract, read_model_description
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import FMU2Slave

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "fmu_pid.py"
_spec = importlib.util.spec_from_file_location("fmu_pid", EXAMPLE)
fmu_pid = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(fmu_pid)


def open_fmu(path: str):
    description = read_model_description(path)
    refs = {v.name: v.valueReference for v in description.modelVariables}
    fmu = FMU2Slave(guid=description.guid, unzipDirectory=extract(path),
                    modelIdentifier=description.coSimulation.modelIdentifier, instanceName="checks")
    fmu.instantiate(loggingOn=True)  # FMPy's default logger prints the FMU's messages to stdout
    return fmu, refs


def initialise(fmu) -> None:
    fmu.setupExperiment(startTime=0.0)
    fmu.enterInitializationMode()
    fmu.exitInitializationMode()


def pid_trace(fmu, refs, periods: int) -> list:
    """The example's PID for `periods`: the encoder positions it read, (periods, 3)."""
    axes = fmu_pid.AXES
    measured = [refs[f"{a}.{n}"] for n in ("EncoderPosition", "EncoderVelocity", "ReferencePosition",
                                            "ReferenceVelocity") for a in axes]
    period = fmu.getReal([refs["ControlPeriod"]])[0]
    pid, trace = fmu_pid.Pid(period), []
    for k in range(periods):
        values = np.array(fmu.getReal(measured))
        fmu.setReal([refs[f"{a}.DriveSetpoint"] for a in axes], list(pid(*values.reshape(4, 3))))
        fmu.doStep(currentCommunicationPoint=k * period, communicationStepSize=period)
        trace.append(values[:3].tolist())
    return trace


def main(path: str, check: str, *arguments: str) -> None:
    fmu, refs = open_fmu(path)
    initialise(fmu)
    if check == "reset":
        periods = int(arguments[0])
        first = pid_trace(fmu, refs, periods)
        fmu.reset()
        initialise(fmu)
        result = {"first": first, "after_reset": pid_trace(fmu, refs, periods)}
    elif check == "bad-step":
        period = fmu.getReal([refs["ControlPeriod"]])[0]
        try:
            fmu.doStep(currentCommunicationPoint=0.0, communicationStepSize=1.5 * period)
            refused = None
        except FMICallException as exc:  # with the status the FMU returned
            refused = str(exc)
        fmu.setReal([refs["Luff.DriveSetpoint"]], [490500.0])
        fmu.doStep(currentCommunicationPoint=0.0, communicationStepSize=2 * period)  # the machine is unchanged
        result = {"refused": refused, "periods_left_after": fmu.getInteger([refs["PeriodsLeft"]])[0]}
    elif check == "trim":
        periods, chunk = int(arguments[0]), int(arguments[1])
        if len(arguments) > 2:
            fmu.setBoolean([refs["SlewSpeedTrimFromInput"]], [True])
            fmu.setReal([refs["SlewSpeedTrim"]], [float(arguments[2])])
        period = fmu.getReal([refs["ControlPeriod"]])[0]
        velocity, refused = [], None
        for k in range(0, periods, chunk):
            try:
                fmu.doStep(currentCommunicationPoint=k * period, communicationStepSize=chunk * period)
            except FMICallException as exc:
                refused = str(exc)
                break
            velocity.append(fmu.getReal([refs["Slew.ReferenceVelocity"]])[0])
        result = {"slew_velocity": velocity, "refused": refused}
    elif check == "outputs":
        periods, names = int(arguments[0]), arguments[1:]
        period = fmu.getReal([refs["ControlPeriod"]])[0]
        values = []
        for k in range(periods):  # the setpoints left at 0
            fmu.doStep(currentCommunicationPoint=k * period, communicationStepSize=period)
            values.append(fmu.getReal([refs[name] for name in names]))
        result = {"values": values}
    else:
        raise SystemExit(f"unknown check {check!r}")
    fmu.terminate()
    fmu.freeInstance()
    print(json.dumps(result))


if __name__ == "__main__":
    main(*sys.argv[1:])
    fmu_pid.exit_now()  # as the example does: docs/fmu.md, known limits
