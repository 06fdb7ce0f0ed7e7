"""The native (hand-written C) backward pass of the box-DDP solver
(geosyn/controllers/mpc/ddp/native): on the fixture arm with viscous joint damping and dry
friction it gives CasADi's graph of the same mathematics (``DDPOptions(backward="casadi")``)
to 1e-10 of its scale, with torque limits active and inactive; and, referee independent of
both, the DDP's converged solve on the native path equals IPOPT's solve of the same OCP."""

from __future__ import annotations

import fnmatch
import functools
import itertools
from pathlib import Path

import numpy as np
import pytest
import tomllib

from geosyn.controllers import GeodesicMPC, GeodesicReference
from geosyn.controllers.mpc import DDPOptions, NLPOptions
from geosyn.controllers.mpc.ddp import DDPTracking
from geosyn.controllers.mpc.ddp.native import C_DIR
from geosyn.core.errors import InvalidArgument
from geosyn.metrics import KineticEnergyMetric
from geosyn.robots import Robot, load_robot
from geosyn.synergies import GeodesicSynergy

FIXTURE = Path(__file__).parent / "fixtures" / "arm_root_quat.xml"
Q0 = np.array([0.3, 0.2, -0.2, 0.05, 0.3])
V0 = np.array([0.4, -0.3, 0.35, 0.03, 0.5])


@functools.cache
def _arm() -> tuple[Robot, KineticEnergyMetric, GeodesicReference]:
    """The fixture arm (damping 0.4 and 1.5 N m s/rad, dry friction 0.1 N m, armature,
    torque limits) and a geodesic reference."""
    with pytest.warns(Warning):  # the file states no velocity limits (defaults, reported)
        robot = load_robot(str(FIXTURE))
    assert np.any(robot.damping) and np.any(robot.frictionloss)
    metric = KineticEnergyMetric(robot)
    return robot, metric, GeodesicReference(GeodesicSynergy(metric, Q0, V0), duration=1.0)


def _mpc(solver: DDPOptions | NLPOptions, **kw) -> GeodesicMPC:
    robot, metric, ref = _arm()
    return GeodesicMPC(
        robot, metric, horizon=10, dt=0.02, control="torque", solver=solver, reference=ref,
        joint_limit_guard=False, **kw,
    )  # fmt: skip


def _ddp(mpc: GeodesicMPC) -> DDPTracking:
    backend = mpc.backend
    assert isinstance(backend, DDPTracking)
    return backend


def _trajectory(mpc: GeodesicMPC, torque_scale: float, seed: int) -> tuple[np.ndarray, ...]:
    """A seeded trajectory near the reference, in the backward pass's column-major
    layout: X (2n, N+1), U (n, N), XR, TR; U = torque_scale x tau_max x a random sign
    pattern plus noise (1.5: beyond the limits, so that the box QP clamps)."""
    rng = np.random.default_rng(seed)
    robot, N, n = mpc.robot, mpc.N, mpc.nv
    t = mpc.dt * np.arange(N + 1)
    _, _, ref = _arm()
    XR = np.array([np.concatenate(ref.sample(tk)[:2]) for tk in t]).T
    X = XR + 0.05 * rng.standard_normal(XR.shape)
    TR = 0.5 * robot.tau_max[:, None] * rng.uniform(-1, 1, (n, N))
    U = torque_scale * robot.tau_max[:, None] * rng.uniform(-1, 1, (n, N))
    return X, U, XR, TR


def test_native_backward_pass_equals_the_casadi_graph() -> None:
    """Gains k, K and the value function's predicted change dV to 1e-10 of each output's
    largest entry (measured: about 1e-13), on six seeded trajectories with small and
    beyond-the-limit torques: the box QP's every branch runs (controls inside the box,
    clamped ones, whose rows of K are zero)."""
    native, graph = (_mpc(DDPOptions(backward=b)) for b in ("native", "casadi"))
    a, b = _ddp(native), _ddp(graph)
    assert a.solver.backward.name() == "geosyn_ddp_native"
    assert b.solver.backward.name() == "ddp_backward"
    P = a.parameters
    np.testing.assert_array_equal(P, b.parameters)
    clamped = free = 0
    worst = 0.0
    for torque_scale, seed in itertools.product((0.05, 1.5), range(3)):
        args = (*_trajectory(native, torque_scale, seed), P)
        got = [x.copy() for x in a.solver._backward(*args)]
        want = [x.copy() for x in b.solver._backward(*args)]
        for name, x, y in zip(("k", "K", "dV"), got, want, strict=True):
            scale = float(np.max(np.abs(y)))
            assert scale > 0.0, name
            err = float(np.max(np.abs(x - y))) / scale
            assert err <= 1e-10, (name, torque_scale, seed, err)
            worst = max(worst, err)
        K = want[1].reshape(native.nv, 2 * native.nv, native.N, order="F")
        zero_rows = int(np.sum(np.all(K == 0.0, axis=1)))
        clamped, free = clamped + zero_rows, free + native.nv * native.N - zero_rows
    print(f"native vs graph: worst {worst:.1e} relative; {clamped} clamped, {free} free")
    assert clamped > 0 and free > 0, (clamped, free)


@pytest.mark.slow
def test_native_ddp_converges_to_ipopts_solution() -> None:
    """Referee: IPOPT on the same OCP (the NLP family's transcription, tight tolerance).
    From 0.05 rad off the reference at rest the first torques of a converged native-DDP
    solve equal IPOPT's to 1e-6 relative (the DDP's soft joint limits are inactive)."""
    robot, _, ref = _arm()
    q, v = ref.sample(0.0)[0] + 0.05, np.zeros(robot.nv)
    ddp = _mpc(DDPOptions(tol=1e-10, max_iter=300))
    assert _ddp(ddp).solver.backward.name() == "geosyn_ddp_native"
    ipopt = _mpc(NLPOptions("ipopt", tol=1e-12, max_iter=500), max_solve_time=60.0)
    plans = []
    for mpc in (ddp, ipopt):
        mpc.reset(q, v)
        plans.append(mpc.solve(0.0, q, v))
    plan, ref_plan = plans
    assert plan.success and ref_plan.success, (plan.status, ref_plan.status)
    err = np.linalg.norm(plan.tau[0] - ref_plan.tau[0]) / np.linalg.norm(ref_plan.tau[0])
    assert err <= 1e-6, err


def test_unknown_backward_is_refused() -> None:
    with pytest.raises(InvalidArgument, match="backward"):
        DDPOptions(backward="fast")


def test_cold_solves_regularise_the_regularisation_also_with_obstacles() -> None:
    """With obstacles the clearance's parameters follow the regularisation in ``P``: the
    index the cold solve's Levenberg-Marquardt steps raise holds
    ``DDPOptions.regularisation`` (the obstacle slots' values come after it)."""
    from geosyn.world import Sphere

    robot, metric, ref = _arm()
    ball = Sphere((2.0, 0.0, 0.5), 0.05)
    mpc = GeodesicMPC(
        robot, metric, horizon=3, dt=0.02, control="torque", reference=ref,
        solver=DDPOptions(regularisation=3e-9), obstacles=[ball], clearance_margin=0.03,
        joint_limit_guard=False,
    )  # fmt: skip
    solver = _ddp(mpc).solver
    assert solver.P[solver.reg_index] == 3e-9
    assert solver.reg_index < solver.P.size - 1 and solver.P[-1] != 3e-9


def test_the_c_files_ship_as_package_data() -> None:
    """Every C file of the native backward pass (which the Python solver compiles and
    the export copies) is matched by pyproject's package-data of its package."""
    root = Path(__file__).resolve().parents[1]
    config = tomllib.loads((root / "pyproject.toml").read_text())
    patterns = config["tool"]["setuptools"]["package-data"]["geosyn.controllers.mpc.ddp.native"]
    files = sorted(p.name for p in C_DIR.iterdir() if p.suffix in (".c", ".h"))
    assert {"geosyn_ddp.c", "geosyn_ddp.h", "geosyn_ddp_casadi.c"} <= set(files)
    missing = [f for f in files if not any(fnmatch.fnmatch(f, p) for p in patterns)]
    assert not missing, missing
