"""Every MJCF under mjcf/ compiles, meets the model contract and steps quietly."""


import mujoco
import numpy as np
import pytest
from conftest import PAPER_MJCF, VARIANT_MJCF

from bwr_twin import Machine, ModelError
from bwr_twin.shipped import MJCF

MODEL_FILES = sorted(MJCF.glob("*.xml")) + [VARIANT_MJCF]


@pytest.mark.parametrize("path", MODEL_FILES, ids=lambda p: p.name)
def test_model_steps_10_s_unactuated_without_warning(path):
    machine = Machine(path)  # the contract holds, or this raises
    model = machine.model
    data = mujoco.MjData(model)
    if model.nkey:
        mujoco.mj_resetDataKeyframe(model, data, 0)
    for _ in range(int(round(10.0 / model.opt.timestep))):
        mujoco.mj_step(model, data)
    warnings = {mujoco.mjtWarning(i).name: data.warning[i].number for i in range(len(data.warning))}
    assert not any(warnings.values()), warnings
    assert np.all(np.isfinite(data.qpos))


@pytest.mark.parametrize("path", MODEL_FILES, ids=lambda p: p.name)
def test_visual_geometry_carries_no_mass_and_no_contacts(path):
    model = Machine(path).model
    moving = model.geom_bodyid > 0
    assert np.all(model.geom_contype[moving] == 0) and np.all(model.geom_conaffinity[moving] == 0)
    # Masses come from explicit <inertial> elements: recompiling with geoms made massless changes nothing.
    spec = mujoco.MjSpec.from_file(str(path))
    for geom in spec.geoms:
        geom.density = 0
        geom.mass = 0
    np.testing.assert_array_equal(spec.compile().body_mass, model.body_mass)


def test_paper_machine_has_home_keyframe_at_first_via_point():
    machine = Machine(PAPER_MJCF)
    key = mujoco.mj_name2id(machine.model, mujoco.mjtObj.mjOBJ_KEY, "home")
    assert key >= 0
    np.testing.assert_allclose(machine.fk(machine.model.key_qpos[key]), [55, 0, 11])


def test_missing_file_is_a_model_error(tmp_path):
    with pytest.raises(ModelError, match="missing.xml: MJCF file not found"):
        Machine(tmp_path / "missing.xml")


def test_contract_breach_names_file_and_what_is_wrong(tmp_path):
    text = PAPER_MJCF.read_text()
    text = text.replace('<joint name="luff"', '<joint name="boom_hinge"').replace('joint="luff"', 'joint="boom_hinge"')
    path = tmp_path / "renamed.xml"
    path.write_text(text)
    with pytest.raises(ModelError, match=r"renamed.xml: .*joints \['travel', 'slew', 'luff'\]"):
        Machine(path)


def test_malformed_mjcf_is_a_model_error(tmp_path):
    path = tmp_path / "broken.xml"
    path.write_text("<mujoco><worldbody><body></mujoco>")
    with pytest.raises(ModelError, match="broken.xml: MuJoCo cannot compile it"):
        Machine(path)


def test_paper_machine_has_the_assumed_drive_ratings_of_its_readme():
    """mjcf/README.md, drive ratings of bwr.xml: the paper gives none, these are assumed."""
    machine = Machine(PAPER_MJCF)
    np.testing.assert_array_equal(machine.drive_limits, [[-3.2e3, 3.2e3], [-3.0e4, 3.0e4], [-5.6e5, 1.1e6]])
    np.testing.assert_array_equal(machine.rated_speed, [0.5, 0.02, 0.002])
    # Raising, the luff drive holds 2.24 x the boom's largest gravity torque (m3 g x 25 m at luff 0), as the
    # heavy machine's does.
    data = mujoco.MjData(machine.model)
    mujoco.mj_forward(machine.model, data)
    assert machine.drive_limits[2, 1] / data.qfrc_bias[2] == pytest.approx(2.24, abs=0.01)
