"""The Python FMU (bwr_twin.export.fmu, docs/fmu.md): the FMI 2.0 co-simulation FMU that
`python -m bwr_twin.export fmu` writes for the scenes the native FMU does not carry
(tests/test_fmu_native.py tests that one). The short path scene's is built here directly.

FMPy, an independent FMI importer, validates the FMU and co-simulates it under the PID of
examples/fmu_pid.py, one control period a communication step, in a process of its own as an
importing tool would. Its encoder trace equals, bit for bit, the same PID's run in process and
over OPC UA; the same seed gives the same trace; a step that is not a whole number of control
periods is refused and logged, and fmi2Reset starts the run again.
"""

from __future__ import annotations

import asyncio
import importlib.util
import json
import subprocess
import sys
import zipfile

import numpy as np
import pytest
from conftest import ROOT, SCENES, write_short_scene
from fmpy import read_model_description
from fmpy.validation import validate_fmu
from test_serve import Launched, pid_session

from bwr_twin.config.scene import load_scene
from bwr_twin.export.fmu import export_fmu
from bwr_twin.sim.lockstep import Lockstep
from bwr_twin.sim.twin import Twin

PERIODS = 300  # the first 3 s of the short path: travel and slew accelerate, their largest errors
CHECKS = ROOT / "tests" / "fmu_checks.py"
_spec = importlib.util.spec_from_file_location("fmu_pid", ROOT / "examples" / "fmu_pid.py")
fmu_pid = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(fmu_pid)


def python(*arguments, check=True) -> subprocess.CompletedProcess:
    result = subprocess.run([sys.executable, *map(str, arguments)], check=False, cwd=ROOT, capture_output=True,
                            text=True, timeout=300)
    if check:
        assert result.returncode == 0, result.stderr
    return result


@pytest.fixture(scope="module")
def short_scene(tmp_path_factory):
    return write_short_scene(tmp_path_factory.mktemp("fmu_scene"))


@pytest.fixture(scope="module")
def short_fmu(short_scene, tmp_path_factory):
    """The Python FMU of a path scene (the CLI writes the native one for it)."""
    out = tmp_path_factory.mktemp("fmu") / "reclaimer.fmu"
    return export_fmu(load_scene(short_scene), out)


def fmpy_trace(fmu, *options) -> np.ndarray:
    """The example's PID co-simulating `fmu` in FMPy for PERIODS: the encoder positions it read."""
    saved = fmu.parent / "trace.npz"
    python(ROOT / "examples" / "fmu_pid.py", fmu, "--periods", PERIODS, "--save", saved, *options)
    with np.load(saved) as trace:
        return trace["q"]


def in_process_trace(scene) -> np.ndarray:
    """The same PID on the same run, on the twin's own loop."""
    loop = Lockstep([scene], nthread=1)
    pid, trace = fmu_pid.Pid(loop.period), []
    while loop.k < PERIODS:
        q, qd = loop.measure()
        trace.append(q[0].copy())
        loop.advance(pid(q[0], qd[0], loop.path[0][loop.k], loop.path[1][loop.k])[None])
    return np.array(trace)


def test_fmpy_validates_the_fmu_and_finds_every_variable_described_with_its_unit(short_fmu):
    assert validate_fmu(str(short_fmu)) == []
    description = read_model_description(str(short_fmu))
    variables = {v.name: v for v in description.modelVariables}
    axes = fmu_pid.AXES
    assert {n for n, v in variables.items() if v.causality == "input"} == {f"{a}.DriveSetpoint" for a in axes}
    outputs = {n for n, v in variables.items() if v.causality == "output"}
    for signal in ("EncoderPosition", "EncoderVelocity", "ReferencePosition", "ReferenceVelocity",
                   "ReferenceAcceleration", "DriveApplied", "AtLimit"):
        assert {f"{a}.{signal}" for a in axes} <= outputs
    assert "ReclaimRate" not in outputs  # the short scene has no stockpile
    parameters = {n for n, v in variables.items() if v.causality == "parameter"}
    assert {"Seed", "DisturbanceHoldTime", "Travel.EncoderResolution", "Luff.DisturbanceAmplitude"} <= parameters
    for variable in variables.values():
        assert variable.description, variable.name
        if variable.type == "Real":
            assert variable.unit is not None, variable.name
    assert variables["Travel.EncoderPosition"].unit == "m"
    assert variables["Slew.DriveSetpoint"].unit == "N.m"
    assert variables["Luff.ReferenceAcceleration"].unit == "rad/s2"
    # One control period a step by default; the archive carries the twin's mark.
    assert float(description.defaultExperiment.stepSize) == 0.01
    with zipfile.ZipFile(short_fmu) as archive:
        assert archive.comment == b"bwr_twin.export fmu"
        assert "resources/scene.toml" in archive.namelist()


def test_a_pid_in_fmpy_reads_the_encoders_of_its_run_in_process_and_over_opc_ua(short_fmu, short_scene):
    fmu_q = fmpy_trace(short_fmu)
    np.testing.assert_array_equal(fmu_q, in_process_trace(load_scene(short_scene)))

    server = Launched(short_scene)
    try:
        wire_q, _ = asyncio.run(asyncio.wait_for(pid_session(server.ready(), PERIODS, make_pid=fmu_pid.Pid), 120))
    finally:
        assert server.stop() == 0, server.stderr
    np.testing.assert_array_equal(fmu_q, wire_q)
    assert np.ptp(fmu_q[:, :2], axis=0).min() > 0  # travel and slew did move


def test_the_seed_parameter_chooses_the_disturbances_and_the_same_seed_repeats(short_fmu, short_scene):
    seven = fmpy_trace(short_fmu, "--seed", 7)
    np.testing.assert_array_equal(seven, fmpy_trace(short_fmu, "--seed", 7))
    np.testing.assert_array_equal(seven, in_process_trace(load_scene(short_scene, {"simulation.seed": 7})))
    assert not np.array_equal(seven, fmpy_trace(short_fmu, "--seed", 8))


def test_reset_starts_the_run_again(short_fmu):
    result = json.loads(python(CHECKS, short_fmu, "reset", 100).stdout.splitlines()[-1])
    assert result["first"] == result["after_reset"]
    assert result["first"][-1] != result["first"][0]


def test_a_step_that_is_not_a_whole_number_of_periods_is_refused_and_logged(short_fmu, short_scene):
    done = python(CHECKS, short_fmu, "bad-step")
    result = json.loads(done.stdout.splitlines()[-1])
    # pythonfmu reports a step the model refuses as fmi2Discard (status 2); the model logs why.
    assert result["refused"] is not None and "status 2" in result["refused"]
    assert "is not a whole number of control periods (0.01 s)" in done.stdout
    # The refused step left the machine as it was: the two whole periods after it start at t = 0.
    samples = Lockstep([load_scene(short_scene)], nthread=1).samples
    assert result["periods_left_after"] == samples - 2


@pytest.mark.parametrize("case", ["not_fmu", "foreign_file", "no_scene"])
def test_bad_export_requests_get_one_line_and_leave_files_alone(case, short_scene, tmp_path):
    foreign = tmp_path / "theirs.fmu"
    foreign.write_bytes(b"an FMU the twin did not write")
    out, scene, expected = {
        "not_fmu": (tmp_path / "reclaimer.zip", short_scene, "must name an .fmu file"),
        "foreign_file": (foreign, short_scene, "was not written by the twin; it is left alone"),
        "no_scene": (tmp_path / "r.fmu", tmp_path / "missing.toml", "scene file not found"),
    }[case]
    done = python("-m", "bwr_twin.export", "fmu", scene, "--out", out, check=False)
    assert done.returncode == 2
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and expected in lines[0], done.stderr
    assert foreign.read_bytes() == b"an FMU the twin did not write"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["theirs.fmu"]


def test_a_scene_that_digs_publishes_its_reclaim_rate_and_instruments(tmp_path):
    """The heavy machine's belt scale and wheel current are outputs too, each period's reading the
    twin's own in process, bit for bit (the setpoints at 0: the boom sags, the wheel turns empty)."""
    out = tmp_path / "dig.fmu"
    done = python("-m", "bwr_twin.export", "fmu", "heavy_dig_pile", "--out", out)
    assert done.stdout.startswith("Python FMU (pythonfmu), FMI 2.0: the scene has a stockpile")  # the CLI's choice
    variables = {v.name: v for v in read_model_description(str(out)).modelVariables}
    for name, unit in (("ReclaimRate", "t/h"), ("BeltScale", "t/h"), ("WheelCurrent", "A")):
        assert variables[name].causality == "output" and variables[name].unit == unit
    names = ("ReclaimRate", "BeltScale", "WheelCurrent")
    done = python(ROOT / "tests" / "fmu_checks.py", out, "outputs", 60, *names)
    fmpy_values = json.loads(done.stdout.strip().splitlines()[-1])["values"]
    twin = Twin(load_scene(SCENES / "heavy_dig_pile.toml"))
    expected = []
    for _ in range(60):
        twin.advance(np.zeros(3))
        expected.append([twin.reclaim_rate(), twin.belt_scale(), twin.wheel_current()])
    assert fmpy_values == expected
    assert len({row[1] for row in expected}) > 1 and all(row[2] > 0 for row in expected)  # the noise, the idle wheel
    with zipfile.ZipFile(out) as archive:
        packed = archive.read("resources/scene.toml").decode()
    assert "bwr_heavy.xml" in packed and "/" not in packed.split("mjcf = ")[1].split("\n")[0].strip('"')


def test_the_importer_can_trim_a_bench_reclaims_slew_speed_in_place_of_its_rate_loop(tmp_path):
    """A bench reclaim's FMU takes SlewSpeedTrim while SlewSpeedTrimFromInput is true: a trim of 1
    is the scene's open loop, bit for bit; 0.5 halves the first pass's slew speed; a trim below the
    scene's trim_limits is held at them; a trim of 0 is refused."""
    from test_reclaim_plan import scene_file

    out = tmp_path / "bench.fmu"
    python("-m", "bwr_twin.export", "fmu", scene_file(tmp_path), "--out", out)
    variables = {v.name: v for v in read_model_description(str(out)).modelVariables}
    assert variables["SlewSpeedTrim"].causality == "input" and variables["SlewSpeedTrim"].unit == "1"

    def trimmed(*trim) -> dict:
        done = python(CHECKS, out, "trim", 2000, 10, *trim)  # 20 s: the approach (11.3 s), then the first pass
        return json.loads(done.stdout.splitlines()[-1])

    scene_loop, one, half, below = trimmed(), trimmed(1.0), trimmed(0.5), trimmed(0.1)
    assert one["slew_velocity"] == scene_loop["slew_velocity"]  # the scene's rate loop is open: trim 1
    assert below["slew_velocity"] == half["slew_velocity"]  # the scene's trim_limits start at 0.5
    in_pass = slice(115, 185)  # 11.5 to 18.5 s, after 10-period steps: within the first pass (11.3-19.1 s)
    fastest = np.abs(scene_loop["slew_velocity"][in_pass]).max()
    assert fastest > 1e-3  # rad/s: the pass slews
    assert np.abs(half["slew_velocity"][in_pass]).max() == pytest.approx(0.5 * fastest, rel=0.05)
    assert "status 2" in trimmed(0.0)["refused"]


def test_a_scene_with_a_neighbour_publishes_its_position_report(tmp_path):
    """The neighbour's latest position report and its time are outputs, each period's the twin's
    own in process, bit for bit, from its start at rest to its first metres of travel."""
    out = tmp_path / "two.fmu"
    python("-m", "bwr_twin.export", "fmu", "heavy_two_machines", "--out", out)
    variables = {v.name: v for v in read_model_description(str(out)).modelVariables}
    names = ("Travel.NeighbourPosition", "Slew.NeighbourPosition", "Luff.NeighbourPosition", "NeighbourReportTime")
    for name, unit in zip(names, ("m", "rad", "rad", "s")):
        assert variables[name].causality == "output" and variables[name].unit == unit
    periods = 6200  # the neighbour sets off at 60 s
    done = python(ROOT / "tests" / "fmu_checks.py", out, "outputs", periods, *names)
    fmpy_values = json.loads(done.stdout.strip().splitlines()[-1])["values"]
    twin = Twin(load_scene(SCENES / "heavy_two_machines.toml"))
    expected = []
    for _ in range(periods):
        twin.advance(np.zeros(3))
        expected.append([*twin.neighbour_position(), twin.neighbour_report_time()])
    assert fmpy_values == expected
    assert expected[-1][0] > expected[0][0] and expected[-1][3] == pytest.approx(periods * 0.01 - 0.5)
