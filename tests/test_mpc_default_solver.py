"""GeodesicMPC's default solver and its commanded torque (issue 21): ``solver=None`` is
box-DDP at the torque level wherever the DDP solves the problem and fatrop otherwise (the
YAML default is the constructor's); every solver's command stays within the torque
limits, a law torque over a limit is flagged as a saturation, and a tick the guard
changed is counted and described."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from conftest import get_metric, get_robot
from geosyn.controllers import GeodesicMPC, JointTrajectoryReference
from geosyn.controllers.mpc import DDPOptions, NLPOptions
from geosyn.controllers.mpc.backend import TrackingProblem
from geosyn.controllers.mpc.families import default_solver_options
from geosyn.controllers.mpc.ocp.settings import ocp_settings
from geosyn.experiments.schema.controllers import MPCConfig
from geosyn.metrics import KineticEnergyMetric
from geosyn.robots import load_robot


def _problem(name, control, effort=None, hessian="gauss-newton", metric=None):
    robot = get_robot(name)
    s = ocp_settings(robot.nv, 5, 0.02, control, effort, 1, 1e4, 1e1, None, 1e5)
    k = np.full(robot.nv, 1.0)
    return TrackingProblem(
        robot, metric or get_metric(name), s, hessian, None, k, k, 1.0, lambda _: None
    )


@pytest.mark.parametrize(
    ("control", "effort", "hessian", "expected"),
    [
        ("torque", None, "gauss-newton", "ddp"),
        ("torque", "metric", "gauss-newton", "ddp"),
        ("torque", None, "exact", "fatrop"),  # the DDP's Riccati pass is Gauss-Newton
        ("acceleration", None, "gauss-newton", "fatrop"),  # the DDP solves torques only
        ("acceleration", "torque", "gauss-newton", "fatrop"),
    ],
)
def test_default_solver_is_ddp_where_it_solves_the_problem(control, effort, hessian, expected):
    options = default_solver_options(_problem("planar2", control, effort, hessian))
    assert options.name == expected
    assert isinstance(options, DDPOptions if expected == "ddp" else NLPOptions)


def test_metric_effort_on_another_metric_defaults_to_fatrop():
    """The DDP's metric effort needs the robot's own kinetic-energy metric (its model)."""
    other = KineticEnergyMetric(load_robot("planar2"))  # another model object
    options = default_solver_options(_problem("planar2", "torque", "metric", metric=other))
    assert options.name == "fatrop"


def test_yaml_default_is_the_constructors():
    config = MPCConfig(type="mpc")
    assert config.solver is None and config.joint_limit_guard is True


def _far_reference(robot):
    """A still reference 1 rad from the start: the computed-torque fallback asks for
    about 400 M rad/s^2, far over planar2's 50 N m limits."""
    q_ref = np.array([1.0, -1.0])
    return JointTrajectoryReference(np.array([0.0, 2.0]), np.vstack([q_ref, q_ref]))


@pytest.mark.parametrize("guard", [False, True])
def test_fatrop_command_stays_within_the_torque_limits_and_is_flagged(guard):
    """A fatrop solve forced to fail (one iteration) falls back to the computed torque on
    the reference; its torque, written out here with Pinocchio's RNEA, exceeds the limits:
    the command stays inside them and the joints over are flagged as saturated."""
    robot, metric = get_robot("planar2"), get_metric("planar2")
    mpc = GeodesicMPC(
        robot, metric, horizon=5, dt=0.02, control="torque",
        solver=NLPOptions("fatrop", max_iter=1, tol=1e-12), joint_limit_guard=guard,
    )  # fmt: skip
    ref = _far_reference(robot)
    mpc.set_reference(ref)
    q, v = np.zeros(2), np.zeros(2)
    mpc.reset(q, v)
    tau = mpc.compute(0.0, q, v)
    d = mpc.diagnostics
    assert d.fallback_used
    q_ref, v_ref, a_ref = ref.sample(0.0)
    law = pin.rnea(
        robot.model, robot.model.createData(), q, v,
        a_ref + mpc.kp * (q_ref - q) + mpc.kd * (v_ref - v),
    )  # fmt: skip
    over = np.abs(law) > robot.tau_max
    assert over.any()
    np.testing.assert_array_equal(d.saturated, over)
    command = mpc.last_unclipped_torque  # what the benchmark counts: before any clip
    assert np.all(np.abs(command) <= robot.tau_max + 1e-9)
    np.testing.assert_allclose(tau, command, atol=0.0)
    if not guard:
        np.testing.assert_allclose(command, np.clip(law, -robot.tau_max, robot.tau_max))
        assert "guard" not in d.extra
        return
    # the guard's answer: within the box, the least M^-1-weighted change from the law's
    assert d.extra["guard"] == 1.0 and d.extra["guard_count"] == 1.0
    assert abs(d.extra["guard_dtau"] - float(np.max(np.abs(command - law)))) < 1e-9
    assert "changed the commanded torque on 1 ticks" in d.notes["joint_limit_guard"]
    m_inv = np.linalg.inv(pin.crba(robot.model, robot.model.createData(), q))
    clipped = np.clip(law, -robot.tau_max, robot.tau_max)
    cost = float((command - law) @ m_inv @ (command - law))
    assert cost <= float((clipped - law) @ m_inv @ (clipped - law)) + 1e-9
    mpc.reset(q, v)  # a reset forgets the count and its note
    assert mpc.command.count == 0 and "joint_limit_guard" not in d.notes


def test_ddp_feedback_saturated_between_solves_is_flagged():
    """Between solves the default DDP MPC follows its plan with the Riccati feedback
    ``u_j + f_j + K_j dx``, saturated at the torque limits: a joint whose feedback torque,
    written out here from the public plan, is over its limit is flagged as saturated and
    the command is that torque clipped (the state pushed off the plan)."""
    robot, metric = get_robot("planar2"), get_metric("planar2")
    mpc = GeodesicMPC(robot, metric, horizon=5, dt=0.02, control="torque")
    assert mpc.solver_options.name == "ddp"
    ref = _far_reference(robot)
    mpc.set_reference(ref)
    q, v = np.zeros(2), np.zeros(2)
    mpc.reset(q, v)
    mpc.compute(0.0, q, v)  # the solve tick: a plan with gains
    plan = mpc.plan
    assert plan is not None and plan.K is not None
    from geosyn.controllers.mpc.follow import plan_state

    t = 0.005  # inside the first stage, before the next solve (every 0.02 s)
    j, q_s, v_s = plan_state(plan, t, 0.02)
    f = 0.0 if plan.friction is None else plan.friction[j]
    # an offset driving joint 1's feedback 20 N m over its limit, along its gain row (a
    # joint the box QP clamps has no feedback gain: it stays at its limit, not over it)
    row = plan.K[j][1]
    u1 = plan.u[j][1] + (0.0 if np.isscalar(f) else f[1])
    dx = (robot.tau_max[1] + 20.0 - u1) * row / (row @ row)
    law = plan.u[j] + f + plan.K[j] @ dx
    over = np.abs(law) > robot.tau_max
    assert over.any(), law
    q1, v1 = q_s + dx[:2], v_s + dx[2:]
    tau = mpc.compute(t, q1, v1)
    assert not mpc.diagnostics.fallback_used  # still following the plan
    np.testing.assert_array_equal(mpc.diagnostics.saturated, over)
    np.testing.assert_allclose(tau, np.clip(law, -robot.tau_max, robot.tau_max), atol=1e-12)
