"""A heavy port reclaimer by swapping the MJCF, its drive limits, and the unmodelled effects
(Coulomb friction, wind, a wrong controller model), each moving the result the expected way."""

import numpy as np
import pytest
from conftest import HEAVY_MJCF, SCENES

from bwr_twin import ModelError
from bwr_twin.config.scene import load_scene
from bwr_twin.model.machine import AXES
from bwr_twin.sim.lockstep import simulate

# A 500 s path on which all three axes move: (travel m, slew deg, luff deg) from
# (-40, 0, 5) to (-30, 40, 8) to (-20, 80, 0).
FIRST_LEGS = {
    "path.via_points": [
        {"t": 0.0, "p": [18.791, 0.0, 18.794]},
        {"t": 200.0, "p": [14.787, 37.580, 21.655]},
        {"t": 500.0, "p": [-9.755, 58.104, 14.0]},
    ]
}


def run(scene_name, **overrides):
    result = simulate(load_scene(SCENES / f"{scene_name}.toml", overrides))
    return result, result.metrics


@pytest.fixture(scope="module")
def nominal_first_legs():
    return run("heavy_reclaim", **FIRST_LEGS)


@pytest.mark.slow
def test_heavy_machine_tracks_its_path_with_the_paper_gains():
    result, m = run("heavy_reclaim")
    assert result.machine.path == HEAVY_MJCF
    assert result.machine.model.body_subtreemass[0] > 500e3  # hundreds of tonnes
    assert abs(m["travel"]["position_error_max"]) <= 0.05
    for axis in ("slew", "luff"):
        assert np.degrees(abs(m[axis]["position_error_max"])) <= 0.1, axis
        assert m[axis]["saturation_fraction"] == 0.0


def test_paper_path_runs_on_the_heavy_machine_by_swapping_the_mjcf():
    result, m = run("paper_individual_gains", **{"machine.mjcf": str(HEAVY_MJCF)})
    assert result.scene.controller_mjcf == HEAVY_MJCF  # the belief follows the swap
    np.testing.assert_allclose(result.cp_desired[0], [55.0, 0.0, 11.0], atol=1e-9)  # paper's p_i
    assert abs(m["travel"]["position_error_max"]) <= 0.05


def test_drive_limits_are_honoured_and_saturation_is_reported():
    # Ten seconds for a 60 deg slew: more than the slew drive can give.
    fast = {"path.via_points": [{"t": 0.0, "p": [18.791, 0.0, 18.794]}, {"t": 10.0, "p": [-10.605, 50.914, 18.794]}]}
    result, m = run("heavy_reclaim", **fast)
    limits = result.machine.drive_limits
    for j, axis in enumerate(AXES):
        assert np.all(result.drive_force[:, j] >= limits[j, 0] - 1e-6)
        assert np.all(result.drive_force[:, j] <= limits[j, 1] + 1e-6)
    assert m["slew"]["saturation_fraction"] > 0.05
    assert max(abs(result.drive_force_command[:, 1])) > limits[1, 1]
    assert m["slew"]["drive_limit"] == pytest.approx([-1.13e7, 1.13e7])


def test_coulomb_friction_raises_the_tracking_error(nominal_first_legs):
    _, nominal = nominal_first_legs
    _, rubbing = run("heavy_coulomb_friction", **FIRST_LEGS)
    for axis in AXES:
        assert rubbing[axis]["position_error_rms"] > nominal[axis]["position_error_rms"], axis
    assert abs(rubbing["travel"]["position_error_max"]) > 2 * abs(nominal["travel"]["position_error_max"])


def test_a_wrong_controller_model_raises_the_tracking_error(nominal_first_legs):
    nominal_result, nominal = nominal_first_legs
    result, wrong = run("heavy_model_mismatch", **FIRST_LEGS)
    # The plant carries 23 t the controller's belief does not.
    assert result.machine.model.body_subtreemass[0] == pytest.approx(nominal_result.machine.model.body_subtreemass[0] + 23e3)
    assert abs(wrong["luff"]["position_error_max"]) > 2 * abs(nominal["luff"]["position_error_max"])
    assert wrong["luff"]["position_error_rms"] > nominal["luff"]["position_error_rms"]


def test_stronger_wind_raises_the_slew_drive_torque():
    calm = {**FIRST_LEGS, "plant.gust_amplitude": 0.0}
    torque = [run("heavy_wind", **calm, **{"plant.wind_speed": v})[1]["slew"]["drive_force_rms"] for v in (0.0, 10.0, 25.0)]
    assert torque[0] < torque[1] < torque[2]
    assert torque[2] > 1.5 * torque[0]


def test_a_payload_on_a_body_the_model_lacks_is_named():
    scene = load_scene(SCENES / "heavy_model_mismatch.toml", {"plant.payload": [{"body": "jib", "mass": 1.0, "pos": [0.0, 0.0, 0.0]}]})
    with pytest.raises(ModelError, match=r"bwr_heavy.xml: payload 1 names a body 'jib'"):
        simulate(scene)
