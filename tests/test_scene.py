"""Scene files load into typed configuration, and every broken rule is named in one line."""

import re

import numpy as np
import pytest
from conftest import MJCF, PAPER_MJCF, PAPER_VIA_POINTS, SCENES

from bwr_twin import SceneError
from bwr_twin.config.scene import load_scene

INDIVIDUAL = SCENES / "paper_individual_gains.toml"


def edited(tmp_path, old, new, source=INDIVIDUAL):
    text = source.read_text()
    assert old in text, old
    path = tmp_path / "edited.toml"
    path.write_text(text.replace(old, new, 1).replace('"../mjcf/', f'"{PAPER_MJCF.parent}/').replace(
        '"rulebases/', f'"{SCENES}/rulebases/'))
    return path


@pytest.mark.parametrize("name, gains", [("paper_shared_gain", (0.001,) * 3), ("paper_individual_gains", (0.01, 0.04, 0.06))])
def test_paper_scenes_hold_the_paper_settings(name, gains):
    scene = load_scene(SCENES / f"{name}.toml")
    assert scene.controller.settings.output_gain == gains
    assert scene.controller.settings.input_scale_e == scene.controller.settings.input_scale_ec == 50
    assert scene.encoders.resolution == (0.00153, 0.00153, 0.00076)
    assert scene.disturbance.amplitude == (100, 100, 100)
    assert scene.machine.mjcf == PAPER_MJCF
    assert scene.controller_mjcf == PAPER_MJCF
    assert scene.trajectory.frame == "paper"
    assert [(v.t, v.p) for v in scene.trajectory.via_points] == PAPER_VIA_POINTS
    assert not scene.controller.settings.acceleration_feedforward


def test_overrides_are_validated_like_the_file():
    scene = load_scene(INDIVIDUAL, {"simulation.seed": 7, "controller.output_gain": [0.02, 0.04, 0.06]})
    assert scene.simulation.seed == 7 and scene.controller.settings.output_gain == (0.02, 0.04, 0.06)
    with pytest.raises(SceneError, match=r"'controller.output_gain' must hold 3 values"):
        load_scene(INDIVIDUAL, {"controller.output_gain": [0.02]})


@pytest.mark.parametrize("key, value, named", [
    ("plant.frictionloss", [float("inf"), 1.0, 1.0], "plant.frictionloss[0]"),
    ("plant.wind_direction", float("nan"), "plant.wind_direction"),
    ("plant.wind_speed", float("-inf"), "plant.wind_speed"),
    ("plant.payload", [{"body": "boom", "mass": 1.0, "pos": [0.0, float("nan"), 0.0]}], "plant.payload[0].pos[1]"),
])
def test_numbers_that_are_not_numbers_are_refused_naming_the_key(key, value, named):
    with pytest.raises(SceneError, match=rf"'{re.escape(named)}' must be a finite number, got (nan|inf|-inf)"):
        load_scene(INDIVIDUAL, {key: value})


@pytest.mark.parametrize(
    "old, new, message",
    [
        ("seed = 1", "seed = 1\nsed = 2", r"edited.toml: unknown key 'simulation.sed' \(valid here: .*seed"),
        ("seed = 1", 'seed = "one"', r"edited.toml: 'simulation.seed' must be an integer, got 'one'"),
        ("output_gain = [0.01, 0.04, 0.06]", "output_gain = [0.01, -0.04, 0.06]", r"'controller.output_gain \(slew\)' must be > 0"),
        ("output_gain = [0.01, 0.04, 0.06]", "output_gain = [0.01, 0.04]", r"'controller.output_gain' must hold 3 values"),
        ('frame = "paper"', 'frame = "local"', r"'path.frame' must be one of \['paper', 'world'\]"),
        ("t = 300.0", "t = 150.0", r"via point 3 \(t = 150.0 s\) must come after via point 2 \(t = 200.0 s\)"),
        ("timestep = 0.002", "timestep = 0.003", r"'simulation.control_period' \(0.01 s\) must be a whole multiple"),
        ('mjcf = "../mjcf/bwr.xml"', 'mjcf = "../mjcf/nowhere.xml"', r"'machine.mjcf' names a file that does not exist: .*nowhere.xml"),
        ("[encoders]\n", "", r"edited.toml: unknown key 'simulation.resolution'"),
        ("velocity_source = \"true\"", "velocity_source = true", r"'encoders.velocity_source' must be one of"),
        ("acceleration_feedforward = false", 'acceleration_feedforward = false\nvelocity_filter = 0.1',
         r"'controller.velocity_filter' has moved: write it as 'encoders.velocity_filter'"),
        ("timestep = 0.002", "timestep = inf", r"'simulation.timestep' must be a finite number, got inf"),
        ("amplitude = [100.0, 100.0, 100.0]", "amplitude = [100.0, nan, 100.0]",
         r"'disturbance.amplitude\[1\]' must be a finite number, got nan"),
        ("t = 300.0", "t = inf", r"'path.via_points\[2\].t' must be a finite number, got inf"),
        ("seed = 1", "seed = -3", r"'simulation.seed' must be >= 0, got -3"),
        ("record_period = 0.1", "record_period = 0.015",
         r"'simulation.record_period' \(0.015 s\) must be a whole multiple of 'simulation.control_period' \(0.01 s\)"),
    ],
)
def test_bad_scene_names_file_key_and_rule(tmp_path, old, new, message):
    with pytest.raises(SceneError, match=message):
        load_scene(edited(tmp_path, old, new))


def test_malformed_toml_names_the_file_and_line(tmp_path):
    path = tmp_path / "broken.toml"
    path.write_text("[simulation\nseed = 1\n")
    with pytest.raises(SceneError, match=r"broken.toml: malformed TOML: .*line 1"):
        load_scene(path)


def test_missing_scene_file(tmp_path):
    with pytest.raises(SceneError, match="nope.toml: scene file not found"):
        load_scene(tmp_path / "nope.toml")


def test_scene_round_trips_to_plain_data():
    scene = load_scene(INDIVIDUAL)
    plain = scene.to_dict()
    assert plain["machine"]["mjcf"] == str(PAPER_MJCF)
    assert np.allclose(plain["trajectory"]["via_points"][2]["p"], [-55, -11, 2])


def test_a_scene_extends_another_and_overrides_only_what_it_names():
    shared = load_scene(SCENES / "paper_shared_gain.toml")
    individual = load_scene(INDIVIDUAL)
    assert shared.controller.settings.output_gain == (0.001,) * 3
    assert shared.trajectory == individual.trajectory and shared.encoders == individual.encoders
    assert shared.controller.settings.rule_base == individual.controller.settings.rule_base


def test_extends_cycle_and_missing_base_are_named(tmp_path):
    (tmp_path / "a.toml").write_text('extends = "b.toml"\n')
    (tmp_path / "b.toml").write_text('extends = "a.toml"\n')
    with pytest.raises(SceneError, match=r"b.toml: 'extends' makes a cycle through a.toml"):
        load_scene(tmp_path / "a.toml")
    (tmp_path / "c.toml").write_text('extends = "gone.toml"\n')
    with pytest.raises(SceneError, match=r"c.toml: 'extends' names 'gone.toml', neither a file beside it "
                                         r"\(.*gone.toml\) nor a shipped scene"):
        load_scene(tmp_path / "c.toml")


def test_extends_names_a_shipped_scene_and_a_file_beside_it_wins(tmp_path):
    (tmp_path / "mine.toml").write_text('extends = "heavy_reclaim"\n[simulation]\nseed = 7\n')
    scene = load_scene(tmp_path / "mine.toml")
    assert scene.simulation.seed == 7 and scene.machine.mjcf.name == "bwr_heavy.xml"
    (tmp_path / "heavy_reclaim").write_text((SCENES / "paper_individual_gains.toml").read_text()
                                            .replace('"../mjcf/', f'"{MJCF}/')
                                            .replace('"rulebases/', f'"{SCENES}/rulebases/'))
    (tmp_path / "beside.toml").write_text('extends = "heavy_reclaim"\n')
    assert load_scene(tmp_path / "beside.toml").machine.mjcf.name == "bwr.xml"


def test_an_extending_scene_replaces_inherited_alternatives_and_tables(tmp_path):
    np.savez(tmp_path / "survey.npz", x=np.arange(0.0, 40.0, 0.5), y=np.arange(20.0, 50.0, 0.5),
             z=np.full((60, 80), 5.0))
    (tmp_path / "survey.toml").write_text('extends = "heavy_reclaim"\n[stockpile]\nsurface_file = "survey.npz"\n')
    pile = load_scene(tmp_path / "survey.toml").stockpile
    assert pile.windrow is None and pile.surface_file == tmp_path / "survey.npz"
    (tmp_path / "tonnes.toml").write_text('extends = "heavy_bench_reclaim"\n[reclaim]\nstop = { tonnes = 500.0 }\n')
    stop = load_scene(tmp_path / "tonnes.toml").reclaim.stop
    assert (stop.benches, stop.tonnes) == (None, 500.0)
    (tmp_path / "bare.toml").write_text('extends = "heavy_dig_pile"\nreplace = ["digging"]\n')
    assert load_scene(tmp_path / "bare.toml").digging is None
    (tmp_path / "both.toml").write_text('extends = "heavy_reclaim"\n[stockpile]\nsurface_file = "survey.npz"\n'
                                        "[stockpile.windrow]\nlength = 1.0\n")
    with pytest.raises(SceneError, match=r"needs either a \[stockpile.windrow\] or a 'stockpile.surface_file', not both"):
        load_scene(tmp_path / "both.toml")
    (tmp_path / "alone.toml").write_text('replace = ["digging"]\n')
    with pytest.raises(SceneError, match=r"alone.toml: 'replace' names tables of the scene it extends, but it has no"):
        load_scene(tmp_path / "alone.toml")


def test_plant_payload_is_validated():
    with pytest.raises(SceneError, match=r"'plant.payload\[0\].mass' must be > 0"):
        load_scene(INDIVIDUAL, {"plant.payload": [{"body": "boom", "mass": -1.0, "pos": [0.0, 0.0, 0.0]}]})
    with pytest.raises(SceneError, match=r"unknown key 'plant.payload\[0\].weight'"):
        load_scene(INDIVIDUAL, {"plant.payload": [{"body": "boom", "weight": 1.0, "pos": [0.0, 0.0, 0.0]}]})
