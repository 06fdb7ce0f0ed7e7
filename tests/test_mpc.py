"""GeodesicMPC: closed-loop tracking on a Pinocchio plant (pin.aba + RK4 at 1 kHz), the
minimum-effort OCP against the geodesic from the log map, fallbacks and bad input."""

from __future__ import annotations

import dataclasses
import functools

import numpy as np
import pinocchio as pin
import pytest

from conftest import get_metric, get_robot
from geosyn.controllers.mpc import GeodesicMPC, NLPOptions
from geosyn.controllers.plant import PinocchioPlant
from geosyn.controllers.reference import GeodesicReference
from geosyn.core import GeosynError, InvalidArgument
from geosyn.metrics.geodesic import exp, log
from geosyn.synergies.synergy import GeodesicSynergy

TIME_SCALE = 1.5  # the reference traverses the unit-time geodesic in 1.5 s
SIM_TIME = 2.0  # [s]: the motion plus 0.5 s holding the goal


@functools.cache
def get_mpc(
    name: str, control: str = "torque", solver: str | NLPOptions = "fatrop", **kw
) -> GeodesicMPC:
    return GeodesicMPC(
        get_robot(name),
        get_metric(name),
        horizon=40,
        dt=0.02,
        solver=solver,
        control=control,
        **kw,
    )


def synergy_reference(name: str) -> tuple[GeodesicReference, np.ndarray, np.ndarray]:
    """A geodesic synergy from mid-range with 0.6 rad/s on every joint, slowed by 1.5."""
    robot, metric = get_robot(name), get_metric(name)
    q_lo = np.where(np.isfinite(robot.q_min), robot.q_min, -1.0)
    q_hi = np.where(np.isfinite(robot.q_max), robot.q_max, 1.0)
    q0 = 0.5 * (q_lo + q_hi)
    v0 = np.full(robot.nv, 0.6)
    ref = GeodesicReference(
        GeodesicSynergy(metric, q0, v0), time_scale=TIME_SCALE, duration=1.0, steps=200
    )
    return ref, q0, v0 / TIME_SCALE


def closed_loop(mpc: GeodesicMPC, name: str):
    ref, q0, v0 = synergy_reference(name)
    mpc.set_reference(ref)
    mpc.reset(q0, v0)
    plant = PinocchioPlant(get_robot(name), dt=1e-3)
    plant.reset(q0, v0)
    fallbacks = []
    roll = plant.rollout(
        mpc, SIM_TIME, lambda t, q, v, tau: fallbacks.append(mpc.diagnostics.fallback_used)
    )
    q_ref = np.array([ref.sample(t).q for t in roll.t])
    return roll, q_ref, ref, fallbacks


def check_tracking(mpc: GeodesicMPC, name: str) -> None:
    robot = get_robot(name)
    roll, q_ref, ref, fallbacks = closed_loop(mpc, name)
    # The reference really moves (so a small error is not trivial).
    assert np.max(np.abs(q_ref[-1] - q_ref[0])) > 0.3
    rms = float(np.sqrt(np.mean((roll.q - q_ref) ** 2)))
    assert rms <= 5e-3, rms
    assert np.all(np.abs(roll.tau) <= robot.tau_max + 1e-9)
    assert not any(fallbacks)
    # The goal is reached and held: final error and velocity are small.
    assert np.max(np.abs(roll.q[-1] - ref.goal())) <= 1e-3
    assert np.max(np.abs(roll.v[-1])) <= 1e-2
    # Gravity is on for the panda: the torques carry it (nonzero mean where held still).
    if name == "panda":
        g_end = pin.computeGeneralizedGravity(robot.model, robot.model.createData(), roll.q[-1])
        np.testing.assert_allclose(roll.tau[-1], g_end, atol=0.5)


@pytest.mark.parametrize("control", ["torque", "acceleration"])
def test_planar2_tracks_synergy(control: str) -> None:
    check_tracking(get_mpc("planar2", control), "planar2")


def test_planar2_ipopt_tracks_synergy() -> None:
    check_tracking(get_mpc("planar2", "torque", "ipopt"), "planar2")


@pytest.mark.parametrize(
    "options",
    [
        {"hessian": "exact"},
        {"effort": "metric"},
        {"control": "acceleration", "effort": "acceleration"},
        {"control": "acceleration", "effort": "metric", "hessian": "exact"},
    ],
    ids=["exact-hessian", "metric-effort", "acceleration-effort", "acc-metric-exact"],
)
def test_planar2_variants_track_synergy(options: dict) -> None:
    options = dict(options)
    control = options.pop("control", "torque")
    check_tracking(get_mpc("planar2", control, **options), "planar2")


@pytest.mark.slow
@pytest.mark.parametrize("effort", ["acceleration", "torque"])
def test_panda_tracks_synergy_acceleration_control(effort: str) -> None:
    check_tracking(get_mpc("panda", "acceleration", effort=effort), "panda")


@pytest.mark.slow
def test_panda_tracks_synergy_torque_control() -> None:
    # The first run compiles the RK4/ABA step and its Jacobian (slow once, then cached on
    # disk); a shorter horizon keeps the test short (the benchmark uses N = 40).
    mpc = GeodesicMPC(get_robot("panda"), get_metric("panda"), horizon=20, dt=0.02)
    check_tracking(mpc, "panda")


def test_solver_resolves_at_its_own_rate() -> None:
    mpc = get_mpc("planar2")
    ref, q0, v0 = synergy_reference("planar2")
    mpc.set_reference(ref)
    mpc.reset(q0, v0)
    before = mpc.solve_count
    for k in range(20):  # 20 ms at 1 kHz: exactly one solve (at t = 0)
        mpc.compute(k * 1e-3, q0, v0)
    assert mpc.solve_count - before == 1
    mpc.compute(0.02, q0, v0)
    assert mpc.solve_count - before == 2
    assert mpc.diagnostics.iterations > 0


def test_warm_start_needs_fewer_iterations() -> None:
    mpc = get_mpc("planar2")
    ref, q0, v0 = synergy_reference("planar2")
    mpc.set_reference(ref)
    mpc.reset(q0, v0)
    cold = mpc.solve(0.0, q0, v0)
    mpc._plan = cold
    q1, v1 = cold.x[1, :2], cold.x[1, 2:]
    warm = mpc.solve(0.02, q1, v1)
    assert cold.success and warm.success
    assert warm.iterations < cold.iterations


# -- the minimum-effort Riemannian OCP is solved by the geodesic --------------------------
@pytest.mark.parametrize("free_v0", [True, False])
def test_open_loop_effort_ocp_matches_geodesic(free_v0: bool) -> None:
    robot, metric = get_robot("planar2"), get_metric("planar2")
    mpc = get_mpc("planar2")
    q0 = np.array([0.3, 0.3])
    q1 = np.array([1.8, -0.9])
    T = mpc.N * mpc.dt
    v_log = log(metric, q0, q1) / T  # geodesic from q0 reaching q1 at time T
    sol = mpc.solve_open_loop(q0, q1, v0=None if free_v0 else v_log, free_initial_velocity=free_v0)
    assert sol.success, sol.status
    geo = exp(metric, q0, v_log, duration=T, steps=4 * mpc.N, method="dop853")
    q_geo = geo.q[::4]
    err = float(np.max(np.abs(sol.q - q_geo)))
    assert err <= 1e-2, err
    # ... and the test is not trivially met by the straight line.
    line = q0 + np.linspace(0.0, 1.0, mpc.N + 1)[:, None] * (q1 - q0)
    assert np.max(np.abs(line - q_geo)) > 0.05
    # Gravity-free geodesic motion needs no torque: effort ~ 0, limits inactive.
    assert np.max(np.abs(sol.tau)) <= 1e-3 * float(np.min(robot.tau_max))
    np.testing.assert_allclose(sol.q[-1], q1, atol=1e-6)
    if free_v0:
        np.testing.assert_allclose(sol.v[0], v_log, atol=1e-2)


# -- failures and fallbacks -------------------------------------------------------------
def test_forced_failure_falls_back_to_computed_torque() -> None:
    robot = get_robot("planar2")
    mpc = get_mpc("planar2", "torque", NLPOptions("fatrop", max_iter=1))
    ref, q0, v0 = synergy_reference("planar2")
    mpc.set_reference(ref)
    mpc.reset(q0, v0)
    q = q0 + 0.01
    tau = mpc.compute(0.0, q, v0)
    d = mpc.diagnostics
    assert d.fallback_used and d.fallback_count == 1
    assert d.solver_status != "0" and d.iterations >= 1
    # The fallback is the computed torque on the reference with the PD gains.
    q_ref, v_ref, a_ref = ref.sample(0.0)
    a = a_ref + mpc.kp * (q_ref - q) + mpc.kd * (v_ref - v0)
    expected = pin.rnea(robot.model, robot.model.createData(), q, v0, a)
    np.testing.assert_allclose(tau, np.clip(expected, -robot.tau_max, robot.tau_max), atol=1e-9)
    # Between solves the fallback stays flagged.
    mpc.compute(1e-3, q, v0)
    assert mpc.diagnostics.fallback_used and mpc.diagnostics.fallback_count == 2


def test_failure_after_success_keeps_previous_plan() -> None:
    mpc = get_mpc("planar2")
    failing = get_mpc("planar2", "torque", NLPOptions("fatrop", max_iter=1, tol=1e-12))
    ref, q0, v0 = synergy_reference("planar2")
    mpc.set_reference(ref)
    mpc.reset(q0, v0)
    mpc.compute(0.0, q0, v0)
    plan = mpc.plan
    assert plan is not None and plan.success and not mpc.diagnostics.fallback_used
    good = mpc._tracker
    try:
        mpc._tracker = failing._tracker  # same problem, max_iter=1: the next solve fails
        # 0.01 rad off the plan: within plan_tolerance, but one iteration cannot converge.
        q1, v1 = plan.x[1, :2] + 0.01, plan.x[1, 2:]
        tau = mpc.compute(0.02, q1, v1)
    finally:
        mpc._tracker = good
    d = mpc.diagnostics
    assert d.fallback_used and d.extra["fallback"] == 1.0
    assert d.solver_status != "0"
    # The shifted previous plan: its second stage torque plus the PD towards its state.
    robot = get_robot("planar2")
    M = pin.crba(robot.model, robot.model.createData(), q1)
    expected = plan.u[1] + M @ (mpc.kp * (plan.x[1, :2] - q1) + mpc.kd * (plan.x[1, 2:] - v1))
    np.testing.assert_allclose(tau, np.clip(expected, -robot.tau_max, robot.tau_max), atol=1e-9)


def test_infeasible_problem_flags_fallback() -> None:
    robot = dataclasses.replace(get_robot("planar2"), tau_max=np.full(2, 1e-3))
    mpc = GeodesicMPC(
        robot, get_metric("planar2"), horizon=10, dt=0.02, solver=NLPOptions(max_iter=30)
    )
    ref, q0, _ = synergy_reference("planar2")
    mpc.set_reference(ref)
    # Twice the velocity limit and 1 mN m of torque: |v_1| <= v_max cannot be met.
    v = 2.0 * robot.v_max
    mpc.reset(q0, v)
    tau = mpc.compute(0.0, q0, v)
    d = mpc.diagnostics
    assert d.fallback_used and d.fallback_count == 1
    assert d.solver_status != "0", d.solver_status
    assert d.extra["fallback"] == 2.0  # no previous plan: computed torque
    assert np.all(np.abs(tau) <= robot.tau_max)
    assert d.saturated is not None and d.saturated.all()


# -- bad input ----------------------------------------------------------------------------
@pytest.mark.parametrize(
    "kwargs, words",
    [
        ({"horizon": -3}, ["horizon", "-3"]),
        ({"horizon": 0}, ["horizon"]),
        ({"horizon": 2.5}, ["horizon"]),
        ({"dt": -0.01}, ["dt", "-0.01"]),
        ({"dt": float("nan")}, ["dt"]),
        ({"solver": "qpoases"}, ["qpoases", "fatrop", "ipopt"]),
        ({"effort": "energy"}, ["effort", "torque", "metric"]),
        ({"control": "jerk"}, ["control", "acceleration"]),
        ({"effort": "acceleration", "control": "torque"}, ["effort", "control"]),
        ({"rk4_steps": 3}, ["rk4_steps"]),
        ({"hessian": "bfgs"}, ["hessian", "gauss-newton", "exact"]),
        ({"q_weight": np.ones(3)}, ["q_weight", "(2,)"]),
        ({"v_weight": -1.0}, ["v_weight"]),
        ({"terminal_weight": np.ones(2)}, ["terminal_weight", "(4,)"]),
        ({"tau_weight": np.ones((2, 2))}, ["tau_weight"]),
        ({"kp": [1.0, 2.0, 3.0]}, ["kp"]),
    ],
)
def test_bad_input(kwargs: dict, words: list[str]) -> None:
    with pytest.raises(InvalidArgument) as info:
        GeodesicMPC(get_robot("planar2"), get_metric("planar2"), **kwargs)
    assert isinstance(info.value, GeosynError)
    for w in words:
        assert w in str(info.value)


def test_bad_metric_and_state() -> None:
    with pytest.raises(InvalidArgument, match="metric"):
        GeodesicMPC(get_robot("planar2"), get_metric("panda"))
    mpc = get_mpc("planar2")
    with pytest.raises(InvalidArgument, match="q0"):
        mpc.solve_open_loop(np.zeros(3), np.zeros(2))
