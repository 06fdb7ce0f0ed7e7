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
