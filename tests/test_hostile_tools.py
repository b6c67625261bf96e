"""Hostile input to the tools around a run, through their command lines: tuning, the .fis tools,
compare, replay input, file encodings and argument errors (docs/reliability.md, classes 8-13).

Each refusal exits with status 2 and one line naming the file, key, option or path and the
limit, without a traceback, and leaves every file of the folder as it was. The accepted cases
(one tuned parameter, a byte-order mark, CRLF line ends) check that the work is done.
"""

from __future__ import annotations

import hashlib
import json
import pickle
import re
import shutil
from pathlib import Path

import pytest
from conftest import write_short_scene
from test_hostile import assert_refused, cli, snapshot

from bwr_twin.ownership import mark
from bwr_twin.shipped import RULE_BASES, SCENES

ROOT = Path(__file__).resolve().parents[1]
TIPPER = ROOT / "tests" / "assets" / "tipper.fis"
BOM = b"\xef\xbb\xbf"

TUNING = """scene = "short.toml"
[parameters]
"controller.output_gain.travel" = { low = 0.002, high = 0.2, scale = "log" }
"controller.input_scale_e" = { low = 10.0, high = 200.0 }
[seeds]
training = [1]
held_out = [11]
[objective]
position_error_rms = 1.0
[budget]
evaluations = 5
[optimizer]
population = 4
"""
SECOND = '"controller.input_scale_e" = { low = 10.0, high = 200.0 }'


def tuning(tmp: Path, old: str = "", new: str = "") -> str:
    (tmp / "tune.toml").write_text(TUNING.replace(old, new) if old else TUNING)
    return "tune.toml"


def tuned_folder(tmp: Path, damage) -> Path:
    """--out of this tuning as a killed tuning left it, its tuner_state.pkl damaged by `damage`."""
    text = (tmp / tuning(tmp)).read_text()
    (tmp / "out").mkdir()
    mark(tmp / "out", "tuning", file="tune.toml", tuning=hashlib.sha256(text.encode()).hexdigest())
    damage(tmp / "out" / "tuner_state.pkl")
    return tmp / "out"


def notes(tmp: Path, name: str) -> Path:
    """An engineer's file that mentions the twin's writers, but that the twin did not write."""
    (tmp / name).write_bytes(b"% my notes on bwr_twin.fis and bwr_twin.replay\n"
                             b'<meta name="generator" content="bwr_twin.replay">\n')
    return tmp / name


def damaged_run(tmp: Path, run: Path, row: int = 0, column: str = "", value: str = "", *, header=None,
                cut: int | None = None, scene=None) -> Path:
    """A copy of `run` with one value, the header, the end of its time series or its scene changed."""
    folder = tmp / "damaged"
    shutil.copytree(run, folder)
    lines = (folder / "timeseries.csv").read_text().splitlines()
    if column:
        cells = lines[row].split(",")
        cells[lines[0].split(",").index(column)] = value
        lines[row] = ",".join(cells)
    if header:
        lines[0] = lines[0].replace(*header)
    if cut is not None:
        lines = lines[:cut] + [lines[cut][:30]]
    (folder / "timeseries.csv").write_text("\n".join(lines) + "\n")
    if scene:
        recorded = json.loads((folder / "scene.json").read_text())
        recorded["trajectory"]["via_points"][1]["p"][0] += 1.0
        (folder / "scene.json").write_text(json.dumps(recorded))
    return folder


@pytest.fixture(scope="module")
def short_run(tmp_path_factory) -> Path:
    """A run directory of the 20 s scene, no figures: what the replay cases damage."""
    folder = tmp_path_factory.mktemp("run")
    write_short_scene(folder)
    proc = cli("run", "short.toml", "--out", "r", "--no-plots", cwd=folder)
    assert proc.returncode == 0, proc.stderr
    return folder / "r"


# (id, command, argument builder(tmp, short run) -> arguments, pattern of the one error line)
REFUSALS = [
    # 8. Tuning
    ("tune-damaged-state-another-object", "tune",
     lambda t, r: ["tune.toml", "--out", tuned_folder(t, lambda p: p.write_bytes(pickle.dumps({"a": 1})))],
     r"out/tuner_state.pkl: damaged, not a state this tuner saved \(it holds a dict.*remove it"),
    ("tune-damaged-state-bytes", "tune",
     lambda t, r: ["tune.toml", "--out", tuned_folder(t, lambda p: p.write_bytes(b"\x80\x04\x95 not a pickle"))],
     r"out/tuner_state.pkl: damaged, not a state this tuner saved .*or choose another --out"),
    ("tune-damaged-state-a-folder", "tune",
     lambda t, r: ["tune.toml", "--out", tuned_folder(t, lambda p: p.mkdir())],
     r"out/tuner_state.pkl: damaged, not a state this tuner saved \(Is a directory\)"),
    ("tune-control-period", "tune",
     lambda t, r: [tuning(t, SECOND, '"simulation.control_period" = { low = 0.005, high = 0.02 }'), "--out", "o"],
     r"tune.toml: 'parameters.simulation.control_period' cannot be tuned: 'simulation' sets the loop's timing"),
    ("tune-a-file-key", "tune",
     lambda t, r: [tuning(t, SECOND, '"controller.rule_base" = { low = 0.0, high = 1.0 }'), "--out", "o"],
     r"'parameters.controller.rule_base' is not a number \('.*paper_table2.toml'\) in the base scene"),
    ("tune-unknown-key", "tune",
     lambda t, r: [tuning(t, "input_scale_e", "input_scale_x"), "--out", "o"],
     r"'parameters.controller.input_scale_x' names no key of the base scene; its numbers that can be tuned: "
     r".*controller.input_scale_e, .*plant.air_density"),
    ("tune-unknown-axis", "tune",
     lambda t, r: [tuning(t, "output_gain.travel", "output_gain.swing"), "--out", "o"],
     r"'parameters.controller.output_gain.swing' names no axis of the per-axis list 'controller.output_gain': "
     r"tune controller.output_gain.travel, controller.output_gain.slew, controller.output_gain.luff"),
    ("tune-bound-breaks-a-rule", "tune",
     lambda t, r: [tuning(t, SECOND, '"disturbance.hold_time" = { low = 0.0, high = 1.0 }'), "--out", "o"],
     r"'parameters.disturbance.hold_time' at its bound 0 makes a scene that breaks a rule \('disturbance.hold_time' "
     r"must be > 0"),
    ("tune-budget-of-1e8", "tune",
     lambda t, r: [tuning(t, "evaluations = 5", "evaluations = 100000000"), "--out", "o"],
     r"tune.toml: 'budget.evaluations' \(100000000\) x 1 training seeds: would take more than 12 h: .*or pass --force"),
    # 9. Ownership
    ("fis-convert-over-notes", "fis",
     lambda t, r: ["convert", RULE_BASES / "paper_table2.toml", notes(t, "notes.fis"), "--overwrite"],
     r"notes.fis: exists and was not written by bwr_twin.fis; it is left alone"),
    ("fis-convert-over-toml-notes", "fis",
     lambda t, r: ["convert", TIPPER, notes(t, "notes.toml"), "--overwrite"],
     r"notes.toml: exists and was not written by bwr_twin.fis"),
    ("fis-surface-over-notes", "fis",
     lambda t, r: ["surface", TIPPER, "--out", notes(t, "notes.png"), "--overwrite"],
     r"notes.png: exists and was not written by bwr_twin.fis"),
    ("export-over-html-mentioning-the-tag", "replay",
     lambda t, r: ["short.toml", "--export", notes(t, "notes.html")],
     r"notes.html: exists and was not written by the twin"),
    # 10. Runaway work before any estimate
    ("compare-1e8-seeds", "compare",
     lambda t, r: ["short.toml", "--controllers", "short.toml", SCENES / "pid_paper.toml", "--seeds", 100_000_000,
                   "--out", "c"],
     r"--seeds 100000000: 2 controllers x 100000000 seeds are 200,000,000 runs, more than the 1,000,000"),
    ("compare-1e5-seeds", "compare",
     lambda t, r: ["short.toml", "--controllers", "short.toml", SCENES / "pid_paper.toml", "--seeds", 100_000,
                   "--out", "c"],
     r"are 200,000 runs, more than the 20,000 without --force"),
    ("fis-evaluate-1e9-points", "fis", lambda t, r: ["evaluate", TIPPER, "2", "1", "--points", 10**9],
     r"--points 1000000000: more samples of the output range than the limit of 1,000,000"),
    ("fis-surface-grid-1e5", "fis", lambda t, r: ["surface", TIPPER, "--out", "s.png", "--grid", 100_000],
     r"--grid 100000: 1e\+10 points of the surface .* beyond the limit of 250,000 points"),
    # 11. Replay input
    ("replay-nan-row", "replay", lambda t, r: [damaged_run(t, r, 5, "slew_q_actual_rad", "nan"), "--export", "a.html"],
     r"damaged/timeseries.csv: row 5, column 'slew_q_actual_rad': nan, not a finite number"),
    ("replay-nan-row-in-the-ghost", "replay",
     lambda t, r: [r, "--ghost", damaged_run(t, r, 3, "cp_actual_z_m", "inf"), "--export", "a.html"],
     r"damaged/timeseries.csv: row 3, column 'cp_actual_z_m': inf, not a finite number"),
    ("replay-renamed-column", "replay",
     lambda t, r: [damaged_run(t, r, header=("luff_q_actual_rad", "luff_q_actual_deg")), "--export", "a.html"],
     r"timeseries.csv: no column 'luff_q_actual_rad', which bwr_twin.run writes .*: renamed 'luff_q_actual_deg'\?"),
    ("replay-truncated-csv", "replay", lambda t, r: [damaged_run(t, r, cut=50), "--export", "a.html"],
     r"timeseries.csv: row 50 has \d+ values for the header's \d+ columns \(a truncated or damaged file\)"),
    ("replay-text-in-a-row", "replay",
     lambda t, r: [damaged_run(t, r, 7, "time_s", "abc"), "--export", "a.html"],
     r"timeseries.csv: row 7, column 'time_s': 'abc' is not a number"),
    ("replay-ghost-on-another-path", "replay",
     lambda t, r: [r, "--ghost", damaged_run(t, r, scene=True), "--export", "a.html"],
     r"damaged: not the machine and path of .*: via point P2 \(t = 20 s\) at \(.*\) m against"),
    # 12. Messages: argparse's errors, one line
    ("argparse-run", "run", lambda t, r: ["short.toml"], r"python -m bwr_twin.run: the following arguments are "
     r"required: --out \(see python -m bwr_twin.run --help\)"),
    ("argparse-batch", "batch", lambda t, r: ["sweep.toml", "--out", "b", "--workers", "two"],
     r"python -m bwr_twin.batch: argument --workers: invalid int value: 'two'"),
    ("argparse-compare", "compare", lambda t, r: ["short.toml", "--controllers", "a", "b", "--out", "c", "--seeds", "0"],
     r"python -m bwr_twin.compare: --seeds must be at least 1"),
    ("argparse-replay", "replay", lambda t, r: ["short.toml", "--port", "70000"],
     r"python -m bwr_twin.replay: argument --port: 70000 is not a TCP port"),
    ("argparse-fis", "fis", lambda t, r: ["plot", TIPPER], r"python -m bwr_twin.fis: argument COMMAND: invalid choice"),
    ("argparse-fis-evaluate", "fis", lambda t, r: ["evaluate", TIPPER, "1", "--points", "1e9"],
     r"python -m bwr_twin.fis evaluate: argument --points: invalid int value: '1e9'"),
    ("argparse-tune", "tune", lambda t, r: ["tune.toml"], r"python -m bwr_twin.tune: the following arguments are "
     r"required: --out"),
    ("argparse-passwd", "serve.passwd", lambda t, r: [], r"python -m bwr_twin.serve.passwd: the following arguments "
     r"are required: name"),
]


@pytest.mark.parametrize("case", REFUSALS, ids=[case[0] for case in REFUSALS])
def test_hostile_tool_input_is_refused_and_destroys_nothing(tmp_path, short_run, case):
    _, command, arguments, pattern = case
    write_short_scene(tmp_path)
    args = arguments(tmp_path, short_run)
    before, run_before = snapshot(tmp_path), snapshot(short_run)
    proc = cli(command, *args, cwd=tmp_path)
    assert_refused(proc, pattern)
    assert snapshot(tmp_path) == before and snapshot(short_run) == run_before


def test_one_parameter_is_tuned_by_a_bounded_scalar_search(tmp_path):
    write_short_scene(tmp_path)
    tuning(tmp_path, SECOND + "\n", "")
    proc = cli("tune", "tune.toml", "--out", "out", "--workers", "1", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert "tune.toml: 5 evaluations in 1 generations" in proc.stdout
    header = (tmp_path / "out" / "best_scene.toml").read_text().splitlines()[1]
    assert header == "# bounded scalar search over controller.output_gain.travel,"
    again = cli("tune", "tune.toml", "--out", "out", "--workers", "1", cwd=tmp_path)  # resumes: done already
    assert again.returncode == 0 and "5 evaluations in 1 generations" in again.stdout, again.stderr


def test_a_file_the_twin_wrote_is_replaced_and_its_mark_is_its_first_line(tmp_path):
    from matplotlib.figure import Figure

    from bwr_twin.ownership import picture_metadata, written_by

    for name in ("paper.fis", "paper.toml"):
        proc = cli("fis", "convert", RULE_BASES / "paper_table2.toml", name, cwd=tmp_path)
        assert proc.returncode == 0, proc.stderr
        first = (tmp_path / name).read_text().splitlines()[0]
        assert first == ("% " if name.endswith(".fis") else "# ") + "written by bwr_twin.fis"
    again = cli("fis", "convert", RULE_BASES / "paper_table2.toml", "paper.fis", "--overwrite", cwd=tmp_path)
    assert again.returncode == 0, again.stderr
    for suffix in (".png", ".svg", ".pdf"):  # as fis surface saves them
        figure = Figure()
        figure.subplots().plot([0, 1])
        figure.savefig(tmp_path / f"s{suffix}", metadata=picture_metadata("bwr_twin.fis", suffix))
        assert written_by(tmp_path / f"s{suffix}", "bwr_twin.fis") and not written_by(tmp_path / f"s{suffix}", "other")
        (tmp_path / f"n{suffix}").write_bytes(b"bwr_twin.fis " + (tmp_path / f"s{suffix}").read_bytes()[:200])
        assert not written_by(tmp_path / f"n{suffix}", "bwr_twin.fis")


@pytest.mark.parametrize("encode", [lambda t: BOM + t.encode(), lambda t: t.replace("\n", "\r\n").encode(),
                                    lambda t: BOM + t.replace("\n", "\r\n").encode()], ids=["bom", "crlf", "both"])
def test_a_byte_order_mark_and_crlf_line_ends_are_read_as_without(tmp_path, encode):
    from bwr_twin.config.scene import load_scene
    from bwr_twin.config.tuning import load_tuning
    from bwr_twin.control.rulebase import load_rule_base
    from bwr_twin.fis.convert import load_system

    scene = write_short_scene(tmp_path)
    plain = load_scene(scene)
    (tmp_path / "tune.toml").write_text(TUNING)
    digest = load_tuning(tmp_path / "tune.toml").digest
    for path in (scene, tmp_path / "tune.toml"):
        path.write_bytes(encode(path.read_text()))
    assert load_scene(scene).to_dict() == plain.to_dict()
    assert load_tuning(tmp_path / "tune.toml").digest == digest  # the same tuning: its folder resumes
    (tmp_path / "tipper.fis").write_bytes(encode(TIPPER.read_text()))
    assert load_system(tmp_path / "tipper.fis") == load_system(TIPPER)
    (tmp_path / "rules.toml").write_bytes(encode((RULE_BASES / "paper_table2.toml").read_text()))
    assert load_rule_base(tmp_path / "rules.toml").digest() == load_rule_base(RULE_BASES / "paper_table2.toml").digest()


def test_a_bom_and_crlf_scene_runs_and_a_bom_fis_evaluates_through_the_command_line(tmp_path):
    scene = write_short_scene(tmp_path)
    scene.write_bytes(BOM + scene.read_text().replace("\n", "\r\n").encode())
    proc = cli("run", "short.toml", "--out", "o", "--no-plots", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    (tmp_path / "tipper.fis").write_bytes(BOM + TIPPER.read_bytes().replace(b"\n", b"\r\n"))
    evaluated = cli("fis", "evaluate", "tipper.fis", "2", "1", cwd=tmp_path)
    assert evaluated.returncode == 0 and evaluated.stdout.startswith("output = "), evaluated.stderr


def test_the_controllers_page_example_loads_from_a_folder_outside_scenes(tmp_path):
    from bwr_twin.config.scene import load_scene

    page = (ROOT / "docs" / "controllers.md").read_text()
    (python,) = re.findall(r"```python\n(.*?)```", page, flags=re.S)
    (toml,) = re.findall(r"```toml\n(.*?)```", page, flags=re.S)
    (tmp_path / "gravity_pd.py").write_text(python)
    (tmp_path / "my_scene.toml").write_text(toml)
    scene = load_scene(tmp_path / "my_scene.toml")  # extends the shipped paper_individual_gains.toml
    assert scene.controller.type == f"{tmp_path / 'gravity_pd.py'}:GravityPD"
    assert scene.trajectory.via_points[-1].t == 700.0 and scene.machine.mjcf.name == "bwr.xml"



# 14. Physics that cannot be: a bad scene extends a shipped one and changes one physical input.
# (id, the scene's text after its `extends` line, pattern of the one error line)
PHYSICS_REFUSALS = [
    ("bulk-density-1e30", "heavy_dig_pile", "[stockpile]\nbulk_density = 1e30\n",
     r"bad.toml: 'stockpile.bulk_density' must lie in \[150, 5000\] kg/m3 \(.*CEMA.*\), got 1e\+30"),
    ("bulk-density-in-t-per-m3", "heavy_dig_pile", "[stockpile]\nbulk_density = 2.4\n",
     r"bad.toml: 'stockpile.bulk_density' must lie in \[150, 5000\] kg/m3 .*got 2.4$"),
    ("repose-in-radians", "heavy_dig_pile", "[stockpile.windrow]\nangle_of_repose = 0.65\n",
     r"bad.toml: 'stockpile.windrow.angle_of_repose' must lie in \[10, 60\] deg \(.*CEMA Table 3-1\), "
     r"got 0.65"),
    ("wind-beyond-the-record", "heavy_wind", "[plant]\nwind_speed = 110.0\n",
     r"bad.toml: 'plant.wind_speed' \+ 'plant.gust_amplitude' \(110 \+ 5 m/s\) must be at most 113 m/s, the "
     r"strongest gust ever measured"),
    ("air-density-of-water", "paper_individual_gains", "[plant]\nair_density = 1000.0\n",
     r"bad.toml: 'plant.air_density' must lie in \[0.5, 1.6\] kg/m3 \(.*ISO 2533\), got 1000"),
    ("lateral-ratio-3", "heavy_dig_pile", "[digging]\nlateral_ratio = 3.0\n",
     r"bad.toml: 'digging.lateral_ratio' must lie in \[0, 1\] \(.*\), got 3"),
    ("travel-friction-beyond-the-weight", "paper_individual_gains",
     "[plant]\nfrictionloss = [1e6, 0.0, 0.0]\n",
     r"bad.toml: 'plant.frictionloss' \(travel\) 1e\+06 N is more than friction can be on bwr.xml: at most "
     r"6.87e\+04 N, its weight"),
    ("slew-friction-1e30", "heavy_coulomb_friction", "[plant]\nfrictionloss = [5.85e4, 1e30, 1.0e6]\n",
     r"bad.toml: 'plant.frictionloss' \(slew\) 1e\+30 N m is more than friction can be on bwr_heavy.xml: "
     r"at most 6.9e\+08 N m, its weight at the CP's 59 m reach"),
    ("idle-power-beyond-the-wheel-drive", "heavy_dig_pile", "[digging]\nidle_power = 5e6\n",
     r"bad.toml: 'digging.idle_power' 5e\+06 W is more than the wheel drive of bwr_heavy.xml is rated for "
     r"\(1e\+06 W, its 'wheel_power'\)"),
    ("grid-coarser-than-the-windrow", "heavy_dig_pile", "[stockpile]\ngrid_spacing = 10.0\n",
     r"bad.toml: 'stockpile.grid_spacing' 10 m gives 5 cells across the windrow's footprint of "
     r"159.8 x 49.81 m \(X x Y\), fewer than 8: .*choose at most 6.23 m"),
    ("grid-beyond-the-windrow", "heavy_dig_pile", "[stockpile]\ngrid_spacing = 1000.0\n",
     r"bad.toml: 'stockpile.grid_spacing' 1000 m gives 0.05 cells across the windrow's footprint "
     r".*fewer than 8"),
    ("grid-coarser-than-the-survey", "heavy_reclaim",
     '[stockpile]\nsurface_file = "survey.npz"\ngrid_spacing = 1.0\n',
     r"bad.toml: 'stockpile.grid_spacing' 1 m gives 5.5 cells across the surveyed pile of 10.5 x 5.5 m "
     r"\(X x Y\), fewer than 8: .*choose at most 0.688 m"),
    ("survey-without-a-pile", "heavy_reclaim", '[stockpile]\nsurface_file = "ground.npz"\n',
     r"bad.toml: 'stockpile.surface_file' .*ground.npz: holds no height above the yard floor \(Z = 0 m\): "
     r"there is no pile"),
]


def _surveys(folder: Path) -> None:
    """survey.npz: a 10 x 5 m block of 5 m on a 40 x 30 m survey at 0.5 m; ground.npz: the ground alone."""
    import numpy as np

    x, y = np.arange(0.0, 40.0, 0.5), np.arange(20.0, 50.0, 0.5)
    z = np.zeros((len(y), len(x)))
    np.savez(folder / "ground.npz", x=x, y=y, z=z)
    z[20:30, 30:50] = 5.0
    np.savez(folder / "survey.npz", x=x, y=y, z=z)


@pytest.mark.parametrize("case", PHYSICS_REFUSALS, ids=[case[0] for case in PHYSICS_REFUSALS])
def test_physics_that_cannot_be_is_refused_and_nothing_is_written(tmp_path, case):
    _, base, text, pattern = case
    _surveys(tmp_path)
    (tmp_path / "bad.toml").write_text(f'extends = "{base}"\n\n{text}')
    before = snapshot(tmp_path)
    proc = cli("run", "bad.toml", "--out", "out", "--no-plots", cwd=tmp_path)
    assert_refused(proc, pattern)
    assert snapshot(tmp_path) == before and not (tmp_path / "out").exists()


def test_a_travel_gain_of_2000_on_the_paper_scene_is_held_at_its_rating_and_flagged(tmp_path):
    """The paper's machine has assumed drive ratings (mjcf/README.md): a travel output gain of 2,000,
    which drove it at 80 m/s with 56 MN when it had none, is held at the 3.2 kN rating and flagged."""
    (tmp_path / "fast.toml").write_text('extends = "paper_individual_gains"\n\n[controller]\n'
                                        "output_gain = [2000.0, 0.04, 0.06]\n")
    proc = cli("run", "fast.toml", "--out", "out", "--no-plots", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    travel = json.loads((tmp_path / "out" / "metrics.json").read_text())["travel"]
    assert travel["drive_limit"] == [-3200.0, 3200.0] and abs(travel["drive_force_max"]) == 3200.0
    assert travel["beyond_drive_rating_time"] is not None and travel["saturation_fraction"] > 0.5
    flag = f"travel was commanded beyond its drive rating at {travel['beyond_drive_rating_time']:.2f} s"
    assert f"warning: {flag}" in proc.stdout


# fis evaluate --input (classes 10, 11 and 13): a file of inputs, or stdin, with a bad row, a wrong
# header, bytes that are not UTF-8, or more rows (times output samples) than the limits.
# (id, the file's bytes, given on stdin, more arguments, pattern of the one error line)
FIS_INPUT_REFUSALS = [
    ("text-in-a-row", b"service,food\n2,1\n4,x\n", False, [],
     r"points.csv:3: row 2, column 2: 'x' is not a finite number \(input 2 'food', range \[0 10\]\)"),
    ("nan-in-a-row", b"2,1\r\nnan,1\r\n", False, [],
     r"points.csv:2: row 2, column 1: 'nan' is not a finite number"),
    ("a-short-row", b"2,1\n\n4\n", False, [],
     r"points.csv:3: row 2 has 1 value; the system has 2 inputs \('service', 'food'\), one value each"),
    ("a-bad-row-on-stdin", b"2,1\n4,inf\n", True, [],
     r"<stdin>:2: row 2, column 2: 'inf' is not a finite number"),
    ("a-renamed-column", b"\xef\xbb\xbfservice,meal\n2,1\n", False, [],
     r"points.csv:1: header column 2 'meal' is not input 2 'food' \(a header names the inputs in the .fis "
     r"file's order: service,food\)"),
    ("semicolons", b"2;1\n", False, [], r"points.csv:1: a first row without a number is a header, and this "
     r"one has 1 column for the system's 2 inputs .*values are separated by commas"),
    ("not-utf-8", b"2,1\n\xff\xfe,1\n", False, [], r"points.csv: not a UTF-8 text file \(byte 5\)"),
    ("a-header-alone", b"service,food\n", False, [], r"points.csv: no rows of inputs"),
    ("a-million-and-one-rows", b"1,1\n" * 1_000_001, False, [],
     r"points.csv: 1,000,001 rows of inputs; --input takes at most 1,000,000: split the file"),
    ("rows-times-points", b"1,1\n" * 100_000, False, ["--points", 1_000_000],
     r"points.csv: 100,000 rows x 1,000,000 output samples x 3 rules x 1 output: about 25 min of inference, "
     r"beyond the limit of 10 min; choose a smaller --points or split the rows"),
    ("rows-and-x-values", b"2,1\n", False, ["2", "1"],
     r"python -m bwr_twin.fis evaluate: give one value per input \(X ...\) or --input CSV, not both"),
]


@pytest.mark.parametrize("case", FIS_INPUT_REFUSALS, ids=[case[0] for case in FIS_INPUT_REFUSALS])
def test_a_bad_file_of_fis_inputs_is_refused_and_nothing_is_printed(tmp_path, case):
    _, data, stdin, extra, pattern = case
    if not stdin:
        (tmp_path / "points.csv").write_bytes(data)
    before = snapshot(tmp_path)
    proc = cli("fis", "evaluate", TIPPER, *extra, "--input", "-" if stdin else "points.csv", cwd=tmp_path,
               input=data.decode("latin-1") if stdin else None)
    assert_refused(proc, pattern)
    assert proc.stdout == "" and snapshot(tmp_path) == before


def test_a_bom_and_crlf_file_of_fis_inputs_evaluates_as_without(tmp_path):
    (tmp_path / "points.csv").write_bytes(BOM + b"service,food\r\n2,1\r\n4,5\r\n7,8\r\n")
    proc = cli("fis", "evaluate", TIPPER, "--input", "points.csv", cwd=tmp_path)
    assert proc.returncode == 0 and proc.stderr == "", proc.stderr
    assert proc.stdout == "service,food,tip\n2,1,7.0169\n4,5,14.4585\n7,8,20.3414\n"  # MATLAB's evalfis
