"""Obstacles from an MJCF scene (`geosyn.world.load_mjcf_obstacles`), checked against
MuJoCo's own compile of the file: the distance from a probe sphere to each geom by
``mujoco.mj_geomDistance`` equals our signed distance of its centre minus its radius."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from geosyn.world import (
    Box,
    Capsule,
    Cylinder,
    HalfSpace,
    InvalidGeometry,
    Sphere,
    load_mjcf_obstacles,
    signed_distance,
)

SCENE = """
<mujoco>
  <worldbody>
    <geom name="floor" type="plane" size="2 2 0.1" pos="0 0 -0.2" euler="5 -3 0"/>
    <geom name="box" type="box" size="0.2 0.05 0.1" pos="0.5 0.1 0.3" euler="20 -30 45"/>
    <geom name="ball" type="sphere" size="0.08" pos="-0.4 0.2 0.5"/>
    <geom name="pipe" type="capsule" fromto="-0.3 -0.5 0.8 0.3 -0.4 0.9" size="0.03"/>
    <geom name="visual" type="box" size="0.1 0.1 0.1" contype="0" conaffinity="0"/>
    <body name="shelf" pos="0 0.6 0.2" euler="0 0 30">
      <geom name="pillar" type="cylinder" size="0.04 0.25" pos="0.1 0 0" euler="10 0 0"/>
    </body>
    <body name="cart" pos="1 1 0">
      <joint type="free"/>
      <geom name="moving" type="box" size="0.1 0.1 0.1"/>
    </body>
    <body name="probe" mocap="true" pos="0 0 2">
      <geom name="probe" type="sphere" size="0.01" contype="0" conaffinity="0"/>
    </body>
  </worldbody>
</mujoco>
"""


def test_static_geoms_become_shapes_and_the_rest_is_reported() -> None:
    scene = load_mjcf_obstacles(SCENE)
    assert scene.names == ("floor", "box", "ball", "pipe", "pillar")
    assert [type(s) for s in scene.shapes] == [HalfSpace, Box, Sphere, Capsule, Cylinder]
    assert any(s.startswith("visual: visual only") for s in scene.skipped)
    assert any(s.startswith("moving: on a moving body") for s in scene.skipped)
    assert scene.moving == ("moving", "probe")  # the names alone (a mocap body moves too)
    assert load_mjcf_obstacles(SCENE, visual=True).names[4] == "visual"  # mocap: moving


@pytest.mark.parametrize("index", range(5))
def test_distances_match_mujoco(index: int) -> None:
    scene = load_mjcf_obstacles(SCENE)
    model = mujoco.MjModel.from_xml_string(SCENE)
    data = mujoco.MjData(model)
    probe = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "probe")
    geom = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, scene.names[index])
    rng = np.random.default_rng(index)
    ours, theirs = [], []
    while len(ours) < 20:
        p = rng.uniform(-1.0, 1.0, 3) + np.array([0.0, 0.0, 0.5])
        d = float(signed_distance(scene.shapes[index], p)[0]) - 0.01
        if not 0.02 < d < 0.5:  # MuJoCo's distance is exact for separated convex pairs
            continue
        data.mocap_pos[0] = p
        mujoco.mj_forward(model, data)
        theirs.append(mujoco.mj_geomDistance(model, data, probe, geom, 1.0, None))
        ours.append(d)
    # MuJoCo's cylinder and capsule distances come from its convex solver (~1e-6 m)
    np.testing.assert_allclose(ours, theirs, atol=1e-5)


def test_bad_file_is_one_clear_error() -> None:
    with pytest.raises(InvalidGeometry, match="source: MuJoCo could not load it"):
        load_mjcf_obstacles("<mujoco><worldbody><geom type='nope'/></worldbody></mujoco>")
