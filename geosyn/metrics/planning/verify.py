"""The planner's collision geometry and the exact verification of its plans.

`planning_geometry` chooses what `Planner` constrains (spheres fitted to the robot file's
own collision meshes, `geosyn.robots.collision_spheres`, unless the user gives spheres)
and what it verifies against (`geosyn.world.exact_clearance.ExactClearance`: coal
distances to the file's meshes and primitives). `exact_check` verifies one path; a plan
that fails it is solved again with a sphere margin larger by the penetration plus
`REPAIR_STEP` (and more constrained points), or refused: never returned as free.
`deciding_clearance` says which clearance decides: the exact one, and the user's spheres
as well when given (they may stand beyond the file's geometry: a held object).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from geosyn.metrics.base import Metric
from geosyn.metrics.geodesic.collocation_parts import CollocationResult
from geosyn.metrics.planning.errors import InCollision, OutsideJointLimits
from geosyn.metrics.planning.exact_path import PathAids, path_clearance
from geosyn.metrics.planning.relax import OUTSIDE_TOL
from geosyn.metrics.shaping.obstacle import ObstacleTerm
from geosyn.robots.errors import RobotFileError
from geosyn.robots.robot import CollisionSphere, Robot
from geosyn.world.exact_clearance import ExactClearance, PathClearance
from geosyn.world.shapes import Shape

__all__ = [
    "LIMIT_TOL",
    "REPAIR_STEP",
    "check_end",
    "deciding_clearance",
    "exact_check",
    "feasible_result",
    "outside_limits",
    "planning_geometry",
]

LIMIT_TOL = OUTSIDE_TOL
"""Distance [rad] beyond a joint limit that a sample of a plan (or a query's end) may
lie (an NLP's bound tolerance), no more: `relax.OUTSIDE_TOL`, the relaxation's own, so
that a path it accepts within the limits is within them here too."""

REPAIR_STEP = 0.005
"""Added to the sphere margin [m], beyond the exact penetration, when a plan fails the
exact check and is solved again."""


def planning_geometry(
    robot: Robot, spheres: Sequence[CollisionSphere] | None
) -> tuple[tuple[CollisionSphere, ...], ExactClearance | None, str]:
    """The spheres the planner constrains, the exact checker (None without file
    geometry) and a note for the plans' ``attempts`` ("" when nothing is to be said).

    Args:
        robot: the robot.
        spheres: the user's spheres, or None for the file's fitted spheres (those on
            the fixed base left out).
    """
    try:
        exact: ExactClearance | None = ExactClearance(robot)
    except RobotFileError as err:
        exact = None
        why = str(err)
    if spheres is not None:
        note = "" if exact else f"plans checked on the given spheres only ({why})"
        return tuple(spheres), exact, note
    if exact is None:
        return (
            robot.collision_spheres(),
            None,
            (f"plans checked on the robot's capsule spheres only ({why})"),
        )
    from geosyn.robots.collision_spheres import file_spheres

    return file_spheres(robot).moving, exact, ""


def deciding_clearance(
    exact: PathClearance | None, spheres: float, given: bool, floor: float
) -> tuple[float, str]:
    """(clearance [m] that decides whether a path passes (>= 0), what measured it).

    Args:
        exact: the path's exact check (NaN clearance: not finished, the path does not
            pass), or None without file geometry (the spheres decide).
        spheres: the path's smallest sphere clearance [m] (the planner's fine check).
        given: whether the spheres were given by the user (`Planner.given_spheres`):
            then they must keep clear as well as the file's geometry, down to ``floor``.
        floor: the given spheres' clearance [m] allowed, <= 0 (the lower of 0 and their
            clearance at the query's ends, which the exact check admitted).
    """
    if exact is None:
        return spheres, "the fine check"
    if given and spheres - floor < exact.clearance:
        return spheres - floor, "the given spheres"
    return exact.clearance, f"the exact check ({exact.link})"


def exact_check(
    exact: ExactClearance | None,
    path: np.ndarray,
    obstacles: Sequence[Shape],
    resolution: float,
    deadline: float = math.inf,
    aids: PathAids | None = None,
) -> PathClearance:
    """The smallest exact clearance of ``path`` (T, n) [rad] to ``obstacles`` (NaN
    clearance without an exact checker, or when ``deadline`` [s, perf_counter] passes;
    batched: `geosyn.metrics.planning.exact_path`, faster with its ``aids``)."""
    if exact is None:
        return PathClearance(math.nan, 0.0, "", -1, 0, resolution)
    exact.set_obstacles(obstacles)
    return path_clearance(exact, path, resolution, deadline, aids)


def _beyond(robot: Robot, Q: np.ndarray) -> np.ndarray:
    """(T, n) how far [rad] each joint of the configurations ``Q`` (T, n) lies beyond its
    limits (positive outside, negative inside)."""
    return np.maximum(robot.q_min - Q, Q - robot.q_max)


def outside_limits(robot: Robot, path: np.ndarray) -> str:
    """Why ``path`` (T, n) [rad], linear between its samples, leaves the joint limits
    (the sample and joint farthest beyond them, by more than `LIMIT_TOL`), or "" when it
    keeps them (the limits are a box: a segment between two samples inside is inside)."""
    path = np.atleast_2d(np.asarray(path, dtype=float))
    out = _beyond(robot, path)
    if not np.any(out > LIMIT_TOL):  # NaN samples are not counted here
        return ""
    k, j = np.unravel_index(int(np.nanargmax(out)), out.shape)
    return (
        f"sample {k} has joint {j} ({robot.joint_names[j]}) = {path[k, j]:.4f} rad, outside "
        f"its limits [{robot.q_min[j]:.4f}, {robot.q_max[j]:.4f}] rad"
    )


def check_end(
    robot: Robot, term: ObstacleTerm, exact: ExactClearance | None, q: np.ndarray, which: str
) -> None:
    """Raise if ``q`` (n,) [rad], the ``which`` end of a query, is outside the joint
    limits or in collision (the exact geometry decides when there is one, else the
    spheres of ``term``, whose obstacles are set)."""
    bad = np.flatnonzero(_beyond(robot, q) > LIMIT_TOL)
    if bad.size:
        j = int(bad[0])
        raise OutsideJointLimits(
            f"{which}: joint {j} ({robot.joint_names[j]}) = {q[j]:.4f} rad is outside "
            f"its limits [{robot.q_min[j]:.4f}, {robot.q_max[j]:.4f}] rad",
            which,
            tuple(int(i) for i in bad),
        )
    if not term.obstacles:
        return
    if exact is not None:  # the robot's own geometry decides
        exact.set_obstacles(term.obstacles)
        d, link, hit = exact.clearance(q)
        if d < 0.0:
            raise InCollision(
                f"{which} is in collision: link {link!r} of the robot's own collision "
                f"geometry is {-d:.4f} m inside obstacle {hit} ({term.obstacles[hit]!r}); "
                f"move the {which} configuration or the obstacle", which, hit, -1, link, d,
            )  # fmt: skip
        return
    c = term.clearances(q)  # (spheres, obstacles)
    s, o = np.unravel_index(int(np.argmin(c)), c.shape)
    if c[s, o] < 0.0:
        sphere = term.spheres[s]
        raise InCollision(
            f"{which} is in collision: robot sphere {s} (on joint {sphere.joint!r}, radius "
            f"{sphere.radius:g} m) is {-c[s, o]:.4f} m inside obstacle {o} "
            f"({term.obstacles[o]!r}); move the {which} configuration or the "
            "obstacle, or use a robot sphere model that fits the links more tightly",
            which, int(o), int(s), sphere.joint, float(c[s, o]),
        )  # fmt: skip


def feasible_result(metric: Metric, path: np.ndarray, how: str) -> CollocationResult:
    """A `CollocationResult` of kind ``"feasible"`` for a path (T, n) [rad] that is not a
    converged solve (an interrupted IPOPT iterate, a coarse or sampled seed): its energy
    by the midpoint rule on [0, 1], ``how`` in its message."""
    path = np.asarray(path, dtype=float)
    T = len(path)
    dq = np.diff(path, axis=0)
    mid = 0.5 * (path[1:] + path[:-1])
    energy = float(sum(d @ metric.G(m) @ d for d, m in zip(dq, mid, strict=True))) * (T - 1)
    t = np.linspace(0.0, 1.0, T)
    return CollocationResult(
        t, path, "feasible", energy, path, (T - 1) * (path[1] - path[0]), math.nan, 0,
        math.nan, math.nan, 0, "not converged", 0.0,
        f"collision-free, not of minimum energy (the budget ended first): {how}",
    )  # fmt: skip
