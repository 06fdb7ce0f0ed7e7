"""Acceptance of the torque-level MPC (issue 13) on the Panda, N = 10: its first planned
torques are the optimum of the OCP (IPOPT, solved to tight tolerance, agrees), its plan
obeys the robot's dynamics (Pinocchio's ABA, integrated independently), and warm-started
solves after a 250 N push keep the torque limits and recover."""

from __future__ import annotations

import functools

import numpy as np
import pinocchio as pin
import pytest

from conftest import get_metric, get_robot
from geosyn.controllers.mpc import DDPOptions, GeodesicMPC, NLPOptions
from geosyn.controllers.plant import PinocchioPlant
from geosyn.controllers.reference import GeodesicReference
from geosyn.synergies.synergy import GeodesicSynergy

Q0 = np.array([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785])  # Panda "ready" [rad]
V0 = np.array([0.4, 0.3, -0.3, 0.4, 0.5, -0.4, 0.6])  # [rad/s]


@functools.cache
def reference() -> GeodesicReference:
    synergy = GeodesicSynergy(get_metric("panda"), Q0, V0)
    return GeodesicReference(synergy, time_scale=1.5, duration=1.0, steps=200)


def _mpc(**kw) -> GeodesicMPC:
    """The panda's torque-level MPC, N = 10, on `reference` (``kw`` override anything)."""
    options = {"horizon": 10, "dt": 0.02, "control": "torque", "reference": reference(), **kw}
    return GeodesicMPC(get_robot("panda"), get_metric("panda"), **options)


def _rk4_pinocchio(model: pin.Model, x: np.ndarray, tau: np.ndarray, h: float) -> np.ndarray:
    """One RK4 step of ``qdd = pin.aba(q, v, tau)`` (the plan's stage, independently)."""
    data, n = model.createData(), model.nv

    def f(z: np.ndarray) -> np.ndarray:
        return np.concatenate([z[n:], pin.aba(model, data, z[:n], z[n:], tau)])

    k1 = f(x)
    k2 = f(x + 0.5 * h * k1)
    k3 = f(x + 0.5 * h * k2)
    k4 = f(x + h * k3)
    return x + (h / 6.0) * (k1 + 2 * k2 + 2 * k3 + k4)


@pytest.mark.slow
@pytest.mark.parametrize(
    ("solver", "costs"),
    [
        ("fatrop", {}),
        ("ddp", {}),
        # the metric effort and tracking in the metric's norm together (an error in
        # either shows; each alone agreed as well while building them)
        ("ddp", {"effort": "metric", "tracking": "metric"}),
    ],
)
def test_first_torques_equal_ipopt_and_the_plan_obeys_the_dynamics(
    solver: str, costs: dict
) -> None:
    robot = get_robot("panda")
    # 0.05 rad off the reference, at rest: the torques are far from the reference's.
    q, v = Q0 + 0.05, np.zeros(7)
    fast_options = (
        DDPOptions(tol=1e-10, max_iter=300)
        if solver == "ddp"
        else NLPOptions(solver, tol=1e-10, max_iter=300)
    )
    fast = _mpc(solver=fast_options, **costs)
    # The reference solve has no wall-time budget to race (a loaded machine is slow).
    tight = _mpc(solver=NLPOptions("ipopt", tol=1e-12, max_iter=500), max_solve_time=60.0, **costs)
    plans = []
    for mpc in (fast, tight):
        mpc.reset(q, v)
        plans.append(mpc.solve(0.0, q, v))
    plan, ref_plan = plans
    assert plan.success and ref_plan.success, (plan.status, ref_plan.status)
    err = np.linalg.norm(plan.u[0] - ref_plan.u[0]) / np.linalg.norm(ref_plan.u[0])
    assert err <= 1e-6, err
    # The plan obeys the dynamics: each planned state is Pinocchio's RK4 step of the
    # previous one under the planned torque (gaps closed), to 1e-8.
    for k in range(fast.N):
        x_next = _rk4_pinocchio(robot.model, plan.x[k], plan.u[k], fast.dt)
        np.testing.assert_allclose(plan.x[k + 1], x_next, rtol=0, atol=1e-8)
    np.testing.assert_array_equal(plan.tau, plan.u)  # torque control: u is the torque
    np.testing.assert_allclose(plan.x[0], np.concatenate([q, v]), atol=1e-10)
    # Interior-point solvers relax bounds by ~1e-8 relative (IPOPT's bound_relax_factor).
    assert np.all(np.abs(plan.u) <= robot.tau_max * (1 + 1e-7))


@pytest.mark.slow
@pytest.mark.parametrize("solver", ["fatrop", "ddp"])
def test_warm_solves_after_a_250_newton_push_keep_limits_and_recover(solver: str) -> None:
    robot = get_robot("panda")
    model, data = robot.model, robot.model.createData()
    frame = model.getFrameId("panda_link5")
    mpc = _mpc(solver=solver)
    q0, v0 = reference().sample(0.0)[:2]
    mpc.reset(q0, v0)
    plant = PinocchioPlant(robot, dt=1e-3)
    plant.reset(q0, v0)
    push = (0.3, 0.4)  # [s]: 250 N along world x on panda_link5's origin
    force = np.array([250.0, 0.0, 0.0])
    errors, plans = [], []
    t = 0.0
    for _ in range(1000):
        t, q, v = plant.t, plant.q, plant.v
        tau = mpc.compute(t, q, v)
        if solver == "ddp":  # its saturated Riccati feedback never commands beyond a limit
            assert np.all(np.abs(mpc.last_unclipped_torque) <= robot.tau_max)
        if mpc.plan is not None and mpc.plan.t == t:  # a solve happened at this tick
            plans.append((t, mpc.plan, mpc.diagnostics.fallback_used))
        tau_ext = np.zeros(7)
        if push[0] <= t < push[1]:
            J = pin.computeFrameJacobian(model, data, q, frame, pin.LOCAL_WORLD_ALIGNED)
            tau_ext = J[:3].T @ force
        plant.step(tau + tau_ext)
        errors.append(np.max(np.abs(plant.q - reference().sample(plant.t).q)))
    errors_arr = np.array(errors)
    # The push really disturbs (> 1 cm-ish in joint space), then the error recovers.
    assert errors_arr[int(push[1] * 1000)] > 5e-3
    assert errors_arr[-100:].max() < 0.2 * errors_arr.max()
    assert errors_arr[-100:].max() < 5e-3
    after = [(s, p, fb) for s, p, fb in plans if s >= push[0]]
    assert len(after) >= 30
    for _, plan, fallback in after:
        assert plan.success and not fallback
        assert np.all(np.abs(plan.u) <= robot.tau_max * (1 + 1e-7))  # the plan keeps limits
