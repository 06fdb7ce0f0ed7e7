"""A cheap check that an obstacle is not placed inside the robot at its start.

At the start configuration a config names (``reference.q_start``, ``synergies.q0`` or
``params.q0``), the robot's skeleton (every joint's origin and `POINTS_PER_LINK` points
on the segment to its parent's) is tested against every obstacle with
`geosyn.world.signed_distance`. A point deeper than `DEPTH` inside an obstacle means the
robot starts inside it: the metric's clearance, the planner and MuJoCo's contacts are
then meaningless, so the config is refused. The skeleton is a lower bound of the robot's
volume: an obstacle only touching the links' surfaces passes (the simulation reports
contacts), but one that swallows a joint is caught at no cost (no meshes, no spheres).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pinocchio as pin

from geosyn.experiments.run.scene import build_obstacles, mjcf_obstacles, obstacle_field
from geosyn.experiments.schema import ExperimentConfig
from geosyn.robots import Robot
from geosyn.world import MjcfObstacles, signed_distance

#: Points per link on the segment from a joint's origin to its parent joint's origin.
POINTS_PER_LINK = 5
#: Depth inside an obstacle [m] from which a skeleton point counts as inside (a floor
#: through the base's origin, or a joint origin on a surface, is not "inside").
DEPTH = 1e-3


def start_configuration(cfg: ExperimentConfig) -> tuple[str, np.ndarray] | None:
    """The start configuration a config names, with its field path (None if none)."""
    ref, syn = cfg.reference, cfg.synergies
    q_start = getattr(ref, "q_start", None)  # a stance_synergy reference has none
    if q_start is not None:
        return "reference.q_start", np.asarray(q_start, dtype=np.float64)
    q0_syn = getattr(syn, "q0", None)
    if q0_syn is not None:
        return "synergies.q0", np.asarray(q0_syn, dtype=np.float64)
    q0 = cfg.params.get("q0") if isinstance(cfg.params, dict) else None
    if isinstance(q0, list) and all(isinstance(x, (int, float)) for x in q0):
        return "params.q0", np.asarray(q0, dtype=np.float64)
    return None


def skeleton_points(robot: Robot, q: np.ndarray) -> np.ndarray:
    """(P, 3) world points [m] on the robot's skeleton at ``q`` (see the module doc)."""
    model = robot.model
    data = model.createData()
    pin.forwardKinematics(model, data, q)
    points = []
    for j in range(1, model.njoints):
        here = data.oMi[j].translation
        parent = data.oMi[model.parents[j]].translation
        for s in np.linspace(0.0, 1.0, POINTS_PER_LINK):
            points.append((1.0 - s) * parent + s * here)
    return np.asarray(points, dtype=np.float64).reshape(-1, 3)


def start_inside_errors(cfg: ExperimentConfig, robot: Any) -> list[tuple[str, str]]:
    """``(scene.obstacles.<i>, reason)`` (or ``scene.mjcf (geom ...)``) for an obstacle the
    robot starts inside."""
    start = start_configuration(cfg)
    if start is None or not cfg.scene.has_obstacles:
        return []
    field, q = start
    if q.shape != (robot.model.nq,) or not np.all(np.isfinite(q)):
        return []  # another check reports it
    points = skeleton_points(robot, q)
    file = mjcf_obstacles(cfg)
    for i, shape in enumerate(build_obstacles(cfg, file)):
        depth = -float(np.min(signed_distance(shape, points)))
        if depth > DEPTH:
            where = obstacle_field(cfg, i, file)
            return [
                (
                    where,
                    f"the robot starts inside this {type(shape).__name__.lower()}: at {field}"
                    f" its skeleton reaches {depth:.3g} m deep into it (allowed: at most"
                    f" {DEPTH:g} m); move the obstacle or the start configuration"
                    + (_robot_in_file(file) if file and i >= len(cfg.scene.obstacles) else ""),
                )
            ]
    return []


def _robot_in_file(file: MjcfObstacles) -> str:
    """A hint when the scene file also holds moving bodies: a robot in it has its fixed
    base read as a static geom, an obstacle round the robot's own base."""
    if not file.moving:
        return ""
    return (f"; the file also holds {len(file.moving)} geom(s) on moving bodies (e.g. "
            f"{file.moving[0]!r}): if it includes the robot, its fixed base is read as an "
            "obstacle; give scene.mjcf a file with the scene only")  # fmt: skip


__all__ = [
    "DEPTH",
    "POINTS_PER_LINK",
    "skeleton_points",
    "start_configuration",
    "start_inside_errors",
]
