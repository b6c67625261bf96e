"""MuJoCo's dynamics of mjcf/bwr.xml equal the paper's closed-form M, V and G (Sec. 1.2).

The paper orders its joints (theta2, theta3, d1) = (slew, luff, travel); MuJoCo's qpos order is
(travel, slew, luff). The printed V(1,1) is off by a factor of ten; V below is derived from the
printed M by Lagrange's equations (mjcf/README.md, errata).
"""

from types import SimpleNamespace

import mujoco
import numpy as np
import pytest

N_STATES = 200
PAPER_TO_MUJOCO = [2, 0, 1]  # paper index of each MuJoCo dof: travel=d1, slew=theta2, luff=theta3


def paper_masses(model):
    body = lambda name: model.body_mass[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name)]
    return body("carriage"), body("turntable"), body("boom")


def paper_M(q, m1, m2, m3):
    """The printed mass matrix in paper order (theta2, theta3, d1); q in MuJoCo order."""
    _, t2, t3 = q
    s2, c2, s3, c3 = np.sin(t2), np.cos(t2), np.sin(t3), np.cos(t3)
    m11 = 25 * m2 / 4 + 25 * m3 * (1 + 10 * c3) + 625 * m3 * c3**2
    m13 = -0.5 * s2 * (5 * m2 + 10 * m3 + 50 * m3 * c3)
    m23 = -25 * m3 * s3 * c2
    return np.array([[m11, 0, m13], [0, 625 * m3, m23], [m13, m23, m1 + m2 + m3]])


def paper_V(q, qd, m2, m3, *, v11_as_printed=False):
    """Coriolis/centrifugal vector, paper order; V(1,1) derived from M unless asked otherwise."""
    _, t2, t3 = q
    _, w2, w3 = qd
    s2, c2, s3, c3 = np.sin(t2), np.cos(t2), np.sin(t3), np.cos(t3)
    v1 = (-25 if v11_as_printed else -250) * m3 * w2 * w3 * s3 * (1 + 5 * c3)
    v2 = 125 * m3 * w2**2 * s3 * (1 + 5 * c3)
    v3 = (
        -2.5 * m2 * w2**2 * c2
        - 5 * m3 * w2**2 * c2
        - 25 * m3 * w2**2 * c2 * c3
        + 50 * m3 * w2 * w3 * s2 * s3
        - 25 * m3 * w3**2 * c2 * c3
    )
    return np.array([v1, v2, v3])


def paper_G(q, m3, g):
    return np.array([0.0, 25 * m3 * g * np.cos(q[2]), 0.0])


def to_mujoco_order(paper_vector_or_matrix):
    x = np.asarray(paper_vector_or_matrix)
    return x[np.ix_(PAPER_TO_MUJOCO, PAPER_TO_MUJOCO)] if x.ndim == 2 else x[PAPER_TO_MUJOCO]


def random_states(machine, seed=0, n=N_STATES):
    rng = np.random.default_rng(seed)
    low, high = machine.envelope.T
    q = rng.uniform(low, high, size=(n, 3))
    qd = rng.uniform([-0.5, -0.05, -0.05], [0.5, 0.05, 0.05], size=(n, 3))  # m/s, rad/s
    return zip(q, qd)


def rel_err(actual, expected):
    return np.max(np.abs(actual - expected)) / np.max(np.abs(expected))


def test_mass_matrix_equals_paper_M(paper_machine):
    model = paper_machine.model
    data = mujoco.MjData(model)
    m1, m2, m3 = paper_masses(model)
    M = np.zeros((3, 3))
    for q, _ in random_states(paper_machine):
        data.qpos[:] = q
        mujoco.mj_forward(model, data)
        mujoco.mj_fullM(model, data, M)
        assert rel_err(M, to_mujoco_order(paper_M(q, m1, m2, m3))) <= 1e-9


def test_bias_without_gravity_equals_V_derived_from_M(paper_machine):
    model = paper_machine.model
    model_no_g = mujoco.MjModel.from_xml_path(str(paper_machine.path))
    model_no_g.opt.gravity[:] = 0
    data = mujoco.MjData(model_no_g)
    _, m2, m3 = paper_masses(model)
    printed_errors = []
    for q, qd in random_states(paper_machine, seed=1):
        data.qpos[:], data.qvel[:] = q, qd
        mujoco.mj_forward(model_no_g, data)
        scale = max(np.max(np.abs(paper_V(q, qd, m2, m3))), 1.0)
        derived = to_mujoco_order(paper_V(q, qd, m2, m3))
        printed = to_mujoco_order(paper_V(q, qd, m2, m3, v11_as_printed=True))
        assert np.max(np.abs(data.qfrc_bias - derived)) / scale <= 1e-9
        printed_errors.append(np.max(np.abs(data.qfrc_bias - printed)) / scale)
    # The erratum is real: the printed V(1,1) disagrees with MuJoCo (and with M).
    assert np.median(printed_errors) > 1e-3


def test_bias_at_rest_equals_G(paper_machine):
    model = paper_machine.model
    data = mujoco.MjData(model)
    _, _, m3 = paper_masses(model)
    g = -model.opt.gravity[2]
    assert g == pytest.approx(9.81)
    for q, _ in random_states(paper_machine, seed=2):
        data.qpos[:] = q
        data.qvel[:] = 0
        mujoco.mj_forward(model, data)
        assert rel_err(data.qfrc_bias, to_mujoco_order(paper_G(q, m3, g))) <= 1e-9


def test_full_bias_equals_V_plus_G(paper_machine):
    model = paper_machine.model
    data = mujoco.MjData(model)
    _, m2, m3 = paper_masses(model)
    for q, qd in random_states(paper_machine, seed=3):
        data.qpos[:], data.qvel[:] = q, qd
        mujoco.mj_forward(model, data)
        expected = to_mujoco_order(paper_V(q, qd, m2, m3) + paper_G(q, m3, 9.81))
        assert rel_err(data.qfrc_bias, expected) <= 1e-9


def test_viscous_friction_is_joint_damping_not_bias(paper_machine):
    model = paper_machine.model
    undamped = mujoco.MjModel.from_xml_path(str(paper_machine.path))
    undamped.dof_damping[:] = 0
    data, data_undamped = mujoco.MjData(model), mujoco.MjData(undamped)
    np.testing.assert_array_equal(model.dof_damping, [0.05, 0.05, 0.05])  # paper Sec. 1.3
    for q, qd in random_states(paper_machine, seed=4, n=20):
        for d, m in ((data, model), (data_undamped, undamped)):
            d.qpos[:], d.qvel[:] = q, qd
            mujoco.mj_forward(m, d)
        np.testing.assert_allclose(data.qfrc_damper, -0.05 * qd, rtol=1e-12, atol=0)
        np.testing.assert_array_equal(data.qfrc_bias, data_undamped.qfrc_bias)


@pytest.mark.parametrize("mjcf", ["paper", "heavy", "variant", "heavy with payload"])
def test_the_closed_form_gives_mujocos_mass_matrix_and_bias(mjcf):
    """bwr_twin.model.dynamics: M and bias identified from the compiled model equal MuJoCo's at
    states and speeds it was not fitted at, over every angle."""
    from conftest import HEAVY_MJCF, PAPER_MJCF, VARIANT_MJCF

    from bwr_twin import Machine

    path = {"paper": PAPER_MJCF, "heavy": HEAVY_MJCF, "variant": VARIANT_MJCF,
            "heavy with payload": HEAVY_MJCF}[mjcf]
    payload = SimpleNamespace(body="bucket_wheel", mass=23000.0, pos=(1.0, 0.5, 0.0))  # kg, m: off-centre
    payloads = (payload,) if "payload" in mjcf else ()
    machine = Machine(path, payloads=payloads)
    model = machine.physics_model(rigid_body_only=True)
    data = mujoco.MjData(model)
    rng = np.random.default_rng(7)
    dense = np.zeros((3, 3))
    for _ in range(100):
        q = rng.uniform([-30, -np.pi, -np.pi], [30, np.pi, np.pi])
        qd = rng.uniform(-1, 1, 3) * [0.6, 0.2, 0.1]
        data.qpos[:], data.qvel[:] = q, qd
        mujoco.mj_forward(model, data)
        mujoco.mj_fullM(model, data, dense)
        mass, bias = machine.dynamics.at(q, qd)
        assert rel_err(mass, dense) <= 1e-10
        assert rel_err(bias, data.qfrc_bias) <= 1e-10


def test_the_closed_form_is_the_papers_M_V_and_G(paper_machine):
    m1, m2, m3 = paper_masses(paper_machine.model)
    for q, qd in random_states(paper_machine, seed=5):
        mass, bias = paper_machine.dynamics.at(q, qd)
        assert rel_err(mass, to_mujoco_order(paper_M(q, m1, m2, m3))) <= 1e-9
        expected = to_mujoco_order(paper_V(q, qd, m2, m3) + paper_G(q, m3, 9.81))
        assert rel_err(bias, expected) <= 1e-9


def test_a_chain_outside_the_closed_form_has_none():
    """The closed form holds for any slide-hinge-hinge chain, whatever its axes (a slew axis
    tilted off the vertical included); a chain whose slide rides on the slew (a telescoping
    boom) puts the slide into M, and the check against MuJoCo refuses the fit."""
    from bwr_twin.model.dynamics import ChainDynamics

    assert ChainDynamics.identify(chain("slide", "1 0 0", "hinge", "0.3 0 1")).error <= 1e-10
    assert ChainDynamics.identify(chain("hinge", "0 0 1", "slide", "1 0 0")) is None


def chain(first: str, first_axis: str, second: str, second_axis: str) -> mujoco.MjModel:
    """Three rigid bodies on three joints, the last a hinge about a horizontal axis."""
    return mujoco.MjModel.from_xml_string(f"""
    <mujoco><worldbody><body name="carriage">
      <joint name="travel" type="{first}" axis="{first_axis}"/><inertial pos="0 0 1" mass="1000" diaginertia="1 1 1"/>
      <body name="turntable"><joint name="slew" type="{second}" axis="{second_axis}"/>
        <inertial pos="2 0.5 0" mass="500" diaginertia="10 20 25"/>
        <body name="boom" pos="3 0 2"><joint name="luff" axis="0 -1 0"/>
          <inertial pos="20 0 0" mass="800" diaginertia="5 50 52"/></body></body></body></worldbody></mujoco>""")
