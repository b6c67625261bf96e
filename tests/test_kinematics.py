"""Kinematics read from the model: the paper's Eq. (2) and (3), generalised to any machine file."""

import mujoco
import numpy as np
import pytest
from conftest import PAPER_VIA_POINTS

from bwr_twin import EnvelopeError, UnreachableError
from bwr_twin.model.machine import paper_to_world, world_to_paper


def paper_eq3(x, y, z):
    """The paper's inverse kinematics, Eq. (3), in frame 0, as printed."""
    t3 = np.arctan2(-y - 11, np.sqrt(50**2 - (y + 11) ** 2))
    t2 = np.arcsin(-x / (50 * np.cos(t3) + 5))
    d1 = z - 50 * np.cos(t2) * np.cos(t3) - 5 * np.cos(t2)
    return np.array([d1, t2, t3])


def paper_eq2(q):
    """The CP column of the paper's forward kinematics, Eq. (2), in frame 0."""
    d1, t2, t3 = q
    return np.array(
        [
            -np.sin(t2) * (50 * np.cos(t3) + 5),
            -50 * np.sin(t3) - 11,
            50 * np.cos(t2) * np.cos(t3) + 5 * np.cos(t2) + d1,
        ]
    )


def random_configurations(machine, n=1000, seed=0):
    low, high = machine.envelope.T
    return np.random.default_rng(seed).uniform(low, high, size=(n, 3))


def test_geometry_read_from_model_is_table_1(paper_machine):
    g = paper_machine.geometry
    assert g.pivot_height == pytest.approx(6 + 5)  # L2 + L3
    assert g.pivot_reach == pytest.approx(5)  # L4
    assert g.boom_length == pytest.approx(50)  # L5
    assert g.slew_axis_xy == pytest.approx((0, 0))
    assert g.boom_angle0 == pytest.approx(0)
    np.testing.assert_allclose(
        paper_machine.envelope, [[-25, 25], np.radians([-90, 90]), np.radians([-15, 15])], rtol=1e-15
    )


@pytest.mark.parametrize("index", range(len(PAPER_VIA_POINTS)))
def test_via_points_map_to_the_joint_values_they_imply(paper_machine, index):
    _, p_paper = PAPER_VIA_POINTS[index]
    q = paper_machine.ik(paper_to_world(p_paper))
    np.testing.assert_allclose(q, paper_eq3(*p_paper), atol=1e-12)
    np.testing.assert_allclose(world_to_paper(paper_machine.fk(q)), p_paper, atol=1e-9)
    np.testing.assert_allclose(paper_eq2(q), p_paper, atol=1e-9)


def test_second_via_point_is_exactly_at_slew_90_degrees(paper_machine):
    q = paper_machine.ik(paper_to_world(PAPER_VIA_POINTS[2][1]))
    assert q[1] == np.pi / 2
    assert q[1] == paper_machine.envelope[1, 1]


def test_fk_equals_paper_eq2(paper_machine):
    for q in random_configurations(paper_machine, n=200):
        np.testing.assert_allclose(world_to_paper(paper_machine.fk(q)), paper_eq2(q), atol=1e-9)


def test_fk_equals_mujoco_site_position(any_machine):
    data = mujoco.MjData(any_machine.model)
    for q in random_configurations(any_machine, n=200, seed=1):
        data.qpos[:] = q
        mujoco.mj_kinematics(any_machine.model, data)
        np.testing.assert_allclose(any_machine.fk(q), data.site_xpos[any_machine.cp_site], atol=1e-9)


def test_fk_of_ik_is_identity(any_machine):
    points = any_machine.fk(random_configurations(any_machine, seed=2))
    for p in points:
        np.testing.assert_allclose(any_machine.fk(any_machine.ik(p)), p, atol=1e-9)


def test_ik_of_fk_is_identity(any_machine):
    for q in random_configurations(any_machine, seed=3):
        np.testing.assert_allclose(any_machine.ik(any_machine.fk(q)), q, atol=1e-9)


def test_frame_mapping_round_trips():
    p = np.random.default_rng(4).normal(size=(10, 3))
    np.testing.assert_array_equal(world_to_paper(paper_to_world(p)), p)
    np.testing.assert_array_equal(paper_to_world([0, -11, 55]), [55, 0, 11])


def test_unreachable_height_names_point_and_limit(any_machine):
    g = any_machine.geometry
    too_high = [g.slew_axis_xy[0] + 10, g.slew_axis_xy[1], g.pivot_height + g.boom_length + 1]
    with pytest.raises(UnreachableError, match=r"via point 4 at world .*height Z = .* boom's reach"):
        any_machine.ik(too_high, label="via point 4")


def test_unreachable_lateral_offset_names_the_reach(paper_machine):
    with pytest.raises(UnreachableError, match=r"lateral offset 60.000 m .* exceeds .* reach 55.000 m"):
        paper_machine.ik(paper_to_world([-60, -11, 0]), label="via point 2")


def test_outside_envelope_names_axis_limit_and_value(paper_machine):
    with pytest.raises(EnvelopeError, match=r"via point 3 .*travel = 30.000 m is outside .*\[-25.000 m, 25.000 m\]"):
        paper_machine.ik(paper_to_world([0, -11, 85]), label="via point 3")
    with pytest.raises(EnvelopeError, match=r"luff = 2\d\.\d+ deg is outside .*15.000 deg"):
        paper_machine.ik(paper_to_world([0, -30, 45]), label="via point 1")
    # The same point is fine when the caller takes the envelope into its own hands.
    q = paper_machine.ik(paper_to_world([0, -11, 85]), check_envelope=False)
    assert q[0] == pytest.approx(30)
