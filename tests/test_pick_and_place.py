"""Pick-and-place: the load metric after the grasp, the switching controller, the built-in."""

from __future__ import annotations

import json

import numpy as np
import pinocchio as pin
import pytest

from geosyn.experiments.procedures.pick_and_place import GraspSwitchedTorque, attach_payload
from geosyn.metrics import KineticEnergyMetric
from geosyn.metrics.shaping import LoadTerm, ShapedMetric
from geosyn.robots import load_robot
from geosyn.world import Payload


@pytest.fixture(scope="module")
def panda():
    return load_robot("panda")


@pytest.fixture(scope="module")
def obj(panda):
    # the built-in's object (same constants: the compiled load metric is cached)
    return Payload(panda.ee_frame, 1.5, com=(0.0, 0.0, 0.03), radius=0.04, name="object")


def appended_mass_matrix(robot, payload, q):
    """CRBA of the robot with the object appended as its own body (Pinocchio)."""
    model = pin.Model(robot.model)
    frame = model.frames[robot.frame_id(payload.frame)]
    inertia = pin.Inertia(payload.mass, np.array(payload.com), payload.rotational_inertia())
    model.appendBodyToJoint(frame.parentJoint, inertia, frame.placement)
    M = pin.crba(model, model.createData(), q)
    return np.triu(M) + np.triu(M, 1).T


def test_load_metric_after_the_grasp_is_the_mass_matrix_with_the_object_attached(panda, obj):
    loaded = ShapedMetric(KineticEnergyMetric(panda), [LoadTerm.from_payload(obj)])
    rng = np.random.default_rng(14)
    for _ in range(5):
        q = panda.random_q(rng)
        M = appended_mass_matrix(panda, obj, q)
        assert np.max(np.abs(loaded.G(q) - M)) <= 1e-10
        # the controller's model after the grasp is the same mass matrix
        lumped = attach_payload(panda, obj)
        M2 = pin.crba(lumped.model, lumped.model.createData(), q)
        assert np.max(np.abs(np.triu(M2) + np.triu(M2, 1).T - M)) <= 1e-10
        # and the object changes it (the test is not vacuous)
        assert np.max(np.abs(M - KineticEnergyMetric(panda).G(q))) > 1e-3


def test_the_controller_model_switches_at_grasp_and_release(panda, obj):
    from geosyn.controllers import JointTrajectoryReference

    loaded = attach_payload(panda, obj)
    ctl = GraspSwitchedTorque(panda, loaded, 100.0, 20.0, t_grasp=0.5, t_release=1.0)
    q = np.array([0.1, -0.3, 0.2, -2.0, 0.1, 1.8, 0.8])
    t = np.array([0.0, 2.0])
    ctl.set_reference(JointTrajectoryReference(t, np.array([q, q])))
    v = np.full(7, 0.1)
    a_des = 20.0 * (0.0 - v)  # reference at rest at q: a = kd (v_ref - v)
    for time, robot in ((0.2, panda), (0.7, loaded), (1.2, panda)):
        ctl.reset(q, v, 0.0)
        tau = ctl.compute(time, q, v)
        expected = pin.rnea(robot.model, robot.model.createData(), q, v, a_des)
        np.testing.assert_allclose(tau, np.clip(expected, -panda.tau_max, panda.tau_max), atol=1e-9)
        assert ctl.diagnostics.extra["holding"] == float(robot is loaded)


@pytest.mark.slow
def test_builtin_pick_and_place_carry_on_the_load_metric_needs_less_energy(tmp_path):
    from geosyn.experiments import load_config, run_experiment

    cfg, _ = load_config("pick_and_place", ["outputs.plots=false"])
    outcome = run_experiment(cfg, tmp_path / "pp", progress=False, quiet=True)
    s = json.loads((outcome.path / "summary.json").read_text())
    assert s["load_metric_error"] <= 1e-10
    for plan in ("load_aware", "unloaded", "straight"):
        assert s[f"{plan}.ok"] == 1.0
        assert s[f"{plan}.min_clearance"] > 0.0
        assert s[f"{plan}.max_contact_force"] == 0.0  # the box collides (scene.contact)
    # the carry is a geodesic of the true (loaded) metric: least energy of the three
    assert s["load_aware.energy"] < s["unloaded.energy"] < s["straight.energy"]
    assert s["energy_saving_vs_straight"] > 1.0
    assert s["load_aware.effort"] < s["straight.effort"]


def test_builtin_config_needs_an_empty_hand_before_the_grasp():
    from geosyn.experiments import load_config
    from geosyn.experiments.errors import ConfigError

    with pytest.raises(ConfigError, match="scene.payloads.0.mass: must be 0"):
        load_config("pick_and_place", ["scene.payloads.0.mass=0.5"])
