"""Disturbances: pushes and wrenches, payload changes, noise (seeded), latency."""

from __future__ import annotations

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from conftest import get_robot
from geosyn.core.errors import InvalidArgument
from geosyn.sim import (
    Latency,
    PayloadChange,
    Push,
    SensorNoise,
    Simulation,
    TorqueNoise,
    UnknownBody,
    Wrench,
    build_scene,
)
from geosyn.world import Payload


class GravityPD:
    """tau = g(q) + Kp (q0 - q) - Kd v with the robot's nominal model (no payload)."""

    def __init__(self, robot, kp=100.0, kd=20.0):
        self.robot, self.kp, self.kd = robot, kp, kd
        self.data = robot.model.createData()

    def reset(self, q, v, t=0.0):
        self.q_hold = np.array(q)

    def compute(self, t, q, v):
        g = pin.computeGeneralizedGravity(self.robot.model, self.data, q)
        return g + self.kp * (self.q_hold - q) - self.kd * v


def panda_q0():
    robot = get_robot("panda")
    q0 = robot.neutral()
    q0[3], q0[5] = -1.5, 1.5
    return robot, q0


def hand_position(robot, q, frame="panda_hand"):
    data = robot.model.createData()
    pin.framesForwardKinematics(robot.model, data, q)
    return data.oMf[robot.frame_id(frame)].translation.copy()


# -- push and wrench ----------------------------------------------------------------------
def test_push_moves_the_robot_along_the_force():
    robot, q0 = panda_q0()
    force = np.array([0.0, 40.0, 0.0])
    base = Simulation(robot, GravityPD(robot)).run(q0, None, 0.4)
    pushed = Simulation(
        robot, GravityPD(robot), disturbances=[Push("panda_hand", force, start=0.1, duration=0.1)]
    ).run(q0, None, 0.4)
    # identical before the push, different after
    assert np.array_equal(base.q[:101], pushed.q[:101])
    k = 200  # end of the push
    shift = hand_position(robot, pushed.q[k]) - hand_position(robot, base.q[k])
    assert np.linalg.norm(shift) > 5e-3
    assert shift @ force / np.linalg.norm(force) > 0.8 * np.linalg.norm(shift)


def test_push_wrench_at_point_equals_r_cross_f():
    robot, q0 = panda_q0()
    scene = build_scene(robot)
    d = mujoco.MjData(scene.model)
    d.qpos[:] = q0
    mujoco.mj_forward(scene.model, d)
    push = Push("panda_hand", [1.0, -2.0, 3.0], start=0.0, duration=1.0, point=[0.0, 0.05, 0.1])
    push.bind(scene, 1e-3)
    push.on_tick(0.5, scene.model, d)
    bid = scene.resolve_body("panda_hand")
    # independent: point in the world from Pinocchio, CoM of link 7 from Pinocchio
    data = robot.model.createData()
    pin.framesForwardKinematics(robot.model, data, q0)
    p_world = data.oMf[robot.frame_id("panda_hand")].act(np.array([0.0, 0.05, 0.1]))
    jid = robot.joint_id("panda_joint7")
    com = data.oMi[jid].act(robot.model.inertias[jid].lever)
    assert np.allclose(d.xfrc_applied[bid, :3], [1.0, -2.0, 3.0])
    assert np.allclose(
        d.xfrc_applied[bid, 3:], np.cross(p_world - com, [1.0, -2.0, 3.0]), atol=1e-12
    )
    d.xfrc_applied[:] = 0
    push.on_tick(1.0, scene.model, d)  # window is [0, 1)
    assert not np.any(d.xfrc_applied)


def test_wrench_periodic_and_constant():
    w = Wrench("panda_link3", force=(0, 0, 2.0), torque=(1.0, 0, 0), period=0.2, start=0.1)
    assert w.scale(0.05) == 0.0
    assert w.scale(0.15) == pytest.approx(1.0)
    assert w.scale(0.25) == pytest.approx(-1.0)
    assert Wrench("panda_link3", force=(1, 0, 0)).scale(3.0) == 1.0
    robot, q0 = panda_q0()
    res = Simulation(
        robot, GravityPD(robot), disturbances=[Wrench("panda_link3", torque=(0, 0, 5.0), stop=0.2)]
    ).run(q0, None, 0.2)
    # a torque about world z on link 3 turns joint 1 (vertical axis) positively
    assert res.q[-1, 0] - q0[0] > 1e-3


# -- payload change ---------------------------------------------------------------------
def test_payload_change_changes_gravity_torque_as_pinocchio_predicts():
    robot, q0 = panda_q0()
    offset = (0.0, 0.0, 0.05)
    payload = Payload("panda_hand_tcp", 0.5, com=offset, radius=0.04)
    sim = Simulation(
        robot, GravityPD(robot), payloads=[payload], disturbances=[PayloadChange(0.05, 2.0)]
    )
    res = sim.run(q0, None, 0.1)
    assert np.array_equal(res.payload_mass[:, 0], np.where(res.t < 0.05 - 1e-12, 0.5, 2.0))

    def bias(model, q):
        d = mujoco.MjData(model)
        d.qpos[:] = q
        mujoco.mj_forward(model, d)
        return d.qfrc_bias.copy()

    # after the run the model carries 2 kg; a fresh scene carries 0.5 kg
    q = res.q[-1]
    before = bias(build_scene(robot, payloads=[payload]).model, q)
    after = bias(sim.model, q)
    # independent: Pinocchio's gravity torque of a 1.5 kg point at the payload centre
    data = robot.model.createData()
    fid = robot.frame_id("panda_hand_tcp")
    pin.computeJointJacobians(robot.model, data, q)
    pin.framesForwardKinematics(robot.model, data, q)
    placement = data.oMf[fid]
    J = pin.getFrameJacobian(robot.model, data, fid, pin.LOCAL_WORLD_ALIGNED)[:3]
    # Jacobian of the offset point: v_p = v_frame + omega x (R offset)
    r = placement.rotation @ np.asarray(offset)
    Jw = pin.getFrameJacobian(robot.model, data, fid, pin.LOCAL_WORLD_ALIGNED)[3:]
    Jp = J - pin.skew(r) @ Jw
    expected = -Jp.T @ (1.5 * np.asarray(robot.gravity))
    assert np.allclose(after - before, expected, atol=1e-9)
    # mj_setConst refreshed the derived constants (subtree masses)
    assert sim.model.body_subtreemass[0] == pytest.approx(robot.total_mass + 2.0, rel=1e-12)
    assert np.linalg.norm(expected) > 1.0
    # the next run starts from the initial mass again
    again = sim.run(q0, None, 0.02)
    assert np.all(again.payload_mass == 0.5)


def test_payload_change_acts_from_its_tick():
    """A change at t=0 equals building the payload with the new mass (bit for bit)."""
    robot, q0 = panda_q0()
    v0 = np.full(7, 0.3)
    light = Payload("panda_hand_tcp", 0.5, com=(0, 0, 0.05))
    heavy = Payload("panda_hand_tcp", 2.0, com=(0, 0, 0.05))
    changed = Simulation(
        robot, GravityPD(robot), payloads=[light], disturbances=[PayloadChange(0.0, 2.0)]
    ).run(q0, v0, 0.05)
    built = Simulation(robot, GravityPD(robot), payloads=[heavy]).run(q0, v0, 0.05)
    assert np.array_equal(changed.q, built.q)
    assert np.array_equal(changed.kinetic_energy, built.kinetic_energy)


def test_unknown_payload_sags_the_arm():
    robot, q0 = panda_q0()
    payload = Payload("panda_hand_tcp", 0.0)
    hold = Simulation(robot, GravityPD(robot), payloads=[payload]).run(q0, None, 0.5)
    heavy = Simulation(
        robot, GravityPD(robot), payloads=[payload], disturbances=[PayloadChange(0.1, 3.0)]
    ).run(q0, None, 0.5)
    assert np.max(np.abs(hold.q - q0)) < 1e-6
    drop = hand_position(robot, heavy.q[-1])[2] - hand_position(robot, q0)[2]
    assert drop < -1e-3  # falls under the unknown 3 kg


# -- noise ------------------------------------------------------------------------------
def noisy_sim(seed=0):
    robot, q0 = panda_q0()
    return Simulation(
        robot,
        GravityPD(robot),
        disturbances=[TorqueNoise(0.5), SensorNoise(q_std=1e-3, v_std=[1e-2] * 7)],
        seed=seed,
    ), q0


def test_noise_is_seeded():
    sim, q0 = noisy_sim(seed=7)
    a = sim.run(q0, None, 0.1)
    b = sim.run(q0, None, 0.1)
    c = sim.run(q0, None, 0.1, seed=8)
    assert np.array_equal(a.tau_applied, b.tau_applied) and np.array_equal(a.q_meas, b.q_meas)
    assert not np.allclose(a.tau_applied, c.tau_applied)
    assert not np.allclose(a.q_meas, c.q_meas)
    sim2, _ = noisy_sim(seed=7)  # another simulation, same seed
    assert np.array_equal(sim2.run(q0, None, 0.1).tau_applied, a.tau_applied)


def test_noise_statistics():
    sim, q0 = noisy_sim()
    res = sim.run(q0, None, 0.5)
    n = res.n_ticks * 7
    # sample std within 5 standard errors (std error of a std estimate ~ std / sqrt(2n))
    for sample, std in (
        (res.tau_applied - res.tau, 0.5),
        (res.q_meas - res.q, 1e-3),
        (res.v_meas - res.v, 1e-2),
    ):
        assert abs(sample.std() - std) < 5 * std / np.sqrt(2 * n)
        assert abs(sample.mean()) < 5 * std / np.sqrt(n)


# -- latency ----------------------------------------------------------------------------
@pytest.mark.parametrize("k", [0, 1, 7])
def test_latency_delays_measurement_by_exactly_k_ticks(k):
    robot, q0 = panda_q0()
    res = Simulation(robot, GravityPD(robot), disturbances=[Latency(ticks=k)]).run(
        q0, np.full(7, 0.3), 0.05
    )
    assert np.array_equal(res.q_meas[k:], res.q[: res.n_ticks - k])
    assert np.array_equal(res.v_meas[k:], res.v[: res.n_ticks - k])
    assert np.array_equal(res.q_meas[:k], np.tile(res.q[0], (k, 1)))
    assert k == 0 or not np.array_equal(res.q_meas, res.q)


def test_latency_in_seconds_and_bad_values():
    robot, q0 = panda_q0()
    sim = Simulation(
        robot, GravityPD(robot), control_dt=2e-3, disturbances=[Latency(seconds=0.006)]
    )
    assert sim.disturbances[0].ticks == 3
    with pytest.raises(InvalidArgument, match="not a multiple of control_dt"):
        Simulation(robot, GravityPD(robot), disturbances=[Latency(seconds=0.0015)])
    with pytest.raises(InvalidArgument, match="exactly one of ticks or seconds"):
        Latency()
    with pytest.raises(InvalidArgument, match="ticks must be an integer >= 0"):
        Latency(ticks=-1)


# -- bad input --------------------------------------------------------------------------
def test_bad_disturbances():
    robot, _ = panda_q0()
    with pytest.raises(UnknownBody, match="'hand'.*available MuJoCo bodies"):
        Simulation(robot, GravityPD(robot), disturbances=[Push("hand", [1, 0, 0], 0.0, 0.1)])
    with pytest.raises(UnknownBody, match="fixed to the world"):
        Simulation(robot, GravityPD(robot), disturbances=[Push("panda_link0", [1, 0, 0], 0.0, 0.1)])
    with pytest.raises(UnknownBody, match="payload 0 is not in the simulation"):
        Simulation(robot, GravityPD(robot), disturbances=[PayloadChange(0.1, 1.0)])
    with pytest.raises(InvalidArgument, match="force"):
        Push("panda_hand", [1, 0], 0.0, 0.1)
    with pytest.raises(InvalidArgument, match="duration"):
        Push("panda_hand", [1, 0, 0], 0.0, 0.0)
    with pytest.raises(InvalidArgument, match="mass"):
        PayloadChange(0.1, -2.0)
    with pytest.raises(InvalidArgument, match="std"):
        TorqueNoise(-1.0)
    with pytest.raises(InvalidArgument, match=r"std \[N m\] must be a scalar or have shape \(7,\)"):
        Simulation(robot, GravityPD(robot), disturbances=[TorqueNoise([0.1, 0.2])])
    with pytest.raises(InvalidArgument, match="stop must be > start"):
        Wrench("panda_hand", force=(1, 0, 0), start=1.0, stop=0.5)
