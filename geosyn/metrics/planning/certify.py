"""`certified_clearance`: a lower bound of a path's clearance that holds between its
checked configurations too, not only at them.

The exact check (`geosyn.metrics.planning.exact_path.path_clearance`) measures the robot
file's collision geometry at configurations at most ``resolution`` apart; between two of
them a point of the robot can move by up to several centimetres per 5 mrad (the Panda's
fingertips: about 4 m per rad of all seven joints together). This module bounds that
motion and turns the sampled clearances into a certificate (conservative advancement,
Schwarzer, Saha and Latombe, IEEE T-RO 2005):

- a point ``x`` of a collision object carried by joint ``k`` moves, per unit speed of a
  revolute joint ``j`` that supports ``k``, by ``|a_j x (x - o_j)| <= |x - o_j|``,
  at most ``w[k, j]``: the lengths of the joint placements from ``j`` to ``k`` plus the
  object's bounding ball seen from ``k``'s origin (the triangle inequality, valid at
  every configuration); per unit of a prismatic joint, by 1;
- along a linear joint segment ``a -> b`` every point of object ``k`` then travels at
  most ``D_k = sum_j w[k, j] |b_j - a_j|`` [m], and a signed distance is 1-Lipschitz in
  the motion of the robot's points, so the smallest clearance on the segment is at least
  ``(c(a) + c(b) - D) / 2`` with ``D = max_k D_k``;
- a segment whose bound is below ``target`` is halved (its midpoint measured), to at
  most `MAX_HALVINGS` levels; a measured clearance below zero is a collision found, and
  no segment is halved after it (the others are only bounded).

The certificate is the smallest segment bound over the path (>= ``target`` everywhere it
could be shown, lower where the halvings ran out or a collision was measured).
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from geosyn.core.errors import InvalidArgument
from geosyn.core.validation import check_float, check_positive, check_real_array
from geosyn.metrics.planning.errors import NoPathFound
from geosyn.metrics.planning.exact_path import PathAids, configuration_clearances
from geosyn.metrics.planning.plan import Plan
from geosyn.world.exact_clearance import ExactClearance, checked_configurations
from geosyn.world.shapes import Shape

if TYPE_CHECKING:
    from geosyn.metrics.planning.planner import Planner
    from geosyn.robots.robot import Robot

__all__ = [
    "MAX_HALVINGS",
    "CertifiedClearance",
    "certified_clearance",
    "certified_plan",
    "displacement_weights",
    "joint_weights",
    "planner_certificate",
]

MAX_HALVINGS = 12
"""Most halvings of one checked segment (a 5 mrad step down to ~1.2 urad)."""


class CertifiedClearance(NamedTuple):
    """A path's clearance certified between its checked configurations.

    Attributes:
        bound: lower bound [m] of the exact clearance at every point of the linear path
            (negative when a collision was measured, or where the halvings ran out).
        sampled: smallest exact clearance measured [m] (at the checked configurations
            and the midpoints the halvings added).
        measured: configurations measured (the checked ones plus the midpoints).
        halved: segments halved.
        collision: whether a measured configuration penetrates an obstacle.
    """

    bound: float
    sampled: float
    measured: int
    halved: int
    collision: bool


def displacement_weights(exact: ExactClearance) -> np.ndarray:
    """(L, n) ``w[k, j]``: the largest speed [m/s] of any point of collision object
    ``k`` of ``exact`` per unit speed of joint ``j`` [rad/s or m/s], at every
    configuration (module docstring; 0 for an object not carried by ``j``).

    Raises:
        InvalidArgument: a joint other than a one-axis revolute or prismatic joint, or a
            model whose configuration is not its velocity (``nq != nv``).
    """
    return joint_weights(exact.robot, exact.joints, exact.balls)


def joint_weights(robot: Robot, joints: Sequence[int],
                  balls: Sequence[tuple[np.ndarray, float]]) -> np.ndarray:  # fmt: skip
    """`displacement_weights` of objects carried by the Pinocchio joints ``joints`` (L,)
    (0: the world) with bounding balls ``balls`` ((3,) centre in the joint's frame [m],
    radius [m]): (L, n) [m/rad or m/m].

    Raises:
        InvalidArgument: as `displacement_weights`.
    """
    model = robot.model
    if model.nq != model.nv:
        raise InvalidArgument(
            f"robot: the certificate needs nq == nv (one coordinate per joint), got "
            f"nq={model.nq}, nv={model.nv}"
        )
    kinds = {}
    for j in range(1, model.njoints):
        name = model.joints[j].shortname()
        if name in ("JointModelRX", "JointModelRY", "JointModelRZ", "JointModelRevoluteUnaligned"):
            kinds[j] = "revolute"
        elif name in ("JointModelPX", "JointModelPY", "JointModelPZ", "JointModelPrismaticUnaligned"):  # fmt: skip
            kinds[j] = "prismatic"
        else:
            raise InvalidArgument(
                f"robot: joint {model.names[j]!r} is {name}; the certificate allows one-axis "
                "revolute and prismatic joints"
            )
    w = np.zeros((len(joints), model.nv))
    for k, (joint, (centre, radius)) in enumerate(zip(joints, balls, strict=True)):
        reach = float(np.linalg.norm(centre)) + radius  # the object, from its joint's origin
        j = joint
        while j > 0:  # up the chain: reach is now a bound of |x - o_j|
            v = model.joints[j].idx_v
            w[k, v] = reach if kinds[j] == "revolute" else 1.0
            reach += float(np.linalg.norm(model.jointPlacements[j].translation))
            j = model.parents[j]
    return w


def certified_clearance(
    exact: ExactClearance,
    path: np.ndarray,
    resolution: float,
    *,
    target: float = 0.0,
    aids: PathAids | None = None,
) -> CertifiedClearance:
    """The clearance of ``path`` (T, n) [rad], linear between its samples, certified
    between the configurations checked ``resolution`` [rad] apart (joint max-norm), to
    the obstacles set on ``exact`` (module docstring).

    Args:
        exact: the robot's exact clearance, its obstacles set.
        path: (T, n) joint path [rad].
        resolution: the check's step (`checked_configurations`) [rad], > 0.
        target: clearance [m] that a segment's bound should reach before it is no longer
            halved (0: collision-free), >= 0.
        aids: as in `configuration_clearances` (same values, faster).

    Returns:
        The certificate; ``bound`` is inf without obstacles. Costs one
        `configuration_clearances` per checked configuration and per midpoint added.
    """
    resolution = check_positive(resolution, "resolution", "rad")
    target = check_float(target, "target", low=0.0)
    path = np.atleast_2d(check_real_array(path, "path"))
    n = exact.robot.model.nq
    if path.ndim != 2 or path.shape[1] != n or not np.all(np.isfinite(path)):
        raise InvalidArgument(
            f"path: a (T, {n}) array of finite joint positions [rad], got shape {path.shape}"
            + ("" if np.all(np.isfinite(path)) else " with non-finite entries")
        )
    Q = checked_configurations(path, resolution)
    if not exact.obstacles:
        return CertifiedClearance(math.inf, math.inf, len(Q), 0, False)
    w = displacement_weights(exact)
    c = configuration_clearances(exact, Q, aids)
    measured, halved, sampled = len(Q), 0, float(c.min())
    bound = math.inf
    stack = [(Q[i], Q[i + 1], c[i], c[i + 1], 0) for i in range(len(Q) - 1)]
    while stack:
        a, b, ca, cb, depth = stack.pop()
        reach = float((w @ np.abs(b - a)).max())
        seg = min(ca, cb, 0.5 * (ca + cb - reach))
        if seg >= target or sampled < 0.0 or depth >= MAX_HALVINGS:
            bound = min(bound, seg)  # after a collision, the rest is only bounded
            continue
        mid = 0.5 * (a + b)
        cm = float(configuration_clearances(exact, mid[None], aids)[0])
        measured, halved, sampled = measured + 1, halved + 1, min(sampled, cm)
        stack += [(a, mid, ca, cm, depth + 1), (mid, b, cm, cb, depth + 1)]
    if len(Q) == 1:
        bound = float(c[0])
    return CertifiedClearance(bound, sampled, measured, halved, sampled < 0.0)


def planner_certificate(planner: Planner, path: np.ndarray, obstacles: Sequence[Shape],
                        target: float = 0.0) -> CertifiedClearance:  # fmt: skip
    """`certified_clearance` of ``path`` (T, n) [rad] to ``obstacles`` on ``planner``'s
    exact geometry at its ``exact_resolution`` (`Planner.certify`)."""
    if planner.exact is None:
        raise InvalidArgument(
            f"certify: robot {planner.robot.name!r} has no file collision geometry "
            f"({planner.geometry_note})"
        )
    obstacles = tuple(obstacles)
    planner.exact.set_obstacles(obstacles)
    planner.sampling.set_obstacles(obstacles)  # the aids' sphere bounds
    return certified_clearance(planner.exact, path, planner.exact_resolution, target=target,
                               aids=planner.sampling.aids)  # fmt: skip


def certified_plan(planner: Planner, plan: Plan, obstacles: Sequence[Shape],
                   budget: float) -> Plan:  # fmt: skip
    """``plan`` (of a query of ``budget`` [s]) with its ``certified_clearance`` and a line
    in its ``attempts`` (a robot without file geometry: NaN, and the line says why).

    Raises:
        NoPathFound: a collision measured between the checked configurations (the
            plan is refused, never returned as free).
    """
    if planner.exact is None:
        why = f"not certified: no file collision geometry ({planner.geometry_note})"
        return plan._replace(attempts=(*plan.attempts, why))
    t0 = time.perf_counter()
    cert = planner_certificate(planner, plan.q, obstacles)
    line = (f"certified between its checked configurations: clearance >= {cert.bound:.4f} m "
            f"({cert.measured} configurations measured, {cert.halved} segments halved, "
            f"{time.perf_counter() - t0:.3f} s)")  # fmt: skip
    if cert.collision:
        raise NoPathFound(
            f"the plan collides between its checked configurations (exact clearance "
            f"{cert.sampled:.4f} m measured there): refused",
            budget=budget, elapsed=plan.wall_time, attempts=(*plan.attempts, line),
        )  # fmt: skip
    return plan._replace(certified_clearance=cert.bound, attempts=(*plan.attempts, line))
