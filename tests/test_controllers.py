"""The controller slot: the built-in baselines, an engineer's own controller copied from
docs/controllers.md, and the one-line errors of bad controller settings."""

import csv
import json
import re
import subprocess
import sys

import mujoco
import numpy as np
import pytest
from conftest import HEAVY_MJCF, ROOT, SCENES, write_short_scene

from bwr_twin.config.scene import load_scene
from bwr_twin.control import ControllerContext
from bwr_twin.control.computed_torque import ComputedTorqueController, ComputedTorqueSettings
from bwr_twin.control.pid import PidController, PidSettings
from bwr_twin.model.machine import Machine
from bwr_twin.results.rundir import timeseries_columns
from bwr_twin.sim.lockstep import lockstep_key, simulate, simulate_lockstep

DOC = ROOT / "docs" / "controllers.md"


def doc_blocks(language: str) -> list[str]:
    return re.findall(rf"```{language}\n(.*?)```", DOC.read_text(), flags=re.S)


def short_with_controller(folder, table: str):
    """The short paper scene with its [controller] table replaced."""
    def edit(text):
        start = text.index("[controller]")
        end = text.find("\n[", start + 1)
        return text[:start] + table + ("" if end < 0 else text[end:])
    return write_short_scene(folder, edit=edit)


def run_cli(*args, cwd=ROOT):
    return subprocess.run([sys.executable, "-m", "bwr_twin.run", *map(str, args)], cwd=cwd,
                          capture_output=True, text=True, timeout=600)


# --- the example of docs/controllers.md, exactly as printed ----------------------------------------


def test_the_documented_example_runs_from_a_scene(tmp_path):
    (python,) = doc_blocks("python")
    (toml,) = doc_blocks("toml")
    (tmp_path / "gravity_pd.py").write_text(python)
    scene = tmp_path / "my_scene.toml"
    base = write_short_scene(tmp_path / "base")  # the paper scene over 20 s, as the example extends
    scene.write_text(toml.replace("paper_individual_gains.toml", str(base)))
    proc = run_cli(scene, "--out", tmp_path / "out", "--no-plots")
    assert proc.returncode == 0, proc.stderr
    metrics = json.loads((tmp_path / "out" / "metrics.json").read_text())
    assert abs(metrics["travel"]["position_error_max"]) < 0.01  # m: it tracks
    recorded = json.loads((tmp_path / "out" / "scene.json").read_text())["controller"]
    assert recorded["type"] == f"{tmp_path / 'gravity_pd.py'}:GravityPD" and recorded["kp"][0] == 28000.0


def test_an_engineers_controller_runs_in_a_batch_on_spawned_workers(tmp_path):
    (python,) = doc_blocks("python")
    (tmp_path / "gravity_pd.py").write_text(python)
    short_with_controller(tmp_path, '[controller]\ntype = "gravity_pd.py:GravityPD"\n'
                                    "kp = [28000.0, 7262500.0, 5000000.0]\nkd = [28000.0, 7262500.0, 5000000.0]\n")
    (tmp_path / "sweep.toml").write_text('scene = "short.toml"\nseeds = 2\n'
                                         "[vary]\ncontroller.kp.travel = [14000.0, 28000.0]\n")
    proc = subprocess.run([sys.executable, "-m", "bwr_twin.batch", "sweep.toml", "--out", "b", "--workers", "2"],
                          cwd=tmp_path, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    assert "4 runs, 4 ok" in proc.stdout


# --- the baselines ------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", ["pid_paper", "computed_torque_paper", "pid_heavy", "computed_torque_heavy"])
def test_every_baseline_scene_tracks_the_first_minute_of_its_path(name, tmp_path):
    from bwr_twin.config.sections import ViaPoint

    scene = load_scene(SCENES / f"{name}.toml")
    first = scene.trajectory.via_points[:2]
    short = load_scene(scene.path, {"path.via_points": [
        {"t": first[0].t, "p": list(first[0].p)},
        {"t": 60.0, "p": [a + (b - a) * 60.0 / (first[1].t - first[0].t) for a, b in zip(first[0].p, first[1].p)]},
    ]})
    assert isinstance(short.trajectory.via_points[0], ViaPoint)
    result = simulate(short)
    for axis, limit in zip(("travel", "slew", "luff"), (0.02, 0.003, 0.003)):  # m, rad, rad
        assert abs(result.metrics[axis]["position_error_max"]) < limit, (axis, result.metrics[axis])
    assert result.metrics["limits"] == []


def test_each_controller_records_the_signals_it_declares_and_no_others(tmp_path):
    """A PID declares none: its run has no fuzzy or acceleration columns at all; the fuzzy
    controller records its FLC output and acceleration command, and its CSV names them with units."""
    scene = load_scene(short_with_controller(tmp_path, '[controller]\ntype = "pid"\n'
                                             "kp = [28000.0, 7262500.0, 5000000.0]\nki = [0.0, 0.0, 0.0]\n"
                                             "kd = [28000.0, 7262500.0, 5000000.0]\n"))
    pid = simulate(scene)
    assert pid.controller_signals == {} and np.isfinite(pid.drive_force_command).all()
    names, _ = timeseries_columns(pid)
    assert not [name for name in names if "fuzzy" in name or "acceleration_command" in name]

    fuzzy = simulate(load_scene(write_short_scene(tmp_path)))
    assert set(fuzzy.controller_signals) == {"fuzzy_output", "acceleration_command"}
    assert np.abs(fuzzy.controller_signals["fuzzy_output"]).max() <= 4.5  # the output universe
    names, values = timeseries_columns(fuzzy)
    column = dict(zip(names, values.T))
    np.testing.assert_array_equal(column["slew_fuzzy_output_1"], fuzzy.controller_signals["fuzzy_output"][:, 1])
    assert "luff_acceleration_command_rad/s2" in column


def test_pid_clips_to_the_drive_ratings_and_stops_winding_up():
    machine = Machine(HEAVY_MJCF)
    low, high = machine.drive_limits[:, 0], machine.drive_limits[:, 1]
    settings = PidSettings(kp=(1e9, 1e9, 1e9), ki=(1e6, 1e6, 1e6), kd=(0.0, 0.0, 0.0))
    pid = PidController(ControllerContext(runs=2, control_period=0.01, machine=machine), [settings] * 2)
    zero = np.zeros((2, 3))
    error = np.array([[1.0, 1.0, 1.0], [-1.0, -1.0, -1.0]])
    for _ in range(50):
        force = pid.compute(zero, zero, error, zero, zero, None)
    np.testing.assert_array_equal(force[0], high)
    np.testing.assert_array_equal(force[1], low)
    np.testing.assert_array_equal(pid._integral, 0.0)  # saturated the same way as the error: no wind-up
    # Back within the limits, the integral runs again and the output leaves saturation at once.
    small = 1e-4 * np.sign(error)
    force = pid.compute(zero, zero, small, zero, zero, None)
    assert np.all(np.abs(force) < np.abs(machine.drive_limits.max(axis=1))) and np.all(pid._integral != 0.0)


def test_computed_torque_is_inverse_dynamics_on_the_reference(paper_machine):
    rng = np.random.default_rng(3)
    q = rng.uniform([-20, -1.5, -0.25], [20, 1.5, 0.25], (4, 3))
    qd = rng.uniform(-0.3, 0.3, (4, 3))
    qdd = rng.uniform(-0.01, 0.01, (4, 3))
    controller = ComputedTorqueController(ControllerContext(runs=4, control_period=0.01, machine=paper_machine),
                                          [ComputedTorqueSettings(kp=(4.0,) * 3, kd=(4.0,) * 3)] * 4)
    tau = controller.compute(q, qd, q, qd, qdd, None)  # no error: tau = M qdd + bias
    data = mujoco.MjData(paper_machine.model)
    for run in range(4):
        data.qpos[:], data.qvel[:], data.qacc[:] = q[run], qd[run], qdd[run]
        mujoco.mj_inverse(paper_machine.model, data)
        # qfrc_inverse = M qacc + bias - passive: the belief leaves the damping out by design.
        np.testing.assert_allclose(tau[run], data.qfrc_inverse + data.qfrc_passive, rtol=1e-10, atol=1e-9)


def test_a_pid_gain_sweep_shares_a_lockstep_and_each_run_equals_its_run_alone(tmp_path):
    path = short_with_controller(tmp_path, '[controller]\ntype = "pid"\n'
                                 "kp = [28000.0, 7262500.0, 5000000.0]\nki = [14000.0, 3631250.0, 2500000.0]\n"
                                 "kd = [28000.0, 7262500.0, 5000000.0]\nholding_force = [0.0, 0.0, 490500.0]\n")
    scenes = [load_scene(path, {"controller.kp": [k, 7262500.0, 5000000.0], "simulation.seed": s})
              for k, s in ((14000.0, 1), (28000.0, 2), (56000.0, 3))]
    assert len({lockstep_key(s) for s in scenes}) == 1
    together = simulate_lockstep(scenes)
    alone = simulate(scenes[1])
    np.testing.assert_array_equal(together[1].q, alone.q)
    assert together[0].metrics["travel"]["position_error_rms"] > together[2].metrics["travel"]["position_error_rms"]


# --- bad settings: one line naming the file and the key ----------------------------------------------


@pytest.mark.parametrize(
    ("table", "files", "message"),
    [
        ('type = "pid"\nkp = [1.0, 1.0, 1.0]\nki = [0.0, 0.0, 0.0]\nkd = [1.0, 1.0, -1.0]\n', {},
         r"short.toml: 'controller.kd \(luff\)' must be >= 0, got -1.0"),
        ('type = "pid"\nkp = [1.0, 1.0, 1.0]\nki = [0.0, 0.0, 0.0]\nkd = [1.0, 1.0, 1.0]\noutput_gain = [1.0, 1.0, 1.0]\n',
         {}, r"short.toml: unknown key 'controller.output_gain' \(valid here: holding_force, kd, ki, kp\)"),
        ('type = "pid"\nkp = [1.0, 1.0, 1.0]\nkd = [1.0, 1.0, 1.0]\n', {}, r"short.toml: missing key 'controller.ki'"),
        ('type = "computed_torque"\nkp = "fast"\nkd = [1.0, 1.0, 1.0]\n', {},
         r"short.toml: 'controller.kp' must be a list, got str"),
        ('type = "lqr"\n', {}, r"short.toml: 'controller.type' must be one of fuzzy_model, pid, computed_torque"),
        ('type = "nowhere.py:Mine"\n', {}, r"short.toml: 'controller.type': .*nowhere.py does not exist"),
        ('type = "broken.py:Mine"\n', {"broken.py": "def f(:\n"}, r"broken.py:1: invalid syntax"),
        ('type = "plain.py:Mine"\n', {"plain.py": "class Mine:\n    pass\n"},
         r"plain.py: has no class 'Mine' derived from bwr_twin.control.Controller"),
    ],
    ids=["negative-gain", "unknown-key", "missing-key", "wrong-type", "unknown-type", "missing-file",
         "syntax-error", "not-a-controller"],
)
def test_bad_controller_settings_get_one_line(tmp_path, table, files, message):
    for name, text in files.items():
        (tmp_path / name).write_text(text)
    short_with_controller(tmp_path, "[controller]\n" + table)
    proc = run_cli("short.toml", "--out", "out", cwd=tmp_path)
    assert proc.returncode == 2 and "Traceback" not in proc.stderr, proc.stderr
    (line,) = proc.stderr.strip().splitlines()
    assert re.search(message, line), line
    assert not (tmp_path / "out").exists()


def test_a_scene_extending_another_with_another_controller_drops_the_base_settings(tmp_path):
    scene = tmp_path / "ct.toml"
    scene.write_text(f'extends = "{SCENES / "paper_individual_gains.toml"}"\n[controller]\n'
                     'type = "computed_torque"\nkp = [4.0, 4.0, 4.0]\nkd = [4.0, 4.0, 4.0]\n')
    loaded = load_scene(scene)
    assert loaded.controller.type == "computed_torque"
    assert set(loaded.controller.to_dict()) == {"type", "kp", "kd"}
    # The same type extends key by key, as any table.
    scene.write_text(f'extends = "{SCENES / "computed_torque_paper.toml"}"\n[controller]\nkp = [9.0, 9.0, 9.0]\n')
    assert load_scene(scene).controller.settings == ComputedTorqueSettings(kp=(9.0,) * 3, kd=(4.0,) * 3)


# --- a MATLAB .fis file as the fuzzy controller's rule base --------------------------------------------


def test_a_fis_rule_base_drives_the_paper_controller_exactly_as_its_toml(tmp_path):
    converted = subprocess.run([sys.executable, "-m", "bwr_twin.fis", "convert",
                                SCENES / "rulebases" / "paper_table2.toml", tmp_path / "paper.fis"],
                               capture_output=True, text=True, timeout=120)
    assert converted.returncode == 0, converted.stderr
    toml_scene = load_scene(write_short_scene(tmp_path))
    fis_scene = load_scene(toml_scene.path, {"controller.rule_base": str(tmp_path / "paper.fis")})
    np.testing.assert_array_equal(simulate(fis_scene).q, simulate(toml_scene).q)


def test_a_fis_the_paper_controller_cannot_use_gets_one_line(tmp_path):
    (tmp_path / "tipper.fis").write_text((ROOT / "tests" / "assets" / "tipper.fis").read_text())
    short_with_controller(tmp_path, '[controller]\nrule_base = "tipper.fis"\ninput_scale_e = 50.0\n'
                                    "input_scale_ec = 50.0\noutput_gain = [0.01, 0.04, 0.06]\n")
    proc = run_cli("short.toml", "--out", "out", cwd=tmp_path)
    assert proc.returncode == 2 and "Traceback" not in proc.stderr, proc.stderr
    (line,) = proc.stderr.strip().splitlines()
    assert line.startswith("error: ") and "tipper.fis" in line, line
    assert not (tmp_path / "out").exists()


# --- side by side -------------------------------------------------------------------------------------


def test_compare_runs_every_controller_on_the_same_seeds_and_writes_table_and_plots(tmp_path):
    write_short_scene(tmp_path)
    proc = subprocess.run([sys.executable, "-m", "bwr_twin.compare", "short.toml", "--controllers",
                           "paper_individual_gains", "pid_paper", "computed_torque_paper", "--seeds", "2",
                           "--out", "cmp"], cwd=tmp_path, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    out = tmp_path / "cmp"
    rows = list(csv.DictReader((out / "comparison.csv").open()))
    assert [(r["controller"], r["axis"]) for r in rows[:3]] == [("paper_individual_gains", a) for a in
                                                               ("travel", "slew", "luff")]
    assert len(rows) == 9 and all(r["seeds"] == "2" for r in rows)
    travel = {r["controller"]: float(r["position_error_max"]) for r in rows if r["axis"] == "travel"}
    assert travel["computed_torque_paper"] < travel["pid_paper"] < travel["paper_individual_gains"]
    # The table's worst max is the largest over the seeds' metrics.json, which the run directories hold.
    runs = [json.loads((out / f"pid_paper-seed={s}" / "metrics.json").read_text()) for s in (1, 2)]
    assert travel["pid_paper"] == max(abs(m["travel"]["position_error_max"]) for m in runs)
    scenes = [json.loads((out / f"{c}-seed=2" / "scene.json").read_text()) for c in travel]
    assert {s["disturbance"]["amplitude"][0] for s in scenes} == {100.0} and {s["simulation"]["seed"] for s in scenes} == {2}
    assert "| computed_torque_paper |" in (out / "comparison.md").read_text() and "**luff**" in proc.stdout
    assert (out / "errors.png").stat().st_size > 10_000 and (out / "drive_forces.png").stat().st_size > 10_000


def test_compare_refuses_bad_input_in_one_line(tmp_path):
    write_short_scene(tmp_path)
    for args, message in (
        (["--controllers", "pid_paper", "nowhere"], r"nowhere: scene file not found"),
        (["--controllers", "pid_paper", "pid_paper"], r"--controllers: two scenes share the name 'pid_paper'"),
    ):
        proc = subprocess.run([sys.executable, "-m", "bwr_twin.compare", "short.toml", *args, "--out", "cmp"],
                              cwd=tmp_path, capture_output=True, text=True, timeout=600)
        assert proc.returncode == 2 and "Traceback" not in proc.stderr, proc.stderr
        (line,) = proc.stderr.strip().splitlines()
        assert re.search(message, line), line
        assert not (tmp_path / "cmp").exists()
