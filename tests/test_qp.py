"""Tests of geosyn.controllers.qp: limits, KKT conditions, fallback, inputs."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from conftest import get_robot
from geosyn.controllers import JointTrajectoryReference
from geosyn.controllers.computed_torque import ComputedTorque
from geosyn.controllers.plant import PinocchioPlant
from geosyn.controllers.qp import QPController
from geosyn.core import InvalidArgument

Q0 = np.array([0.0, -0.3, 0.0, -2.0, 0.0, 1.8, 0.8])
KP, KD, DT = 900.0, 60.0, 1e-3


def _hold(q):
    return JointTrajectoryReference(np.array([0.0, 1.0]), np.stack([q, q]))


def _check_kkt(ctl, tol):
    """KKT conditions of the last solve, from the QP data and proxsuite's multipliers."""
    n = ctl.nv
    res = ctl.qp.results
    x, y, z = res.x, res.y, res.z
    H, g, A, b = ctl._H, ctl._g, ctl._A, ctl._b
    lo, hi = ctl._lbox, ctl._ubox
    # Primal: the dynamics equality M qdd - tau = -h and the boxes.
    assert np.abs(A @ x - b).max() <= tol
    assert np.all(x >= lo - tol) and np.all(x <= hi + tol)
    # Dual: stationarity H x + g + A^T y + z = 0 ...
    assert np.abs(H @ x + g + A.T @ y + z).max() <= tol * max(1.0, np.abs(g).max())
    # ... and complementarity: a multiplier is non-zero only at its active bound.
    scale = max(1.0, np.abs(z).max())
    at_lo = np.abs(x - lo) <= 1e-6 * np.maximum(1.0, np.abs(lo))
    at_hi = np.abs(x - hi) <= 1e-6 * np.maximum(1.0, np.abs(hi))
    assert np.all((z >= -tol * scale) | at_lo)
    assert np.all((z <= tol * scale) | at_hi)
    # The equality is also satisfied by Pinocchio's own inverse dynamics.
    model, data = ctl.robot.model, ctl.robot.model.createData()
    return x[:n], x[n:], data, model


def test_matches_computed_torque_when_no_limit_is_active():
    robot = get_robot("panda")
    rng = np.random.default_rng(0)
    ref = JointTrajectoryReference(
        np.array([0.0, 2.0]), np.stack([Q0, Q0 + rng.uniform(-0.2, 0.2, 7)])
    )
    qp = QPController(robot, KP, KD, DT, reference=ref)
    ct = ComputedTorque(robot, KP, KD, reference=ref)
    qp.reset(Q0, np.zeros(7))
    for t in (0.0, 0.5, 1.0):
        q_ref, v_ref, _ = ref.sample(t)
        q, v = q_ref + rng.uniform(-0.01, 0.01, 7), v_ref + rng.uniform(-0.1, 0.1, 7)
        tau_qp = qp.compute(t, q, v)
        tau_ct = ct.compute(t, q, v)
        assert qp.diagnostics.solver_status == "ok" and not qp.diagnostics.fallback_used
        # Differs only through the eps ||tau||^2 regularisation (eps = 1e-6).
        assert not ct.diagnostics.saturated.any()
        np.testing.assert_allclose(tau_qp, tau_ct, atol=2e-3)


def test_respects_torque_limits_where_computed_torque_would_not():
    """A 0.3 rad initial error: CT asks for far more than tau_max; the QP never does."""
    robot = get_robot("panda")
    ref = _hold(Q0)
    q0, v0 = Q0 + 0.3 * np.array([1, -1, 1, 1, -1, -1, 1.0]), np.zeros(7)
    kp, kd = 225.0, 30.0
    ct = ComputedTorque(robot, kp, kd, reference=ref)
    ct.compute(0.0, q0, v0)
    assert np.any(np.abs(ct.last_unclipped_torque) > 1.5 * robot.tau_max)

    qp = QPController(robot, kp, kd, DT, braking_acceleration=20.0, reference=ref)
    plant = PinocchioPlant(robot, dt=DT)
    plant.reset(q0, v0)
    qp.reset(q0, v0)
    raw, statuses, kkt_checked = [], set(), 0

    def record(t, q, v, tau):
        nonlocal kkt_checked
        raw.append(qp.last_unclipped_torque)
        statuses.add(qp.diagnostics.solver_status)
        if len(raw) % 50 == 1:
            _check_kkt(qp, 1e-6)
            kkt_checked += 1

    ro = plant.rollout(qp, 0.8, callback=record)
    raw = np.array(raw)
    assert statuses == {"ok"} and qp.diagnostics.fallback_count == 0
    # The QP's own torque (before any clipping) is within the limits: zero violations.
    assert np.all(np.abs(raw) <= robot.tau_max + 1e-6)
    # The limits were actually reached (the scenario is constrained) ...
    assert np.any(np.abs(raw) >= robot.tau_max - 1e-6)
    # ... joint and velocity limits held, and the error still went down.
    assert np.all(ro.q >= robot.q_min) and np.all(ro.q <= robot.q_max)
    assert np.all(np.abs(ro.v) <= robot.v_max + 1e-6)
    assert np.abs(ro.q[-1] - Q0).max() < 0.1 * np.abs(q0 - Q0).max()
    assert kkt_checked >= 10


def test_respects_joint_limits_where_computed_torque_would_not():
    """A reference that drives joint 4 (index 3) through its upper limit."""
    robot = get_robot("panda")
    j = 3
    q_goal = Q0.copy()
    q_goal[j] = robot.q_max[j] + 0.4
    ref = JointTrajectoryReference(np.array([0.0, 0.6]), np.stack([Q0, q_goal]))
    q0, v0 = Q0.copy(), np.zeros(7)

    ct = ComputedTorque(robot, KP, KD, reference=ref)
    plant = PinocchioPlant(robot, dt=DT)
    plant.reset(q0, v0)
    assert plant.rollout(ct, 1.0).q[:, j].max() > robot.q_max[j] + 0.2

    qp = QPController(robot, KP, KD, DT, braking_acceleration=10.0, reference=ref)
    plant.reset(q0, v0)
    qp.reset(q0, v0)
    ro = plant.rollout(qp, 1.0)
    assert qp.diagnostics.fallback_count == 0
    assert np.all(ro.q <= robot.q_max) and np.all(ro.q >= robot.q_min)
    # It gets close to the limit (the constraint is not overly conservative).
    assert ro.q[-1, j] > robot.q_max[j] - 0.02
    _check_kkt(qp, 1e-6)


def test_kkt_equality_is_the_robot_dynamics():
    robot = get_robot("panda")
    qp = QPController(robot, KP, KD, DT, reference=_hold(Q0))
    q, v = Q0 + 0.3, np.linspace(-1, 1, 7)
    qp.reset(q, v)
    tau = qp.compute(0.0, q, v)
    qdd, tau_x, data, model = _check_kkt(qp, 1e-6)
    np.testing.assert_allclose(tau, tau_x, atol=1e-12)
    np.testing.assert_allclose(pin.rnea(model, data, q, v, qdd), tau_x, atol=1e-5)


def test_warm_start_reduces_iterations():
    robot = get_robot("panda")
    qp = QPController(robot, KP, KD, DT, reference=_hold(Q0))
    q, v = Q0 + 0.5, np.zeros(7)
    qp.reset(q, v)
    qp.compute(0.0, q, v)
    cold = qp.diagnostics.iterations
    qp.compute(1e-3, q + 1e-6, v)
    assert qp.diagnostics.iterations <= cold


def test_empty_acceleration_box_falls_back_to_saturated_computed_torque():
    """Monkeypatched limits that exclude the current position: infeasible before solving."""
    robot = get_robot("panda")
    ref = _hold(Q0)
    qp = QPController(robot, KP, KD, DT, reference=ref)
    ct = ComputedTorque(robot, KP, KD, reference=ref)
    q, v = Q0 + 0.4, np.zeros(7)
    qp.reset(q, v)
    qp._q_max[0] = q[0] - 0.1  # the joint is already 0.1 rad beyond its upper limit
    tau = qp.compute(0.0, q, v)
    d = qp.diagnostics
    assert d.fallback_used and d.fallback_count == 1 and d.solver_status == "infeasible"
    np.testing.assert_allclose(tau, ct.compute(0.0, q, v), atol=1e-9)
    assert np.all(np.abs(tau) <= robot.tau_max) and d.saturated.any()
    qp.compute(1e-3, q, v)
    assert d.fallback_count == 2
    # Restored limits: the QP solves again and the flag clears.
    qp._q_max[0] = robot.q_max[0]
    qp.compute(2e-3, q, v)
    assert not d.fallback_used and d.solver_status == "ok" and d.fallback_count == 2
    qp.reset(q, v)
    assert d.fallback_count == 0


def test_solver_failure_triggers_fallback():
    """One iteration with an unreachable tolerance: proxsuite stops at max_iter."""
    robot = get_robot("panda")
    ref = _hold(Q0)
    qp = QPController(robot, KP, KD, DT, eps_abs=1e-15, max_iter=1, reference=ref)
    ct = ComputedTorque(robot, KP, KD, reference=ref)
    q, v = Q0 + 0.4, np.ones(7)
    qp.reset(q, v)
    tau = qp.compute(0.0, q, v)
    d = qp.diagnostics
    assert d.solver_status == "max_iter" and d.fallback_used and d.fallback_count == 1
    np.testing.assert_allclose(tau, ct.compute(0.0, q, v), atol=1e-9)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"kp": np.ones(5)}, r"kp must be a scalar or an array of shape \(7,\)"),
        ({"kd": -1.0}, "kd must be finite and >= 0"),
        ({"dt": 0.0}, r"dt must be a finite number in \[1e-06, 1\] \[s\], got 0.0"),
        ({"eps": -1e-3}, "eps"),
        ({"position_horizon": 1e-4}, "position_horizon must be >= dt"),
        ({"braking_acceleration": 0.0}, "braking_acceleration must be > 0"),
        ({"max_iter": 0}, "max_iter"),
        # issue 23: nothing accepted that means nothing
        ({"dt": 1e300}, r"dt must be a finite number in \[1e-06, 1\] \[s\], got 1e\+300"),
        ({"dt": True}, "dt must be a finite number"),
        ({"kp": 900.0 + 1j}, "kp must be a real"),
        ({"kp": np.full(7, 900.0 + 0j)}, "kp must be a real"),
        ({"kd": np.ones(7, dtype=bool)}, "kd must be a float array, got booleans"),
        ({"kp": "900"}, "kp must be a real"),
        ({"eps_abs": 1e-300}, r"eps_abs must be a finite number in \[1e-15, 1\]"),
        ({"max_iter": 10**9}, r"max_iter must be an integer in \[1, 1000\]"),
        ({"max_inner_iter": 1001}, r"max_inner_iter must be an integer in \[1, 1000\]"),
        ({"max_iter": 1000, "max_inner_iter": 30}, "max_iter \\* max_inner_iter must be <="),
        ({"position_horizon": 1e300}, "position_horizon must be a finite number in"),
    ],
)
def test_rejects_bad_input(kwargs, match):
    args = {"kp": KP, "kd": KD, "dt": DT} | kwargs
    with pytest.raises(InvalidArgument, match=match):
        QPController(get_robot("panda"), **args)


def test_rejects_reference_of_wrong_dimension():
    qp = QPController(get_robot("panda"), KP, KD, DT)
    with pytest.raises(InvalidArgument, match="dimension 2.*nv=7"):
        qp.set_reference(JointTrajectoryReference(np.array([0.0, 1.0]), np.zeros((2, 2))))
