"""The robot's own MJCF as the plant with the run's scene (sim/file_scene.py, issue 21):
``fixed_base`` welds the file's free joint in the file plant as in geosyn's model; obstacles,
payloads and contact go into the file as into the model, with the model plant's results on
a file written as geosyn's own model of it (tests/fixtures/scene_arm.xml)."""

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
from geosyn.world import Box, Payload

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


SCENE_ARM = FIXTURES / "scene_arm.xml"


def _scene_run(plant: str, payloads: tuple[Payload, ...]):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RobotWarning)
        robot = load_robot(SCENE_ARM, tau_max=50.0)
    q0 = np.array([0.0, 0.3, 0.2])
    synergy = GeodesicSynergy(KineticEnergyMetric(robot), q0, np.array([1.5, 0.0, 0.0]))
    ref = GeodesicReference(synergy, duration=1.0, steps=100, rest_to_rest=True)
    box = Box(center=(0.3, 0.55, 0.35), half_extents=(0.1, 0.05, 0.2))  # in the sweep
    sim = Simulation(
        robot,
        ComputedTorque(robot, 400.0, 40.0, reference=ref),
        obstacles=[box],
        payloads=payloads,
        contact=True,
        plant=plant,
    )
    return sim, sim.run(q0, duration=1.0)


def test_file_plant_with_a_box_a_payload_and_contact_equals_the_model_plant() -> None:
    """Same dynamics in both plants (the file is geosyn's model of it): every logged
    quantity agrees to 1e-9 while the arm pushes into the box (contact > 100 N)."""
    payload = (Payload("l3", 0.4, com=(0.3, 0.0, 0.0), radius=0.03, name="load"),)
    (m_sim, model), (f_sim, file) = _scene_run("model", payload), _scene_run("file", payload)
    assert model.status == file.status == "ok"
    assert model.contact_force.max() > 100.0  # the box is hit
    for field in ("q", "v", "tau", "contact_force", "clearance", "kinetic_energy"):
        a, b = getattr(model, field), getattr(file, field)
        scale = max(1.0, float(np.abs(a).max()))
        assert float(np.abs(a - b).max()) <= 1e-9 * scale, field
    # The payload sits at the same place in both plants, in the body of the link it names.
    pm, pf = m_sim.model.body("load").id, f_sim.model.body("load").id
    assert f_sim.model.body_parentid[pf] == f_sim.model.body("l3").id
    np.testing.assert_allclose(f_sim.data.xipos[pf], m_sim.data.xipos[pm], atol=1e-12)
    np.testing.assert_allclose(f_sim.model.body_mass[pf], 0.4)
    # ... and it matters: without it the file plant's run differs.
    _, bare = _scene_run("file", ())
    assert float(np.abs(bare.tau - file.tau).max()) > 0.1
