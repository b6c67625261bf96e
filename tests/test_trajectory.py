"""The desired path (paper Sec. 4): cubic segments with zero velocity at the via points."""

import numpy as np
import pytest
from conftest import PAPER_VIA_POINTS

from bwr_twin import EnvelopeError, UnreachableError
from bwr_twin.config.sections import PathSection, ViaPoint
from bwr_twin.model.machine import paper_to_world
from bwr_twin.planning.trajectory import Trajectory


def paper_path():
    return PathSection(frame="paper", via_points=tuple(ViaPoint(t, p) for t, p in PAPER_VIA_POINTS))


def test_path_passes_every_via_point_at_rest(paper_machine):
    trajectory = Trajectory.plan(paper_path(), paper_machine)
    q, qd, _ = trajectory.sample(trajectory.times)
    np.testing.assert_allclose(paper_machine.fk(q), paper_to_world([p for _, p in PAPER_VIA_POINTS]), atol=1e-9)
    np.testing.assert_allclose(qd, 0, atol=1e-15)


def test_velocity_and_acceleration_are_derivatives_of_position(paper_machine):
    trajectory = Trajectory.plan(paper_path(), paper_machine)
    t = np.linspace(1, 699, 777)
    h = 1e-4
    q_plus, q_minus = trajectory.sample(t + h)[0], trajectory.sample(t - h)[0]
    _, qd, qdd = trajectory.sample(t)
    np.testing.assert_allclose((q_plus - q_minus) / (2 * h), qd, atol=1e-8)
    qd_plus, qd_minus = trajectory.sample(t + h)[1], trajectory.sample(t - h)[1]
    np.testing.assert_allclose((qd_plus - qd_minus) / (2 * h), qdd, atol=1e-8)


def test_segment_is_the_cubic_with_zero_end_velocities(paper_machine):
    trajectory = Trajectory.plan(paper_path(), paper_machine)
    q0, q1 = trajectory.knots[1], trajectory.knots[2]  # 200 s -> 300 s
    q_mid, qd_mid, qdd_start = trajectory.sample(250.0)[0], trajectory.sample(250.0)[1], trajectory.sample(200.0)[2]
    np.testing.assert_allclose(q_mid, (q0 + q1) / 2, atol=1e-12)
    np.testing.assert_allclose(qd_mid, 1.5 * (q1 - q0) / 100, atol=1e-12)  # peak of 6 s (1 - s) / T
    np.testing.assert_allclose(qdd_start, 6 * (q1 - q0) / 100**2, atol=1e-12)


def test_unreachable_via_point_is_named(paper_machine):
    via = list(paper_path().via_points)
    via[3] = ViaPoint(500.0, (-38.5, -80.0, 50.0))
    with pytest.raises(UnreachableError, match=r"via point 4 \(t = 500 s\)"):
        Trajectory.plan(PathSection("paper", tuple(via)), paper_machine)


def test_via_point_outside_envelope_is_named(paper_machine):
    via = list(paper_path().via_points)
    via[1] = ViaPoint(200.0, (-35.0, -11.0, -10.0))  # travel about -52 m
    with pytest.raises(EnvelopeError, match=r"via point 2 \(t = 200 s\).*travel = -5\d\.\d+ m is outside"):
        Trajectory.plan(PathSection("paper", tuple(via)), paper_machine)


def test_whole_path_is_checked_not_only_the_via_points(paper_machine):
    # Knots built by hand, past the envelope mid-segment: the sampled check names the segment.
    times = np.array([0.0, 100.0, 200.0])
    knots = np.array([[0.0, 0.0, 0.0], [20.0, 0.3, 0.1], [0.0, 0.0, 0.0]])
    knots[1, 0] = 30.0
    trajectory = Trajectory(times=times, knots=knots, points=paper_machine.fk(knots))
    with pytest.raises(EnvelopeError, match=r"segment from via point 1 to 2 \(t = 100.0 s\): travel reaches 30.000 m"):
        trajectory.check_envelope(paper_machine)
