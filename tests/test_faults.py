"""Scheduled sensor and drive faults: the rules of `[[faults]]`, what each kind does to the
readings and the commands of every run, when it acts, and the report of what it did."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest

from bwr_twin import SceneError
from bwr_twin.config.faults import FAULT_KINDS, FaultSection, check_fault_scanners, check_faults
from bwr_twin.sensing.faults import Faults, fault_periods
from bwr_twin.sim.fault_report import fault_metrics
from bwr_twin.streams import Stream

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

SCENE = Path("/scenes/faulty.toml")
PERIOD = 0.01  # s, the heavy scenes' control period
DEG = math.pi / 180

EXAMPLE = """
[[faults]]
kind = "encoder_stuck"
axis = "slew"
start = 200.0
duration = 30.0

[[faults]]
kind = "encoder_drift"
axis = "travel"
start = 100.0
duration = 60.0
rate = 0.01

[[faults]]
kind = "encoder_noise"
axis = "luff"
start = 50.0
sigma = 0.05

[[faults]]
kind = "late_inputs"
start = 300.0
duration = 20.0
periods = 5

[[faults]]
kind = "scanner_blinded"
start = 10.0

[[faults]]
kind = "belt_scale_frozen"
start = 10.0
duration = 5.0

[[faults]]
kind = "drive_trip"
axis = "luff"
start = 0.0

[[faults]]
kind = "encoder_dropout"
axis = "travel"
start = 400.0
duration = 0.5

[[faults]]
kind = "friction_rise"
axis = "slew"
percent = 20.0
ramp = 60.0
start = 100.0

[[faults]]
kind = "mass_change"
mass = 5000.0
start = 100.0

[[faults]]
kind = "drive_derate"
axis = "travel"
percent = 15.0
start = 100.0
duration = 50.0
"""


def _example() -> tuple[FaultSection, ...]:
    return tuple(FaultSection(**table) for table in tomllib.loads(EXAMPLE)["faults"])


def _refused(faults, match: str, runs_until: float | None = None) -> None:
    with pytest.raises(SceneError, match=match) as caught:
        check_faults(SCENE, tuple(faults), runs_until)
    assert str(caught.value).startswith(f"{SCENE}: ")


def _readings(k: int, runs: int = 2) -> tuple[np.ndarray, np.ndarray]:
    """(runs, 3) readings that differ in every period, run and axis."""
    base = k + 1000.0 * np.arange(runs)[:, None] + np.array([0.1, 0.2, 0.3])
    return base.copy(), -base


# -- the rules ---------------------------------------------------------------------------------

def test_the_example_keeps_every_rule():
    faults = _example()
    assert {f.kind for f in faults} == set(FAULT_KINDS)
    check_faults(SCENE, faults)
    check_faults(SCENE, faults, runs_until=700.0)


def test_an_unknown_kind_lists_the_kinds_counting_tables_from_zero():
    faults = (FaultSection("encoder_stuck", 0.0, axis="slew"), FaultSection("gremlins", 0.0))
    _refused(faults, r"'faults\[1\]\.kind' must be one of encoder_stuck, encoder_dropout, encoder_drift, "
                     r"encoder_noise, scanner_blinded, belt_scale_frozen, drive_trip, late_inputs, "
                     r"friction_rise, mass_change, drive_derate, got 'gremlins'")


def test_start_and_duration():
    _refused([FaultSection("drive_trip", -1.0, axis="slew")], r"'faults\[0\]\.start' must be >= 0 s, got -1\.0")
    _refused([FaultSection("drive_trip", 1.0, 0.0, axis="slew")], r"'faults\[0\]\.duration' must be > 0 s")
    _refused([FaultSection("drive_trip", 1.0, -5.0, axis="slew")], r"'faults\[0\]\.duration' must be > 0 s")
    _refused([FaultSection("drive_trip", math.nan, axis="slew")], r"'faults\[0\]\.start' must be >= 0 s")


def test_a_fault_after_the_runs_end_would_never_act():
    _refused([FaultSection("belt_scale_frozen", 700.0)],
             r"'faults\[0\]\.start' \(700\.0 s\) must come before the run's end \(700\.0 s\)", runs_until=700.0)
    check_faults(SCENE, (FaultSection("belt_scale_frozen", 699.0),), runs_until=700.0)


def test_the_axis():
    _refused([FaultSection("encoder_stuck", 1.0), FaultSection("encoder_stuck", 1.0, axis="boom")],
             r"'faults\[0\]\.axis' is missing: kind \"encoder_stuck\" needs one of travel, slew, luff")
    _refused([FaultSection("encoder_stuck", 1.0, axis="slew"), FaultSection("encoder_stuck", 1.0, axis="boom")],
             r"'faults\[1\]\.axis' must be one of travel, slew, luff for kind \"encoder_stuck\", got 'boom'$")
    _refused([FaultSection("drive_trip", 1.0)], r"'faults\[0\]\.axis' is missing: kind \"drive_trip\"")


def test_the_drift_rate():
    _refused([FaultSection("encoder_drift", 1.0, axis="slew")],
             r"'faults\[0\]\.rate' is missing: kind \"encoder_drift\" needs the drift rate \(m/s for travel, "
             r"deg/s for slew and luff\)")
    _refused([FaultSection("encoder_drift", 1.0, axis="slew", rate=math.inf)],
             r"'faults\[0\]\.rate' must be a finite number, got inf")


def test_the_noise_sigma():
    _refused([FaultSection("encoder_noise", 1.0, axis="luff")], r"'faults\[0\]\.sigma' is missing")
    for sigma in (0.0, -0.1):
        _refused([FaultSection("encoder_noise", 1.0, axis="luff", sigma=sigma)],
                 rf"'faults\[0\]\.sigma' must be > 0 \(m for travel, deg for slew and luff\) for kind "
                 rf"\"encoder_noise\", got {sigma}")


def test_the_late_periods():
    _refused([FaultSection("late_inputs", 1.0)], r"'faults\[0\]\.periods' is missing")
    for periods in (0, -2, 2.5, True):
        _refused([FaultSection("late_inputs", 1.0, periods=periods)],
                 rf"'faults\[0\]\.periods' must be an integer >= 1 for kind \"late_inputs\", got {periods}")


@pytest.mark.parametrize(("fault", "key", "uses"), [
    (FaultSection("encoder_stuck", 1.0, axis="slew", rate=0.1), "rate", "it uses axis"),
    (FaultSection("encoder_noise", 1.0, axis="slew", sigma=0.1, periods=2), "periods", "it uses axis, sigma"),
    (FaultSection("belt_scale_frozen", 1.0, axis="travel"), "axis", "it uses only start and duration"),
    (FaultSection("drive_trip", 1.0, axis="slew", scanner="scanner_boom"), "scanner", "it uses axis"),
    (FaultSection("late_inputs", 1.0, periods=2, sigma=0.1), "sigma", "it uses periods"),
])
def test_a_key_the_kind_does_not_use_is_refused(fault, key, uses):
    _refused([fault], rf"'faults\[0\]\.{key}' is not used by kind \"{fault.kind}\" \({uses}\)")


def test_the_scanner():
    _refused([FaultSection("scanner_blinded", 1.0, scanner="boom")],
             r"'faults\[0\]\.scanner' must name a scanner site \(its name starts with 'scanner'\)")
    faults = (FaultSection("scanner_blinded", 1.0, scanner="scanner_left"), FaultSection("scanner_blinded", 2.0))
    check_faults(SCENE, faults)
    check_fault_scanners(SCENE, faults, ("scanner_left", "scanner_right"))
    with pytest.raises(SceneError, match=r"'faults\[0\]\.scanner' names 'scanner_left', a scanner heavy\.xml "
                                         r"does not have \(it has: scanner_boom\)"):
        check_fault_scanners(SCENE, faults, ("scanner_boom",), Path("heavy.xml"))


# -- when a fault acts -------------------------------------------------------------------------

def test_windows_at_their_boundaries():
    assert fault_periods(FaultSection("drive_trip", 200.0, 30.0, axis="slew"), PERIOD) == (20000, 22999)
    assert fault_periods(FaultSection("drive_trip", 0.3, 0.2, axis="slew"), 0.1) == (3, 4)  # 0.3 / 0.1 < 3
    assert fault_periods(FaultSection("drive_trip", 0.305, 0.01, axis="slew"), 0.01) == (31, 31)
    first, last = fault_periods(FaultSection("drive_trip", 0.0, axis="slew"), PERIOD)
    assert first == 0 and last >= 2**62
    faults = Faults((FaultSection("drive_trip", 0.3, 0.2, axis="slew"),), [1], 0.1)
    tripped = []
    for k in range(8):
        command = np.ones((1, 3))
        faults.command(k, command)
        tripped.append(command[0, 1] == 0.0)
    assert tripped == [False, False, False, True, True, False, False, False]


def test_no_fault_is_inactive():
    assert Faults((), [1, 2], PERIOD).active is False
    assert Faults(_example(), [1, 2], PERIOD).active is True


def test_a_derate_grows_over_its_ramp_and_scales_only_its_axis():
    """15 % over a ramp of 0.04 s (4 periods): 3.75 % more each period from its first, then held."""
    faults = Faults((FaultSection("drive_derate", 1.0, 1.0, axis="travel", percent=15.0, ramp=0.04),), [1, 2], PERIOD)
    shares = []
    for k in range(99, 106):
        command = np.full((2, 3), 1000.0)
        faults.command(k, command)
        np.testing.assert_array_equal(command[:, 1:], 1000.0)
        shares.append(round(1 - command[0, 0] / 1000.0, 6))
    assert shares == [0.0, 0.0375, 0.075, 0.1125, 0.15, 0.15, 0.15]


def test_plant_fault_sizes_are_checked():
    _refused([FaultSection("drive_derate", 0.0, axis="slew", percent=100.0)],
             r"'faults\[0\]\.percent' must be > 0 and < 100")
    _refused([FaultSection("friction_rise", 0.0, axis="slew")], r"'faults\[0\]\.percent' must be > 0")
    _refused([FaultSection("mass_change", 0.0, mass=-5.0)], r"'faults\[0\]\.mass' must be > 0 kg")
    _refused([FaultSection("mass_change", 0.0, mass=5.0, ramp=-1.0)], r"'faults\[0\]\.ramp' must be >= 0 s")
    _refused([FaultSection("mass_change", 0.0, mass=5.0, axis="slew")], r"'faults\[0\]\.axis' is not used")


def test_drive_trip_zeros_only_its_axis():
    faults = Faults((FaultSection("drive_trip", 1.0, 1.0, axis="luff"),), [1, 2, 3], PERIOD)
    command = np.arange(9.0).reshape(3, 3) + 1
    before = command.copy()
    faults.command(99, command)
    np.testing.assert_array_equal(command, before)
    faults.command(100, command)
    np.testing.assert_array_equal(command[:, :2], before[:, :2])
    np.testing.assert_array_equal(command[:, 2], 0.0)


def test_scanner_blinded_and_scale_frozen():
    faults = Faults((FaultSection("scanner_blinded", 1.0, 1.0, scanner="scanner_left"),
                     FaultSection("scanner_blinded", 3.0, 1.0),
                     FaultSection("belt_scale_frozen", 5.0, 0.5)), [1], 0.5)
    assert [faults.scanner_blinded(k, "scanner_left") for k in range(9)] == [
        False, False, True, True, False, False, True, True, False]
    assert [faults.scanner_blinded(k, "scanner_right") for k in range(9)] == [
        False, False, False, False, False, False, True, True, False]
    assert [faults.scale_frozen(k) for k in range(12)] == [False] * 10 + [True, False]


# -- what the encoder faults do to the readings ------------------------------------------------

def test_a_stuck_encoder_holds_its_first_periods_reading_and_reads_no_speed():
    faults = Faults((FaultSection("encoder_stuck", 0.05, 0.05, axis="slew"),), [1, 2], PERIOD)
    for k in range(12):
        q, qd = _readings(k)
        q_true, qd_true = q.copy(), qd.copy()
        faults.measured(k, q, qd)
        if 5 <= k < 10:
            np.testing.assert_array_equal(q[:, 1], _readings(5)[0][:, 1])
            np.testing.assert_array_equal(qd[:, 1], 0.0)
            np.testing.assert_array_equal(q[:, [0, 2]], q_true[:, [0, 2]])
            np.testing.assert_array_equal(qd[:, [0, 2]], qd_true[:, [0, 2]])
        else:
            np.testing.assert_array_equal(q, q_true)
            np.testing.assert_array_equal(qd, qd_true)


def test_a_dropped_out_encoder_reads_zero():
    faults = Faults((FaultSection("encoder_dropout", 0.0, 0.02, axis="travel"),), [1, 2], PERIOD)
    q, qd = _readings(1)
    faults.measured(1, q, qd)
    np.testing.assert_array_equal(q[:, 0], 0.0)
    np.testing.assert_array_equal(qd[:, 0], 0.0)
    np.testing.assert_array_equal(q[:, 1:], _readings(1)[0][:, 1:])
    q, qd = _readings(2)
    faults.measured(2, q, qd)
    np.testing.assert_array_equal(q, _readings(2)[0])


@pytest.mark.parametrize(("axis", "j", "unit"), [("travel", 0, 1.0), ("slew", 1, DEG), ("luff", 2, DEG)])
def test_drift_grows_at_its_rate_in_the_twins_units(axis, j, unit):
    start, rate = 1.0, 0.01  # s; m/s or deg/s
    faults = Faults((FaultSection("encoder_drift", start, 2.0, axis=axis, rate=rate),), [1], PERIOD)
    offsets = []
    for k in range(90, 310):
        q, qd = np.full((1, 3), 5.0), np.full((1, 3), 0.5)
        faults.measured(k, q, qd)
        others = [i for i in range(3) if i != j]
        np.testing.assert_array_equal(q[0, others], 5.0)
        if 100 <= k < 300:
            assert qd[0, j] == pytest.approx(0.5 + rate * unit, abs=1e-15)
            assert q[0, j] - 5.0 == pytest.approx(rate * unit * (k * PERIOD - start), abs=1e-13)
            offsets.append(q[0, j] - 5.0)
        else:
            assert (q[0, j], qd[0, j]) == (5.0, 0.5)
    assert offsets[0] == pytest.approx(0.0, abs=1e-15)
    np.testing.assert_allclose(np.diff(offsets), rate * unit * PERIOD, rtol=1e-6)


def test_noise_has_its_sigma_and_comes_from_each_runs_own_stream():
    sigma = 0.05  # deg
    schedule = (FaultSection("drive_trip", 0.0, axis="travel"),
                FaultSection("encoder_noise", 1.0, axis="luff", sigma=sigma))
    periods = range(100, 20100)

    def noise(seeds):
        faults = Faults(schedule, seeds, PERIOD)
        out = []
        for k in periods:
            q, qd = np.zeros((len(seeds), 3)), np.zeros((len(seeds), 3))
            faults.measured(k, q, qd)
            assert not q[:, :2].any() and not qd.any()
            out.append(q[:, 2])
        return np.array(out)  # (periods, runs) rad

    together = noise([7, 8, 9])
    assert together.std(axis=0) == pytest.approx([sigma * DEG] * 3, rel=0.03)
    assert abs(together.mean(axis=0)).max() < 4 * sigma * DEG / math.sqrt(len(periods))
    assert abs(np.corrcoef(together.T)[np.triu_indices(3, 1)]).max() < 0.05  # the runs' draws are independent
    np.testing.assert_array_equal(noise([8])[:, 0], together[:, 1])  # alone, the same numbers
    np.testing.assert_array_equal(noise([3, 8])[:, 1], together[:, 1])
    # The second fault's stream of the seed: one standard normal a period, from its first period.
    stream = np.random.default_rng(np.random.SeedSequence(8, spawn_key=(Stream.FAULT, 1)))
    np.testing.assert_array_equal(together[:, 1], sigma * DEG * stream.standard_normal(len(periods)))


def test_late_inputs_are_the_readings_of_periods_earlier_exactly():
    faults = Faults((FaultSection("late_inputs", 0.2, 0.1, periods=5),), [1, 2], PERIOD)
    assert len(faults._late._ring_period) == 6  # the longest delay and the period itself: no more
    for k in range(40):
        q, qd = _readings(k)
        faults.measured(k, q, qd)
        source = k - 5 if 20 <= k < 30 else k
        np.testing.assert_array_equal(q, _readings(source)[0])
        np.testing.assert_array_equal(qd, _readings(source)[1])


def test_late_inputs_see_period_zero_before_it():
    faults = Faults((FaultSection("late_inputs", 0.0, periods=3),), [1], PERIOD)
    for k in range(10):
        q, qd = _readings(k, runs=1)
        faults.measured(k, q, qd)
        np.testing.assert_array_equal(q, _readings(max(k - 3, 0), runs=1)[0])


def test_late_inputs_carry_the_encoder_faults():
    """The delayed readings are those after the encoder faults: a stuck encoder's held value
    arrives late too, and a dropout's zeros."""
    faults = Faults((FaultSection("encoder_dropout", 0.1, 0.02, axis="slew"),
                     FaultSection("late_inputs", 0.1, 0.1, periods=2)), [1], PERIOD)
    seen = []
    for k in range(8, 16):
        q, qd = _readings(k, runs=1)
        faults.measured(k, q, qd)
        seen.append(q[0, 1])
    assert seen == [8.2, 9.2, 8.2, 9.2, 0.0, 0.0, 12.2, 13.2]


def test_skipping_a_period_under_late_inputs_is_caught():
    faults = Faults((FaultSection("late_inputs", 0.0, periods=2),), [1], PERIOD)
    faults.measured(0, *_readings(0, runs=1))
    with pytest.raises(RuntimeError, match="call measured"):
        faults.measured(3, *_readings(3, runs=1))


# -- the report --------------------------------------------------------------------------------

def _record():
    """101 s at 0.5 s; errors: travel 0.1 m over [20, 30) and 0.02 m at 60 s, slew 1 deg at 25 s
    and 0.5 deg at 80 s, luff none."""
    time = np.arange(0.0, 100.5, 0.5)
    q_desired = np.zeros((len(time), 3))
    q = np.zeros((len(time), 3))
    q[(time >= 20) & (time < 30), 0] = -0.1
    q[time == 60, 0] = 0.02
    q[time == 25, 1] = 1.0 * DEG
    q[time == 80, 1] = -0.5 * DEG
    metrics = {
        "travel": {"left_envelope_time": 10.0, "end_stop_time": None, "beyond_drive_rating_time": 25.0},
        "slew": {"left_envelope_time": None, "end_stop_time": 50.0, "beyond_drive_rating_time": None},
        "luff": {"left_envelope_time": None, "end_stop_time": None, "beyond_drive_rating_time": None},
    }
    return time, q_desired, q, metrics


def test_fault_metrics_of_a_timed_fault():
    time, q_desired, q, metrics = _record()
    fault = FaultSection("encoder_drift", 20.0, 10.0, axis="slew", rate=0.01)
    rate = np.full(len(time), 3600.0)  # t/h: 1 t/s
    (entry,) = fault_metrics((fault,), time, q_desired, q, metrics, rate=rate, target_rate=7200.0)
    assert entry["kind"] == "encoder_drift" and entry["axis"] == "slew" and entry["rate"] == 0.01
    assert "sigma" not in entry and "scanner" not in entry
    assert (entry["start_s"], entry["end_s"]) == (20.0, 30.0)
    assert entry["error_max_during"] == pytest.approx({"travel_m": 0.1, "slew_deg": 1.0, "luff_deg": 0.0})
    assert entry["error_max_after"] == pytest.approx({"travel_m": 0.02, "slew_deg": 0.5, "luff_deg": 0.0})
    assert entry["limits_after_start"] == {"travel": {"beyond_drive_rating_s": 25.0},
                                           "slew": {"end_stop_s": 50.0}, "luff": {}}
    assert entry["tonnes_during_t"] == pytest.approx(10.0)
    assert entry["shortfall_t"] == pytest.approx(20.0 - 10.0)


def test_fault_metrics_to_the_runs_end_and_beyond_it():
    time, q_desired, q, metrics = _record()
    faults = (FaultSection("late_inputs", 55.0, periods=3), FaultSection("drive_trip", 150.0, 5.0, axis="luff"),
              FaultSection("scanner_blinded", 90.0, 50.0, scanner="scanner_boom"))
    rate = 36.0 * time  # t/h, rising: the trapezoid of a straight line is exact
    no_error = {"travel_m": None, "slew_deg": None, "luff_deg": None}
    late, never, blinded = fault_metrics(faults, time, q_desired, q, metrics, rate=rate)
    assert late["periods"] == 3 and (late["start_s"], late["end_s"]) == (55.0, 100.0)
    assert late["error_max_during"] == pytest.approx({"travel_m": 0.02, "slew_deg": 0.5, "luff_deg": 0.0})
    assert late["error_max_after"] == no_error
    assert late["limits_after_start"] == {"travel": {}, "slew": {}, "luff": {}}
    assert late["tonnes_during_t"] == pytest.approx(0.005 * (100.0**2 - 55.0**2))
    assert "shortfall_t" not in late
    assert never["end_s"] is None and never["tonnes_during_t"] is None
    assert never["error_max_during"] == no_error and never["error_max_after"] == no_error
    assert blinded["scanner"] == "scanner_boom" and blinded["end_s"] == 100.0
    assert blinded["error_max_after"] == no_error  # its end lies beyond the run's


def test_fault_metrics_interpolates_the_rate_at_a_windows_ends():
    time, q_desired, q, metrics = _record()
    fault = FaultSection("belt_scale_frozen", 20.25, 10.1)
    (entry,) = fault_metrics((fault,), time, q_desired, q, metrics, rate=36.0 * time, target_rate=3600.0)
    assert entry["tonnes_during_t"] == pytest.approx(0.005 * (30.35**2 - 20.25**2))
    assert entry["shortfall_t"] == pytest.approx(10.1 - 0.005 * (30.35**2 - 20.25**2))
    assert "rate" not in entry and "tonnes_during_t" not in fault_metrics((fault,), time, q_desired, q, metrics)[0]
