"""The box-DDP solver of the torque-level MPC (``GeodesicMPC(solver="ddp")``, issue 13):
its box QP against SciPy, its feedback gains against finite differences of re-solved
problems, its warm step against a cold solve, the reference sampler against
`sample_reference`, and its refusals of bad input."""

from __future__ import annotations

from pathlib import Path

import casadi as ca
import numpy as np
import pinocchio as pin
import pytest
from scipy.optimize import minimize
from test_mpc_torque import _mpc as torque_mpc
from test_mpc_torque import reference

from conftest import get_metric, get_robot
from geosyn.controllers.mpc import DDPOptions, GeodesicMPC
from geosyn.controllers.mpc.ddp.box_qp import BOX_ITERATIONS, box_qp
from geosyn.controllers.mpc.ddp.parts import riccati_step
from geosyn.controllers.mpc.ocp.plan import ReferenceSampler, sample_reference
from geosyn.controllers.reference import GeodesicReference
from geosyn.core.errors import GeosynError, InvalidArgument
from geosyn.synergies.synergy import GeodesicSynergy


def _mpc(**kw) -> GeodesicMPC:
    """`test_mpc_torque`'s panda MPC (N = 10, its geodesic reference) with the DDP solver."""
    return torque_mpc(**{"solver": "ddp", **kw})


def test_box_qp_matches_scipy_on_seeded_problems() -> None:
    """The unrolled projected Newton reaches the box-QP optimum (L-BFGS-B to 1e-12)."""
    n = 7
    H, g, lo, hi = (
        ca.SX.sym(s, *d) for s, d in [("H", (n, n)), ("g", (n, 1)), ("lo", (n, 1)), ("hi", (n, 1))]
    )
    k, free, _ = box_qp(H, g, lo, hi, BOX_ITERATIONS)
    qp = ca.Function("qp", [H, g, lo, hi], [k, free])
    rng = np.random.default_rng(3)
    active_counts = []
    for _ in range(100):
        M = rng.normal(size=(n, n))
        Hn, gn = M @ M.T + 0.1 * np.eye(n), 3.0 * rng.normal(size=n)
        lon, hin = -rng.uniform(0.1, 1.0, n), rng.uniform(0.1, 1.0, n)
        kk, ff = (np.asarray(a).ravel() for a in qp(Hn, gn, lon, hin))
        ref = minimize(
            lambda z, H=Hn, g=gn: 0.5 * z @ H @ z + g @ z, np.zeros(n),
            jac=lambda z, H=Hn, g=gn: H @ z + g,
            bounds=list(zip(lon, hin, strict=True)), method="L-BFGS-B",
            options={"ftol": 1e-15, "gtol": 1e-12, "maxiter": 10000},
        )  # fmt: skip
        value = 0.5 * kk @ Hn @ kk + gn @ kk
        assert np.all(kk >= lon) and np.all(kk <= hin)
        assert value <= ref.fun + 1e-9 * (1 + abs(ref.fun)), (value, ref.fun)
        np.testing.assert_allclose(kk, ref.x, atol=1e-5)
        # The free mask is the complement of the bounds that hold k with an outward gradient.
        grad = Hn @ kk + gn
        clamped = ((kk <= lon) & (grad > 0)) | ((kk >= hin) & (grad < 0))
        np.testing.assert_array_equal(ff, 1.0 - clamped)
        active_counts.append(int(clamped.sum()))
    assert max(active_counts) >= 3  # the draw exercises several active bounds at once


def test_feedback_gain_is_the_sensitivity_of_the_optimal_torque() -> None:
    """At the optimum, ``K_0 = d u_0^* / d x_0`` (finite differences of converged cold
    solves; Gauss-Newton drops the dynamics' curvature, so agreement is to ~1 %)."""
    mpc = _mpc(solver=DDPOptions(tol=1e-12, max_iter=200))
    q, v = reference().sample(0.0)[:2]
    x0 = np.concatenate([q, v])
    mpc.reset(q, v)
    plan = mpc.solve(0.0, q, v)
    assert plan.success and plan.K is not None
    assert np.all(np.abs(plan.u) < get_robot("panda").tau_max)  # no bound active
    h = 1e-5
    fd = np.empty((7, 14))
    for i in range(14):
        dx = np.zeros(14)
        dx[i] = h
        u = []
        for sign in (1.0, -1.0):
            mpc.reset(q, v)
            x = x0 + sign * dx
            u.append(mpc.solve(0.0, x[:7], x[7:]).u[0])
        fd[:, i] = (u[0] - u[1]) / (2 * h)
    err = np.linalg.norm(plan.K[0] - fd) / np.linalg.norm(fd)
    assert err < 1e-2, err


def test_a_warm_step_from_the_optimum_stays_at_the_optimum() -> None:
    """Shifting a converged plan by one stage and taking one DDP step from the state it
    predicts lands on the cold solve of that problem (RTI from a good guess: 1e-3 rel.)."""
    mpc = _mpc(solver=DDPOptions(tol=1e-12, max_iter=200))
    q, v = reference().sample(0.0)[:2]
    q = q + 0.02
    mpc.reset(q, v)
    first = mpc.solve(0.0, q, v)
    mpc._plan = first  # the controller keeps a successful plan the same way
    x1 = first.x[1]
    warm = mpc.solve(mpc.dt, x1[:7], x1[7:])
    assert warm.status == "warm step" and warm.iterations == 1
    cold = _mpc(solver=DDPOptions(tol=1e-12, max_iter=200))
    cold.reset(x1[:7], x1[7:])
    ref = cold.solve(mpc.dt, x1[:7], x1[7:])
    err = np.linalg.norm(warm.u[0] - ref.u[0]) / np.linalg.norm(ref.u[0])
    assert err < 1e-3, err


def test_reference_sampler_shifts_what_sample_reference_computes() -> None:
    robot = get_robot("panda")
    model, data = robot.model, robot.model.createData()
    sampler = ReferenceSampler(model, data)
    for t in (0.0, 0.02, 0.06, 0.06, 0.1, 0.31, 0.33):  # whole-stage shifts, a repeat, a jump
        got = sampler.sample(reference(), t, 10, 0.02)
        want = sample_reference(reference(), model, data, t, 10, 0.02)
        for a, b in zip(got, want, strict=True):
            assert a.shape == b.shape
            np.testing.assert_allclose(a, b, rtol=0, atol=1e-12)


@pytest.mark.parametrize(
    ("kwargs", "named"),
    [
        ({"control": "acceleration"}, "control='torque'"),
        ({"effort": "acceleration"}, "effort"),
        ({"hessian": "exact"}, "hessian"),
        ({"solver": "ddpx"}, "solver"),
        ({"tracking": "riemann"}, "tracking"),
    ],
)
def test_bad_ddp_settings_are_refused_by_name(kwargs: dict, named: str) -> None:
    with pytest.raises(InvalidArgument, match=named) as info:
        _mpc(**kwargs)
    assert isinstance(info.value, GeosynError)


@pytest.mark.parametrize(
    ("kwargs", "named"),
    [
        ({"warm_iterations": 0}, "warm_iterations"),
        ({"limit_weight": -1.0}, "limit_weight"),
        ({"tol": float("nan")}, "tol"),
    ],
)
def test_bad_ddp_options_are_refused_by_name(kwargs: dict, named: str) -> None:
    with pytest.raises(InvalidArgument, match=named):
        DDPOptions(**kwargs)


def test_the_open_loop_ocp_still_solves_with_ddp_tracking() -> None:
    """``solve_open_loop`` uses IPOPT when the tracking solver is DDP (documented);
    planar2, whose open-loop NLP builds in a fraction of the panda's time."""
    mpc = GeodesicMPC(
        get_robot("planar2"), get_metric("planar2"), horizon=10, dt=0.05,
        control="torque", solver="ddp",
    )  # fmt: skip
    q0 = np.array([0.3, -0.4])
    sol = mpc.solve_open_loop(q0, q0 + 0.1)
    assert sol.success, sol.status
    np.testing.assert_allclose(sol.q[-1], q0 + 0.1, atol=1e-6)


def test_mx_riccati_step_equals_the_sx_one() -> None:
    """Robots beyond SX_RICCATI_MAX_JOINTS get the MX form (LDL^T solves, loops): the
    same step to rounding, with and without active torque bounds."""
    n = 7
    sx, mx = riccati_step(n, ca.SX), riccati_step(n, ca.MX)
    rng = np.random.default_rng(5)
    for tau_scale in (1e3, 0.5):  # bounds inactive, then several active
        M = rng.normal(size=(2 * n, 2 * n))
        args = [
            rng.normal(size=2 * n), M @ M.T, np.eye(2 * n) + 0.02 * rng.normal(size=(2 * n, 2 * n)),
            0.02 * rng.normal(size=(2 * n, n)), rng.normal(size=2 * n), rng.normal(size=n),
            rng.normal(size=2 * n), rng.normal(size=n),
            np.concatenate([np.full(2 * n, 10.0), np.full(n, 1e-3), np.full(2 * n, 100.0),
                            np.full(n, -3.0), np.full(n, 3.0), np.full(n, 2.0),
                            np.full(n, tau_scale), np.zeros(n), [0.01, 1e6, 1e-9]]),
        ]  # fmt: skip
        out_sx, out_mx = sx(*args), mx(*args)
        for a, b in zip(out_sx, out_mx, strict=True):
            np.testing.assert_allclose(np.asarray(b), np.asarray(a), rtol=1e-9, atol=1e-9)
        if tau_scale < 1:
            assert np.any(np.abs(np.asarray(out_sx[2]).ravel() + args[5]) >= tau_scale - 1e-12)


@pytest.mark.parametrize(("horizon", "rk4_steps"), [(1, 1), (6, 2)])
def test_ddp_plan_obeys_the_dynamics_for_other_horizons_and_rk4_steps(
    horizon: int, rk4_steps: int
) -> None:
    """planar2, converged cold solve: each planned state is ``rk4_steps`` RK4 steps of
    ``pin.aba`` under the planned torque (1e-10), torques within the limits."""
    robot = get_robot("planar2")
    model, data = robot.model, robot.model.createData()
    q0 = np.array([0.3, -0.4])
    synergy = GeodesicSynergy(get_metric("planar2"), q0, np.array([0.5, -0.3]))
    mpc = GeodesicMPC(
        robot, get_metric("planar2"), horizon=horizon, dt=0.05, control="torque",
        solver=DDPOptions(tol=1e-10, max_iter=100), rk4_steps=rk4_steps,
        reference=GeodesicReference(synergy, duration=1.0, steps=100),
    )  # fmt: skip
    q, v = q0 + 0.05, np.zeros(2)
    mpc.reset(q, v)
    plan = mpc.solve(0.0, q, v)
    assert plan.success, plan.status
    h = mpc.dt / rk4_steps

    def f(z: np.ndarray, tau: np.ndarray) -> np.ndarray:
        return np.concatenate([z[2:], pin.aba(model, data, z[:2], z[2:], tau)])

    for k in range(horizon):
        x = plan.x[k].copy()
        for _ in range(rk4_steps):
            k1 = f(x, plan.u[k])
            k2 = f(x + 0.5 * h * k1, plan.u[k])
            k3 = f(x + 0.5 * h * k2, plan.u[k])
            k4 = f(x + h * k3, plan.u[k])
            x = x + (h / 6.0) * (k1 + 2 * k2 + 2 * k3 + k4)
        np.testing.assert_allclose(plan.x[k + 1], x, rtol=0, atol=1e-10)
    assert np.all(np.abs(plan.u) <= robot.tau_max)


def test_metric_effort_needs_the_robots_kinetic_metric() -> None:
    """Another model's M(q) (armature 0) is not the OCP's dynamics: refused by name."""
    from geosyn.metrics import KineticEnergyMetric
    from geosyn.robots import load_robot

    other = KineticEnergyMetric(load_robot("panda", armature=0.0))
    with pytest.raises(InvalidArgument, match="KineticEnergyMetric"):
        GeodesicMPC(
            get_robot("panda"), other, horizon=5, control="torque", solver="ddp",
            effort="metric",
        )  # fmt: skip


def test_clearance_margin_keeps_the_world_obstacle_away() -> None:
    """A reference sweeping the panda's base joint passes 5 mm from a ball: the DDP MPC
    with ``obstacles=[ball]``, ``clearance_margin=0.03`` keeps 3 cm to within 5 mm in
    closed loop (Pinocchio plant, 1 kHz), without fallbacks, and tracks the reference
    again afterwards; the same MPC without it comes within 5 mm (clearances measured
    independently, by the metric shaping term's exact distance)."""
    from geosyn.controllers import JointTrajectoryReference
    from geosyn.controllers.plant import PinocchioPlant
    from geosyn.metrics.shaping import ObstacleTerm
    from geosyn.world import Sphere

    robot, K = get_robot("panda"), get_metric("panda")
    qa = np.array([-0.6, -0.3, 0.0, -2.2, 0.0, 1.9, 0.785])
    qb = qa.copy()
    qb[0] = 0.6
    t = np.linspace(0.0, 1.5, 31)
    s = np.clip(t / 1.2, 0.0, 1.0)
    ref = JointTrajectoryReference(t, qa + np.outer(10 * s**3 - 15 * s**4 + 6 * s**5, qb - qa))
    model, data = robot.model, robot.model.createData()
    pin.forwardKinematics(model, data, ref.sample(0.6).q)
    hand = robot.collision_spheres()[-1]
    c = data.oMi[model.getJointId(hand.joint)].act(np.array(hand.center))
    radial = np.array([c[0], c[1], 0.0]) / np.linalg.norm(c[:2])
    ball = Sphere(tuple(c + 0.095 * radial), 0.03)
    term = ObstacleTerm([ball], capacity=1)
    term.bind(robot)
    assert (
        0.004 < min(term.min_clearance(ref.sample(x).q) for x in np.linspace(0, 1.5, 151)) < 0.006
    )
    runs = {}
    guarded: dict = {"clearance_margin": 0.03, "obstacles": [ball]}
    for label, kw in (("plain", {}), ("guarded", guarded)):
        mpc = GeodesicMPC(
            robot, K, horizon=10, dt=0.02, control="torque", solver="ddp",
            reference=ref, **kw,
        )  # fmt: skip
        mpc.reset(qa, np.zeros(7))
        plant = PinocchioPlant(robot, dt=1e-3)
        plant.reset(qa, np.zeros(7))
        clearance = []
        for _ in range(1500):
            plant.step(mpc.compute(plant.t, plant.q, plant.v))
            clearance.append(term.min_clearance(plant.q))
        error = np.abs(plant.q - ref.sample(plant.t).q).max()
        runs[label] = (min(clearance), mpc.diagnostics.fallback_count, error)
    assert runs["plain"][0] < 0.006
    assert runs["guarded"][0] > 0.025, runs
    assert runs["guarded"][1] == 0 and runs["guarded"][2] < 1e-3, runs


def test_clearance_margin_needs_ddp_and_obstacles() -> None:
    with pytest.raises(InvalidArgument, match="clearance_margin needs solver='ddp'"):
        GeodesicMPC(get_robot("panda"), get_metric("panda"), horizon=5, clearance_margin=0.02)
    with pytest.raises(InvalidArgument, match=r"needs obstacles: GeodesicMPC\(obstacles="):
        _mpc(clearance_margin=0.02)  # obstacles come as shapes, never through the metric


def test_yaml_mpc_clearance_keeps_clear_of_the_scene_even_on_a_colliding_reference(tmp_path):
    """The built-in obstacle experiment with the DDP MPC and ``clearance_margin: 0.02``
    instead of computed torque: the MPC keeps clear of the scene's sphere (the experiment
    builder hands it the scene's obstacles). The unshaped reference runs 13 cm into the
    sphere, yet neither run touches it in MuJoCo (contact on): executed clearance > 1 cm,
    zero contact force, no fallback."""
    import json

    import yaml

    from geosyn.experiments import run_experiment
    from geosyn.experiments.config.loader import load_config

    text = (
        Path(__file__).parents[1] / "experiments/configs/panda_obstacle_shaping.yaml"
    ).read_text()
    cfg_dict = yaml.safe_load(text)
    cfg_dict["name"] = "panda_obstacle_mpc_clearance"
    cfg_dict["controllers"] = [
        {"type": "mpc", "horizon": 10, "control": "torque", "solver": "ddp",
         "clearance_margin": 0.02},
    ]  # fmt: skip
    path = tmp_path / "obstacle_mpc.yaml"
    path.write_text(yaml.safe_dump(cfg_dict))
    cfg, _ = load_config(str(path), ["outputs.plots=false"])
    outcome = run_experiment(cfg, tmp_path / "run", progress=False, quiet=True)
    s = json.loads((outcome.path / "summary.json").read_text())
    assert s["unshaped.planned_clearance"] < -0.1  # the reference runs into the sphere
    for run in ("shaped", "unshaped"):
        assert s[f"{run}.ok"] == 1.0 and s[f"{run}.fallbacks"] == 0.0
        assert s[f"{run}.executed_clearance"] > 0.01, s
        assert s[f"{run}.max_contact_force"] == 0.0 and s[f"{run}.contact_time"] == 0.0


def test_yaml_mpc_clearance_without_obstacles_is_refused_by_name() -> None:
    from geosyn.experiments.run.build import build_controller
    from geosyn.experiments.schema import MPCConfig

    section = MPCConfig.model_validate(
        {"type": "mpc", "control": "torque", "solver": "ddp", "clearance_margin": 0.02}
    )
    with pytest.raises(InvalidArgument, match="scene.obstacles"):
        build_controller(section, get_robot("panda"), get_metric("panda"), 1e-3, [])
