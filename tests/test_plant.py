"""Tests of geosyn.controllers.plant: RK4 accuracy, energy, the unmodelled payload."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from conftest import get_robot
from geosyn.controllers.plant import PinocchioPlant
from geosyn.core import InvalidArgument
from geosyn.robots import RobotWarning, UnknownFrame, load_robot
from geosyn.world import Payload

Q0 = np.array([0.0, -0.3, 0.0, -2.0, 0.0, 1.8, 0.8])
V0 = 0.5 * np.array([1.0, 1.0, -1.0, 1.0, 1.0, -1.0, 1.0])


def _energy(model, q, v):
    data = model.createData()
    kin = 0.5 * v @ pin.crba(model, data, q) @ v
    return kin + pin.computePotentialEnergy(model, data, q)


def test_unactuated_plant_conserves_energy():
    """Zero torque: kinetic plus potential energy is conserved to RK4 accuracy."""
    robot = get_robot("panda")
    plant = PinocchioPlant(robot, dt=1e-3)
    plant.reset(Q0, V0)
    e0 = _energy(plant.model, Q0, V0)
    zero = np.zeros(7)
    for _ in range(500):
        plant.step(zero)
    assert plant.t == pytest.approx(0.5)
    e1 = _energy(plant.model, plant.q, plant.v)
    assert abs(e1 - e0) < 1e-7 * max(1.0, abs(e0))
    # And the robot did move (falling under gravity).
    assert np.linalg.norm(plant.q - Q0) > 0.1


def test_rk4_is_fourth_order():
    """Halving the step shrinks the error ~16x (against a step 16x smaller)."""
    robot = get_robot("panda")
    tau = 0.3 * np.array(robot.tau_max) * np.sin(np.arange(7))

    def final(dt):
        plant = PinocchioPlant(robot, dt=dt)
        plant.reset(Q0, V0)
        for _ in range(int(round(0.2 / dt))):
            plant.step(tau)
        return plant.q

    ref = final(0.004 / 16)
    e1 = np.abs(final(0.004) - ref).max()
    e2 = np.abs(final(0.002) - ref).max()
    assert e1 / e2 > 12.0, (e1, e2)


def test_payload_changes_dynamics_by_a_point_mass():
    """A point payload adds m Jv^T Jv to M and m g Jv_z to the gravity torque."""
    robot = get_robot("panda")
    mass = 1.3
    com = np.array([0.01, -0.02, 0.05])
    plant = PinocchioPlant(robot, payload=Payload(robot.ee_frame, mass, tuple(com), radius=0.0))
    assert isinstance(plant.payload, Payload)
    # The robot's own model is untouched.
    assert robot.total_mass == pytest.approx(
        sum(robot.model.inertias[j].mass for j in range(1, robot.model.njoints))
    )
    rng = np.random.default_rng(3)
    base = robot.model
    dbase = base.createData()
    dpl = plant.model.createData()
    fid = robot.frame_id(robot.ee_frame)
    for _ in range(3):
        q = robot.random_q(rng)
        # Jacobian of the payload point (frame origin + com in the frame) in world axes.
        pin.computeJointJacobians(base, dbase, q)
        pin.updateFramePlacements(base, dbase)
        J = pin.getFrameJacobian(base, dbase, fid, pin.LOCAL_WORLD_ALIGNED)
        R = dbase.oMf[fid].rotation
        r = R @ com
        Jv = J[:3] - pin.skew(r) @ J[3:]
        M_extra = pin.crba(plant.model, dpl, q) - pin.crba(base, dbase, q)
        np.testing.assert_allclose(M_extra, mass * Jv.T @ Jv, atol=1e-10)
        g_extra = pin.computeGeneralizedGravity(
            plant.model, dpl, q
        ) - pin.computeGeneralizedGravity(base, dbase, q)
        np.testing.assert_allclose(g_extra, -mass * Jv.T @ np.array(robot.gravity), atol=1e-10)


def test_rollout_records_closed_loop():
    robot = get_robot("planar2")

    class Zero:
        def compute(self, t, q, v):
            return np.zeros(2)

    plant = PinocchioPlant(robot, dt=2e-3)
    plant.reset(np.array([0.3, -0.2]), np.zeros(2))
    calls = []
    ro = plant.rollout(Zero(), 0.1, callback=lambda t, q, v, tau: calls.append(t))
    assert ro.q.shape == (51, 2) and ro.tau.shape == (50, 2) and len(calls) == 50
    np.testing.assert_allclose(ro.t[-1], 0.1)
    np.testing.assert_allclose(ro.q[-1], plant.q)


@pytest.mark.parametrize(
    "kwargs, error, match",
    [
        ({"dt": 0.0}, InvalidArgument, "dt"),
        ({"dt": np.nan}, InvalidArgument, "dt"),
        ({"payload": ("panda_hand_tcp", -1.0)}, InvalidArgument, "mass"),
        ({"payload": ("panda_hand_tcp", 1.0, (0.0, 0.0))}, InvalidArgument, "com"),
        ({"payload": ("panda_hand_tcp", 1.0, (0, 0, 0), np.eye(2))}, InvalidArgument, "inertia"),
        ({"payload": ("nope", 1.0)}, UnknownFrame, "nope"),
        ({"payload": ()}, InvalidArgument, "payload"),
    ],
)
def test_plant_rejects_bad_input(kwargs, error, match):
    with pytest.raises(error, match=match):
        PinocchioPlant(get_robot("panda"), **kwargs)


def test_step_rejects_bad_torque():
    plant = PinocchioPlant(get_robot("panda"))
    with pytest.raises(InvalidArgument, match="tau"):
        plant.step(np.zeros(6))


def test_controllers_package_resolves_exports_without_mujoco():
    """Every __all__ name resolves, and importing the layer does not import mujoco."""
    import subprocess
    import sys

    code = (
        "import sys, geosyn.controllers as c\n"
        "missing = [n for n in c.__all__ if not hasattr(c, n)]\n"
        "print(missing, 'mujoco' in sys.modules)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[] False"


FIXTURE = Path(__file__).parent / "fixtures" / "arm_root_quat.xml"


def _file_without_dry_friction(tmp_path: Path) -> Path:
    """The fixture arm (armature 0.05-0.3, damping 0.4 and 1.5, gravity) with its dry
    friction and joint ranges removed, so that MuJoCo's RK4 integrates the same ODE."""
    text = FIXTURE.read_text().replace('frictionloss="0.1"', 'frictionloss="0"')
    text = text.replace('integrator="implicitfast"', 'integrator="RK4"')
    text = re.sub(r' range="[^"]*"', "", text)
    path = tmp_path / "arm_damped.xml"
    path.write_text(text)
    return path


def test_damping_and_armature_match_mujocos_own_simulation_of_the_file(tmp_path):
    """Referee: MuJoCo compiles the original file and integrates it (RK4, 1 ms, its
    actuators disabled) from the same state: the plant agrees to 1e-9 rad over 0.5 s; the same plant
    with the damping zeroed is off by > 1e-3 rad (the damping is what makes them agree)."""
    import mujoco

    path = _file_without_dry_friction(tmp_path)
    robot = load_robot(str(path))
    assert np.any(robot.damping) and np.any(robot.armature)
    m = mujoco.MjModel.from_xml_path(str(path))
    m.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_ACTUATION  # its servos: not the plant
    d = mujoco.MjData(m)
    rng = np.random.default_rng(7)
    q0 = m.qpos0 + rng.uniform(-0.3, 0.3, m.nq)
    v0 = rng.uniform(-1.0, 1.0, m.nv)
    d.qpos[:], d.qvel[:] = q0, v0
    plant = PinocchioPlant(robot, dt=m.opt.timestep)
    plant.reset(q0, v0)
    undamped = PinocchioPlant(robot, dt=m.opt.timestep)
    undamped.damping[:] = 0.0
    undamped.reset(q0, v0)
    for _ in range(500):
        mujoco.mj_step(m, d)
        plant.step(np.zeros(robot.nv))
        undamped.step(np.zeros(robot.nv))
    np.testing.assert_allclose(plant.q, d.qpos, atol=1e-9)
    np.testing.assert_allclose(plant.v, d.qvel, atol=1e-8)
    assert np.abs(undamped.q - d.qpos).max() > 1e-3
    assert plant.unmodelled == ()


def test_dry_friction_the_plant_cannot_model_is_reported():
    robot = load_robot(str(FIXTURE))
    with pytest.warns(RobotWarning, match="frictionloss"):
        plant = PinocchioPlant(robot)
    assert len(plant.unmodelled) == 1 and "dry joint friction" in plant.unmodelled[0]
