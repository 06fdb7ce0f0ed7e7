"""The Robot description (robots/robot.py)."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from conftest import get_robot
from geosyn.core import GeosynError, InvalidArgument
from geosyn.robots import UnknownFrame


def test_check_q_names_expected_shape() -> None:
    robot = get_robot("panda")
    with pytest.raises(InvalidArgument, match=r"q must have shape \(7,\), got shape \(6,\)"):
        robot.check_q(np.zeros(6))
    with pytest.raises(InvalidArgument, match="finite"):
        robot.check_q(np.full(7, np.nan))
    with pytest.raises(InvalidArgument, match="float array"):
        robot.check_q("seven")


def test_unknown_frame_lists_names() -> None:
    robot = get_robot("planar2")
    with pytest.raises(UnknownFrame, match="available: .*tip") as info:
        robot.frame_id("hand")
    assert info.value.name == "hand" and "tip" in info.value.available
    with pytest.raises(UnknownFrame, match="joint 'j9'.*available: joint1, joint2") as info:
        robot.joint_id("j9")
    assert info.value.available == ("joint1", "joint2")
    with pytest.raises(InvalidArgument, match="per_capsule"):
        robot.collision_spheres(per_capsule=0)
    assert isinstance(UnknownFrame("x"), GeosynError)


def test_random_q_within_limits() -> None:
    robot = get_robot("talos_arm")
    rng = np.random.default_rng(0)
    qs = np.array([robot.random_q(rng, margin=0.1) for _ in range(500)])
    assert np.all(qs >= robot.q_min + 0.1 - 1e-12) and np.all(qs <= robot.q_max - 0.1 + 1e-12)
    q = robot.neutral()
    assert np.all(q >= robot.q_min) and np.all(q <= robot.q_max)


def test_collision_spheres_lie_on_link_segments() -> None:
    robot = get_robot("planar2")
    spheres = robot.collision_spheres(per_capsule=3)
    assert len(spheres) == 6
    # Sphere centres of link 2 at 0, l2/2, l2 along its x axis; world positions by FK.
    data = robot.model.createData()
    q = np.array([0.3, 0.9])
    pin.forwardKinematics(robot.model, data, q)
    s = spheres[5]
    p = data.oMi[robot.joint_id(s.joint)].act(np.asarray(s.center))
    tip = np.array([np.cos(0.3) + np.cos(1.2), np.sin(0.3) + np.sin(1.2), 0.0])
    np.testing.assert_allclose(p, tip, atol=1e-14)


def test_total_mass_equals_sum_of_links() -> None:
    robot = get_robot("panda")
    mm = robot.mj_model()
    assert robot.total_mass == pytest.approx(float(np.sum(mm.body_mass)), rel=1e-14)


def test_joint_friction_fields_are_validated_and_read_only() -> None:
    import dataclasses

    planar = get_robot("planar2")
    np.testing.assert_array_equal(planar.damping, [0.0, 0.0])
    assert not planar.has_joint_friction and planar.base == "fixed"
    assert planar.tau_max_source == ("built-in: planar arm tau_max=50",) * 2
    damped = dataclasses.replace(planar, damping=np.array([0.5, 0.0]))
    assert damped.has_joint_friction and damped.damping[0] == 0.5
    with pytest.raises(ValueError):
        damped.damping[0] = 1.0  # read-only
    with pytest.raises(InvalidArgument, match="frictionloss must be >= 0"):
        dataclasses.replace(planar, frictionloss=[-1.0, 0.0])
    with pytest.raises(InvalidArgument, match="damping must have shape"):
        dataclasses.replace(planar, damping=[1.0])


def test_duplicate_frame_names_prefer_the_body_frame() -> None:
    """so100's 'gripper' is a joint and a link: frame_id picks the link's BODY frame."""
    from geosyn.robots import load_robot

    robot = load_robot("so100")
    fid = robot.frame_id("gripper")
    assert robot.model.frames[fid].type == pin.FrameType.BODY
