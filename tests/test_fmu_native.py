"""The native FMU (`python -m bwr_twin.export fmu`, docs/fmu.md): C over MuJoCo's C library, FMI 2.0
and 3.0, loaded as the engineer's tools load it.

- A C host (tests/fmi_host.c, compiled here) dlopens it with no Python in the process, steps the
  paper's whole 700 s path, and under valgrind leaks nothing; it tries every call in every state.
- Its trace under a PD equals the twin's own in process (bwr_twin.sim.twin.Twin) with the
  disturbances off; with them on, their amplitudes and hold time match the twin's.
- FMPy, installed alone in a fresh virtual environment, validates and simulates it.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path
from xml.etree import ElementTree

import numpy as np
import pytest
from conftest import ROOT, SCENES
from scipy import stats

from bwr_twin.config.scene import load_scene
from bwr_twin.sim.disturbances import Disturbances
from bwr_twin.sim.parameters import RunParameters
from bwr_twin.sim.twin import Twin

NATIVE = ROOT / "bwr_twin" / "export" / "native"
PAPER = SCENES / "pid_paper.toml"
PATH_PERIODS = 70001  # the paper's 700 s path at 10 ms, both ends included
TRACE_PERIODS = 3000
# examples/fmu_pid.py's gains without the integral, as tests/fmi_host.c computes them
KP = np.array([28000.0, 7262500.0, 5000000.0])
KD = np.array([28000.0, 7262500.0, 5000000.0])
HOLD = np.array([0.0, 0.0, 490500.0])


def export(scene, out: Path, fmi: int) -> subprocess.CompletedProcess:
    done = subprocess.run([sys.executable, "-m", "bwr_twin.export", "fmu", str(scene), "--out", str(out),
                           "--fmi", str(fmi)], cwd=ROOT, capture_output=True, text=True, timeout=300, check=False)
    assert done.returncode == 0, done.stderr
    return done


@pytest.fixture(scope="module")
def fmus(tmp_path_factory) -> dict[int, Path]:
    """The paper scene's FMU in each FMI version, unzipped beside it."""
    folder = tmp_path_factory.mktemp("native_fmu")
    built = {}
    for fmi in (2, 3):
        out = folder / f"paper{fmi}.fmu"
        done = export(PAPER, out, fmi)
        assert done.stdout.splitlines()[0] == f"native FMU, FMI {fmi}.0: C and MuJoCo's C library, no Python inside"
        with zipfile.ZipFile(out) as archive:
            archive.extractall(folder / f"paper{fmi}")
        built[fmi] = out
    return built


@pytest.fixture(scope="module")
def host(tmp_path_factory) -> Path:
    """tests/fmi_host.c compiled with the FMI headers the FMU carries."""
    binary = tmp_path_factory.mktemp("host") / "fmi_host"
    subprocess.run(["cc", "-std=c11", "-O2", "-Wall", "-Werror", f"-I{NATIVE / 'fmi'}", str(ROOT / "tests" / "fmi_host.c"),
                    "-o", str(binary), "-ldl", "-lm"], check=True, timeout=120)
    return binary


def host_environment(fmu: Path) -> dict[str, str]:
    """The FMU's GUID and each variable's value reference, as the host reads them."""
    with zipfile.ZipFile(fmu) as archive:
        root = ElementTree.fromstring(archive.read("modelDescription.xml"))
    environment = {**os.environ, "FMU_GUID": root.get("guid") or root.get("instantiationToken")}
    for variable in root.find("ModelVariables"):
        environment[f"VR_{variable.get('name').replace('.', '_')}"] = variable.get("valueReference")
    return environment


def run_host(host: Path, fmu: Path, *arguments, valgrind: bool = False,
             folder: Path | None = None) -> subprocess.CompletedProcess:
    """The host on `fmu` unzipped (beside it, or in `folder`)."""
    command = [str(host), str(folder or fmu.with_suffix("")), *map(str, arguments)]
    if valgrind:
        command = ["valgrind", "-q", "--leak-check=full", "--errors-for-leak-kinds=definite", "--error-exitcode=3",
                   f"--suppressions={ROOT / 'tests' / 'valgrind.supp'}", *command]
    return subprocess.run(command, capture_output=True, text=True, timeout=600, env=host_environment(fmu), check=False)


@pytest.mark.parametrize("fmi", [2, 3])
def test_a_c_host_steps_the_whole_paper_path_with_no_python_in_the_process(fmi, fmus, host):
    library = fmus[fmi].with_suffix("") / "binaries" / ("linux64" if fmi == 2 else "x86_64-linux") / "BwrReclaimer.so"
    undefined = subprocess.run(["nm", "-D", "--undefined-only", str(library)], capture_output=True, text=True,
                               check=True).stdout
    assert "Py" not in undefined and "mj_step" in undefined  # MuJoCo's C library, no Python's
    needed = subprocess.run(["readelf", "-d", str(library)], capture_output=True, text=True, check=True).stdout
    assert "[$ORIGIN]" in needed and "libpython" not in needed
    done = run_host(host, fmus[fmi], "run", fmi, PATH_PERIODS, "quiet")
    assert done.returncode == 0, done.stderr
    assert done.stdout.split()[:2] == ["end", "0"]  # PeriodsLeft 0: the path's end
    if fmi == 3:
        assert done.stdout.split()[2:] == ["terminate", "1"]


@pytest.mark.parametrize("fmi", [2, 3])
def test_under_valgrind_the_host_leaks_nothing_and_reads_no_memory_it_should_not(fmi, fmus, host):
    """Fewer periods than the whole path (300), and the rules' six instances: valgrind runs 50
    times slower; a leak per instance or per period would show all the same."""
    for arguments in (("run", fmi, 300, "quiet"), ("rules", fmi)):
        done = run_host(host, fmus[fmi], *arguments, valgrind=True)
        assert done.returncode == 0, done.stderr[-3000:]


def in_process_trace(scene, periods: int) -> np.ndarray:
    """The twin's encoder positions under the host's PD, period by period."""
    twin, trace = Twin(scene), []
    for _ in range(periods):
        q, qd, q_ref, qd_ref, _ = (np.array(values) for values in twin.measured)
        trace.append(q)
        twin.advance(HOLD + KP * (q_ref - q) + KD * (qd_ref - qd))
    return np.array(trace)


@pytest.mark.parametrize("fmi", [2, 3])
def test_the_trace_equals_the_twins_in_process_with_the_disturbances_off(fmi, fmus, host):
    done = run_host(host, fmus[fmi], "run", fmi, TRACE_PERIODS)
    assert done.returncode == 0, done.stderr
    native = np.loadtxt(done.stdout.splitlines()[:-1])
    twin = in_process_trace(load_scene(PAPER, {"disturbance.amplitude": [0.0, 0.0, 0.0]}), TRACE_PERIODS)
    scale = np.maximum(np.abs(twin).max(axis=0), 1e-12)  # m, rad: the luff rests on this stretch
    assert np.ptp(twin[:, :2], axis=0).min() > 0.01  # travel and slew did move
    assert (np.abs(native - twin) / scale).max() <= 1e-9  # in fact bit for bit: the same compiled model and steps
    np.testing.assert_array_equal(native, twin)


def test_the_disturbances_have_the_twins_amplitudes_and_hold_time(fmus, host):
    """Seeded in C with a generator of its own, so not the twin's numbers: the twin's law. Each
    axis's draws uniform in [-amplitude, amplitude] (two-sample Kolmogorov-Smirnov against the
    twin's, and the moments), held for the hold time: new draws at the same periods as the twin's."""
    periods, hold, seed = 20000, 0.05, 11
    done = run_host(host, fmus[2], "disturbance", 2, periods, seed, hold)
    assert done.returncode == 0, done.stderr
    native = np.loadtxt(done.stdout.splitlines())
    scene = load_scene(PAPER, {"disturbance.hold_time": hold, "simulation.seed": seed})
    forces = Disturbances(RunParameters.of([scene]), scene.simulation.control_period).forces
    twin = np.array([forces.sample(k)[0] for k in range(periods)])
    amplitude = np.array(scene.disturbance.amplitude)
    for axis in range(3):
        changes = [np.flatnonzero(np.diff(trace[:, axis])) for trace in (native, twin)]
        np.testing.assert_array_equal(changes[0], changes[1])  # new draws at the same periods: every 5th
        assert set(np.diff(changes[0])) == {5}
        draws = [trace[np.r_[0, changes[0] + 1], axis] for trace in (native, twin)]
        assert np.abs(draws[0]).max() <= amplitude[axis]
        assert stats.ks_2samp(draws[0] / amplitude[axis], draws[1] / amplitude[axis]).pvalue > 1e-3
        assert abs(draws[0].mean()) < 0.03 * amplitude[axis]  # 4000 draws: 3.5 standard errors
        assert draws[0].std() == pytest.approx(amplitude[axis] / np.sqrt(3), rel=0.03)
    again = run_host(host, fmus[2], "disturbance", 2, 200, seed, hold)
    other = run_host(host, fmus[2], "disturbance", 2, 200, seed + 1, hold)
    np.testing.assert_array_equal(np.loadtxt(again.stdout.splitlines()), native[:200])  # the seed decides
    assert not np.array_equal(np.loadtxt(other.stdout.splitlines()), native[:200])


# The calls that succeed, by state; every other call in every state is fmiError with its reason
# logged, and every call with a null instance fmiError.
READS = {"initialization", "step", "terminated", "error"}
ALLOWED = {
    2: {"SetDebugLogging": {"instantiated", *READS}, "SetupExperiment": {"instantiated"},
        "EnterInitializationMode": {"instantiated"}, "ExitInitializationMode": {"initialization"},
        "Terminate": {"step"}, "Reset": {"instantiated", *READS}, "GetReal": READS, "GetInteger": READS,
        "GetBoolean": READS, "SetReal(input)": {"instantiated", "initialization", "step"},
        "SetReal(parameter)": {"instantiated", "initialization"}, "SetInteger(parameter)": {"instantiated", "initialization"},
        "DoStep": {"step"}, "GetRealStatus": {"step", "error"}, "GetBooleanStatus": {"step", "error"}},
    3: {"SetDebugLogging": {"instantiated", *READS}, "EnterInitializationMode": {"instantiated"},
        "ExitInitializationMode": {"initialization"}, "Terminate": {"step"}, "Reset": {"instantiated", *READS},
        "GetFloat64": READS, "GetInt32": READS, "GetBoolean": READS,
        "SetFloat64(input)": {"instantiated", "initialization", "step"},
        "SetFloat64(parameter)": {"instantiated", "initialization"},
        "SetInt32(parameter)": {"instantiated", "initialization"}, "DoStep": {"step"}},
}


@pytest.mark.parametrize("fmi", [2, 3])
def test_every_call_in_every_state_is_valid_or_refused_with_a_logged_reason(fmi, fmus, host):
    done = run_host(host, fmus[fmi], "states", fmi)
    assert done.returncode == 0, done.stderr  # no crash, whatever was called
    rows = [line.split() for line in done.stdout.splitlines()]
    calls = {call for _, call, _, _ in rows}
    assert len(rows) == 6 * len(calls) and len(calls) == (31 if fmi == 2 else 27)
    for state, call, status, logged in rows:
        if state == "null":  # no instance: an error, with no instance's logger to say why
            assert status == "3", (call, status)
            continue
        expected_ok = state in ALLOWED[fmi].get(call, set())
        assert (status == "0") == expected_ok, (state, call, status)
        if status != "0":
            assert status == "3" and int(logged) >= 1, (state, call, status, logged)  # fmiError, and why

    rules = run_host(host, fmus[fmi], "rules", fmi)
    assert rules.returncode == 0, rules.stderr
    results = dict(line.split(" ", 1) for line in rules.stdout.splitlines())
    assert all(result.startswith("ok") for result in results.values()), results
    assert "not a whole number of control periods (0.01 s)" in results["non-whole-step-refused"]
    assert "must be a finite number" in results["nan-and-inf-refused" if fmi == 2 else "nan-refused"]
    assert "is a fixed parameter" in results["fixed-parameter-after-init-refused"]


def test_fmpy_alone_in_a_fresh_environment_validates_and_simulates_both_versions(fmus, fmpy_alone):
    for samples, periods_left, position in fmpy_alone(*fmus.values()):
        assert samples == 201 and periods_left == PATH_PERIODS - 200 and position != 0.0


def test_the_cli_keeps_the_python_fmu_for_a_scene_c_does_not_carry_and_says_why(tmp_path):
    out = tmp_path / "dig.fmu"
    done = subprocess.run([sys.executable, "-m", "bwr_twin.export", "fmu", "heavy_dig_pile", "--out", str(out),
                           "--fmi", "3"], cwd=ROOT, capture_output=True, text=True, timeout=300, check=False)
    assert done.returncode == 2 and not out.exists()
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and "--fmi 3 is the native FMU's, but the scene has a stockpile" in lines[0], done.stderr


def test_without_a_c_compiler_the_export_says_so_in_one_line(tmp_path):
    empty = tmp_path / "bin"
    empty.mkdir()
    out = tmp_path / "paper.fmu"
    environment = {key: value for key, value in os.environ.items() if key != "CC"} | {"PATH": str(empty)}
    done = subprocess.run([sys.executable, "-m", "bwr_twin.export", "fmu", str(PAPER), "--out", str(out)], cwd=ROOT,
                          capture_output=True, text=True, timeout=300, env=environment, check=False)
    assert done.returncode == 2 and not out.exists()
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: no C compiler found"), done.stderr
    assert shutil.which("cc") is not None  # this machine has one: the refusal came from the PATH given


def test_the_wind_from_its_input_acts_as_the_twins_mean_wind(tmp_path):
    """The heavy machine (its boom and wheel have wind areas) on the paper's path in a 20 m/s wind
    across the rail, no stockpile: WindSpeed and AirDensity start at the scene's, and the encoders
    are the twin's bit for bit (the setpoints at 0); still air gives another trace."""
    from fmpy import read_model_description
    from fmpy.fmi2 import FMU2Slave

    from bwr_twin.export.native_fmu import export_native_fmu

    windy = {"machine.mjcf": str(ROOT / "mjcf" / "bwr_heavy.xml"), "plant.wind_speed": 20.0,
             "plant.wind_direction": 90.0, "plant.air_density": 1.204, "disturbance.amplitude": [0.0, 0.0, 0.0]}
    scene = load_scene(PAPER, windy)
    out = export_native_fmu(scene, tmp_path / "wind.fmu")
    with zipfile.ZipFile(out) as archive:
        archive.extractall(tmp_path / "wind")
    description = read_model_description(str(out))
    refs = {v.name: v.valueReference for v in description.modelVariables}
    fmu = FMU2Slave(guid=description.guid, unzipDirectory=str(tmp_path / "wind"), modelIdentifier="BwrReclaimer",
                    instanceName="wind")
    fmu.instantiate()
    fmu.setupExperiment(startTime=0.0)
    fmu.enterInitializationMode()
    fmu.exitInitializationMode()
    assert fmu.getReal([refs["WindSpeed"], refs["AirDensity"]]) == [20.0, 1.204]
    positions = [refs[f"{axis}.EncoderPosition"] for axis in ("Travel", "Slew", "Luff")]
    native = []
    for k in range(300):
        native.append(fmu.getReal(positions))
        fmu.doStep(k * 0.01, 0.01)
    fmu.terminate()
    fmu.freeInstance()

    def twin_trace(scene) -> np.ndarray:
        twin, trace = Twin(scene), []
        for _ in range(300):
            trace.append(twin.measured[0])
            twin.advance([0.0, 0.0, 0.0])
        return np.array(trace)

    np.testing.assert_array_equal(np.array(native), twin_trace(scene))
    assert not np.array_equal(np.array(native), twin_trace(load_scene(PAPER, windy | {"plant.wind_speed": 0.0})))


@pytest.mark.parametrize("fmi", [2, 3])
def test_the_fmus_sources_build_its_library_again_as_the_docs_say(fmi, fmus, host, tmp_path):
    """docs/fmu.md's Linux command, run on sources/ alone (with the mujoco wheel's headers), makes a
    library the host runs: what an engineer does on another platform with that platform's compiler."""
    import mujoco

    unzipped = tmp_path / f"rebuilt{fmi}"
    shutil.copytree(fmus[fmi].with_suffix(""), unzipped)
    platform = unzipped / "binaries" / ("linux64" if fmi == 2 else "x86_64-linux")
    (platform / "BwrReclaimer.so").unlink()
    if fmi == 3:
        listed = ElementTree.parse(unzipped / "sources" / "buildDescription.xml").iter("SourceFile")
    else:
        listed = ElementTree.parse(unzipped / "modelDescription.xml").find("CoSimulation/SourceFiles").iter("File")
    files = [str(unzipped / "sources" / element.get("name")) for element in listed]
    assert [Path(f).name for f in files] == ["reclaimer.c", f"fmi{fmi}.c"]
    include = Path(mujoco.__file__).parent / "include"
    subprocess.run(["cc", "-std=c11", "-O2", "-fPIC", "-shared", "-fvisibility=hidden", f"-I{unzipped / 'sources'}",
                    f"-I{include}", *files, "-o", str(platform / "BwrReclaimer.so"), f"-L{platform}",
                    "-l:libmujoco.so.4.0.1", "-Wl,-rpath,$ORIGIN", "-lm"], check=True, timeout=120)
    done = run_host(host, fmus[fmi], "run", fmi, 100, "quiet", folder=unzipped)
    assert done.returncode == 0, done.stderr
    assert done.stdout.split()[:2] == ["end", str(PATH_PERIODS - 100)]
