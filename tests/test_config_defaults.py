"""Config defaults have one source: every YAML default is the Python default
(experiments/schema/), and every constructor option can be set from YAML."""

from __future__ import annotations

import inspect
import math

import numpy as np
import pytest

from geosyn.experiments import schema as S
from geosyn.experiments.config.loader import load_config

SECTIONS = sorted(
    (
        obj
        for name in S.__all__
        if isinstance(obj := getattr(S, name), type) and issubclass(obj, S.Section) and obj.builds
    ),
    key=lambda cls: cls.__name__,
)

#: Defaults the config gives to arguments that every target requires (no Python default).
CONFIG_ONLY = {
    ("ComputedTorqueConfig", "kp"): 400.0,
    ("ComputedTorqueConfig", "kd"): 40.0,
    ("RiemannianPDConfig", "lam"): 20.0,
    ("RiemannianPDConfig", "k"): 50.0,
    ("QPConfig", "kp"): 400.0,
    ("QPConfig", "kd"): 40.0,
    ("PayloadConfig", "frame"): None,  # the robot's end effector
    ("LoadTermConfig", "frame"): None,  # the robot's end effector, or the payload's frame
    ("LoadTermConfig", "mass"): None,  # the payload's mass
}

#: Fields with a default that are not parameters of the section's targets.
NOT_PARAMETERS = {
    ("ComputedTorqueConfig", "label"),
    ("RiemannianPDConfig", "label"),
    ("QPConfig", "label"),
    ("MPCConfig", "label"),
    ("WholeBodyConfig", "label"),
    ("LoadTermConfig", "payload"),  # an index into scene.payloads
    ("OutputsConfig", "plots"),
    ("OutputsConfig", "video"),
    ("OutputsConfig", "video_format"),
    ("OutputsConfig", "csv"),  # per-run CSV tables (geosyn.experiments.results.data)
    ("OutputsConfig", "parquet"),  # per-run Parquet tables (geosyn.experiments.results.parquet)
}

#: Parameters of a section's first target that the config does not expose, and why.
NOT_EXPOSED = {
    "robot": "the experiment's robot",
    "metric": "the experiment's metric",
    "reference": "the experiment's reference",
    "controller": "the configured controllers",
    "QPController.dt": "simulation.control_dt",
    "ObstacleTerm.obstacles": "scene.obstacles",
    "ObstacleTerm.capacity": "one slot per obstacle of scene.obstacles",
    "Simulation.payloads": "scene.payloads",
    "Simulation.obstacles": "scene.obstacles",
    "GeodesicMPC.obstacles": "scene.obstacles (with clearance_margin)",
    "Simulation.disturbances": "the disturbances section",
    "Simulation.gravity": "robot.options.gravity",
    "Simulation.plant": "robot.plant",
    "Simulation.contact": "scene.contact (a property of the scene's obstacles)",
    "Simulation.seed": "the experiment's seed",
    "render_video.result": "the run",
    "render_video.path": "the run directory",
    "render_video.payloads": "scene.payloads",
    "render_video.obstacles": "scene.obstacles",
    "render_video.plant": "robot.plant (the plant that was simulated)",
    "render_video.camera": "a CameraView object, framed automatically",
    "render_video.disturbances": "the disturbances section (arrows for pushes, wrenches)",
    "render_video.label": "the run's name (the controller)",
    "orthonormal_synergies.directions": "a matrix of candidate directions (designed: none)",
    "GeodesicSynergy.trajectory.self": "the combined synergy",
    "exp.q0": "reference.q_start",
    "exp.v0": "log(q_start, goal) / duration",
    "exp.method": "RK4, the integrator of every geodesic of the experiments",
    "WholeBodyController.contacts": "stance.frames",
    "WholeBodyController.points": "stance.points",
    "WholeBodyController.mu": "stance.mu (one friction cone for every controller)",
    "WholeBodyController.f_min": "stance.f_min",
    "synergy": "the stance synergy built from the stance and reference.direction",
}


def _as_config(value):
    """A Python default as a config value (tuples are YAML sequences)."""
    return list(value) if isinstance(value, tuple) else value


def _same(a, b) -> bool:
    return (a is None) == (b is None) and _as_config(a) == _as_config(b)


def _python_defaults(target):
    empty = inspect.Parameter.empty
    return {
        name: (p.default is not empty, p.default)
        for name, p in inspect.signature(target).parameters.items()
    }


def test_the_sections_cover_every_library_class_the_config_builds():
    names = {cls.__name__ for cls in SECTIONS}
    for expected in (
        "ComputedTorqueConfig",
        "RiemannianPDConfig",
        "QPConfig",
        "MPCConfig",
        "LoadTermConfig",
        "ObstacleTermConfig",
        "JointLimitTermConfig",
        "PushConfig",
        "WrenchConfig",
        "PayloadChangeConfig",
        "TorqueNoiseConfig",
        "SensorNoiseConfig",
        "LatencyConfig",
        "SimulationConfig",
        "PayloadConfig",
        "OutputsConfig",
        "CombinationReference",
        "LogReference",
        "DesignedSynergies",
    ):
        assert expected in names


@pytest.mark.parametrize("section", SECTIONS, ids=lambda cls: cls.__name__)
def test_every_yaml_default_equals_the_python_default(section):
    """For each field with a default: every target taking that argument with a default
    has the same default (after the section's `to_python` conversion); an argument all
    targets require has its config default listed in CONFIG_ONLY."""
    targets = [_python_defaults(t) for t in section.builds]
    for name, field in section.model_fields.items():
        if field.is_required() or name == "type":
            continue
        value = field.get_default(call_default_factory=True)
        key = (section.__name__, name)
        param = section.parameter_names.get(name, name)
        found = [t[param] for t in targets if param in t]
        if not found:
            assert key in NOT_PARAMETERS, f"{key}: default {value!r} of no target parameter"
            continue
        python = [default for has, default in found if has]
        if not python:
            assert key in CONFIG_ONLY and _same(CONFIG_ONLY[key], value), (
                f"{key}: config default {value!r} for an argument the targets require"
            )
            continue
        converted = section.to_python.get(name, lambda v: v)(value)
        for default in python:
            assert _same(converted, default), (
                f"{key}: YAML default {value!r}, Python default {default!r}"
            )


@pytest.mark.parametrize("section", SECTIONS, ids=lambda cls: cls.__name__)
def test_every_constructor_option_can_be_set_from_yaml(section):
    target = section.builds[0]
    fields = {section.parameter_names.get(name, name) for name in section.model_fields}
    for name in inspect.signature(target).parameters:
        if name in fields:
            continue
        assert name in NOT_EXPOSED or f"{target.__qualname__}.{name}" in NOT_EXPOSED, (
            f"{target.__qualname__}({name}=...) cannot be set from a config"
        )


def test_mpc_options_a_researcher_needs_are_in_the_yaml():
    mpc = S.MPCConfig.model_validate(
        {"type": "mpc", "effort": "acceleration", "hessian": "exact", "rk4_steps": 2}
    )
    assert mpc.kwargs()["effort"] == "acceleration" and mpc.kwargs()["hessian"] == "exact"
    with pytest.raises(ValueError, match="hessian"):
        S.MPCConfig.model_validate({"type": "mpc", "hessian": "newton"})


def test_kwargs_build_the_library_objects():
    from geosyn.controllers import ComputedTorque, QPController
    from geosyn.metrics.shaping import JointLimitTerm
    from geosyn.robots import load_robot
    from geosyn.sim import Wrench

    robot = load_robot("planar2")
    ct = ComputedTorque(robot, **S.ComputedTorqueConfig(type="computed_torque").kwargs())
    np.testing.assert_array_equal(ct.kp, [400.0, 400.0])
    qp = QPController(robot, dt=1e-3, **S.QPConfig(type="qp", kd=[1.0, 2.0]).kwargs())
    np.testing.assert_array_equal(qp.kd, [1.0, 2.0])
    term = JointLimitTerm(**S.JointLimitTermConfig(type="joint_limit", d_min=1e-6).kwargs())
    assert term.d_min == 1e-6
    wrench = Wrench(**S.WrenchConfig(type="wrench", body="link2").kwargs())
    assert wrench.stop == math.inf  # None in the config: never stops


def test_a_config_only_default_may_not_shadow_a_python_default():
    from geosyn.controllers import GeodesicMPC

    with pytest.raises(TypeError, match="has a Python default"):
        S.python_defaults(GeodesicMPC, horizon=10)
    with pytest.raises(TypeError, match="is not a parameter"):
        S.python_defaults(GeodesicMPC, horizont=10)


def test_builtin_experiments_keep_the_settings_they_were_written_with():
    """Settings the built-ins relied on as defaults before the defaults came from Python."""
    cfg, _ = load_config("panda_push_recovery")
    mpc = next(c for c in cfg.controllers if c.type == "mpc")
    assert (mpc.horizon, mpc.control, mpc.effort, mpc.tau_weight) == (10, "torque", "torque", 1e-3)
    assert cfg.reference is not None and cfg.reference.steps == 200
    assert (cfg.outputs.fps, cfg.outputs.width, cfg.outputs.height) == (25.0, 480, 360)
    assert cfg.scene.payloads[0].radius == 0.03
    for name in ("panda_obstacle_shaping", "panda_payload_shaping"):
        cfg, _ = load_config(name)
        assert cfg.reference is not None and cfg.reference.steps == 200


def test_scene_contact_default_is_the_simulations_and_has_one_place():
    """``contact`` is set in the scene section only (default: Simulation's own)."""
    from geosyn.sim import Simulation

    python = inspect.signature(Simulation).parameters["contact"].default
    assert S.SceneConfig().contact is python is False
    from geosyn.experiments.config.loader import builtin_names

    with_obstacles = [n for n in builtin_names() if load_config(n)[0].scene.obstacles]
    assert "panda_obstacle_shaping" in with_obstacles and "ur5_tracking" in with_obstacles
    for name in with_obstacles:  # on in every built-in experiment with obstacles
        assert load_config(name)[0].scene.contact is True, name
    from geosyn.experiments.errors import ConfigError

    with pytest.raises(ConfigError, match="scene.contact: true"):
        load_config("panda_obstacle_shaping", ["simulation.contact=true"])
    with pytest.raises(ConfigError, match="scene.contact"):  # nothing to collide with
        load_config("panda_payload_shaping", ["scene.contact=true"])
