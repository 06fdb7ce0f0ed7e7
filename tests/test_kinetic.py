"""The kinetic-energy metric (metrics/kinetic.py): numeric and symbolic paths agree with
Pinocchio, MuJoCo, the 2-link closed form, finite differences and the geometric invariants."""

from __future__ import annotations

import functools
from pathlib import Path

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from conftest import BUILTIN_NAMES, get_metric, get_robot
from geosyn.core import GeosynError, InvalidArgument
from geosyn.metrics import KineticEnergyMetric, Metric
from geosyn.robots import load_robot, symbolic
from geosyn.robots.files import example_robot_data_dir

N_SAMPLES = 200


@functools.cache
def dynamics(name: str):
    robot = get_robot(name)
    return symbolic.dynamics_functions(robot.model, np.asarray(robot.gravity))


def _samples(name: str, count: int, seed: int):
    robot = get_robot(name)
    rng = np.random.default_rng(seed)
    for _ in range(count):
        yield robot.random_q(rng), rng.normal(size=robot.nv), rng.normal(size=robot.nv)


@pytest.mark.parametrize("name", BUILTIN_NAMES)
def test_symbolic_M_equals_pinocchio_and_mujoco(name: str) -> None:
    robot = get_robot(name)
    fns = dynamics(name)
    data = robot.model.createData()
    mm = robot.mj_model(limits=False)
    md = mujoco.MjData(mm)
    M_mj = np.zeros((robot.nv, robot.nv))
    worst_pin = worst_mj = 0.0
    for q, _, _ in _samples(name, N_SAMPLES, seed=1):
        M_sym = np.asarray(fns.M(q))
        M_pin = pin.crba(robot.model, data, q)
        md.qpos[:] = q
        mujoco.mj_forward(mm, md)
        mujoco.mj_fullM(mm, md, M_mj)
        scale = np.abs(M_pin).max()
        worst_pin = max(worst_pin, np.abs(M_sym - M_pin).max() / scale)
        worst_mj = max(worst_mj, np.abs(M_sym - M_mj).max() / scale)
    assert worst_pin <= 1e-9, f"{name}: symbolic vs pin.crba {worst_pin:.1e} x max|M|"
    assert worst_mj <= 1e-9, f"{name}: symbolic vs mj_fullM {worst_mj:.1e} x max|M|"


@pytest.mark.parametrize("name", BUILTIN_NAMES)
def test_symbolic_rnea_equals_pinocchio_and_bias_equals_mujoco(name: str) -> None:
    robot = get_robot(name)
    fns = dynamics(name)
    data = robot.model.createData()
    mm = robot.mj_model(limits=False)
    md = mujoco.MjData(mm)
    worst_rnea = worst_bias = 0.0
    for q, v, a in _samples(name, N_SAMPLES, seed=2):
        tau_sym = np.asarray(fns.rnea(q, v, a)).ravel()
        tau_pin = pin.rnea(robot.model, data, q, v, a)
        worst_rnea = max(worst_rnea, np.abs(tau_sym - tau_pin).max())
        md.qpos[:], md.qvel[:] = q, v
        mujoco.mj_forward(mm, md)
        h_sym = np.asarray(fns.bias(q, v)).ravel()
        worst_bias = max(worst_bias, np.abs(h_sym - md.qfrc_bias).max())
    assert worst_rnea <= 1e-9, f"{name}: symbolic RNEA vs pin.rnea {worst_rnea:.1e} N m"
    assert worst_bias <= 1e-8, f"{name}: symbolic bias vs MuJoCo qfrc_bias {worst_bias:.1e} N m"


def _planar2_constants(robot):
    (m1, m2) = (robot.model.inertias[1].mass, robot.model.inertias[2].mass)
    l1 = robot.model.jointPlacements[2].translation[0]
    lc1 = robot.model.inertias[1].lever[0]
    lc2 = robot.model.inertias[2].lever[0]
    I1 = robot.model.inertias[1].inertia[2, 2]
    I2 = robot.model.inertias[2].inertia[2, 2]
    h = m2 * l1 * lc2
    a = I1 + m1 * lc1**2 + m2 * l1**2
    b = I2 + m2 * lc2**2
    return a, b, h


def test_planar2_closed_form_metric_and_christoffel() -> None:
    robot = get_robot("planar2")
    metric = get_metric("planar2")
    a, b, h = _planar2_constants(robot)
    # Uniform rods of 1 kg, 1 m: a = 1/12 + 1/4 + 1, b = 1/12 + 1/4, h = 1/2.
    assert (a, b, h) == pytest.approx((4.0 / 3.0, 1.0 / 3.0, 0.5), abs=1e-15)
    rng = np.random.default_rng(7)
    for _ in range(50):
        q = rng.uniform(-np.pi, np.pi, size=2)
        c2, s2 = np.cos(q[1]), np.sin(q[1])
        M_closed = np.array([[a + b + 2 * h * c2, b + h * c2], [b + h * c2, b]])
        np.testing.assert_allclose(metric.G(q), M_closed, rtol=0, atol=1e-12)
        np.testing.assert_allclose(metric.functions.evaluate("G", q), M_closed, rtol=0, atol=1e-12)
        gamma_closed = np.zeros((2, 2, 2))
        gamma_closed[0, 0, 1] = gamma_closed[0, 1, 0] = gamma_closed[0, 1, 1] = -h * s2
        gamma_closed[1, 0, 0] = h * s2
        np.testing.assert_allclose(metric.christoffel(q), gamma_closed, rtol=0, atol=1e-12)


@pytest.mark.parametrize("name", ["planar3", "panda", "ur5"])
def test_christoffel_symmetry_and_skew_symmetry(name: str) -> None:
    metric = get_metric(name)
    for q, v, _ in _samples(name, 20, seed=3):
        gamma = metric.christoffel(q)
        np.testing.assert_allclose(gamma, gamma.transpose(0, 2, 1), rtol=0, atol=1e-12)
        dG = metric.dG(q)
        M_dot = dG @ v  # sum_k dM_ij/dq_k v_k
        C = gamma @ v  # C_ij = sum_k Gamma_ijk v_k
        N = M_dot - 2.0 * C
        scale = max(np.abs(M_dot).max(), 1.0)
        np.testing.assert_allclose(N, -N.T, rtol=0, atol=1e-12 * scale)
        # C(q, v) v from the tensor equals the Coriolis term from RNEA.
        np.testing.assert_allclose(C @ v, metric.coriolis(q, v), rtol=0, atol=1e-10 * scale)


@pytest.mark.parametrize("name", ["planar2", "panda", "talos_arm"])
def test_dG_matches_central_finite_differences(name: str) -> None:
    metric = get_metric(name)
    eps = 1e-6
    for q, _, _ in _samples(name, 10, seed=4):
        dG = metric.dG(q)
        fd = np.empty_like(dG)
        for k in range(metric.n):
            dq = np.zeros(metric.n)
            dq[k] = eps
            fd[:, :, k] = (metric.G(q + dq) - metric.G(q - dq)) / (2 * eps)
        assert np.abs(dG - fd).max() <= 1e-6, f"{name}: dG vs FD {np.abs(dG - fd).max():.1e}"


@pytest.mark.parametrize("name", BUILTIN_NAMES)
def test_geodesic_acceleration_three_ways(name: str) -> None:
    robot = get_robot(name)
    metric = get_metric(name)
    model0 = pin.Model(robot.model)
    model0.gravity = pin.Motion.Zero()
    data0 = model0.createData()
    f_sym = metric.functions.geodesic_acceleration
    for q, v, _ in _samples(name, 50, seed=5):
        a = metric.geodesic_acceleration(q, v)
        a_solve = -np.linalg.solve(metric.G(q), metric.coriolis(q, v))
        a_pin = pin.aba(model0, data0, q, v, np.zeros(robot.nv))
        a_sym = np.asarray(f_sym(q, v)).ravel()
        scale = max(np.abs(a_pin).max(), 1.0)
        for other, label in ((a_solve, "-M^-1 C v"), (a_pin, "pin.aba"), (a_sym, "symbolic ABA")):
            err = np.abs(a - other).max() / scale
            assert err <= 1e-9, f"{name}: geodesic acceleration vs {label}: {err:.1e}"


def test_metric_is_spd_and_inner_product_consistent() -> None:
    metric = get_metric("panda")
    for q, u, v in _samples("panda", 20, seed=6):
        G = metric.G(q)
        np.testing.assert_allclose(G, G.T, rtol=0, atol=0)
        assert np.linalg.eigvalsh(G).min() > 0
        assert metric.inner(q, u, v) == pytest.approx(u @ G @ v, rel=1e-14)
        assert metric.norm(q, v) ** 2 == pytest.approx(v @ G @ v, rel=1e-13)
        assert metric.energy(q, v) == pytest.approx(0.5 * v @ G @ v, rel=1e-13)


def test_compiled_functions_equal_virtual_machine(tmp_path, monkeypatch) -> None:
    monkeypatch.setenv("GEOSYN_CACHE_DIR", str(tmp_path))
    robot = get_robot("planar3")
    compiled = KineticEnergyMetric(robot, compile=True)
    plain = get_metric("planar3")
    for q, v, _ in _samples("planar3", 10, seed=8):
        np.testing.assert_allclose(compiled.christoffel(q), plain.christoffel(q), atol=1e-13)
        np.testing.assert_allclose(
            np.asarray(compiled.functions.geodesic_acceleration(q, v)).ravel(),
            plain.geodesic_acceleration(q, v),
            atol=1e-12,
        )
    assert any(tmp_path.rglob("*.so")), "compiled code is cached on disk"


def test_bad_q_raises_clear_errors() -> None:
    metric = get_metric("panda")
    with pytest.raises(InvalidArgument, match=r"q must have shape \(7,\), got shape \(3,\)"):
        metric.G(np.zeros(3))
    with pytest.raises(InvalidArgument, match="q must be finite"):
        metric.G(np.array([0.0, np.nan, 0, 0, 0, 0, 0]))
    with pytest.raises(InvalidArgument, match="v must have shape"):
        metric.geodesic_acceleration(np.zeros(7), np.zeros(2))
    with pytest.raises(InvalidArgument, match="q must be finite"):
        metric.christoffel(np.full(7, np.inf))
    with pytest.raises(GeosynError, match="Robot"):
        KineticEnergyMetric("panda")  # type: ignore[arg-type]


@pytest.mark.parametrize("name", BUILTIN_NAMES)
@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_non_finite_entry_in_any_coordinate_is_rejected(name: str, bad: float) -> None:
    """G's fast path checks trace(M) + sum(q); a bad value in any coordinate must raise."""
    metric = get_metric(name)
    q0 = get_robot(name).neutral()
    for k in range(metric.n):
        q = q0.copy()
        q[k] = bad
        with pytest.raises(InvalidArgument, match="q must be finite"):
            metric.G(q)
        with pytest.raises(InvalidArgument, match="finite"):
            metric.geodesic_acceleration(q, np.zeros(metric.n))


def test_non_array_inputs_take_the_validating_path() -> None:
    metric = get_metric("planar2")
    np.testing.assert_allclose(metric.G([0.1, 0.2]), metric.G(np.array([0.1, 0.2])), atol=0)
    with pytest.raises(InvalidArgument, match=r"shape \(2,\)"):
        metric.G(np.zeros((2, 2)))


FIXTURES = Path(__file__).parent / "fixtures"


@functools.cache
def _tree_metric(name: str) -> KineticEnergyMetric:
    """Metrics of trees with several root joints: a two-finger hand, the TALOS upper body."""
    if name == "two_fingers":
        return KineticEnergyMetric(load_robot(FIXTURES / "two_fingers.xml", tau_max=1.0))
    arms = [f"arm_{s}_{i}_joint" for s in ("left", "right") for i in range(1, 5)]
    return KineticEnergyMetric(
        load_robot(
            example_robot_data_dir() / "talos_data/robots/talos_reduced.urdf",
            keep_joints=[*arms, "head_1_joint"],  # torso locked: arms and head are roots
        )
    )


@pytest.mark.parametrize("name", ["two_fingers", "talos_upper"])
def test_G_fast_path_costs_one_crba_on_trees_with_several_roots(name: str, monkeypatch) -> None:
    """Several root joints: G calls pin.crba once (no validating second call), and a NaN or
    inf in any coordinate is still rejected."""
    metric = _tree_metric(name)
    model = metric.robot.model
    assert sum(model.parents[j] == 0 for j in range(1, model.njoints)) >= 2
    calls = []
    crba = pin.crba

    def counting(*args):
        calls.append(1)
        return crba(*args)

    monkeypatch.setattr(pin, "crba", counting)
    rng = np.random.default_rng(3)
    for _ in range(5):
        q = metric.robot.random_q(rng)
        np.testing.assert_allclose(metric.G(q), crba(model, model.createData(), q), atol=0)
    assert len(calls) == 5, f"{len(calls)} pin.crba calls for 5 G(q) calls"
    for bad in (np.nan, np.inf, -np.inf):
        for k in range(metric.n):
            q = metric.robot.neutral()
            q[k] = bad
            with pytest.raises(InvalidArgument, match="q must be finite"):
                metric.G(q)


@pytest.mark.parametrize("name", ["panda", "talos_arm", "ur5"])
def test_batched_metric_equals_pinocchio_and_finite_differences(name: str) -> None:
    """`G_many` row by row equals pin.crba; `quadratic_gradients` equals central finite
    differences (step 1e-6 rad) of d^T M(q) d on pin.crba, both for the kinetic metric's
    fast path and for the base class's generic loop (on the symbolic dG)."""
    robot, metric = get_robot(name), get_metric(name)
    data = robot.model.createData()
    rng = np.random.default_rng(11)
    Q = np.array([robot.random_q(rng) for _ in range(12)])
    D = rng.normal(size=Q.shape)
    M = metric.G_many(Q)
    assert M.shape == (12, robot.nv, robot.nv)
    for k, q in enumerate(Q):
        ref = pin.crba(robot.model, data, q)
        assert np.abs(M[k] - ref).max() <= 1e-14 * np.abs(ref).max()
    eps = 1e-6
    fd = np.empty_like(D)
    for k, (q, d) in enumerate(zip(Q, D, strict=True)):
        for i in range(robot.nv):
            e = np.zeros(robot.nv)
            e[i] = eps
            hi, lo = pin.crba(robot.model, data, q + e), pin.crba(robot.model, data, q - e)
            fd[k, i] = (d @ hi @ d - d @ lo @ d) / (2 * eps)
    scale = np.abs(fd).max()
    for label, g in (("fast", metric.quadratic_gradients(Q, D)),
                     ("generic", Metric.quadratic_gradients(metric, Q, D))):  # fmt: skip
        err = np.abs(g - fd).max() / scale
        assert err <= 1e-7, f"{name} {label}: quadratic_gradients vs finite differences {err:.1e}"
    assert metric.G_many(np.zeros((0, robot.nv))).shape == (0, robot.nv, robot.nv)


def test_batched_metric_refuses_bad_rows_naming_them() -> None:
    metric = get_metric("panda")
    Q = np.zeros((3, 7))
    with pytest.raises(InvalidArgument, match=r"Q must have shape \(K, 7\), got shape \(3, 6\)"):
        metric.G_many(np.zeros((3, 6)))
    with pytest.raises(InvalidArgument, match=r"D must have as many rows as Q \(3\)"):
        metric.quadratic_gradients(Q, np.zeros((2, 7)))
    bad = Q.copy()
    bad[1, 4] = np.nan
    with pytest.raises(InvalidArgument, match="D must be finite"):
        metric.quadratic_gradients(Q, bad)
    with pytest.raises(InvalidArgument, match="Q is too large"):
        metric.G_many(np.full((2, 7), 1e200))
    with pytest.raises(InvalidArgument, match="Q must be a real float array"):
        metric.G_many(np.zeros((2, 7), dtype=bool))
    np.testing.assert_array_equal(metric.G_many(Q.tolist()), metric.G_many(Q))
