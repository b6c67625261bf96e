"""Physics that cannot be, round three (docs/reliability.md, class 24): inputs a review found
accepted without a word, each refused as the scene loads (or as the PLC code is written), through
the real command line: exit status 2, one line on stderr naming the file, the key and the bound,
nothing written."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
from conftest import ROOT, SCENES

from test_hostile import assert_refused, snapshot


def cli(module: str, *args) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", f"bwr_twin.{module}", *map(str, args)], cwd=ROOT,
                          capture_output=True, text=True, timeout=600)


def refused(tmp_path: Path, text: str, pattern: str, *, module: str = "run", args=("--out",)) -> None:
    """`text` as tmp_path/bad.toml, run through `module`, refused with `pattern`; nothing written."""
    scene = tmp_path / "bad.toml"
    scene.write_text(text)
    before = snapshot(tmp_path)
    assert_refused(cli(module, *((args[0], scene) if module == "export" else (scene,)), *args[1:],
                       "--out", tmp_path / "out"), pattern)
    assert snapshot(tmp_path) == before


def extends(name: str) -> str:
    return f'extends = "{SCENES / name}"\n'


def test_a_neighbour_at_380_m_per_s(tmp_path):
    text = extends("heavy_two_machines.toml") + (
        "\n[neighbour]\nschedule = [\n  { t = 0.0, q = [-190.0, 0.0, 0.0] },\n"
        "  { t = 1.0, q = [190.0, 0.0, 0.0] },\n]\n")
    refused(tmp_path, text, r"bad\.toml: 'neighbour\.schedule\[1\]' asks the neighbour's travel for 380 m/s .*"
                            r"at most 0\.5 m/s \(stacker_heavy\.xml's rated travel speed\)")


@pytest.mark.parametrize("fault, pattern", [
    ('kind = "encoder_drift"\naxis = "travel"\nrate = 1e30',
     r"'faults\[0\]\.rate' 1e\+30 m/s drifts faster than the travel axis can move: at most 0\.5 m/s"),
    ('kind = "encoder_noise"\naxis = "slew"\nsigma = 1e30',
     r"'faults\[0\]\.sigma' 1e\+30 deg is noisier than the slew axis is long: at most \d+(\.\d+)? deg "
     r"\(the span of bwr_heavy\.xml's slew envelope\)"),
], ids=["drift", "noise"])
def test_an_encoder_fault_beyond_the_axis(tmp_path, fault, pattern):
    refused(tmp_path, extends("heavy_reclaim.toml") + f"\n[[faults]]\n{fault}\nstart = 10.0\n", r"bad\.toml: " + pattern)


def test_a_grade_of_minus_5_percent_with_sd_1e300(tmp_path):
    text = extends("heavy_chevron_stack.toml") + "\n[stacking.grade]\nmean = -5.0\nsd = 1e300\n"
    refused(tmp_path, text, r"bad\.toml: 'stacking\.grade\.mean' must lie in \[0, 100\] % \(the grade 'Fe %' is a "
                            r"percentage of the stream\), got -5")


def test_a_grade_sd_beyond_its_range(tmp_path):
    text = extends("heavy_chevron_stack.toml") + '\n[stacking.grade]\nname = "Cu ppm"\nmean = 50.0\nsd = 1e300\n'
    refused(tmp_path, text, r"bad\.toml: 'stacking\.grade\.sd' must lie in \[0, 1e\+06\] .*ppm.*got 1e\+300")


@pytest.mark.parametrize("kind, lacks", [("scanner_blinded", "scanner"), ("belt_scale_frozen", "belt scale")])
def test_a_fault_on_hardware_the_paper_machine_lacks(tmp_path, kind, lacks):
    text = extends("paper_individual_gains.toml") + f'\n[[faults]]\nkind = "{kind}"\nstart = 1.0\n'
    refused(tmp_path, text, rf"bad\.toml: 'faults\[0\]\.kind' \"{kind}\" .* but bwr\.xml has none .*would never act")


NEGATIVE_TRIM = '''
import numpy as np

from bwr_twin.control import RateControl


class Backwards(RateControl):
    def trim(self, signals):
        return np.full(len(self.target), -5.0)
'''

SMALL_RECLAIM = """
[reclaim]
target_rate = 4000.0
bench_height = 2.0
cut_depth = 1.0
bench_length = 3.0
slew_limits = [20.0, 80.0]
start = [-49.0, 44.0, -7.0]
acceleration = [0.1, 0.2, 0.2]
stop = { benches = 1 }

[reclaim.rate_control]
type = "backwards.py:Backwards"

[stockpile]
grid_spacing = 0.5

[stockpile.windrow]
length = 4.0
crest_width = 2.0
height = 4.0
angle_of_repose = 37.0
centre = [0.0, 45.0]
"""


def test_a_rate_plugin_trimming_to_minus_5(tmp_path):
    (tmp_path / "backwards.py").write_text(NEGATIVE_TRIM)
    refused(tmp_path, extends("heavy_dig_pile.toml") + SMALL_RECLAIM,
            r"bad\.toml: rate control .*backwards\.py.*trim\(\) returned \[-5\.\] at t = 0\.00 s; trims must lie "
            r"within 'reclaim\.rate_control\.trim_limits' \[0\.5, 2\]")


def test_measured_rate_signals_without_a_pile(tmp_path):
    text = extends("paper_individual_gains.toml") + '\n[sensing]\nrate_signals = "measured"\n'
    refused(tmp_path, text, r"bad\.toml: 'sensing\.rate_signals' \"measured\" .* no \[reclaim\]")


@pytest.mark.parametrize("gain, real, pattern", [
    ("1e308", True, r"FB_BwrPid\.KP\[0\] = 1\.0E\+308 lies outside REAL's range \(magnitudes 1\.18e-38 to 3\.4e\+38"),
    ("5e-324", False, r"FB_BwrPid\.KP\[0\] = 5\.0E-324 lies outside LREAL's range \(magnitudes 2\.23e-308"),
    ("1e-40", True, r"FB_BwrPid\.KP\[0\] = 1\.0E-40 lies outside REAL's range"),
    ("1e308", False, r"FB_BwrPid\.KP\[0\] = 1\.0E\+308 times the envelope's span of the travel \(50\) overflows "
                     r"LREAL \(largest 1\.8e\+308\): the block would compute infinity"),
], ids=["1e308 REAL", "5e-324 LREAL", "1e-40 REAL", "1e308 LREAL"])
def test_a_gain_beyond_the_plcs_numbers(tmp_path, gain, real, pattern):
    text = extends("pid_paper.toml") + f"\n[controller]\nkp = [{gain}, 7262500.0, 5000000.0]\n"
    refused(tmp_path, text, r"bad\.toml: \[controller\]: the constant " + pattern, module="export",
            args=("plc", "--real") if real else ("plc",))


def test_a_recorded_grade_of_1e300(tmp_path):
    grade = tmp_path / "grade.csv"
    grade.write_text("t,grade\n0,62\n100000,1e300\n")
    text = extends("heavy_chevron_stack.toml") + (f'replace = ["stacking.grade"]\n\n[stacking.grade]\nname = "Fe %"\n'
                                                  f'file = "{grade}"\n')
    refused(tmp_path, text, r"grade\.csv: line 3, column 2 \(grade\): 1e300 lies beyond \+-1e\+06")
