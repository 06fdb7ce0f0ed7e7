"""Simulation: dynamics parity with the Pinocchio plant, the per-tick log, divergence."""

from __future__ import annotations

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from conftest import get_robot
from geosyn.controllers import ControllerError, JointTrajectoryReference
from geosyn.controllers.computed_torque import ComputedTorque
from geosyn.controllers.plant import PinocchioPlant
from geosyn.core.errors import InvalidArgument
from geosyn.sim import SimResult, Simulation
from geosyn.sim.scene import build_scene
from geosyn.world import Payload


# -- stand-in controllers ---------------------------------------------------------------
class GravityPD:
    """tau = g(q) + Kp (q_hold - q) - Kd v, holding the initial configuration."""

    def __init__(self, robot, kp=50.0, kd=10.0):
        self.robot, self.kp, self.kd = robot, kp, kd
        self.data = robot.model.createData()
        self.q_hold = None
        self.calls = 0

    def reset(self, q, v, t=0.0):
        self.q_hold = np.array(q)
        self.calls = 0

    def compute(self, t, q, v):
        self.calls += 1
        g = pin.computeGeneralizedGravity(self.robot.model, self.data, q)
        return g + self.kp * (self.q_hold - q) - self.kd * v


class Scripted:
    """Returns a scripted torque ``f(t)``; optional diagnostics."""

    def __init__(self, f, statuses=None):
        self.f = f
        self.statuses = statuses
        self.diagnostics = None

    def reset(self, q, v, t=0.0):
        pass

    def compute(self, t, q, v):
        if self.statuses is not None:
            k = int(round(t / 1e-3))
            self.diagnostics = type(
                "D",
                (),
                {
                    "solver_status": self.statuses(k),
                    "iterations": k % 5,
                    "fallback_used": k % 3 == 0,
                },
            )()
        return self.f(t)


def panda_setup():
    robot = get_robot("panda")
    q0 = robot.neutral()
    q0[3], q0[5] = -1.5, 1.5
    t = np.linspace(0.0, 1.0, 11)
    sign = np.array([1.0, -1.0, 1.0, 1.0, -1.0, 1.0, 1.0])
    ref = JointTrajectoryReference(t, q0 + 0.3 * np.sin(np.pi * t)[:, None] * sign)
    return robot, q0, ref


# -- dynamics parity --------------------------------------------------------------------
def test_parity_with_pinocchio_plant_rk4():
    """Same controller and reference on MuJoCo (RK4) and on the Pinocchio plant (RK4)."""
    robot, q0, ref = panda_setup()
    ctl = ComputedTorque(robot, 400.0, 40.0, reference=ref)
    plant = PinocchioPlant(robot, dt=1e-3)
    plant.reset(q0, np.zeros(7))
    ctl.reset(q0, np.zeros(7))
    rollout = plant.rollout(ctl, 1.0)
    res = Simulation(robot, ctl, integrator="RK4").run(q0, None, 1.0, ref)
    assert res.ok and res.n_ticks == 1000
    q_mj = np.vstack([res.q, res.q_final])
    assert np.max(np.abs(q_mj - rollout.q)) < 1e-4
    # The motion is not trivial: it moves 0.3 rad.
    assert np.max(np.abs(rollout.q - q0)) > 0.25


def test_implicitfast_is_first_order_close_to_pinocchio_plant():
    """implicitfast differs from RK4 by O(dt); substeps shrink the gap about linearly."""
    robot, q0, ref = panda_setup()
    ctl = ComputedTorque(robot, 100.0, 20.0, reference=ref)
    plant = PinocchioPlant(robot, dt=1e-3)
    plant.reset(q0, np.zeros(7))
    ctl.reset(q0, np.zeros(7))
    q_pin = plant.rollout(ctl, 0.5).q
    errs = []
    for substeps in (1, 4):
        res = Simulation(robot, ctl, substeps=substeps).run(q0, None, 0.5, ref)
        errs.append(np.max(np.abs(np.vstack([res.q, res.q_final]) - q_pin)))
    assert errs[0] < 2e-3
    assert errs[1] < errs[0] / 2.5


def test_step1_step2_split_matches_plain_mj_step():
    """The tick loop (mj_step1, controller, mj_step2) equals a plain mj_step loop."""
    robot, q0, ref = panda_setup()
    ctl = ComputedTorque(robot, 100.0, 20.0, reference=ref)
    res = Simulation(robot, ctl, substeps=2).run(q0, None, 0.2, ref)
    scene = build_scene(robot, timestep=0.5e-3)
    m, d = scene.model, mujoco.MjData(scene.model)
    d.qpos[:], d.qvel[:] = q0, 0.0
    ctl.reset(q0, np.zeros(7))
    for k in range(200):
        assert np.array_equal(d.qpos, res.q[k])
        d.ctrl[:] = ctl.compute(k * 1e-3, d.qpos.copy(), d.qvel.copy())
        mujoco.mj_step(m, d)
        mujoco.mj_step(m, d)
    assert np.allclose(d.qpos, res.q_final, rtol=0, atol=1e-12)


# -- the log ----------------------------------------------------------------------------
def test_log_quantities_against_pinocchio():
    robot, q0, ref = panda_setup()
    ctl = ComputedTorque(robot, 100.0, 20.0, reference=ref)
    res = Simulation(robot, ctl, control_dt=2e-3, substeps=2).run(q0, None, 0.4, ref)
    assert res.ok and res.n_ticks == 200
    assert np.allclose(res.t, 2e-3 * np.arange(200), atol=1e-15)
    data = robot.model.createData()
    for k in range(0, 200, 37):
        q, v = res.q[k], res.v[k]
        M = pin.crba(robot.model, data, q)
        assert res.kinetic_energy[k] == pytest.approx(0.5 * v @ M @ v, rel=1e-9, abs=1e-12)
        assert np.allclose(res.q_ref[k], ref.sample(res.t[k]).q, atol=1e-14)
    assert np.allclose(res.power, np.sum(res.tau_applied * res.v, axis=1))
    assert np.allclose(res.effort, np.cumsum(np.sum(res.tau_applied**2, axis=1)) * 2e-3)
    assert np.allclose(res.tracking_error, res.q_ref - res.q)
    assert np.array_equal(res.q_meas, res.q) and np.array_equal(res.tau, res.tau_applied)
    assert np.all(np.isinf(res.clearance)) and res.payload_mass.shape == (200, 0)
    assert np.all(res.compute_time > 0)
    assert res.kinetic_energy.max() > 0.05


def test_energy_balance_rk4():
    """Work of the motors = change of kinetic + potential energy (no friction, no damping)."""
    robot, q0, ref = panda_setup()
    ctl = ComputedTorque(robot, 100.0, 20.0, reference=ref)
    res = Simulation(robot, ctl, integrator="RK4").run(q0, None, 0.5, ref)
    data = robot.model.createData()

    def potential(q):
        return pin.computePotentialEnergy(robot.model, data, q)

    t_end = len(res.t) - 1
    work = np.sum(res.power[:t_end]) * 1e-3  # left rectangle, O(dt)
    change = (
        res.kinetic_energy[t_end]
        + potential(res.q[t_end])
        - res.kinetic_energy[0]
        - potential(res.q[0])
    )
    assert work == pytest.approx(change, rel=0.02)


def test_saturation_is_clipped_and_flagged():
    robot = get_robot("panda")
    q0 = robot.neutral()
    g = GravityPD(robot)

    def f(t):
        tau = pin.computeGeneralizedGravity(robot.model, g.data, q0).copy()
        tau[0] = 2.0 * robot.tau_max[0]
        return tau

    res = Simulation(robot, Scripted(f)).run(q0, None, 0.01)
    assert np.all(res.saturated[:, 0]) and not np.any(res.saturated[:, 1:])
    assert np.allclose(res.tau[:, 0], robot.tau_max[0])
    assert np.allclose(res.tau_applied[:, 0], robot.tau_max[0])
    assert res.saturation_count() == res.n_ticks


def test_solver_diagnostics_logged_as_codes():
    robot = get_robot("planar2")
    q0 = np.array([0.3, 0.2])
    ctl = Scripted(lambda t: np.zeros(2), statuses=lambda k: "ok" if k % 4 else "max_iter")
    res = Simulation(robot, ctl).run(q0, None, 0.02)
    names = [res.solver_status_names[c] for c in res.solver_status]
    assert names == ["max_iter" if k % 4 == 0 else "ok" for k in range(20)]
    assert np.array_equal(res.iterations, np.arange(20) % 5)
    assert np.array_equal(res.fallback_used, np.arange(20) % 3 == 0)


def test_save_load_roundtrip(tmp_path):
    robot, q0, ref = panda_setup()
    ctl = ComputedTorque(robot, 100.0, 20.0, reference=ref)
    res = Simulation(robot, ctl, payloads=[Payload("panda_hand_tcp", 1.0)]).run(q0, None, 0.05, ref)
    path = res.save(tmp_path / "run")
    back = SimResult.load(path)
    assert path.suffix == ".npz"
    for name in ("t", "q", "tau", "saturated", "solver_status", "payload_mass", "q_final"):
        a, b = getattr(res, name), getattr(back, name)
        assert a.dtype == b.dtype and np.array_equal(a, b)
    assert (back.status, back.joint_names, back.control_dt) == (
        res.status,
        res.joint_names,
        res.control_dt,
    )
    with pytest.raises(InvalidArgument, match="not a file"):
        SimResult.load(tmp_path / "missing.npz")


def test_runs_are_repeatable_and_controller_called_once_per_tick():
    robot = get_robot("panda")
    q0 = robot.neutral()
    ctl = GravityPD(robot)
    sim = Simulation(robot, ctl, control_dt=4e-3, substeps=4)
    assert sim.model.opt.timestep == pytest.approx(1e-3)
    a = sim.run(q0, np.full(7, 0.2), 0.2)
    assert ctl.calls == 50 and a.n_ticks == 50
    b = sim.run(q0, np.full(7, 0.2), 0.2)
    assert np.array_equal(a.q, b.q)


# -- divergence and failures ------------------------------------------------------------
def test_divergence_on_speed_keeps_results():
    robot = get_robot("panda")
    q0 = robot.neutral()
    huge = np.full(7, 1e4)
    sim = Simulation(robot, Scripted(lambda t: huge), torque_limits=False, position_limits=False)
    res = sim.run(q0, None, 1.0)
    assert res.diverged and "exceeds 3x its limit" in res.status
    assert 0 < res.n_ticks < 1000
    assert np.all(np.isfinite(res.q)) and np.all(np.isfinite(res.tau))
    assert np.all(np.abs(res.v) <= 3 * robot.v_max + 1e-12)  # the rows kept are before the stop
    assert np.any(np.abs(res.v_final) > 3 * robot.v_max)
    assert np.array_equal(res.tau_applied, np.tile(huge, (res.n_ticks, 1)))  # limits disabled
    assert not np.any(res.saturated)


def test_divergence_on_nan_torque():
    robot = get_robot("planar2")

    def f(t):
        return np.array([np.nan, 0.0]) if t >= 0.1 - 1e-12 else np.zeros(2)

    res = Simulation(robot, Scripted(f)).run(np.zeros(2), None, 1.0)
    assert res.diverged and "non-finite torque" in res.status and "t=0.1" in res.status
    assert res.n_ticks == 100 and np.all(np.isfinite(res.tau))


def test_controller_error_stops_with_status():
    robot = get_robot("planar2")

    def f(t):
        if t > 0.05:
            raise ControllerError("solver exploded")
        return np.zeros(2)

    res = Simulation(robot, Scripted(f)).run(np.zeros(2), None, 1.0)
    assert res.status.startswith("controller failed: ControllerError: solver exploded")
    assert res.n_ticks == 51


# -- bad input --------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"control_dt": -1e-3}, "control_dt"),
        ({"control_dt": "fast"}, "control_dt"),
        ({"substeps": 0}, "substeps"),
        ({"integrator": "leapfrog"}, "integrator"),
        ({"seed": -1}, "seed"),
        ({"disturbances": ["push"]}, r"disturbances\[0\]"),
        ({"payloads": [("panda_hand", 1.0)]}, r"payloads\[0\]"),
        ({"gravity": (0, 0)}, "gravity"),
    ],
)
def test_bad_constructor_arguments(kwargs, match):
    robot = get_robot("panda")
    with pytest.raises(InvalidArgument, match=match):
        Simulation(robot, GravityPD(robot), **kwargs)


def test_bad_run_arguments():
    robot = get_robot("panda")
    sim = Simulation(robot, GravityPD(robot))
    with pytest.raises(InvalidArgument, match="q0"):
        sim.run(np.zeros(6), None, 0.1)
    with pytest.raises(InvalidArgument, match="v0"):
        sim.run(np.zeros(7), [np.nan] * 7, 0.1)
    with pytest.raises(InvalidArgument, match="duration"):
        sim.run(np.zeros(7), None, 0.0)
    with pytest.raises(InvalidArgument, match="controller"):
        Simulation(robot, object())

    def raises(t):
        raise InvalidArgument("q must be finite")

    with pytest.raises(InvalidArgument, match="q must be finite"):
        Simulation(robot, Scripted(raises)).run(np.zeros(7), None, 0.01)
    bad = Simulation(robot, Scripted(lambda t: np.zeros(3)))
    with pytest.raises(InvalidArgument, match=r"returned shape \(3,\), expected \(7,\)"):
        bad.run(np.zeros(7), None, 0.01)


def test_public_names_resolve():
    import geosyn.sim as sim_pkg

    for name in sim_pkg.__all__:
        assert getattr(sim_pkg, name) is not None
    assert len(set(sim_pkg.__all__)) == len(sim_pkg.__all__)


def test_contact_option_stops_the_robot_at_an_obstacle():
    """With contact=True the hand is stopped by a box it is pushed into; without, it enters.
    What collides is the file's collision meshes (measured exactly, coal), not the capsules."""
    from geosyn.sim import Wrench
    from geosyn.world import Box

    robot = get_robot("panda")
    q0 = robot.neutral()
    q0[3], q0[5] = -1.5, 1.5
    data = robot.model.createData()
    pin.framesForwardKinematics(robot.model, data, q0)
    hand = data.oMf[robot.frame_id("panda_hand")].translation
    # a small slab 3 cm below the robot's lowest mesh point above it, pushed onto with 80 N
    half = (0.12, 0.12, 0.05)
    probe = Simulation(robot, GravityPD(robot), obstacles=[Box(hand - [0, 0, 0.3], half)])
    gap = probe.run(q0, None, 1e-3).mesh_clearance  # the fingers nearest, not the base
    wall = Box(hand - [0, 0, 0.3 - gap + 0.03], half)
    push = Wrench("panda_hand", force=(0, 0, -80.0))
    runs = {
        c: Simulation(
            robot,
            GravityPD(robot, kp=5.0, kd=5.0),
            obstacles=[wall],
            disturbances=[push],
            contact=c,
        )
        for c in (False, True)
    }
    start = runs[False].run(q0, None, 1e-3).mesh_clearance
    assert start == pytest.approx(0.03, abs=1e-6)
    res = {c: sim.run(q0, None, 0.5) for c, sim in runs.items()}
    assert res[False].mesh_clearance < -0.05
    # MuJoCo's soft contact (default solref) lets the 80 N push sink the hull ~1 cm
    assert res[True].mesh_clearance > -0.015
    assert res[True].contact_force.max() > 80.0 > res[False].contact_force.max()
