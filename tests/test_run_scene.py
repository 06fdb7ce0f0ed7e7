"""The scene of a run (experiments/run/scene.py): built once from the config, the same
shapes handed to the metric, the controllers, the simulation and the video."""

from __future__ import annotations

import numpy as np

from geosyn.experiments import load_config, run_experiment
from geosyn.experiments.run import scene as scene_mod
from geosyn.experiments.run.scene import build_run_scene
from geosyn.world import Box, signed_distance

#: A short ur5_tracking run with computed torque (nothing to compile): the controllers'
#: scene (clearance) and the simulation both need the box.
SHORT = [
    "simulation.duration=0.05",
    "outputs.plots=false",
    "outputs.csv=false",
    "disturbances=[]",
    "controllers=[{type: computed_torque}]",
]


def test_built_scene_holds_the_config_world():
    cfg, _ = load_config("ur5_tracking", ["scene.payloads=[{mass: 0.4}]"])
    scene = build_run_scene(cfg)
    (box,) = scene.obstacles
    o = cfg.scene.obstacles[0]
    point = np.array([0.3, 0.2, 0.5])  # [m]
    # independent: the box written from the YAML values (no rotation), distance by hand
    expected = Box(tuple(o.center), tuple(o.half_extents))
    got = signed_distance(box, point)[0]
    assert got == signed_distance(expected, point)[0]
    outside = np.abs(point - np.array(o.center)) - np.array(o.half_extents)
    assert abs(got - np.linalg.norm(np.maximum(outside, 0.0))) < 1e-15  # [m]
    (payload,) = scene.payloads
    assert payload.mass == 0.4 and payload.frame == scene.robot.ee_frame
    assert scene.contact is True and scene.plant == "model" and scene.cameras == ()
    assert scene.robot.name == "ur5"


def test_each_yaml_obstacle_becomes_a_shape_once_per_run(tmp_path, monkeypatch):
    """Data flows forward: one run converts the YAML box once (the controllers and the
    MuJoCo scene share it; before the built scene, each rebuilt its own)."""
    calls = []
    build_box = scene_mod.OBSTACLES["box"]

    def counting(section):
        calls.append(section)
        return build_box(section)

    # loaded first: validation checks the start against the box (issue 23), not the run
    cfg, _ = load_config("ur5_tracking", SHORT)
    monkeypatch.setitem(scene_mod.OBSTACLES, "box", counting)
    out = run_experiment(cfg, tmp_path / "run", progress=False, quiet=True)
    assert len(calls) == len(cfg.scene.obstacles) == 1
    assert out.summary["computed_torque.ok"] == 1.0
    # the run's clearance is to that box: positive and finite
    assert 0.0 < out.summary["computed_torque.min_clearance"] < 1.0


#: A MuJoCo scene file for the UR5: a box rotated by a quaternion, a mesh far off the way
#: (enclosed by its box), a visual-only ball and a ball on a moving body (both left out).
MJCF_SCENE = """<mujoco model="ur5_scene">
  <asset>
    <mesh name="rock" vertex="0 0 0  0.1 0 0  0 0.1 0  0 0 0.1  0.08 0.08 0.08"/>
  </asset>
  <worldbody>
    <geom name="crate" type="box" size="0.08 0.07 0.09" pos="0.45 0.45 0.2"
          quat="0.9659258 0 0 0.2588190"/>
    <geom name="rock" type="mesh" mesh="rock" pos="-0.8 -0.8 0.0"/>
    <geom name="glow" type="sphere" size="0.05" pos="0 0 2" contype="0" conaffinity="0"/>
    <body name="cart" pos="2 2 0">
      <joint type="slide" axis="1 0 0"/>
      <geom name="wheel" type="sphere" size="0.05" mass="1"/>
    </body>
  </worldbody>
</mujoco>
"""


def _ur5_scene_config(tmp_path, scene: str) -> str:
    """A UR5 planned-reference run whose obstacles come from ``scene`` (an MJCF text,
    written beside the YAML and named relative to it)."""
    import yaml

    (tmp_path / "scene.xml").write_text(scene)
    data = {
        "name": "ur5_mjcf_scene",
        "kind": "tracking",
        "robot": {"name": "ur5"},
        "scene": {"mjcf": {"file": "scene.xml"}},
        "reference": {
            "type": "planned",
            "q_start": [0.0, -1.2, 1.6, -1.9, -1.57, 0.0],
            "goal": [1.2, -1.0, 1.3, -1.9, -1.57, 0.0],
            "duration": 2.0,
            "rest_to_rest": True,
        },
        "controllers": [{"type": "computed_torque"}],
        "simulation": {"duration": 0.1, "control_dt": 0.002},
        "outputs": {"plots": False, "csv": False},
    }
    path = tmp_path / "run.yaml"
    path.write_text(yaml.safe_dump(data))
    return str(path)


def test_a_mujoco_scene_file_gives_the_obstacles_of_a_planned_run(tmp_path):
    """``scene.mjcf``: a URDF robot planned around the static geoms of an MJCF scene file.
    Referee: the crate and the rock's box written by hand (the crate's rotation from its
    quaternion by Pinocchio): coal's exact clearance of the planned path to them equals the
    plan's own (1e-9 m); what was enclosed or left out is in the run log."""
    import pinocchio as pin

    from geosyn.world.exact_clearance import ExactClearance

    cfg, _ = load_config(_ur5_scene_config(tmp_path, MJCF_SCENE))
    out = run_experiment(cfg, tmp_path / "run", progress=False, quiet=True)
    rotation = pin.Quaternion(0.9659258, 0.0, 0.0, 0.2588190).normalized().matrix()
    crate = Box((0.45, 0.45, 0.2), (0.08, 0.07, 0.09), tuple(map(tuple, rotation)))
    rock = Box((-0.75, -0.75, 0.05), (0.05, 0.05, 0.05))  # its vertices' bounding box
    exact = ExactClearance(build_run_scene(cfg).robot)
    exact.set_obstacles([crate, rock])
    with np.load(out.path / "results.npz") as d:
        q_plan = d["reference__q"]
    planned = out.summary["planned_clearance"]
    assert planned > 0.0 and out.summary["planned_certified_clearance"] >= 0.0
    assert abs(exact.path_clearance(q_plan, 0.005).clearance - planned) < 1e-9
    log = (out.path / "run.log").read_text()
    assert "rock: mesh -> its bounding box" in log
    assert "glow: visual only" in log and "wheel: on a moving body" in log


def test_a_bad_mujoco_scene_file_is_one_clear_error(tmp_path):
    """A file MuJoCo cannot load, one with nothing static in it, and one whose box holds
    the robot's start: refused by field (the last names the geom)."""
    import pytest

    from geosyn.experiments import ConfigError

    with pytest.raises(ConfigError, match=r"scene\.mjcf\.file.*could not load"):
        load_config(_ur5_scene_config(tmp_path, "<mujoco><worldbody><geom type='nope'/>"))
    moving_only = """<mujoco><worldbody><body name="cart" pos="2 2 0">
      <joint type="slide" axis="1 0 0"/><geom name="wheel" type="sphere" size="0.05" mass="1"/>
    </body></worldbody></mujoco>"""
    with pytest.raises(ConfigError, match=r"scene\.mjcf\.file.*no static geom.*wheel"):
        load_config(_ur5_scene_config(tmp_path, moving_only))
    around_base = '<mujoco><worldbody><geom name="vault" type="box" size="0.3 0.3 0.3"/>'
    with pytest.raises(ConfigError, match=r"scene\.mjcf \(geom 'vault'\).*starts inside this box"):
        load_config(_ur5_scene_config(tmp_path, around_base + "</worldbody></mujoco>"))
    # a file that holds a robot too: its fixed base is a static geom round the UR5's base
    with_arm = """<mujoco><worldbody><geom name="table" type="box" pos="2 0 0" size="0.3 0.3 0.3"/>
      <body name="base"><geom name="base_link" type="cylinder" size="0.08 0.05"/>
        <body name="link1" pos="0 0 0.1"><joint type="hinge" axis="0 0 1"/>
          <geom name="link1_geom" type="capsule" fromto="0 0 0 0 0 0.3" size="0.05"/>
        </body></body></worldbody></mujoco>"""
    with pytest.raises(ConfigError, match=r"(?s)geom 'base_link'.*1 geom\(s\) on moving bodies.*"
                                          r"'link1_geom'.*includes the robot"):  # fmt: skip
        load_config(_ur5_scene_config(tmp_path, with_arm))
