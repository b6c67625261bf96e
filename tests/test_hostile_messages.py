"""Hostile input that gave a traceback or a misleading message (docs/reliability.md, classes 20
and 21): each case is refused with status 2 and one line naming the file, key or line and the
limit, leaving its folder as it was; the accepted cases (a negative input, a NaN in an MJCF) say
what they should, once.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from conftest import PAPER_MJCF, write_short_scene
from test_hostile import assert_refused, cli, snapshot

from bwr_twin.config.scene import load_scene
from bwr_twin.errors import SceneError
from bwr_twin.serve.security import SecurityError, hash_password, load_users
from bwr_twin.shipped import SCENES

ROOT = Path(__file__).resolve().parents[1]
TIPPER = ROOT / "tests" / "assets" / "tipper.fis"

FCL = """FUNCTION_BLOCK small
VAR_INPUT
  e : REAL;
END_VAR
VAR_OUTPUT
  u : REAL;
END_VAR
FUZZIFY e
  RANGE := (-1 .. 1);
  TERM neg := (-1, 0) (-0.5, 1) (0, 0);
  TERM pos := (0, 0) (0.5, 1) (1, 0);
END_FUZZIFY
DEFUZZIFY u
  RANGE := (-1 .. 1);
  TERM z := (-1, 0) (0, 1) (1, 0);
  METHOD : COG;
END_DEFUZZIFY
RULEBLOCK rules
  RULE 1 : IF e IS neg THEN u IS z;
END_RULEBLOCK
END_FUNCTION_BLOCK
"""


def fcl(tmp: Path, old: str = "", new: str = "") -> Path:
    assert old in FCL
    (tmp / "rules.fcl").write_text(FCL.replace(old, new))
    return tmp / "rules.fcl"


def refused_by_fis(tmp: Path, path: Path, pattern: str) -> None:
    """`fis evaluate` and `fis convert` both refuse `path`, naming it; nothing is written."""
    before = snapshot(tmp)
    assert_refused(cli("fis", "evaluate", path, "0.5", cwd=tmp), re.escape(str(path)) + pattern)
    assert_refused(cli("fis", "convert", path, tmp / "out.fis", cwd=tmp), re.escape(str(path)) + pattern)
    assert snapshot(tmp) == before


# -- class 20: tracebacks --------------------------------------------------------------------


def test_a_stop_time_within_the_survey_is_refused_before_the_run(tmp_path):
    """An IndexError in the follower's continue_with, once: no bench was left to plan."""
    from bwr_twin.planning.bench import plan_scene

    (tmp_path / "stop.toml").write_text('extends = "heavy_scanned_reclaim.toml"\n[reclaim]\nstop = { time = 30.0 }\n')
    scene = load_scene(tmp_path / "stop.toml")
    with pytest.raises(SceneError, match=r"stop\.toml: \[reclaim\]: 'stop\.time' = 30 s ends within the survey, "
                                         r"which takes 765\.0 s through its 4 waypoints"):
        plan_scene(scene)  # what a run plans before its first step


def test_a_grade_file_shorter_than_the_stacking_is_refused_up_front(tmp_path):
    """A ValueError in the middle of the run, once; now refused as the run is assembled, naming
    the file, the span it records and the stacking's."""
    text = (SCENES / "heavy_chevron_stack.toml").read_text()
    text = text[:text.index("[stacking.grade]")] + '[stacking.grade]\nfile = "grade.csv"\n\n' + \
        text[text.index("[simulation]"):]
    text = text.replace('"../mjcf/', f'"{PAPER_MJCF.parent}/')
    (tmp_path / "stack.toml").write_text(text)
    (tmp_path / "grade.csv").write_text("t,grade\n" + "".join(f"{10 * k},62\n" for k in range(31)))
    before = snapshot(tmp_path)
    assert_refused(cli("run", "stack.toml", "--out", "out", cwd=tmp_path),
                   r"stack\.toml: 'stacking\.grade\.file' grade\.csv records the grade from t = 0 s to 300 s, "
                   r"300 s; the stacking lasts 7200 s, its deposits from 0 s to 7199 s")
    assert snapshot(tmp_path) == before


def test_a_variable_declared_twice_in_fcl_is_refused(tmp_path):
    path = fcl(tmp_path, "  e : REAL;\n", "  e : REAL;\n  e : REAL;\n")
    refused_by_fis(tmp_path, path, r":4: variable 'e' is declared twice \(first on line 3\)")


# -- class 21: messages ----------------------------------------------------------------------


@pytest.mark.parametrize("value", ["-1e-3", "-.5", "-2.", "-1E+2"])
def test_negative_inputs_in_any_notation_are_values(value):
    proc = cli("fis", "evaluate", TIPPER, "5", value)
    assert proc.returncode == 0 and proc.stdout.startswith("output = "), proc.stderr
    assert "unrecognized" not in proc.stderr and f"(from {float(value):g}" in proc.stderr


def test_minus_inf_is_refused_by_the_command_not_the_parser():
    assert_refused(cli("fis", "evaluate", TIPPER, "5", "-inf"), r"X2 '-inf' is not a finite number")


def test_an_output_range_that_would_overflow_is_refused(tmp_path):
    path = fcl(tmp_path, "DEFUZZIFY u\n  RANGE := (-1 .. 1);", "DEFUZZIFY u\n  RANGE := (-1.7e308 .. 1.7e308);")
    refused_by_fis(tmp_path, path, r":13: output 1 'u': Range \[-1.7e\+308 1.7e\+308\] is beyond ±1e\+100")


def test_a_set_of_200000_points_gets_a_short_message(tmp_path):
    points = " ".join(f"({k}, 0)" for k in range(200_000))
    path = fcl(tmp_path, "TERM neg := (-1, 0) (-0.5, 1) (0, 0);", f"TERM neg := {points};")
    proc = cli("fis", "evaluate", path, "0.5", cwd=tmp_path)
    assert_refused(proc, r":10: set 'neg' has points of degrees \(0\.0, 0\.0, 0\.0, 0\.0, \.\.\. 200,000 in all\)")
    assert len(proc.stderr) < 400


def test_a_term_named_twice_is_refused(tmp_path):
    path = fcl(tmp_path, "  TERM pos := (0, 0) (0.5, 1) (1, 0);\n",
               "  TERM pos := (0, 0) (0.5, 1) (1, 0);\n  TERM pos := (0, 0) (0.5, 1) (1, 0);\n")
    refused_by_fis(tmp_path, path, r":12: TERM pos appears twice in this FUZZIFY \(first on line 11\)")


def test_a_fis_set_named_twice_is_refused(tmp_path):
    (tmp_path / "twice.fis").write_text(TIPPER.read_text().replace("'good'", "'poor'", 1))
    refused_by_fis(tmp_path, tmp_path / "twice.fis", r":25: MF2 'poor' of input 1 'service': the name of MF1 too")


def test_an_empty_rule_block_is_refused(tmp_path):
    path = fcl(tmp_path, "  RULE 1 : IF e IS neg THEN u IS z;\n", "")
    refused_by_fis(tmp_path, path, r":19: the RULEBLOCK holds no RULE")
    text = TIPPER.read_text()
    (tmp_path / "none.fis").write_text(text[:text.index("[Rules]")] + "[Rules]\n")
    refused_by_fis(tmp_path, tmp_path / "none.fis", r":\d+: \[Rules\] holds no rule")


def test_a_narrow_gaussian_far_from_its_centre_gives_no_numpy_warning(tmp_path):
    text = TIPPER.read_text().replace("Range = [0 10]\nNumMFs = 3\nMF1 = 'poor':'gaussmf',[1.5 0]",
                                      "Range = [-1e99 1e99]\nNumMFs = 3\nMF1 = 'poor':'gaussmf',[1e-99 0]")
    (tmp_path / "narrow.fis").write_text(text.replace(
        "MF1 = 'rancid':'trapmf',[0 0 1 3]", "MF1 = 'rancid':'gbellmf',[1e-90 -2 0]"))
    proc = cli("fis", "evaluate", tmp_path / "narrow.fis", "0", "5")
    assert proc.returncode == 0 and proc.stdout.strip() == "output = 5.0780", proc.stderr
    assert "encountered" not in proc.stderr and proc.stderr == ""
    (tmp_path / "zero.fis").write_text(text.replace("[1e-99 0]", "[1e-200 0]"))
    assert_refused(cli("fis", "evaluate", tmp_path / "zero.fis", "0", "5"), r":24: .* narrower than 1e-100")


@pytest.mark.parametrize("case", ["same user twice", "1-byte digest"])
def test_a_users_file_with_a_user_twice_or_a_short_digest_is_refused(case, tmp_path):
    line = f"plc:{hash_password('secret', salt=bytes(16))}"
    text = {"same user twice": f"# the PLC\n{line}\n{line}\n",
            "1-byte digest": f"{line.rsplit('$', 1)[0]}$ab\n"}[case]
    (tmp_path / "users.txt").write_text(text)
    expected = {"same user twice": r"users\.txt:3: user 'plc' is in the users file twice \(first on line 2\)",
                "1-byte digest": r"users\.txt:1: user 'plc': a 16-byte salt and a 1-byte digest"}[case]
    with pytest.raises(SecurityError, match=expected):
        load_users(tmp_path / "users.txt")


def test_a_nan_in_the_mjcf_is_warned_of_once(tmp_path):
    text = PAPER_MJCF.read_text().replace('<joint damping="0.05"/>', '<joint damping="nan"/>')
    (tmp_path / "nan.xml").write_text(text)
    write_short_scene(tmp_path, edit=lambda s: s.replace(f'"{PAPER_MJCF}"', f'"{tmp_path / "nan.xml"}"'))
    proc = cli("run", "short.toml", "--out", "out", cwd=tmp_path)
    lines = proc.stderr.strip().splitlines()
    assert lines.count(f"warning: {tmp_path / 'nan.xml'}: MuJoCo: XML contains a 'NaN'. Please check it "
                       "carefully.") == 1, lines
    assert not any(line.startswith("WARNING") for line in lines) and "Traceback" not in proc.stderr
