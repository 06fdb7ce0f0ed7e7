"""The whole-body QP on a floating base standing in MuJoCo with its base free
(geosyn.controllers.whole_body).

References: MuJoCo's simulation of the robot on a floor with friction (the scene of
tests/whole_body_scene.py: geosyn's fixed-base twin under a free joint, checked against
Pinocchio's free-flyer mass matrix), the feet's displacement on the floor, Newton's law
for the standing robot (the contact forces carry the weight), and the dynamics the
torques must satisfy (Pinocchio's RNEA with the contact forces).
"""

from __future__ import annotations

import mujoco
import numpy as np
import pinocchio as pin
import pytest
from whole_body_scene import build_scene, run_standing, standing_synergy

from geosyn.controllers import QPController
from geosyn.controllers.errors import ControllerError
from geosyn.controllers.whole_body import WholeBodyController
from geosyn.robots import FloatingBaseError, UnknownFrame
from geosyn.robots.floating import to_mujoco


def controller(scene, reference, **gains) -> WholeBodyController:  # type: ignore[no-untyped-def]
    return WholeBodyController(scene.robot, scene.feet, scene.corners, reference, **gains)


def test_the_scene_is_pinocchios_free_flyer_model() -> None:
    scene = build_scene("talos_reduced")
    m = mujoco.MjModel.from_xml_string(scene.xml)
    d = mujoco.MjData(m)
    rng = np.random.default_rng(26)
    q = scene.robot.random_q(rng)
    d.qpos[:], _ = to_mujoco(q, np.zeros(m.nv))
    mujoco.mj_forward(m, d)
    M_mj = np.zeros((m.nv, m.nv))
    mujoco.mj_fullM(m, d, M_mj)
    T = np.eye(m.nv)  # MuJoCo's base linear velocity is in world axes
    T[:3, :3] = pin.Quaternion(q[6], q[3], q[4], q[5]).matrix()
    M_pin = pin.crba(scene.robot.model, scene.robot.model.createData(), q)
    assert np.abs(T.T @ M_mj @ T - M_pin).max() < 1e-12 * np.abs(M_pin).max()


def test_standing_still_the_feet_carry_the_weight_and_the_torques_are_the_dynamics() -> None:
    scene = build_scene("talos_reduced")
    _, _, ref = standing_synergy(scene, t0=10.0)  # at rest before t0
    ctrl = controller(scene, ref)
    robot = scene.robot
    q, v = scene.q0, np.zeros(robot.nv)
    ctrl.reset(q, v)
    tau = ctrl.compute(0.0, q, v)
    model, data = robot.model, robot.model.createData()
    pin.centerOfMass(model, data, q, v, ctrl.acceleration)
    newton = robot.total_mass * (data.acom[0] - model.gravity.linear)  # = sum of the forces
    assert np.abs(ctrl.forces.sum(axis=0) - newton).max() < 1e-6 * newton[2]
    assert np.abs(ctrl.acceleration).max() < 1e-2  # nearly at rest (measured 1.6e-3)
    # tau + J_p^T f = RNEA(q, 0, a) at the QP's acceleration
    pin.computeJointJacobians(model, data, q)
    pin.updateFramePlacements(model, data)
    gen = np.zeros(robot.nv)
    for i, foot in enumerate(scene.feet):
        fid = robot.frame_id(foot)
        for j, p in enumerate(scene.corners):
            f = ctrl.forces[4 * i + j]
            wrench = pin.Force(f, np.cross(data.oMf[fid].rotation @ p, f))  # about the frame
            J = pin.getFrameJacobian(model, data, fid, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
            gen += J.T @ wrench.vector
    rnea = pin.rnea(model, data, q, v, ctrl.acceleration)
    assert np.abs(tau + gen - rnea).max() < 1e-6 * np.abs(rnea).max()
    assert ctrl.diagnostics.extra["max_friction_ratio"] < 1e-3  # measured 2.1e-4


def test_humanoid_tracks_a_whole_body_synergy_under_a_50_newton_push() -> None:
    scene = build_scene("talos_reduced")
    _, synergy, ref = standing_synergy(scene, duration=1.0, t0=0.1)
    run = run_standing(scene, controller(scene, ref), ref, duration=1.4, push=(0.0, 50.0, 0.0))
    # measured: slip 0.22 mm, feet 0.7 mm deeper in the soft floor, lowest base 0.95 m
    # (0.07 m down by design), no QP failure, RMS 0.27 (base and legs 0.043): mostly the
    # right arm, whose joints have 1 N m of dry friction each in the file
    assert run.slip < 1e-3 and run.lift < 2e-3 and run.qp_failures == 0
    assert run.min_base_height > 0.9 and run.rms_base_legs < 0.06 and run.rms < 0.35
    assert np.linalg.norm(synergy.v0) > 0.5  # it moved


def test_quadruped_shifts_its_body_over_its_feet_under_a_50_newton_push() -> None:
    scene = build_scene("go2")
    _, synergy, ref = standing_synergy(scene, duration=1.0, t0=0.1)
    ctrl = controller(scene, ref, kp=400.0, kd=40.0)
    run = run_standing(scene, ctrl, ref, duration=1.4, push=(0.0, 50.0, 0.0))
    # measured: slip 0.64 mm, feet 1.3 mm deeper in the soft floor, RMS 0.033
    assert run.slip < 1e-3 and run.lift < 2e-3 and run.qp_failures == 0
    assert run.min_base_height > 0.25 and run.rms < 0.05


def test_a_floating_robot_needs_this_controller_and_this_controller_a_floating_robot() -> None:
    scene = build_scene("go2")
    _, _, ref = standing_synergy(scene)
    with pytest.raises(FloatingBaseError, match="QPController .* needs a fixed-base robot"):
        QPController(scene.robot, kp=100.0, kd=20.0, dt=1e-3)
    from floating_cases import load_quietly

    with pytest.raises(ControllerError, match="needs a floating-base robot, got 'panda'"):
        WholeBodyController(load_quietly("panda"), ["panda_hand"], np.zeros((1, 3)))
    with pytest.raises(UnknownFrame, match="'FL_toe' is not in robot 'go2'"):
        WholeBodyController(scene.robot, ["FL_toe"], np.zeros((1, 3)), ref)
    with pytest.raises(ControllerError, match=r"points must have shape \(P, 3\)"):
        WholeBodyController(scene.robot, scene.feet, np.zeros((2, 3)), ref)
