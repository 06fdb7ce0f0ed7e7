"""Linear joint couplings (robots/couplings.py) and the pull-back metric
(metrics/coupled.py) against MuJoCo's constrained passive dynamics on the ORIGINAL file."""

from __future__ import annotations

import functools
import warnings
from pathlib import Path

import mujoco
import numpy as np
import pytest

from geosyn.core import GeosynError, InvalidArgument
from geosyn.metrics import CoupledMetric, KineticEnergyMetric, exp
from geosyn.robots import RobotFileError, load_robot
from geosyn.robots.couplings import LinearConstraint, linear_coupling

FIXTURE = Path(__file__).parent / "fixtures" / "coupled.xml"
Z0 = np.array([0.3, -0.4])
ZDOT0 = np.array([1.2, -2.0])


@functools.cache
def _coupled():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        robot = load_robot(FIXTURE, tau_max=10.0)
    return robot, CoupledMetric(KineticEnergyMetric(robot), robot.coupling)


def test_coupling_of_the_fixture_is_the_files() -> None:
    """j3 = 0.1 + 0.5 j2 (joint equality); j4 - 0.8 j3 = L0 = 0 (fixed-tendon equality)."""
    with pytest.warns(UserWarning, match="has joint couplings"):
        load_robot(FIXTURE, tau_max=10.0)
    robot, _ = _coupled()
    c = robot.coupling
    assert c.independent == ("j1", "j2") and len(c.constraints) == 2
    np.testing.assert_allclose(c.S, [[1, 0], [0, 1], [0, 0.5], [0, 0.4]], rtol=0, atol=1e-15)
    np.testing.assert_allclose(c.c, [0, 0, 0.1, 0.08], rtol=0, atol=1e-15)
    q = c.q(Z0)
    assert c.residual(q) == 0.0
    np.testing.assert_array_equal(c.z(q), Z0)


def test_pull_back_metric_and_its_derivatives() -> None:
    """G_z = S^T M S; c_z = S^T c(q, S z_dot) equals the Christoffel contraction of G_z
    (symbolic path) and a finite difference of G_z."""
    robot, metric = _coupled()
    S = robot.coupling.S
    base = metric.base
    rng = np.random.default_rng(4)
    for _ in range(5):
        z, zd = rng.uniform(-1, 1, 2), rng.normal(size=2)
        q = robot.coupling.q(z)
        np.testing.assert_allclose(metric.G(z), S.T @ base.G(q) @ S, rtol=1e-14)
        sym = metric.functions.evaluate("christoffel", z).reshape(2, 2, 2)
        np.testing.assert_allclose(
            metric.coriolis(z, zd), np.einsum("ijk,j,k->i", sym, zd, zd), rtol=1e-10, atol=1e-12
        )
        h = 1e-6
        dG = [(metric.G(z + h * e) - metric.G(z - h * e)) / (2 * h) for e in np.eye(2)]
        np.testing.assert_allclose(np.stack(dG, -1), metric.dG(z), rtol=1e-6, atol=1e-9)


def _mujoco_passive(solref_time: float, timestep: float, q0, qdot0, times):
    """MuJoCo's constrained passive motion of the ORIGINAL file (gravity and damping are
    zero in it), sampled at ``times``."""
    m = mujoco.MjModel.from_xml_path(str(FIXTURE))
    m.opt.timestep = timestep
    m.eq_solref[:, 0] = solref_time
    d = mujoco.MjData(m)
    d.qpos[:], d.qvel[:] = q0, qdot0
    out, k = [], 0
    for t in times:
        while d.time < t - 0.5 * timestep:
            mujoco.mj_step(m, d)
            k += 1
        out.append(d.qpos.copy())
    return np.array(out)


def test_geodesics_of_the_pull_back_metric_follow_mujocos_constrained_motion() -> None:
    """The acceptance: 1e-3 rad over 1 s, and the error shrinks as the constraint gets
    stiffer (MuJoCo's solref time constant 8 ms -> 2 ms -> 0.5 ms)."""
    robot, metric = _coupled()
    geo = exp(metric, Z0, ZDOT0, duration=1.0, steps=400)
    q_geo = np.array([robot.coupling.q(z) for z in geo.q])
    q0, qdot0 = robot.coupling.q(Z0), robot.coupling.velocity(ZDOT0)
    errors = []
    for tc in (8e-3, 2e-3, 5e-4):
        q_mj = _mujoco_passive(tc, 1.25e-4, q0, qdot0, geo.t)  # one time step for all
        errors.append(float(np.abs(q_mj - q_geo).max()))
    print("max |q_mujoco - q_geodesic| [rad] for solref 8, 2, 0.5 ms:", errors)
    assert errors[-1] <= 1e-3, errors
    assert errors[0] > errors[1] > errors[2], errors
    assert errors[0] > 4 * errors[2], errors
    # the motion is not trivial: the uncoupled tree from the same state goes elsewhere
    free = exp(KineticEnergyMetric(robot), q0, qdot0, duration=1.0, steps=400)
    assert np.abs(free.q[-1] - q_geo[-1]).max() > 100 * errors[-1]


def test_rebuilt_twin_keeps_the_couplings() -> None:
    """geosyn's own MJCF export carries the couplings (fixed tendons + tendon equalities):
    its passive motion follows the same geodesic."""
    robot, metric = _coupled()
    m = robot.mj_model(timestep=1.25e-4, integrator="RK4", limits=False)
    assert m.neq == 2 and m.ntendon == 2
    geo = exp(metric, Z0, ZDOT0, duration=1.0, steps=100)
    d = mujoco.MjData(m)
    d.qpos[:], d.qvel[:] = robot.coupling.q(Z0), robot.coupling.velocity(ZDOT0)
    while d.time < 1.0 - 0.5 * m.opt.timestep:
        mujoco.mj_step(m, d)
    err = np.abs(d.qpos - robot.coupling.q(geo.q[-1])).max()
    assert err <= 1e-3, err


def _mjcf(tmp_path, equality: str, tendon: str = "") -> Path:
    text = FIXTURE.read_text().split("<tendon>")[0]
    text = text.replace('<site name="tip"', '<site name="tip2" pos="0 0 0"/><site name="tip"')
    path = tmp_path / "c.xml"
    path.write_text(f"{text}{tendon}<equality>{equality}</equality></mujoco>")
    return path


def test_nonlinear_and_loop_constraints_are_refused_naming_them(tmp_path) -> None:
    quad = '<joint name="quad" joint1="j3" joint2="j2" polycoef="0 0.5 0.1 0 0"/>'
    with pytest.raises(RobotFileError, match=r"'quad' \(joint\) has polycoef .* nonlinear"):
        load_robot(_mjcf(tmp_path, quad), tau_max=1.0)
    weld = '<weld name="w" body1="l4" body2="l2"/>'
    with pytest.raises(RobotFileError, match=r"'w' \(weld\) closes a kinematic loop"):
        load_robot(_mjcf(tmp_path, weld), tau_max=1.0)
    spatial = '<tendon><spatial name="s"><site site="tip"/><site site="tip2"/></spatial></tendon>'
    with pytest.raises(RobotFileError, match="spatial tendon"):
        load_robot(_mjcf(tmp_path, '<tendon name="e" tendon1="s"/>', spatial), tau_max=1.0)


def test_linear_coupling_errors_and_metric_arguments() -> None:
    names = ("a", "b", "c")
    rows = [LinearConstraint("r1", {"c": 1.0, "b": -2.0}, 0.0, "c")]
    coupling = linear_coupling(names, rows)
    np.testing.assert_array_equal(coupling.q([1.0, 2.0]), [1.0, 2.0, 4.0])
    twice = [*rows, LinearConstraint("r2", {"c": 1.0}, 1.0, "c")]
    with pytest.raises(GeosynError, match="'c' dependent a second time"):
        linear_coupling(names, twice)
    with pytest.raises(GeosynError, match="not a robot joint"):
        linear_coupling(names, [LinearConstraint("r", {"x": 1.0}, 0.0, "a")])
    robot, metric = _coupled()
    with pytest.raises(InvalidArgument, match="coupling maps to 3 joints"):
        CoupledMetric(metric.base, coupling)
    with pytest.raises(InvalidArgument, match="coupling must be"):
        CoupledMetric(metric.base, robot.coupling.S)  # type: ignore[arg-type]


def test_urdf_mimic_becomes_a_coupling() -> None:
    with pytest.warns(UserWarning, match=r"panda_finger_joint2 = 1 \* panda_finger_joint1"):
        robot = load_robot("panda_collision")
    assert robot.nv == 9 and robot.coupling.nz == 8
    assert robot.coupling.independent[-1] == "panda_finger_joint1"


def test_computed_torque_tracks_a_pull_back_geodesic_in_the_coupled_file() -> None:
    """Controllers work in z: a geodesic of G_z, lifted to the joints (q = S z + c, ...),
    tracked by computed torque inside the ORIGINAL coupled file (its equality constraints
    active): RMS 8.4e-5 rad measured (the soft constraints set the floor)."""
    from geosyn.controllers import ComputedTorque, JointTrajectoryReference
    from geosyn.sim import Simulation

    robot, metric = _coupled()
    geo = exp(metric, Z0, ZDOT0, duration=1.0, steps=200)
    z_ddot = np.array(
        [metric.geodesic_acceleration(z, v) for z, v in zip(geo.q, geo.v, strict=True)]
    )
    q, v, a = robot.coupling.lift(geo.q, geo.v, z_ddot)
    assert max(robot.coupling.residual(qk) for qk in q) <= 1e-14
    ref = JointTrajectoryReference(geo.t, q, v, a)
    sim = Simulation(robot, ComputedTorque(robot, 400.0, 40.0), plant="file", substeps=4)
    assert sim.model.neq == 2
    result = sim.run(q[0], v[0], 1.0, ref)
    rms = float(np.sqrt(np.mean((result.q - result.q_ref) ** 2)))
    assert result.status == "ok" and rms <= 1e-3, rms
    with pytest.raises(InvalidArgument, match="z_dot must have shape"):
        robot.coupling.lift(geo.q, geo.v[:, :1], z_ddot)


def test_coupled_reference_lifts_a_z_geodesic_for_any_controller() -> None:
    """`CoupledReference`: the geodesic of G_z as a reference in z (exact geodesic
    acceleration of `CoupledMetric`), sampled in q = S z + c; computed torque tracks it
    inside the ORIGINAL coupled file as well as the sampled lift above (RMS <= 1e-3 rad,
    within 20 % of it)."""
    from geosyn.controllers import (
        ComputedTorque,
        CoupledReference,
        GeodesicReference,
        JointTrajectoryReference,
    )
    from geosyn.sim import Simulation

    robot, metric = _coupled()
    c = robot.coupling
    geo = exp(metric, Z0, ZDOT0, duration=1.0, steps=200)
    z_ref = GeodesicReference(geo, metric)
    ref = CoupledReference(z_ref, c)
    assert (ref.n, ref.t0, ref.duration) == (4, 0.0, 1.0)
    for t in (0.0, 0.37, 1.0, 1.5):  # 1.5: after the end, the goal held at rest
        (q, v, a), (z, zd, zdd) = ref.sample(t), z_ref.sample(t)
        np.testing.assert_allclose(q, c.S @ z + c.c, rtol=0, atol=1e-15)
        np.testing.assert_allclose(v, c.S @ zd, rtol=0, atol=1e-15)
        np.testing.assert_allclose(a, c.S @ zdd, rtol=0, atol=1e-15)
        assert c.residual(q) <= 1e-14
    np.testing.assert_allclose(ref.goal(), c.q(geo.q[-1]), rtol=0, atol=1e-15)
    _, _, a_mid = ref.sample(0.37)
    z, zd, _ = z_ref.sample(0.37)
    np.testing.assert_allclose(a_mid, c.S @ metric.geodesic_acceleration(z, zd), rtol=1e-12)

    q, v, a = c.lift(
        geo.q,
        geo.v,
        np.array([metric.geodesic_acceleration(*s) for s in zip(geo.q, geo.v, strict=True)]),
    )
    sampled = JointTrajectoryReference(geo.t, q, v, a)
    np.testing.assert_allclose(ref.sample(0.5).q, sampled.sample(0.5).q, rtol=0, atol=1e-9)
    sim = Simulation(robot, ComputedTorque(robot, 400.0, 40.0), plant="file", substeps=4)
    rms = {}
    for name, r in (("coupled", ref), ("sampled", sampled)):
        result = sim.run(q[0], v[0], 1.0, r)
        assert result.status == "ok", result.status
        rms[name] = float(np.sqrt(np.mean((result.q - result.q_ref) ** 2)))
    print("RMS tracking error [rad], CoupledReference vs sampled lift:", rms)
    assert rms["coupled"] <= 1e-3 and rms["coupled"] <= 1.2 * rms["sampled"], rms
    with pytest.raises(InvalidArgument, match="coupling must be a geosyn.robots.Coupling"):
        CoupledReference(z_ref, c.S)  # type: ignore[arg-type]
    with pytest.raises(InvalidArgument, match=r"dimension n=4, but the coupling has nz=2"):
        CoupledReference(sampled, c)
