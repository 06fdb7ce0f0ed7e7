"""LoadTerm: the payload term equals the mass-matrix change of an attached rigid body."""

from __future__ import annotations

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from conftest import get_metric, get_robot
from geosyn.core import InvalidArgument
from geosyn.metrics.shaping import LoadTerm, ShapedMetric
from geosyn.robots.errors import UnknownFrame

MASS = 2.0
COM = np.array([0.013, -0.021, 0.047])  # [m] in the hand frame
# Rotational inertia about the com [kg m^2]: SPD, off-diagonal, triangle inequality holds.
INERTIA = np.array([[0.021, 0.0015, -0.0007], [0.0015, 0.030, 0.0022], [-0.0007, 0.0022, 0.026]])
N_Q = 100


def _payload_pinocchio_model(robot, frame: str) -> pin.Model:
    model = pin.Model(robot.model)
    f = model.frames[robot.frame_id(frame)]
    model.appendBodyToJoint(f.parentJoint, pin.Inertia(MASS, COM, INERTIA), f.placement)
    return model


def _payload_mjcf_body(robot, frame: str) -> tuple[str, str]:
    f = robot.model.frames[robot.frame_id(frame)]
    quat = pin.Quaternion(f.placement.rotation)
    v = " ".join
    body = (
        f'<body name="payload" pos="{v(map(repr, f.placement.translation.tolist()))}" '
        f'quat="{quat.w!r} {quat.x!r} {quat.y!r} {quat.z!r}">'
        f'<inertial pos="{v(map(repr, COM.tolist()))}" mass="{MASS!r}" fullinertia="'
        + v(repr(float(x)) for x in INERTIA[[0, 1, 2, 0, 0, 1], [0, 1, 2, 1, 2, 2]])
        + '"/></body>'
    )
    return robot.model.names[f.parentJoint], body


@pytest.mark.parametrize("name", ["panda", "talos_arm"])
def test_load_term_matches_pinocchio_and_mujoco_payload(name: str) -> None:
    robot = get_robot(name)
    frame = robot.ee_frame
    shaped = ShapedMetric(get_metric(name), [LoadTerm(frame, MASS, COM, INERTIA)])
    model = _payload_pinocchio_model(robot, frame)
    data = model.createData()
    joint, body = _payload_mjcf_body(robot, frame)
    mm = robot.mj_model(limits=False, body_extra={joint: body})
    md = mujoco.MjData(mm)
    M_mj = np.zeros((robot.nv, robot.nv))
    rng = np.random.default_rng(4)
    err_pin = err_mj = 0.0
    for _ in range(N_Q):
        q = robot.random_q(rng)
        G = shaped.G(q)
        err_pin = max(err_pin, np.abs(G - pin.crba(model, data, q)).max())
        md.qpos[:] = q
        mujoco.mj_forward(mm, md)
        mujoco.mj_fullM(mm, md, M_mj)
        err_mj = max(err_mj, np.abs(G - M_mj).max())
    assert err_pin <= 1e-10
    assert err_mj <= 1e-10
    # The payload changes the metric by far more than the tolerance (the test can fail).
    q = robot.random_q(rng)
    assert np.abs(shaped.G(q) - get_metric(name).G(q)).max() > 1e-3


def test_point_mass_is_m_jv_transpose_jv() -> None:
    """A point mass at the frame origin adds m Jv^T Jv (closed form from Pinocchio's Jacobian)."""
    robot = get_robot("panda")
    frame = robot.ee_frame
    term = LoadTerm(frame, 1.5).bind(robot)
    data = robot.model.createData()
    fid = robot.frame_id(frame)
    rng = np.random.default_rng(5)
    for _ in range(10):
        q = robot.random_q(rng)
        J = pin.computeFrameJacobian(robot.model, data, q, fid, pin.LOCAL_WORLD_ALIGNED)[:3]
        np.testing.assert_allclose(term.G(q), 1.5 * J.T @ J, atol=1e-12)


def test_load_term_is_symmetric_psd_with_rank_at_most_six() -> None:
    robot = get_robot("panda")
    term = LoadTerm(robot.ee_frame, MASS, COM, INERTIA).bind(robot)
    rng = np.random.default_rng(6)
    for _ in range(20):
        g = term.G(robot.random_q(rng))
        assert np.array_equal(g, g.T) or np.abs(g - g.T).max() <= 1e-15
        eig = np.linalg.eigvalsh(g)
        assert eig[0] >= -1e-12 * eig[-1]
        assert np.sum(eig > 1e-9 * eig[-1]) <= 6


@pytest.mark.parametrize(
    ("kwargs", "fragment"),
    [
        ({"mass": -1.0}, "mass"),
        ({"mass": 0.0}, "mass"),
        ({"mass": float("nan")}, "mass"),
        ({"com": (0.0, 0.0)}, "com"),
        ({"com": np.zeros((3, 1))}, "com"),
        ({"inertia": -np.eye(3) * 0.01}, "positive definite"),
        ({"inertia": np.diag([0.01, 0.0, 0.01])}, "positive definite"),
        ({"inertia": np.array([[0.01, 0.002, 0], [0.0, 0.01, 0], [0, 0, 0.01]])}, "symmetric"),
        ({"inertia": np.diag([0.01, 0.01, 0.05])}, "triangle"),
        ({"inertia": np.eye(2)}, "inertia"),
    ],
)
def test_bad_payloads_raise_invalid_argument(kwargs: dict, fragment: str) -> None:
    """A bad mass is the term's InvalidTermArgument, a bad com or inertia the payload's
    InvalidGeometry: both are InvalidArgument, told apart by the message."""
    args = {"frame": "panda_hand_tcp", "mass": 1.0, "com": (0.0, 0.0, 0.0), "inertia": None}
    args.update(kwargs)
    with pytest.raises(InvalidArgument, match=fragment):
        LoadTerm(**args)


def test_unknown_frame_lists_available_frames() -> None:
    robot = get_robot("panda")
    with pytest.raises(UnknownFrame, match="panda_hand_tcp") as info:
        ShapedMetric(get_metric("panda"), [LoadTerm("panda_hnd", 1.0)])
    assert "'panda_hnd'" in str(info.value)
    assert robot.ee_frame in str(info.value)


def test_from_payload_uses_the_payloads_inertia() -> None:
    """A world Payload without an inertia is a solid ball: 2/5 m r^2 about every axis."""
    from geosyn.world import Payload

    robot = get_robot("panda")
    mass, radius = 1.2, 0.05
    term = LoadTerm.from_payload(Payload(robot.ee_frame, mass, tuple(COM), radius=radius))
    ball = np.eye(3) * 0.4 * mass * radius**2
    ref = LoadTerm(robot.ee_frame, mass, COM, ball).bind(robot)
    term.bind(robot)
    q = robot.random_q(np.random.default_rng(7))
    np.testing.assert_array_equal(term.G(q), ref.G(q))
    assert np.abs(term.G(q) - LoadTerm(robot.ee_frame, mass, COM).bind(robot).G(q)).max() > 1e-5
    with pytest.raises(InvalidArgument, match="mass"):
        LoadTerm.from_payload(Payload(robot.ee_frame, 0.0))
