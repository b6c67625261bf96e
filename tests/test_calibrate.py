"""Calibration (bwr_twin.calibrate) with the real mujoco.sysid on logs the twin writes: the heavy
machine with numbers the fit does not know (a variant of mjcf/bwr_heavy.xml written through the
same in-place editing the calibration uses, or the scene's plant friction), a short test motion
run by the twin, and the nominal model calibrated back from its log."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from bwr_twin.calibrate.cli import main as calibrate
from bwr_twin.calibrate.fit import Problem, fit
from bwr_twin.calibrate.log import read_log
from bwr_twin.calibrate.mjcf_edit import edit
from bwr_twin.calibrate.parameters import catalogue
from bwr_twin.calibrate.plan import scene_for
from bwr_twin.model.machine import Machine
from bwr_twin.run import main as run

HEAVY = Path(__file__).resolve().parent.parent / "mjcf" / "bwr_heavy.xml"

# Joint values (travel m, slew rad, luff rad) at times (s): each axis both ways at two speeds,
# the luff at several angles; 90 s.
MOVES = [(0.0, (0.0, 0.0, 0.0)), (15.0, (3.0, 0.08, 0.02)), (20.0, (3.0, 0.08, 0.02)),
         (35.0, (0.5, -0.02, -0.01)), (40.0, (0.5, -0.02, -0.01)), (50.0, (2.0, 0.04, 0.01)),
         (55.0, (2.0, 0.04, 0.01)), (75.0, (-1.0, -0.05, 0.04)), (90.0, (-1.0, -0.05, 0.04))]
TRAVEL_ONLY = [(0.0, (0.0, 0.0, 0.0)), (15.0, (3.0, 0.0, 0.0)), (20.0, (3.0, 0.0, 0.0)),
               (35.0, (0.0, 0.0, 0.0)), (40.0, (0.0, 0.0, 0.0)), (50.0, (2.0, 0.0, 0.0)),
               (60.0, (2.0, 0.0, 0.0))]


def variant(folder: Path, changes: list[tuple[str, str, str, int, str, str]]) -> Path:
    """folder/variant.xml: the heavy machine with `changes` made (mjcf_edit.edit's form)."""
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / "variant.xml"
    path.write_text(edit(HEAVY.read_text(), changes))
    return path


def twin_log(folder: Path, mjcf: Path, moves=MOVES, plant: str = "") -> Path:
    """The run directory of the twin moving the machine of `mjcf` through `moves`, `plant` a
    [plant] table's lines."""
    machine = Machine(mjcf)
    times = np.array([t for t, _ in moves])
    points = np.array([q for _, q in moves])
    scene = folder / "test.toml"
    text = scene_for(machine, mjcf, scene, times, points, ["# a test motion"])
    scene.write_text(text + (f"\n[plant]\n{plant}\n" if plant else ""))
    assert run([str(scene), "--out", str(folder / "log"), "--no-plots"]) == 0
    return folder / "log"


def fitted(log: Path, names: list[str], **options):
    machine = Machine(HEAVY)
    return fit(Problem(machine, catalogue(machine, names), [read_log(log, machine)], **options))


def estimate(result, name):
    return next(e for e in result.estimates if e.knob.name == name)


def test_viscous_damping_is_recovered(tmp_path):
    mjcf = variant(tmp_path, [("joint", "travel", "damping", 0, "7.0e4", "30 % more"),
                              ("joint", "slew", "damping", 0, "5.0e7", "23 % less")])
    result = fitted(twin_log(tmp_path, mjcf), ["travel_damping", "slew_damping"])
    for name, truth in (("travel_damping", 7.0e4), ("slew_damping", 5.0e7)):
        e = estimate(result, name)
        assert e.identifiable and e.fitted == pytest.approx(truth, rel=0.05), (name, e)
    fitted_axes = [0, 1, 3, 4]  # the travel's and the slew's positions and speeds
    assert (result.rms_after[fitted_axes] < result.rms_before[fitted_axes]).all()


def test_coulomb_friction_is_recovered_and_written_into_the_mjcf(tmp_path):
    truth = [4.0e4, 2.0e5, 8.0e5]
    log = twin_log(tmp_path, HEAVY, plant=f"frictionloss = [{', '.join(map(str, truth))}]")
    out = tmp_path / "calibration"
    names = ["travel_frictionloss", "slew_frictionloss", "luff_frictionloss"]
    assert calibrate(["fit", str(log), "--model", str(HEAVY), "--out", str(out), "--params", *names]) == 0
    summary = json.loads((out / "calibration.json").read_text())
    for name, value in zip(names, truth, strict=True):
        entry = summary["parameters"][name]
        assert entry["identifiable"] and entry["fitted"] == pytest.approx(value, rel=0.05), (name, entry)
        assert entry["interval_95"][0] < entry["fitted"] < entry["interval_95"][1]
    for column, rms in summary["residual_rms"].items():
        assert rms["calibrated"] < rms["nominal"], column
    # The engineer's file as written, but for the three joints: each gains its number and a comment.
    before, after = HEAVY.read_text().splitlines(), (out / "calibrated.xml").read_text().splitlines()
    assert len(before) == len(after)
    changed = [(a, b) for a, b in zip(before, after, strict=True) if a != b]
    assert len(changed) == 3
    for (old, new), joint in zip(changed, ("travel", "slew", "luff"), strict=True):
        assert f'name="{joint}"' in old and 'frictionloss="' in new and "frictionloss was 0 N" in new
        assert f"calibrated from {log}" in new
    calibrated = Machine(out / "calibrated.xml")
    np.testing.assert_allclose(calibrated.model.dof_frictionloss[:3], truth, rtol=0.05)


def test_reflected_drive_inertia_is_recovered(tmp_path):
    mjcf = variant(tmp_path, [("joint", "travel", "armature", 0, "4.0e5", "a third of the carriage"),
                              ("joint", "slew", "armature", 0, "2.5e8", "a third of the slewing part")])
    result = fitted(twin_log(tmp_path, mjcf), ["travel_armature", "slew_armature"])
    own = {"travel_armature": 1.193e6, "slew_armature": 7.056e8}  # kg, kg m^2: the axes' own inertia at the start
    for name, truth in (("travel_armature", 4.0e5), ("slew_armature", 2.5e8)):
        e = estimate(result, name)
        # The drive's share within 10 %, the axis's whole inertia (what moves it) within 2 %.
        assert e.identifiable and e.fitted == pytest.approx(truth, rel=0.1), (name, e)
        assert own[name] + e.fitted == pytest.approx(own[name] + truth, rel=0.02), (name, e)


def test_counterweight_mass_is_recovered(tmp_path):
    mjcf = variant(tmp_path, [("body", "boom_counterweight", "mass", 0, "3.6e5", "9 % heavier")])
    result = fitted(twin_log(tmp_path, mjcf), ["boom_counterweight_mass"])
    e = estimate(result, "boom_counterweight_mass")
    assert e.identifiable and e.fitted == pytest.approx(3.6e5, rel=0.02), e


def test_a_parameter_the_log_cannot_determine_is_named_and_left_alone(tmp_path, capsys):
    log = twin_log(tmp_path, HEAVY, TRAVEL_ONLY, plant="frictionloss = [4.0e4, 2.0e5, 8.0e5]")
    out = tmp_path / "calibration"
    assert calibrate(["fit", str(log), "--model", str(HEAVY), "--out", str(out), "--params",
                      "travel_frictionloss", "slew_frictionloss"]) == 0
    summary = json.loads((out / "calibration.json").read_text())
    slew = summary["parameters"]["slew_frictionloss"]
    assert not slew["identifiable"] and slew["left_at_nominal"] and slew["fitted"] == slew["nominal"] == 0.0
    assert "slew" in slew["test_motion"]
    travel = summary["parameters"]["travel_frictionloss"]
    assert travel["identifiable"] and travel["fitted"] == pytest.approx(4.0e4, rel=0.05)
    printed = capsys.readouterr().out
    assert "slew_frictionloss" in printed and "not determined by these logs" in printed
    text = (out / "calibrated.xml").read_text()
    assert '<joint name="slew" class="slew"/>\n' in text  # the slew's line as written
