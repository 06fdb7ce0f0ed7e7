"""The controllers' models hold the robot file's viscous joint damping (MPC, every solver family; PD):
tracked inside MuJoCo's compile of the original file, it does as well as the file's
dynamics allow, and measurably worse with the damping removed from its model (issue 21).
The file's dry friction is fed forward on the reference velocity (noted in the
diagnostics); tests/test_property_matrix.py measures it inside the file plant."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from geosyn.controllers import ComputedTorque, GeodesicMPC, GeodesicReference
from geosyn.metrics import KineticEnergyMetric
from geosyn.robots import load_robot
from geosyn.sim import Simulation
from geosyn.synergies import GeodesicSynergy

FIXTURE = Path(__file__).parent / "fixtures" / "arm_root_quat.xml"
Q0 = np.array([0.3, 0.2, -0.2, 0.05, 0.3])
V0 = np.array([0.4, -0.3, 0.35, 0.03, 0.5])
DURATION = 1.5


@pytest.fixture(scope="module")
def damped(tmp_path_factory):
    """The fixture arm (damping 0.4 and 1.5 N m s/rad, armature, gravity, joint ranges and
    torque limits as in the file) without its dry friction, and a geodesic reference."""
    path = tmp_path_factory.mktemp("damped") / "arm_damped.xml"
    path.write_text(FIXTURE.read_text().replace('frictionloss="0.1"', 'frictionloss="0"'))
    with pytest.warns(Warning):  # the file states no velocity limits (defaults, reported)
        robot = load_robot(str(path))
    assert np.any(robot.damping) and not np.any(robot.frictionloss)
    metric = KineticEnergyMetric(robot)
    ref = GeodesicReference(GeodesicSynergy(metric, Q0, V0), duration=DURATION)
    return robot, ref


def _rms(robot, model_robot, make, ref) -> float:
    ctl = make(model_robot)
    result = Simulation(robot, ctl, plant="file").run(Q0, ref.sample(0.0).v, DURATION, ref)
    return float(np.sqrt(np.mean((result.q - result.q_ref) ** 2)))


def _mpc(solver: str):
    def make(r):
        return GeodesicMPC(
            r, KineticEnergyMetric(r), horizon=10, dt=0.02, control="torque", solver=solver
        )

    return make


@pytest.mark.parametrize("solver", ["ddp", "fatrop"])
def test_mpc_models_the_files_damping(damped, solver):
    """Referee: MuJoCo's own compile of the file (plant='file'). Measured: ddp 1.1e-4 rad
    RMS with the damping in its model against 2.3e-3 without; fatrop 1.1e-4 against
    2.7e-3; computed torque (which adds D v) 2.6e-6 against 1.0e-2."""
    robot, ref = damped
    undamped = dataclasses.replace(robot, damping=np.zeros(robot.nv))
    with_damping = _rms(robot, robot, _mpc(solver), ref)
    without = _rms(robot, undamped, _mpc(solver), ref)
    assert with_damping < 3e-4, with_damping
    assert without > 5.0 * with_damping, (with_damping, without)
    ct = _rms(robot, robot, lambda r: ComputedTorque(r, 400.0, 40.0), ref)
    assert ct < with_damping  # the MPC's own tracking error dominates, not the model


def test_mpc_notes_the_dry_friction_it_models(damped):
    robot, _ = damped
    rough = dataclasses.replace(robot, frictionloss=np.full(robot.nv, 0.1))
    mpc = GeodesicMPC(
        rough, KineticEnergyMetric(rough), horizon=10, dt=0.02, control="torque", solver="ddp"
    )
    assert "dry joint friction [0.1" in mpc.diagnostics.notes["frictionloss"]
    assert "modelled" in mpc.diagnostics.notes["frictionloss"]
    assert "modelled" in mpc.diagnostics.notes["damping"]


def test_riemannian_pd_compensates_the_files_damping(damped):
    """Referee: MuJoCo's compile of the damped file. Measured: 1.7e-6 rad RMS with D v_r
    in the law against 3.1e-4 with the damping removed from its model."""
    from geosyn.controllers import RiemannianPD

    robot, ref = damped
    undamped = dataclasses.replace(robot, damping=np.zeros(robot.nv))
    make = lambda r: RiemannianPD(r, 20.0, 40.0)  # noqa: E731
    with_damping = _rms(robot, robot, make, ref)
    without = _rms(robot, undamped, make, ref)
    assert without > 5.0 * with_damping, (with_damping, without)
