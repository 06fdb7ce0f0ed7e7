"""A procedure's task as segments inside the joint limits and clear of the scene's obstacles.

- `task_sequence`: the configurations that bring a frame to Cartesian goals, one
  segment after the other, by synergy reaching (`reach_sequence`: every sample inside the
  joint limits); a segment with no motion inside the limits, or whose goal is missed by
  more than a tolerance, raises `SegmentFailed` naming it.
- `avoiding_sequence`: between those configurations, the geodesic of each segment's
  metric, kept when its clearance to the scene's obstacles, measured on the robot file's
  own collision geometry (`geosyn.world.exact_clearance`), is at least `CLEARANCE`;
  otherwise the planner's minimum-energy collision-free path on the same metric
  (`geosyn.metrics.planning.Planner`, verified on the same geometry). A segment the
  planner cannot join raises `SegmentFailed` naming it, its start and goal and why (an
  end outside the limits or in collision, no path within the budget). An object held
  during a segment (a `geosyn.world.Payload` ball) counts as part of the robot: its
  clearance is checked with the robot's, and the planner constrains it as one more sphere.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
import pinocchio as pin

from geosyn.core.types import Matrix, Vector
from geosyn.experiments.errors import ProcedureFailed
from geosyn.metrics import Metric
from geosyn.metrics.planning import InCollision, NoPathFound, OutsideJointLimits, Plan, Planner
from geosyn.robots import Robot
from geosyn.robots.collision_spheres import file_spheres
from geosyn.robots.errors import RobotFileError
from geosyn.robots.robot import CollisionSphere
from geosyn.synergies import GeodesicSynergy, ReachOutsideLimits
from geosyn.synergies.errors import SynergyNotConverged
from geosyn.synergies.sequence import (
    SequenceSegment,
    SynergySequence,
    geodesic_segment,
    reach_sequence,
)
from geosyn.synergies.synergy import checked_log
from geosyn.world import Payload, Shape
from geosyn.world.distance import signed_distance
from geosyn.world.exact_clearance import ExactClearance

#: Smallest exact clearance [m] for which a segment's geodesic is kept among obstacles.
CLEARANCE = 0.01
#: Joint-space resolution (max-norm) of the exact clearance checks [rad].
RESOLUTION = 0.005


class SegmentFailed(ProcedureFailed):
    """A segment of a task could not be made (its message says which, from where to
    where, and why).

    Attributes:
        index: the segment's index (0: the first motion).
        start: (n,) its start configuration [rad].
        goal: (n,) its goal configuration [rad], or (3,) the Cartesian target [m] when no
            configuration reaching it was found.
        reason: why, without the segment's description.
    """

    def __init__(self, index: int, where: str, start: Vector, goal: Vector, reason: str) -> None:
        super().__init__(f"{where}: {reason}")
        self.index = index
        self.start = np.asarray(start, dtype=np.float64)
        self.goal = np.asarray(goal, dtype=np.float64)
        self.reason = reason


class SegmentPath(NamedTuple):
    """How a segment's path was made.

    Attributes:
        kind: ``"geodesic"`` (the metric's geodesic, clear of the obstacles), a planner
            result kind (``"geodesic"``, ``"constrained"``, ``"feasible"``: see
            `geosyn.metrics.geodesic.collocation.CollocationResult`) or ``"straight"``.
        planned: whether the planner made it.
        clearance: smallest exact clearance of the path (and of a held ball) to the
            obstacles [m]; at least `ExactClearance`'s ``near`` (0.05 m) is reported as
            ``near``; inf without obstacles, NaN without the robot's file geometry.
        how: one line on what was done.
    """

    kind: str
    planned: bool
    clearance: float
    how: str


def _name(names: Sequence[str] | None, i: int) -> str:
    return f"segment {i}" + (f" ({names[i]})" if names is not None and i < len(names) else "")


def task_sequence(
    synergies: Sequence[GeodesicSynergy],
    targets: Matrix,
    frame: str,
    robot: Robot,
    durations: Sequence[float],
    *,
    steps: int,
    tol: float,
    names: Sequence[str] | None = None,
) -> SynergySequence:
    """`reach_sequence` to ``targets`` (K, 3) [m], each goal within ``tol`` [m].

    Raises:
        SegmentFailed: no motion inside the joint limits reaches a target, or the best
            one misses it by more than ``tol`` (the segment, its start and target named).
    """
    try:
        seq = reach_sequence(synergies, targets, frame, robot, durations, steps=steps)
    except ReachOutsideLimits as err:
        i = err.segment if err.segment is not None else 0
        start = np.full(robot.nq, np.nan) if err.q_start is None else err.q_start
        raise SegmentFailed(
            i, _name(names, i), start, targets[i],
            f"no synergy motion inside the joint limits reaches the target: {err}",
        ) from err  # fmt: skip
    for i, seg in enumerate(seq.segments):
        if not seg.reach_error <= tol:
            where = (
                f"{_name(names, i)} from q={np.round(seg.start, 4).tolist()} to target"
                f" {np.round(targets[i], 4).tolist()} m"
            )
            raise SegmentFailed(
                i, where, seg.start, targets[i],
                f"no synergy motion inside the joint limits reaches the target: the best"
                f" misses it by {seg.reach_error * 1e3:.3g} mm (tolerance {tol * 1e3:.3g} mm)",
            )  # fmt: skip
    return seq


def exact_checker(robot: Robot, obstacles: Sequence[Shape]) -> ExactClearance | None:
    """The exact clearance of ``robot``'s file geometry to ``obstacles`` (None without
    obstacles or without file geometry: the planner then decides, on its spheres)."""
    if not obstacles:
        return None
    try:
        exact = ExactClearance(robot)
    except RobotFileError:
        return None
    exact.set_obstacles(obstacles)
    return exact


def path_clearance(exact: ExactClearance | None, q: Matrix, obstacles: Sequence[Shape]) -> float:
    """Smallest exact clearance [m] along ``q`` (T, n), linear in between (inf without
    obstacles, NaN without an exact checker)."""
    if not obstacles:
        return math.inf
    if exact is None:
        return math.nan
    return float(exact.path_clearance(np.asarray(q), RESOLUTION).clearance)


def _densified(path: Matrix) -> Matrix:
    """``path`` (T, n) with linear points in between, at most `RESOLUTION` apart (max-norm)."""
    path = np.asarray(path, dtype=np.float64)
    pts = [path[:1]]
    for a, b in zip(path[:-1], path[1:], strict=True):
        k = max(1, math.ceil(float(np.abs(b - a).max()) / RESOLUTION))
        pts.append(a + (np.arange(1, k + 1)[:, None] / k) * (b - a))
    return np.vstack(pts)


def held_clearance(
    robot: Robot, held: Payload | None, q: Matrix, obstacles: Sequence[Shape]
) -> float:
    """Smallest clearance [m] of the ball ``held`` (carried by ``robot``) to ``obstacles``
    along ``q`` (T, n), linear in between, at most `RESOLUTION` apart (inf without a ball
    or obstacles)."""
    if held is None or not obstacles:
        return math.inf
    model, data = robot.model, robot.model.createData()
    fid = robot.frame_id(held.frame)
    com = np.asarray(held.com, dtype=np.float64)
    centres = []
    for qk in _densified(q):
        pin.framesForwardKinematics(model, data, qk)
        centres.append(data.oMf[fid].act(com))
    C = np.array(centres)
    return float(min(signed_distance(o, C).min() for o in obstacles)) - held.radius


def held_sphere(robot: Robot, held: Payload) -> CollisionSphere:
    """The held ball as a collision sphere of the joint that carries it."""
    frame = robot.model.frames[robot.frame_id(held.frame)]
    centre = frame.placement.act(np.asarray(held.com, dtype=np.float64))
    return CollisionSphere(
        str(robot.model.names[frame.parentJoint]),
        (float(centre[0]), float(centre[1]), float(centre[2])),
        float(held.radius),
    )


def planning_spheres(robot: Robot, held: Payload | None) -> tuple[CollisionSphere, ...] | None:
    """The planner's spheres: its default (None) without a held ball, else the spheres
    fitted to the robot file's geometry (those on the fixed base left out, as the
    planner's default) or the robot's capsule spheres, and the ball."""
    if held is None:
        return None
    try:
        spheres = file_spheres(robot).moving
    except RobotFileError:
        spheres = tuple(robot.collision_spheres())
    return (*spheres, held_sphere(robot, held))


def planned_segment(
    metric: Metric, plan: Plan, q0: Vector, t0: float, duration: float, steps: int
) -> SequenceSegment:
    """A planner's path as a segment from ``q0`` (n,) [rad] at ``t0`` [s] over ``duration`` [s].

    A geodesic plan is integrated again from its initial velocity (so the segment is the
    metric's geodesic, residual ~1e-10); any other path is the natural cubic spline
    through its collocation nodes, sampled ``steps + 1`` times uniformly (metric None:
    not a geodesic).
    """
    res = plan.result
    if res.kind == "geodesic":
        return geodesic_segment(metric, q0, np.asarray(res.v0), t0, duration, steps)
    nodes = np.asarray(res.nodes, dtype=np.float64)
    u = np.linspace(0.0, 1.0, len(nodes))
    from scipy.interpolate import CubicSpline  # heavy: imported where used

    spline = CubicSpline(u, nodes, axis=0, bc_type="natural")
    s = np.linspace(0.0, 1.0, steps + 1)
    q = spline(s)
    q[0], q[-1] = q0, nodes[-1]  # the ends exactly (the next segment starts there)
    return SequenceSegment(None, s, q, spline(s, 1), spline(s, 2), t0, duration)


def avoiding_sequence(
    metrics: Sequence[Metric],
    waypoints: Matrix,
    durations: Sequence[float],
    obstacles: Sequence[Shape],
    *,
    steps: int,
    budget: float,
    seed: int = 0,
    names: Sequence[str] | None = None,
    planners: dict[tuple[int, int], Planner] | None = None,
    held: Sequence[Payload | None] | None = None,
    geodesics: Sequence[SequenceSegment] | None = None,
) -> tuple[SynergySequence, list[SegmentPath]]:
    """Segments of ``metrics[i]`` from ``waypoints[i]`` to ``waypoints[i+1]`` clear of
    ``obstacles`` (see the module doc).

    Args:
        metrics: one metric with a robot per segment (K).
        waypoints: (K+1, n) configurations [rad].
        durations: (K,) traversal times [s].
        obstacles: the scene's obstacles.
        steps: RK4 steps of each geodesic (path samples - 1).
        budget: the planner's time budget per segment [s].
        seed: seed of the planner's sampling fallback (segment i uses ``seed + i``).
        names: a name per segment for the messages (``"pick -> via"``).
        planners: planners by ``(id(metric), id(held ball))``, reused and filled (one
            build per metric and ball).
        held: the ball held during each segment (None: nothing held), part of the robot
            for the clearances and the planner.
        geodesics: the geodesic of each segment when already known (e.g. a synergy
            combination's, `reach_sequence`), used when it starts where the segment does
            (1e-12 rad), else the log map's.

    Returns:
        (the sequence, how each segment's path was made).

    Raises:
        SegmentFailed: a segment that no geodesic nor planned path joins clear of the
            obstacles.
    """
    robot: Robot = metrics[0].robot  # type: ignore[attr-defined]
    exact = exact_checker(robot, obstacles)
    planners = {} if planners is None else planners
    segs: list[SequenceSegment] = []
    paths: list[SegmentPath] = []
    q, t = np.asarray(waypoints[0], dtype=np.float64), 0.0
    held = [None] * len(metrics) if held is None else list(held)

    def clearance_of(q: Matrix, ball: Payload | None) -> float:
        exact_c = path_clearance(exact, q, obstacles)
        return min(exact_c, held_clearance(robot, ball, q, obstacles))

    for i, metric in enumerate(metrics):
        goal = np.asarray(waypoints[i + 1], dtype=np.float64)
        where = (
            f"{_name(names, i)} from q={np.round(q, 4).tolist()} to q={np.round(goal, 4).tolist()}"
        )
        seg, why = None, "no geodesic found"
        known = None if geodesics is None else geodesics[i]
        if known is not None and float(np.max(np.abs(known.q[0] - q))) <= 1e-12:
            seg = dataclasses.replace(known, t0=t, duration=float(durations[i]))
        else:
            try:
                v0 = checked_log(metric, q, goal, steps=steps)
                seg = geodesic_segment(metric, q, v0, t, float(durations[i]), steps)
            except SynergyNotConverged as err:
                why = f"no geodesic found ({err})"
        clearance = math.nan if seg is None else clearance_of(seg.q, held[i])
        if seg is not None and (not obstacles or clearance >= CLEARANCE):
            paths.append(SegmentPath("geodesic", False, clearance, "the geodesic"))
        else:
            if seg is not None:
                why = f"the geodesic's clearance is {clearance:.4g} m (< {CLEARANCE:g} m)"
            key = (id(metric), id(held[i]))
            if key not in planners:
                spheres = planning_spheres(robot, held[i])
                count = max(1, len(obstacles))
                planners[key] = Planner(metric, capacity=count, spheres=spheres, prebuild=count)
            plan = _plan(planners[key], q, goal, obstacles, budget, seed + i, i, where)
            seg = planned_segment(metric, plan, q, t, float(durations[i]), steps)
            clearance = clearance_of(seg.q, held[i])
            if clearance < 0.0:
                raise SegmentFailed(
                    i, where, q, goal,
                    f"contact: the planned path, sampled, passes {-clearance:.4g} m inside an"
                    " obstacle (the planner verified its nodes, linear in between)",
                )  # fmt: skip
            how = f"planned ({why}): {plan.result.kind} path from the {plan.seed}"
            paths.append(SegmentPath(plan.result.kind, True, clearance, how))
        segs.append(seg)
        q, t = seg.q[-1], t + float(durations[i])
    return SynergySequence(segs), paths


def _plan(
    planner: Planner,
    q0: Vector,
    q1: Vector,
    obstacles: Sequence[Shape],
    budget: float,
    seed: int,
    index: int,
    where: str,
) -> Plan:
    """The planner's path from ``q0`` to ``q1``, its failures as `SegmentFailed`."""
    try:
        return planner.plan(q0, q1, obstacles, budget=budget, seed=seed)
    except OutsideJointLimits as err:
        reason = f"the {err.which} is outside the joint limits: {err}"
        raise SegmentFailed(index, where, q0, q1, reason) from err
    except InCollision as err:
        reason = f"contact: {err}"
        raise SegmentFailed(index, where, q0, q1, reason) from err
    except NoPathFound as err:
        reason = f"the planner found no path: {err}"
        raise SegmentFailed(index, where, q0, q1, reason) from err


__all__ = [
    "CLEARANCE",
    "RESOLUTION",
    "SegmentFailed",
    "SegmentPath",
    "avoiding_sequence",
    "exact_checker",
    "held_clearance",
    "held_sphere",
    "path_clearance",
    "planned_segment",
    "task_sequence",
]
