"""Tests of geosyn.controllers.computed_torque and of the Controller base behaviour."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from conftest import get_metric, get_robot
from geosyn.controllers import GeodesicReference, JointTrajectoryReference, NoReference
from geosyn.controllers.computed_torque import ComputedTorque
from geosyn.controllers.plant import PinocchioPlant
from geosyn.core import InvalidArgument
from geosyn.synergies import GeodesicSynergy

Q0 = np.array([0.0, -0.3, 0.0, -2.0, 0.0, 1.8, 0.8])
V0 = 0.5 * np.array([1.0, 1.0, -1.0, 1.0, 1.0, -1.0, 1.0])
KP, KD = 900.0, 60.0


@pytest.fixture(scope="module")
def synergy_reference():
    """A 1.5 s panda synergy (a geodesic), inside position and velocity limits."""
    robot, metric = get_robot("panda"), get_metric("panda")
    synergy = GeodesicSynergy(metric, Q0, V0)
    geo = synergy.trajectory(1.5, 150)
    assert np.all(geo.q > robot.q_min + 0.1) and np.all(geo.q < robot.q_max - 0.1)
    assert np.all(np.abs(geo.v) < 0.8 * robot.v_max)
    return GeodesicReference(synergy, duration=1.5, steps=150)


def _track(controller, ref, payload=None, duration=1.5):
    robot = controller.robot
    plant = PinocchioPlant(robot, dt=1e-3, payload=payload)
    q0, v0, _ = ref.sample(0.0)
    plant.reset(q0, v0)
    controller.reset(q0, v0)
    ro = plant.rollout(controller, duration)
    q_ref = np.array([ref.sample(t).q for t in ro.t])
    return ro, ro.q - q_ref


def test_tracks_panda_synergy_with_exact_model(synergy_reference):
    ctl = ComputedTorque(get_robot("panda"), KP, KD, reference=synergy_reference)
    ro, err = _track(ctl, synergy_reference)
    rms = np.sqrt(np.mean(err**2))
    assert rms <= 1e-3, rms
    assert ctl.diagnostics.fallback_count == 0


def test_tracks_panda_synergy_with_unmodelled_payload(synergy_reference):
    robot = get_robot("panda")
    ctl = ComputedTorque(robot, KP, KD, reference=synergy_reference)
    _, err_exact = _track(ctl, synergy_reference)
    _, err = _track(ctl, synergy_reference, payload=(robot.ee_frame, 1.0))
    rms, rms_exact = np.sqrt(np.mean(err**2)), np.sqrt(np.mean(err_exact**2))
    assert rms <= 2e-2, rms
    # The payload is felt: the error is much larger than with the exact model.
    assert rms > 10 * rms_exact


def test_torque_is_inverse_dynamics_of_desired_acceleration():
    """tau = M (a_ref + Kd (v_ref - v) + Kp (q_ref - q)) + C(q, v) v + g(q), assembled
    from Pinocchio's separate CRBA, Coriolis matrix and gravity."""
    robot = get_robot("panda")
    model, data = robot.model, robot.model.createData()
    rng = np.random.default_rng(1)
    t = np.array([0.0, 1.0])
    qs = np.stack([robot.random_q(rng, 0.3), robot.random_q(rng, 0.3)])
    ref = JointTrajectoryReference(t, qs)
    kp = rng.uniform(10, 50, 7)
    kd = rng.uniform(1, 10, 7)
    ctl = ComputedTorque(robot, kp, kd, reference=ref)
    for tt in (0.2, 0.6):
        q = robot.random_q(rng, 0.3)
        v = rng.normal(size=7)
        q_ref, v_ref, a_ref = ref.sample(tt)
        a_des = a_ref + kd * (v_ref - v) + kp * (q_ref - q)
        M = pin.crba(model, data, q)
        C = pin.computeCoriolisMatrix(model, data, q, v)
        g = pin.computeGeneralizedGravity(model, data, q)
        tau = ctl.compute(tt, q, v)
        expected = M @ a_des + C @ v + g
        # The control law before clipping, and the clipped torque actually returned.
        np.testing.assert_allclose(ctl.last_unclipped_torque, expected, atol=1e-9)
        np.testing.assert_allclose(tau, np.clip(expected, -robot.tau_max, robot.tau_max), atol=1e-9)
        assert ctl.diagnostics.compute_time > 0.0


def test_error_follows_linear_closed_loop():
    """With an exact model the error obeys e'' + kd e' + kp e = 0 (critically damped)."""
    robot = get_robot("panda")
    kp, kd = 100.0, 20.0  # double pole at -10
    q_goal = Q0.copy()
    ref = JointTrajectoryReference(np.array([0.0, 1.0]), np.stack([q_goal, q_goal]))
    ctl = ComputedTorque(robot, kp, kd, reference=ref)
    e0 = np.array([0.02, -0.02, 0.01, 0.02, -0.03, 0.02, 0.03])
    plant = PinocchioPlant(robot)
    plant.reset(q_goal + e0, np.zeros(7))
    ro = plant.rollout(ctl, 0.4)
    for k in (100, 200, 400):
        t = ro.t[k]
        e_exact = e0 * (1.0 + 10.0 * t) * np.exp(-10.0 * t)
        np.testing.assert_allclose(ro.q[k] - q_goal, e_exact, atol=2e-3 * np.abs(e0).max())


def test_saturation_is_flagged_and_torque_clipped(synergy_reference):
    robot = get_robot("panda")
    ctl = ComputedTorque(robot, KP, KD, reference=synergy_reference)
    q, v, _ = synergy_reference.sample(0.0)
    tau = ctl.compute(0.0, q + 0.5, v)  # a 0.5 rad error everywhere
    raw = ctl.last_unclipped_torque
    sat = ctl.diagnostics.saturated
    assert sat.any()
    np.testing.assert_array_equal(sat, np.abs(raw) > robot.tau_max)
    np.testing.assert_allclose(np.abs(tau[sat]), robot.tau_max[sat])
    np.testing.assert_array_equal(tau[~sat], raw[~sat])
    # Back on the reference: nothing saturated.
    ctl.compute(0.0, q, v)
    assert not ctl.diagnostics.saturated.any()


@pytest.mark.parametrize(
    "kp, kd, match",
    [
        (np.ones(6), 1.0, r"kp must be a scalar or an array of shape \(7,\), got shape \(6,\)"),
        (1.0, -2.0, "kd must be finite and >= 0"),
        (np.full(7, np.nan), 1.0, "kp must be finite"),
        (np.ones((7, 7)), 1.0, "kp"),
        ("fast", 1.0, "kp"),
    ],
)
def test_rejects_bad_gains(kp, kd, match):
    with pytest.raises(InvalidArgument, match=match):
        ComputedTorque(get_robot("panda"), kp, kd)


def test_rejects_reference_of_wrong_dimension():
    ctl = ComputedTorque(get_robot("panda"), KP, KD)
    ref2 = JointTrajectoryReference(np.array([0.0, 1.0]), np.zeros((2, 2)))
    with pytest.raises(InvalidArgument, match="dimension 2.*nv=7"):
        ctl.set_reference(ref2)
    with pytest.raises(InvalidArgument, match="dimension 2.*nv=7"):
        ComputedTorque(get_robot("panda"), KP, KD, reference=ref2)
    with pytest.raises(InvalidArgument, match="Reference"):
        ctl.set_reference(np.zeros(7))
    with pytest.raises(InvalidArgument, match="metric"):
        ComputedTorque(get_robot("panda"), KP, KD, metric=get_metric("planar2"))


def test_compute_validates_state_and_needs_reference(synergy_reference):
    ctl = ComputedTorque(get_robot("panda"), KP, KD)
    with pytest.raises(NoReference, match="set_reference"):
        ctl.compute(0.0, Q0, V0)
    ctl.set_reference(synergy_reference)
    with pytest.raises(InvalidArgument, match=r"q must have shape \(7,\)"):
        ctl.compute(0.0, Q0[:6], V0)
    with pytest.raises(InvalidArgument, match="v must be finite"):
        ctl.compute(0.0, Q0, np.full(7, np.nan))
    with pytest.raises(InvalidArgument, match="t must be"):
        ctl.compute(np.inf, Q0, V0)
    # Lists are accepted (validated and converted).
    assert ctl.compute(0.0, list(Q0), list(V0)).shape == (7,)


def test_friction_compensation_keeps_a_light_wrist_at_rest() -> None:
    """xarm7's file has damping and dry friction (1 N m) on joints as light as its wrist:
    dry friction compensated on the measured velocity spun the wrist up from rest (2.4 rad
    in 0.5 s); as a feed-forward on the reference velocity it holds the pose exactly."""
    import warnings

    from geosyn.controllers import JointTrajectoryReference
    from geosyn.robots import load_robot
    from geosyn.sim import Simulation

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        robot = load_robot("xarm7")
    assert robot.has_joint_friction
    q0 = robot.neutral()
    ref = JointTrajectoryReference(np.array([0.0, 1.0]), np.stack([q0, q0]))
    ctl = ComputedTorque(robot, 400.0, 40.0)
    assert ctl.compensate_friction
    res = Simulation(robot, ctl).run(q0, None, 0.5, ref)
    assert res.status == "ok"
    assert np.abs(res.q - q0).max() <= 1e-9
