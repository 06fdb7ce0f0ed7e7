"""How much of a file's collision geometry collision spheres leave out
(robots/sphere_cover.py), against a closed form, and the warning the obstacle terms and
the MPC's clearance give once when their spheres leave part of the robot out."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from geosyn.robots import CollisionSphere, RobotWarning, load_robot
from geosyn.robots.collision_spheres import file_spheres
from geosyn.robots.sphere_cover import report_sphere_miss, sphere_miss

#: One hinge carrying a box (half-extents 0.1, 0.02, 0.03 at x = 0.1) and, on a second
#: hinge, a ball of radius 0.02.
ARM = """<mujoco model="box_arm">
  <worldbody>
    <body name="l1">
      <joint name="j1" type="hinge" axis="0 0 1"/>
      <inertial pos="0.1 0 0" mass="1" diaginertia="0.01 0.01 0.01"/>
      <geom name="slab" type="box" size="0.1 0.02 0.03" pos="0.1 0 0"/>
      <body name="l2" pos="0.2 0 0">
        <joint name="j2" type="hinge" axis="0 0 1"/>
        <inertial pos="0.05 0 0" mass="0.5" diaginertia="0.001 0.001 0.001"/>
        <geom name="ball" type="sphere" size="0.02" pos="0.05 0 0"/>
      </body>
    </body>
  </worldbody>
  <actuator><motor joint="j1"/><motor joint="j2"/></actuator>
</mujoco>
"""


@pytest.fixture()
def arm(tmp_path):
    path = tmp_path / "box_arm.xml"
    path.write_text(ARM)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RobotWarning)  # the file's missing limits
        return load_robot(str(path))


def test_the_miss_is_the_farthest_corner_outside_the_sphere(arm) -> None:
    """A sphere of radius 0.05 at the slab's centre: the farthest surface points are its
    corners, sqrt(0.1^2 + 0.02^2 + 0.03^2) from the centre (closed form, 1e-9 m); the
    second link has no sphere and is named."""
    miss = sphere_miss(arm, [CollisionSphere("j1", (0.1, 0.0, 0.0), 0.05)])
    assert abs(miss.distance - (math.sqrt(0.1**2 + 0.02**2 + 0.03**2) - 0.05)) < 1e-9
    assert miss.link == "l1" and miss.bare == ("l2",)
    # a sphere that holds the ball: -(0.03 - 0.02) inside, the slab unchanged
    both = sphere_miss(
        arm,
        [CollisionSphere("j1", (0.1, 0.0, 0.0), 0.05), CollisionSphere("j2", (0.05, 0, 0), 0.03)],
    )
    assert both.bare == () and both.link == "l1" and both.distance == miss.distance


def test_a_new_process_reads_the_miss_from_the_disk_cache(arm, tmp_path, monkeypatch) -> None:
    """The miss of the closed-form case above, measured once into an empty cache folder,
    is read back (equal, every field) with the process's memory emptied and the sampling
    disabled, as a new process would; a damaged entry is warned and measured again."""
    from geosyn.robots import sphere_cover

    monkeypatch.setenv("GEOSYN_CACHE_DIR", str(tmp_path / "cache"))
    spheres = [CollisionSphere("j1", (0.1, 0.0, 0.0), 0.05)]
    monkeypatch.setattr(sphere_cover, "_CACHE", {})
    first = sphere_miss(arm, spheres)
    assert abs(first.distance - (math.sqrt(0.1**2 + 0.02**2 + 0.03**2) - 0.05)) < 1e-9
    (entry,) = (tmp_path / "cache" / "spheres").glob("miss_*.json")

    def no_sampling(*args: object) -> None:
        raise AssertionError("measured again")

    monkeypatch.setattr(sphere_cover, "_CACHE", {})
    with monkeypatch.context() as m:
        m.setattr(sphere_cover, "_measure", no_sampling)
        assert sphere_miss(arm, spheres) == first
    entry.write_text("{not json")
    monkeypatch.setattr(sphere_cover, "_CACHE", {})
    with pytest.warns(RuntimeWarning, match="damaged"):
        assert sphere_miss(arm, spheres) == first


def test_the_fitted_spheres_leave_nothing_out_and_are_not_warned(arm) -> None:
    fitted = file_spheres(arm).spheres
    miss = sphere_miss(arm, fitted)
    assert miss.distance <= -file_spheres(arm).margin + 1e-9 and miss.bare == ()
    with warnings.catch_warnings():
        warnings.simplefilter("error", RobotWarning)
        report_sphere_miss(arm, fitted, "test", "n/a")


def test_the_default_spheres_are_warned_once_per_user() -> None:
    """The Panda's default spheres (along its capsules) leave out links 1 and 5 and
    centimetres of others: the obstacle term says so once, naming them."""
    from geosyn.metrics.shaping import ObstacleTerm

    panda = load_robot("panda")
    miss = sphere_miss(panda, panda.collision_spheres())
    assert miss.distance > 0.01 and "panda_link5" in miss.bare
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        for _ in range(2):
            ObstacleTerm((), capacity=1, spheres=panda.collision_spheres()[:-1]).bind(panda)
    ours = [w for w in seen if w.category is RobotWarning and "ObstacleTerm" in str(w.message)]
    (warned,) = ours  # once, though bound twice
    text = str(warned.message)
    assert "panda_link5" in text and f"the {len(panda.collision_spheres()) - 1} collision" in text


def test_covering_spheres_are_asked_for_by_name_and_keep_the_meshes_clear() -> None:
    """``spheres='file'`` (an obstacle term) and ``clearance_spheres='file'`` (the MPC's
    slots, also from YAML) give the fitted spheres, silently; their clearance never
    exceeds coal's exact distance of the meshes (they cover them), at seeded
    configurations. Other strings, and 'file' for a robot built in code, are refused."""
    from geosyn.controllers.mpc.ocp.obstacles import ObstacleSlots, obstacle_slots
    from geosyn.core.errors import InvalidArgument
    from geosyn.experiments.schema import MPCConfig
    from geosyn.experiments.schema.metric import ObstacleTermConfig
    from geosyn.metrics.shaping import ObstacleTerm
    from geosyn.world import Box
    from geosyn.world.exact_clearance import ExactClearance

    panda = load_robot("panda")
    box = Box((0.45, 0.1, 0.35), (0.05, 0.1, 0.05))
    moving = tuple(s for s in file_spheres(panda).spheres if s.joint != "universe")
    with warnings.catch_warnings():
        warnings.simplefilter("error", RobotWarning)
        term = ObstacleTerm([box], capacity=1, spheres="file")
        term.bind(panda)
        slots = ObstacleSlots(panda, [box], spheres="file")
    assert term.spheres == moving == slots.spheres
    exact = ExactClearance(panda, near=1.0)
    exact.set_obstacles([box])
    rng = np.random.default_rng(11)
    for _ in range(8):
        q = rng.uniform(panda.q_min, panda.q_max)
        assert term.min_clearance(q) <= exact.clearance(q)[0] + 1e-9
    with pytest.raises(InvalidArgument, match="spheres"):
        ObstacleTerm([box], capacity=1, spheres="capsules")
    with pytest.raises(InvalidArgument, match="clearance_spheres='file'"):
        ObstacleSlots(load_robot("planar2"), [box], spheres="file")
    with pytest.raises(InvalidArgument, match="clearance_spheres needs clearance_margin"):
        obstacle_slots(panda, None, None, "file")
    assert ObstacleTermConfig(type="obstacle", spheres="file").kwargs()["spheres"] == "file"
    mpc = MPCConfig.model_validate(
        {"type": "mpc", "clearance_margin": 0.02, "clearance_spheres": "file"}
    )
    assert mpc.kwargs()["clearance_spheres"] == "file"
