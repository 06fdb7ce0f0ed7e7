"""The robot's own MJCF as the plant with the run's scene (sim/file_scene.py, issue 21):
``fixed_base`` welds the file's free joint in the file plant as in geosyn's model."""

from __future__ import annotations

import warnings
from pathlib import Path

import mujoco
import numpy as np
import pytest

from geosyn.controllers import ComputedTorque, GeodesicReference
from geosyn.metrics import KineticEnergyMetric
from geosyn.robots import load_robot
from geosyn.robots.errors import RobotWarning
from geosyn.sim import Simulation
from geosyn.synergies import GeodesicSynergy

FIXTURES = Path(__file__).parent / "fixtures"
FLOATING = FIXTURES / "floating_arm.xml"
BASE_POS = np.array([0.1, -0.2, 0.6])  # the file's base pose
BASE_QUAT = np.array([0.9659258, 0.0, 0.0, 0.2588190])
Q0 = np.array([0.2, -0.5, 0.8])


def _fixed_robot():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RobotWarning)
        return load_robot(FLOATING, fixed_base=True)


def test_the_raw_file_lets_its_base_fall() -> None:
    """MuJoCo's compile of the file as it is: the free base drops (what the weld prevents)."""
    m = mujoco.MjModel.from_xml_path(str(FLOATING))
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, 0)
    for _ in range(300):
        mujoco.mj_step(m, d)
    assert BASE_POS[2] - d.xpos[m.body("base").id][2] > 0.3


def test_fixed_base_welds_the_free_joint_in_the_file_plant() -> None:
    robot = _fixed_robot()
    synergy = GeodesicSynergy(KineticEnergyMetric(robot), Q0, np.array([0.8, 0.6, -0.9]))
    ref = GeodesicReference(synergy, duration=0.6, steps=60, rest_to_rest=True)
    with pytest.warns(RuntimeWarning, match="welded at the file's pose"):
        sim = Simulation(robot, ComputedTorque(robot, 400.0, 40.0, reference=ref), plant="file")
    m = sim.model
    assert m.nq == 3 and not np.any(m.jnt_type == mujoco.mjtJoint.mjJNT_FREE)
    np.testing.assert_allclose(m.key_qpos[0], [0.2, -0.5, 0.8], atol=0)  # keyframe kept
    result = sim.run(Q0, duration=0.8)
    base = m.body("base").id
    np.testing.assert_allclose(sim.data.xpos[base], BASE_POS, atol=1e-9)
    np.testing.assert_allclose(sim.data.xquat[base], BASE_QUAT, atol=1e-7)  # file's digits
    assert np.ptp(result.q[:, 0]) > 0.3  # the arm moved
    assert float(np.sqrt(np.mean((result.q - result.q_ref) ** 2))) < 1e-3


def test_yaml_fixed_base_with_the_file_plant_runs_ok(tmp_path: Path) -> None:
    """``robot: {plant: file, options: {fixed_base: true}}`` through ``geosyn run``: the run
    is ok and tracks (the issue's humanoid fell and 'diverged' at 0.22 s)."""
    from geosyn.experiments import load_config, run_experiment

    yaml = tmp_path / "fixed.yaml"
    yaml.write_text(
        f"""name: fixed_base_file
kind: tracking
robot: {{name: {FLOATING}, plant: file, options: {{fixed_base: true}}}}
reference: {{type: log, q_start: [0.2, -0.5, 0.8], goal: [-0.4, 0.3, 0.2], duration: 0.5,
  steps: 40, rest_to_rest: true}}
controllers: [{{type: computed_torque, kp: 400.0, kd: 40.0}}]
simulation: {{duration: 0.6, control_dt: 0.002}}
outputs: {{plots: false}}
"""
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cfg, _ = load_config(str(yaml))
        s = run_experiment(cfg, tmp_path / "run", progress=False, quiet=True).summary
    assert s["computed_torque.ok"] == 1.0
    assert s["computed_torque.rms_error"] < 1e-3, s
