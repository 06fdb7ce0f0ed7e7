"""Config sections to library objects (experiments/run/build.py)."""

from __future__ import annotations

import numpy as np

from geosyn.experiments.config.loader import builtin_names, load_config
from geosyn.experiments.run.build import (
    SIM_FIELDS,
    build_disturbances,
    build_metric,
    build_obstacles,
    build_payloads,
    build_robot,
)
from geosyn.metrics.shaping import LoadTerm
from geosyn.sim import Disturbance
from geosyn.world import Box, Payload
from geosyn.world.shapes import SHAPES


def _config_with(obstacle: str):
    """The built-in obstacle experiment with its obstacles replaced (a --set override)."""
    cfg, _ = load_config("panda_obstacle_shaping", [f"scene.obstacles=[{obstacle}]"])
    return cfg


def test_box_rpy_gives_the_urdf_rotation() -> None:
    """rpy = (0, 0, pi/2): a quarter turn about z, R = [[0, -1, 0], [1, 0, 0], [0, 0, 1]]."""
    cfg = _config_with(
        {
            "type": "box",
            "center": [0.5, 0, 0.3],
            "half_extents": [0.1, 0.2, 0.3],
            "rpy": [0, 0, np.pi / 2],
        }
    )
    (box,) = build_obstacles(cfg)
    assert isinstance(box, Box)
    expected = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    np.testing.assert_allclose(np.asarray(box.rotation), expected, atol=1e-15)


def test_box_without_rpy_is_axis_aligned() -> None:
    cfg = _config_with("{type: box, center: [0.5, 0, 0.3], half_extents: [0.1, 0.2, 0.3]}")
    (box,) = build_obstacles(cfg)
    np.testing.assert_array_equal(np.asarray(box.rotation), np.eye(3))


def test_payload_load_term_is_the_payloads_ball() -> None:
    """The load term of a scene payload is its solid ball (2/5 m r^2), exactly."""
    cfg, _ = load_config("panda_payload_shaping")
    robot = build_robot(cfg)
    (payload,) = build_payloads(cfg, robot)
    p = cfg.scene.payloads[0]
    assert payload == Payload(robot.ee_frame, p.mass, tuple(p.offset), radius=p.radius, name=p.name)
    (term,) = build_metric(cfg, robot).terms  # type: ignore[attr-defined]
    inertia = np.eye(3) * 0.4 * p.mass * p.radius**2
    ref = LoadTerm(robot.ee_frame, p.mass, p.offset, inertia)
    np.testing.assert_array_equal(term.spatial_inertia, ref.spatial_inertia)


def test_every_builtin_scene_builds() -> None:
    for name in builtin_names():
        cfg, _ = load_config(name)
        robot = build_robot(cfg)
        assert all(isinstance(p, Payload) for p in build_payloads(cfg, robot))
        assert all(isinstance(o, SHAPES) for o in build_obstacles(cfg))
        assert all(isinstance(d, Disturbance) for d in build_disturbances(cfg))


def test_saved_fields_are_the_per_tick_log() -> None:
    """results.npz keeps these arrays of a run (their names are the file format)."""
    assert SIM_FIELDS == (
        "t",
        "q",
        "v",
        "tau_applied",
        "q_ref",
        "tracking_error",
        "kinetic_energy",
        "power",
        "effort",
        "saturated",
        "clearance",
        "contact_force",
        "payload_mass",
        "fallback_used",
    )


class _Still:
    """Zero torque: the arm only sags under gravity during the few ticks of the test."""

    def reset(self, q0: np.ndarray, v0: np.ndarray, t0: float) -> None:
        pass

    def compute(self, t: float, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        return np.zeros(len(q))


def test_scene_contact_makes_the_simulated_obstacles_collide() -> None:
    """``scene.contact`` reaches `Simulation`: a sphere around the hand at the start pushes
    on the arm (MuJoCo's contact solver reports a normal force) only when it is true."""
    from geosyn.experiments.run.build import simulate
    from geosyn.robots.kinematics import frame_position

    base, _ = load_config("panda_obstacle_shaping")
    robot = build_robot(base)
    assert base.reference is not None
    q0 = np.array(base.reference.q_start)
    hand = frame_position(robot, q0, robot.ee_frame)
    sphere = f"{{type: sphere, center: {hand.tolist()}, radius: 0.05}}"
    forces = {}
    for contact in (True, False):
        cfg, _ = load_config(
            "panda_obstacle_shaping",
            [f"scene.obstacles=[{sphere}]", f"scene.contact={str(contact).lower()}"],
        )
        res = simulate(cfg, robot, _Still(), None, q0, duration=0.01)
        assert res.status == "ok"
        forces[contact] = res.contact_force
    assert forces[True].max() > 1.0  # [N]
    # every tick, the first included, logs the force solved for its own contacts (not a
    # stale or unset constraint force of the step before)
    assert np.all(np.isfinite(forces[True])) and forces[True][0] > 1.0
    assert np.all(forces[False] == 0.0)  # visual only: nothing pushes
