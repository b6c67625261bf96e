"""The automation on its own senses: a bench reclaim planned on the pile its survey scanned, the
rate instruments it trims from, and the scheduled faults as the controller sees them."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from conftest import SCENES
from test_reclaim_plan import scene_file

from bwr_twin import SceneError
from bwr_twin.config.builder import build
from bwr_twin.config.scene import load_scene
from bwr_twin.config.sections import RateControlSection
from bwr_twin.control.rate import PowerAndScale, RateSignals, WheelCalibration
from bwr_twin.model.instruments import BeltScaleSpec, WheelMotorSpec
from bwr_twin.model.machine import Machine
from bwr_twin.planning.bench import plan_after_survey, plan_scene
from bwr_twin.results.rundir import write_run
from bwr_twin.sensing.rate_instruments import RateInstruments
from bwr_twin.sim.lockstep import simulate
from bwr_twin.units import KG_PER_T, SECONDS_PER_HOUR

# The small bench scene surveyed first: from where it starts, the boom slews across the small
# windrow and back, its fan sweeping the pile 10-25 m beyond the wheel head.
SURVEY = '\n[reclaim.survey]\nwaypoints = [[-49.0, 25.0, -7.0], [-49.0, 70.0, -7.0], [-49.0, 44.0, -7.0]]\n'
SCANNED = '\n[sensing]\npile_model = "scanned"\n'
FINE = {"stockpile.grid_spacing": 0.25}  # the heavy scenes' cells: a scan's bias on a slope is up to half a cell


@pytest.fixture(scope="module")
def scanned_run(tmp_path_factory):
    """The small bench scene planned on its scanned pile, simulated once."""
    folder = tmp_path_factory.mktemp("scanned")
    return simulate(load_scene(scene_file(folder, extra=SURVEY + SCANNED), FINE)), folder


def test_the_benches_are_planned_on_the_scanned_pile_as_the_survey_ends(scanned_run):
    """The plan starts with the survey's moves and lands on the face it scanned: the scanned
    pile's tonnes at the plan's start near the truth over the cells seen, and the
    wheel meeting the true face within 0.2 m of where the plan on the scanned pile said."""
    result, _ = scanned_run
    scan, reclaim = result.metrics["scan"], result.metrics["reclaim"]
    names = result.metrics["run"]["waypoint_names"]
    assert names[:3] == ["survey"] * 3 and names[3] == "bench 1"
    survey_end = sum(s.duration for s in plan_scene(result.scene).segments[:3])
    start = scan["plan_start"]
    assert start["time_s"] == pytest.approx(survey_end)
    assert start["footprint_seen_share"] > 0.5
    # The latest scan of a cell is of the part the scan plane left last, up to half a cell from
    # its centre: on this 4 m windrow's 37 deg faces and 0.5 m cells that is some 4 %; on
    # heavy_scanned_reclaim's 15 m windrow and 0.25 m cells, under 0.1 % (docs/sensing.md).
    assert abs(start["error_share"]) < 0.05, start
    assert reclaim["landing_error_m"] < 0.2
    assert reclaim["first_contact_time_s"] > survey_end
    assert reclaim["bench_t"][0] > 0.5 * reclaim["bench_planned_t"][0]


def test_the_survey_file_keeps_the_pile_known_at_the_plan_s_start(scanned_run, tmp_path):
    result, _ = scanned_run
    write_run(result, tmp_path / "run")
    known = np.load(tmp_path / "run" / "survey.npz")
    assert {"z_plan", "seen_plan", "last_seen_plan", "t_plan", "t_end"} <= set(known)
    assert float(known["t_plan"]) == result.metrics["scan"]["plan_start"]["time_s"]
    assert np.nanmax(known["last_seen_plan"]) <= float(known["t_plan"])
    assert (known["seen"] >= known["seen_plan"]).all() and known["seen"].sum() > known["seen_plan"].sum()


def test_the_plan_on_the_scans_is_the_plan_on_the_truth_but_for_the_scans_error(scanned_run, tmp_path):
    """Planned again on the pile the run knew at the plan's start, the plan is the run's; on the
    true pile from the same survey, it has the same passes, the first a few centimetres apart."""
    result, _ = scanned_run
    scene = result.scene
    scanned = plan_after_survey(scene, Machine(scene.machine.mjcf), result.scan.plan_start.z)
    exact = plan_scene(load_scene(scene_file(tmp_path, extra=SURVEY), FINE))
    assert scanned.first_contact is not None and len(scanned.passes) == len(exact.passes) > 0
    assert [p.bench for p in scanned.passes] == [p.bench for p in exact.passes]
    assert abs(scanned.passes[0].travel - exact.passes[0].travel) < 0.1
    # The first touch lies along the approach, nearly parallel to the face's slope: a few
    # centimetres of scanned height move it decimetres along the move.
    assert np.linalg.norm(scanned.first_contact - exact.first_contact) < 0.5
    for ours, theirs in zip(scanned.segments[:3], exact.segments[:3]):  # the survey, planned without the pile
        assert ours.duration == theirs.duration and (ours.end == theirs.end).all()


def test_a_scanned_plan_needs_a_survey_and_scanners(tmp_path):
    with pytest.raises(SceneError, match=r"needs a \[reclaim.survey\] to scan it first: give its 'waypoints'"):
        simulate(load_scene(scene_file(tmp_path, extra=SCANNED)))
    with pytest.raises(SceneError, match=r"'sensing.pile_model' \"scanned\" needs the scanners, but "
                                          r"'sensing.scanners' is false"):
        load_scene(scene_file(tmp_path, extra=SURVEY + SCANNED + "scanners = false\n"))


def test_the_belt_scale_reads_the_rate_a_transport_delay_late():
    """Without noise or filter the scale reads exactly the rate delay / period periods earlier;
    frozen, it holds its reading; the wheel current is the power as the motor draws it."""
    scale = BeltScaleSpec(distance=9.0, speed=4.5, noise=(0.0, 0.0), filter_time=0.0)
    motor = WheelMotorSpec(voltage=690.0, efficiency=0.95, power_factor=0.86, noise=(0.0, 0.0))
    instruments = RateInstruments(scale, motor, [1, 2], 0.1)
    assert instruments.delay_periods == 20
    rates = np.arange(60.0)[:, None] * [1.0, 2.0]
    seen = []
    for k, rate in enumerate(rates):
        instruments.read(k, rate, 1e6 * rate, scale_frozen=40 <= k < 45)
        seen.append(instruments.belt_scale.copy())
        np.testing.assert_allclose(instruments.wheel_current, 1e6 * rate / (np.sqrt(3) * 690 * 0.86 * 0.95))
        np.testing.assert_allclose(instruments.wheel_power, 1e6 * rate)
    seen = np.array(seen)
    np.testing.assert_array_equal(seen[:20], 0.0)
    np.testing.assert_array_equal(seen[20:40], rates[:20])
    np.testing.assert_array_equal(seen[40:45], np.repeat(rates[19:20], 5, axis=0))  # frozen
    np.testing.assert_array_equal(seen[45:], rates[25:40])


def test_the_instruments_noise_is_the_data_sheet_s_and_the_run_s_own():
    scale = BeltScaleSpec(distance=4.5, speed=4.5, noise=(20.0, 0.01), filter_time=0.0)
    one, two = RateInstruments(scale, None, [7], 0.01), RateInstruments(scale, None, [7, 8], 0.01)
    readings = []
    for k in range(5000):
        for instruments in (one, two):
            instruments.read(k, np.full(instruments.belt_scale.shape, 8000.0), np.zeros(instruments.belt_scale.shape))
        readings.append(two.belt_scale.copy())
        assert one.belt_scale[0] == two.belt_scale[0]  # a run's readings are its seed's alone
    after = np.array(readings)[200:]
    assert np.std(after[:, 0]) == pytest.approx(20.0 + 80.0, rel=0.05)
    assert np.mean(after[:, 0]) == pytest.approx(8000.0, abs=5.0)
    assert np.isnan(one.wheel_current).all()


def test_a_rate_loop_without_its_instrument_is_refused(tmp_path):
    (tmp_path / "noscale.xml").write_text(
        (SCENES.parent / "mjcf" / "bwr_heavy.xml").read_text().replace('name="belt_scale_distance"', 'name="x_a"')
        .replace('name="belt_speed"', 'name="x_b"').replace('name="belt_scale_noise"', 'name="x_c"')
        .replace('name="belt_scale_filter"', 'name="x_d"'))
    assert Machine(tmp_path / "noscale.xml").belt_scale is None
    path = scene_file(tmp_path, extra=f'\n[machine]\nmjcf = "{tmp_path / "noscale.xml"}"\n[sensing]\n'
                                      'rate_signals = "measured"\n[reclaim.rate_control]\ntype = "belt_scale"\n')
    with pytest.raises(SceneError, match=r"'reclaim.rate_control.type' \"belt_scale\" reads a belt scale, but "
                                          r"noscale.xml describes none \(custom numeric 'belt_scale_distance'"):
        simulate(load_scene(path))
    both = path.read_text().replace('type = "belt_scale"', 'type = "power_and_scale"')
    path.write_text(both)
    with pytest.raises(SceneError, match=r"'reclaim.rate_control.type' \"power_and_scale\" reads a belt scale, "
                                          r"but noscale.xml"):
        simulate(load_scene(path))


def test_the_belt_scale_calibrates_the_power_the_loop_trims_from():
    """The automation assumes a cutting energy 20 % low: the power alone then reads the rate 25 %
    high; once the scale has weighed enough, the scale's tonnes over the power's a belt delay
    earlier bring the loop's reading to the true rate, the pulses of the face and all."""
    period, delay, target = 0.1, 2.0, np.array([8000.0, 8000.0])
    settings = build(RateControlSection, {"type": "power_and_scale", "calibration_time": 60.0}, Path("scene.toml"),
                     "reclaim.rate_control")  # the other keys from the shipped defaults
    true_energy, density, idle = 6.0e5, 2200.0, 3.0e5
    wheel = WheelCalibration(idle_power=np.full(2, idle), cutting_energy=np.array([0.8, 1.0]) * true_energy,
                             bulk_density=np.full(2, density), belt_delay=delay)
    loop = PowerAndScale(settings, target, period, wheel)
    steps = round(400.0 / period)
    time = np.arange(steps) * period
    rate = 8000.0 * (1.0 + 0.3 * np.sin(2 * np.pi * time / 40.0))  # t/h, the face rising and falling
    power = idle + rate / (SECONDS_PER_HOUR / KG_PER_T) / density * true_energy
    lag = round(delay / period)
    seen = np.empty((steps, 2))
    for k in range(steps):
        weighed = rate[k - lag] if k >= lag else 0.0
        signals = RateSignals(np.full(2, weighed), np.full(2, power[k]), np.ones(2, bool), np.ones(2, bool))
        seen[k] = loop.measured(signals)
    assert seen[5, 0] == pytest.approx(1.25 * rate[5])  # before the scale has weighed enough
    np.testing.assert_allclose(loop.correction, [0.8, 1.0], rtol=1e-3)
    np.testing.assert_allclose(seen[-1000:], np.column_stack([rate[-1000:]] * 2), rtol=1e-3)


# -- faults as the controller sees them ---------------------------------------------------------

@pytest.fixture(scope="module")
def paper_runs():
    """pid_paper without faults and with one of each kind that acts on the loop."""
    faults = [
        {"kind": "encoder_stuck", "axis": "slew", "start": 10.0, "duration": 5.0},
        {"kind": "drive_trip", "axis": "luff", "start": 20.0, "duration": 2.0},
        {"kind": "encoder_dropout", "axis": "travel", "start": 30.0, "duration": 1.0},
        {"kind": "late_inputs", "periods": 10, "start": 40.0, "duration": 5.0},
        {"kind": "encoder_drift", "axis": "luff", "rate": 0.1, "start": 50.0, "duration": 5.0},
        {"kind": "encoder_noise", "axis": "travel", "sigma": 0.05, "start": 60.0, "duration": 20.0},
    ]
    clean = simulate(load_scene(SCENES / "pid_paper.toml"))
    faulty = simulate(load_scene(SCENES / "pid_paper.toml", {"faults": faults}))
    return clean, faulty


def _window(result, start: float, end: float) -> np.ndarray:
    return (result.time >= start - 1e-9) & (result.time < end - 1e-9)


def test_each_fault_acts_on_what_the_controller_sees_and_is_reported(paper_runs):
    clean, faulty = paper_runs
    np.testing.assert_array_equal(clean.q_measured[_window(clean, 0, 10)], faulty.q_measured[_window(faulty, 0, 10)])
    stuck = faulty.q_measured[_window(faulty, 10, 15), 1]
    assert (stuck == stuck[0]).all() and (faulty.qd_measured[_window(faulty, 10, 15), 1] == 0).all()
    assert not (faulty.q[_window(faulty, 10, 15), 1] == faulty.q[_window(faulty, 10, 15), 1][0]).all()
    tripped = _window(faulty, 20, 22)
    assert (faulty.drive_force[tripped, 2] == 0).all() and (faulty.drive_force_command[tripped, 2] != 0).any()
    assert (faulty.q_measured[_window(faulty, 30, 31), 0] == 0).all()
    late = np.flatnonzero(_window(faulty, 40.1, 45))  # 10 periods late: one record sample of 0.1 s
    np.testing.assert_allclose(faulty.q_measured[late], np.round(faulty.q[late - 1] / [0.00153, 0.00153, 0.00076])
                               * [0.00153, 0.00153, 0.00076], atol=1e-12)
    drift = np.flatnonzero(_window(faulty, 50, 55))
    offset = faulty.q_measured[drift, 2] - faulty.q[drift, 2]
    np.testing.assert_allclose(offset, np.radians(0.1) * (faulty.time[drift] - 50.0), atol=0.00076)
    noisy = np.flatnonzero(_window(faulty, 60, 80))
    noise = faulty.q_measured[noisy, 0] - faulty.q[noisy, 0]
    assert np.std(noise) == pytest.approx(0.05, rel=0.15) and abs(np.mean(noise)) < 0.015
    quiet = np.flatnonzero(_window(faulty, 80, 90))
    assert np.abs(faulty.q_measured[quiet, 0] - faulty.q[quiet, 0]).max() <= 0.00153 / 2 + 1e-12  # quantised only
    report = faulty.metrics["faults"]
    assert [f["kind"] for f in report] == ["encoder_stuck", "drive_trip", "encoder_dropout", "late_inputs",
                                           "encoder_drift", "encoder_noise"]
    assert report[0]["axis"] == "slew" and (report[0]["start_s"], report[0]["end_s"]) == (10.0, 15.0)
    assert report[1]["error_max_during"]["luff_deg"] > clean.metrics["luff"]["position_error_rms"]
    assert "faults" not in clean.metrics


def test_a_blinded_scanner_returns_nothing_while_the_dust_lasts(scanned_run, tmp_path):
    result, _ = scanned_run
    dust = '\n[[faults]]\nkind = "scanner_blinded"\nstart = 20.0\nduration = 10.0\n'
    blinded = simulate(load_scene(scene_file(tmp_path, extra=SURVEY + SCANNED + dust), FINE))
    t, hits = blinded.scan.t, blinded.scan.hits
    during = (t >= 20.0) & (t < 30.0)
    assert during.sum() == 250 and np.isnan(hits[during]).all()
    assert not np.isnan(hits[~during]).all()
    np.testing.assert_array_equal(hits[t < 20.0], result.scan.hits[result.scan.t < 20.0])
