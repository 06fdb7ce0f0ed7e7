"""End-effector goals: a frame's position or pose, with tolerances, as a planning goal.

`EndEffectorGoal` says where a frame of the robot should be; `ik_solutions` finds joint
configurations that put it there: damped least squares on Pinocchio's frame Jacobian
(position error, or the SE(3) log error with its Jacobian ``Jlog6``) in the planner's
metric at the start, each step projected on the joint limits, started from the query's
start (then drawn towards it in the task's null space: a redundant arm's solution lies
near the least straight-line energy on its branch) and then from seeded random
configurations inside the limits; it keeps distinct solutions (>= `DISTINCT` rad apart,
max-norm) that a caller's check accepts. `plan_to_goal` asks the planner for them (its
check: within the joint limits, clear of the scene on the robot's own collision geometry
as the planner's end check decides, and of itself on the file's self-collision pairs),
plans to them in order of straight-line energy from the start and keeps the lowest-energy
plan. Budget rule: IK takes at most `IK_SHARE` of the budget; each IK solution's plan gets
half the time left (the last one all of it), and a further solution is tried only while
the time left is at least the time the first plan took. The plans to IK solutions skip
the planner's other-seed alternatives (``alternatives``): the IK solutions are the
alternatives here.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, NamedTuple

import numpy as np
import pinocchio as pin

from geosyn.core.errors import InvalidArgument
from geosyn.core.validation import check_int, check_positive, check_real_array, check_vec3
from geosyn.metrics.planning.errors import GoalUnreachable, NoPathFound, PlanningError
from geosyn.metrics.planning.plan import Plan
from geosyn.robots.robot import Robot
from geosyn.world.shapes import Shape

if TYPE_CHECKING:
    from geosyn.metrics.planning.planner import Planner

__all__ = [
    "DISTINCT",
    "IK_SHARE",
    "NULL_GAIN",
    "NULL_STEP",
    "TIGHTEN",
    "EndEffectorGoal",
    "IKSolution",
    "ik_solutions",
    "plan_to_goal",
]

DISTINCT = 0.1
"""Two IK solutions closer than this (max-norm) [rad] count as one."""

IK_SHARE = 0.25
"""Largest share of a query's budget spent on inverse kinematics."""

TIGHTEN = 0.01
"""IK iterates until its errors are within this fraction of the goal's tolerances (a
solution is accepted within the tolerances themselves)."""

NULL_GAIN = 0.5
"""Fraction of the way to the reference configuration taken per IK step, in the task's
null space."""

NULL_STEP = 1e-4
"""IK stops once its null-space step is below this (max-norm) [rad]."""


@dataclass(frozen=True)
class EndEffectorGoal:
    """Where a frame of the robot should be: a position, optionally an orientation.

    Args:
        position: (3,) world position of the frame's origin [m].
        rotation: (3, 3) world orientation of the frame, or None (position only).
        frame: frame name of the robot's model; None: the robot's ``ee_frame``.
        position_tolerance: largest distance of the frame's origin from ``position``
            [m], > 0.
        orientation_tolerance: largest rotation angle between the frame's orientation
            and ``rotation`` [rad], > 0 (unused without ``rotation``).
        solutions: distinct IK solutions to plan to, >= 1 (the lowest-energy plan kept).
    """

    position: tuple[float, float, float]
    rotation: tuple[tuple[float, float, float], ...] | None = None
    frame: str | None = None
    position_tolerance: float = 1e-3
    orientation_tolerance: float = 1e-2
    solutions: int = 4

    def __post_init__(self) -> None:
        set_ = object.__setattr__
        set_(self, "position", check_vec3(self.position, "position"))
        if self.rotation is not None:
            R = check_real_array(self.rotation, "rotation")
            if R.shape != (3, 3) or not np.all(np.isfinite(R)):
                raise InvalidArgument(f"rotation: a finite (3, 3) matrix, got shape {R.shape}")
            err = float(np.abs(R.T @ R - np.eye(3)).max())
            if err > 1e-6 or np.linalg.det(R) < 0.0:
                raise InvalidArgument(
                    f"rotation: a rotation matrix (R^T R = I to 1e-6, det +1); got "
                    f"|R^T R - I| = {err:.2e}, det {np.linalg.det(R):.3f}"
                )
            set_(self, "rotation", tuple(tuple(float(x) for x in row) for row in R))
        if self.frame is not None and not isinstance(self.frame, str):
            raise InvalidArgument(f"frame: a frame name or None, got {self.frame!r}")
        set_(self, "position_tolerance",
             check_positive(self.position_tolerance, "position_tolerance", "m"))  # fmt: skip
        set_(self, "orientation_tolerance",
             check_positive(self.orientation_tolerance, "orientation_tolerance", "rad"))  # fmt: skip
        set_(self, "solutions", check_int(self.solutions, "solutions", low=1))

    @classmethod
    def from_rpy(cls, position: Sequence[float], rpy: Sequence[float],
                 **options: float | int | str | None) -> EndEffectorGoal:  # fmt: skip
        """The goal at ``position`` (3,) [m] with orientation roll-pitch-yaw ``rpy`` (3,)
        [rad] (``R = Rz(yaw) Ry(pitch) Rx(roll)``, as URDF); ``options`` as the class's."""
        r, p, y = check_vec3(rpy, "rpy")
        R = pin.rpy.rpyToMatrix(r, p, y)
        return cls(check_vec3(position, "position"), tuple(map(tuple, R)), **options)  # type: ignore[arg-type]

    def target(self) -> pin.SE3:
        """The goal pose (identity rotation when only a position is given)."""
        R = np.eye(3) if self.rotation is None else np.array(self.rotation)
        return pin.SE3(R, np.array(self.position))

    def frame_id(self, robot: Robot) -> int:
        """The goal frame's index in ``robot.model`` (raises `UnknownFrame` naming them)."""
        return robot.frame_id(self.frame if self.frame is not None else robot.ee_frame)

    def errors(self, robot: Robot, q: np.ndarray) -> tuple[float, float]:
        """(position error [m], orientation error [rad]; 0 without ``rotation``) at ``q``
        (n,) [rad], from Pinocchio's forward kinematics."""
        data = robot.model.createData()
        pin.forwardKinematics(robot.model, data, np.asarray(q, dtype=float))
        M = pin.updateFramePlacement(robot.model, data, self.frame_id(robot))
        return _errors(self, M)


def _errors(goal: EndEffectorGoal, M: pin.SE3) -> tuple[float, float]:
    dp = float(np.linalg.norm(M.translation - np.asarray(goal.position)))
    if goal.rotation is None:
        return dp, 0.0
    return dp, float(np.linalg.norm(pin.log3(np.array(goal.rotation).T @ M.rotation)))


class IKSolution(NamedTuple):
    """One configuration reaching an end-effector goal.

    Attributes:
        q: (n,) joint positions [rad], inside the joint limits.
        position_error: distance of the frame from the goal position [m].
        orientation_error: rotation angle from the goal orientation [rad] (0 without one).
        start: where the iteration started (``"start"`` or ``"random #k"``).
    """

    q: np.ndarray
    position_error: float
    orientation_error: float
    start: str


def _step(robot: Robot, goal: EndEffectorGoal, fid: int, data: pin.Data, q: np.ndarray,
          damping: float, W_inv: np.ndarray) -> tuple[float, float, np.ndarray, np.ndarray]:  # fmt: skip
    """At ``q``: (position error [m], orientation error [rad], the damped least-squares
    step (n,) in the metric ``W_inv^-1``, the projector (n, n) on the task's null space)."""
    model = robot.model
    pin.forwardKinematics(model, data, q)
    M = pin.updateFramePlacement(model, data, fid)
    ep, eo = _errors(goal, M)
    if goal.rotation is None:
        e = M.translation - np.asarray(goal.position)
        J = pin.computeFrameJacobian(model, data, q, fid, pin.LOCAL_WORLD_ALIGNED)[:3]
    else:
        dM = goal.target().actInv(M)
        e = pin.log6(dM).vector
        J = pin.Jlog6(dM) @ pin.computeFrameJacobian(model, data, q, fid, pin.LOCAL)
    JWJ = J @ W_inv @ J.T
    step = -W_inv @ J.T @ np.linalg.solve(JWJ + damping**2 * np.eye(len(e)), e)
    # the projector from the undamped pseudo-inverse: a damped one would leak the
    # null-space step into the task (a steady error of order damping^2)
    projector = np.eye(len(q)) - W_inv @ J.T @ np.linalg.pinv(JWJ, rcond=1e-10) @ J
    return ep, eo, step, projector


def _solve(robot: Robot, goal: EndEffectorGoal, fid: int, q: np.ndarray, iterations: int,
           damping: float, q_ref: np.ndarray | None, W: np.ndarray) -> tuple[np.ndarray, float, float]:  # fmt: skip
    """Damped least squares from ``q`` in the metric ``W`` (n, n), each step projected on
    the limits, to within `TIGHTEN` times the tolerances; then, from a solution within
    them, unless ``q_ref`` is None, steps towards ``q_ref`` (n,) [rad] in the task's
    null space (`NULL_GAIN`),
    keeping the iterate within the tolerances nearest ``q_ref`` in ``W``, until the
    null-space step is below `NULL_STEP`. Returns (q, errors): that iterate, or the
    last one when none is within the tolerances."""
    data, lo, hi = robot.model.createData(), robot.q_min, robot.q_max
    W_inv = np.linalg.inv(W)

    def limited(dq: np.ndarray) -> np.ndarray:
        size = float(np.linalg.norm(dq))  # keep steps inside the linearisation's reach
        return dq * (0.5 / size) if size > 0.5 else dq

    ep = eo = math.inf
    for _ in range(iterations):
        ep, eo, step, _ = _step(robot, goal, fid, data, q, damping, W_inv)
        if ep <= TIGHTEN * goal.position_tolerance and eo <= TIGHTEN * goal.orientation_tolerance:
            break
        q = np.clip(q + limited(step), lo, hi)
    if q_ref is None or ep > goal.position_tolerance or eo > goal.orientation_tolerance:
        return q, ep, eo
    best, best_cost = (q, ep, eo), float((q - q_ref) @ W @ (q - q_ref))
    for _ in range(iterations):
        null = NULL_GAIN * (q_ref - q)
        ep, eo, step, projector = _step(robot, goal, fid, data, q, damping, W_inv)
        null = projector @ null
        cost = float((q - q_ref) @ W @ (q - q_ref))
        if ep <= goal.position_tolerance and eo <= goal.orientation_tolerance and cost < best_cost:
            best, best_cost = (q, ep, eo), cost
        if float(np.abs(null).max()) <= NULL_STEP:
            break
        q = np.clip(q + limited(step + null), lo, hi)
    return best


def ik_solutions(
    robot: Robot,
    goal: EndEffectorGoal,
    q_start: np.ndarray,
    *,
    accept: Callable[[np.ndarray], str] | None = None,
    restarts: int = 40,
    iterations: int = 150,
    damping: float = 1e-2,
    seed: int = 0,
    deadline: float = math.inf,
    weight: np.ndarray | None = None,
) -> tuple[list[IKSolution], list[str]]:
    """Up to ``goal.solutions`` distinct configurations reaching ``goal``.

    Args:
        robot: a fixed-base robot (nq = nv).
        goal: the end-effector goal.
        q_start: (n,) first initial configuration [rad] (e.g. the query's start).
        accept: ``accept(q) -> ""`` for a usable solution, else why not (e.g. in
            collision); None: every solution within the limits.
        restarts: most initial configurations tried (the start, then seeded uniform
            draws inside the limits).
        iterations: most iterations per initial configuration.
        damping: damping of the least-squares step (Levenberg-Marquardt), > 0.
        seed: seed of the random initial configurations.
        deadline: ``time.perf_counter()`` [s] after which no new start is tried.
        weight: (n, n) symmetric positive-definite metric of the joint steps (e.g. the
            planner's metric at ``q_start``) from ``q_start``; None: the identity (the
            random starts always use it). Within the task's null space the solution
            from ``q_start`` is drawn towards it in this metric, to near a local minimum of ``(q - q_start)^T weight (q - q_start)``
            on its branch of solutions (the straight-line energy from the start, for
            the kinetic-energy metric).

    Returns:
        (the solutions in the order found, one line per distinct refused solution
        saying why).
    """
    if robot.floating or robot.nq != robot.nv:
        raise InvalidArgument(f"robot: IK goals need a fixed-base robot with nq = nv, "
                              f"got {robot.name!r} (nq {robot.nq}, nv {robot.nv})")  # fmt: skip
    fid = goal.frame_id(robot)
    q_ref = np.clip(np.asarray(q_start, dtype=float), robot.q_min, robot.q_max)
    W = np.eye(robot.nv) if weight is None else np.asarray(weight, dtype=float)
    if W.shape != (robot.nv, robot.nv) or not np.all(np.isfinite(W)):
        raise InvalidArgument(f"weight: a finite ({robot.nv}, {robot.nv}) matrix, got {W.shape}")
    rng = np.random.default_rng(seed)
    found: list[IKSolution] = []
    refused: list[str] = []
    seen: list[np.ndarray] = []  # every distinct solution, accepted or not
    for k in range(check_int(restarts, "restarts", low=1)):
        if len(found) >= goal.solutions or (k and time.perf_counter() > deadline):
            break
        init = q_ref if k == 0 else robot.random_q(rng)
        # only the start's solution is drawn towards the start, in the metric: drawn
        # too, the random starts' solutions gathered on fewer branches (measured)
        start = k == 0  # the random starts step in joint space (identity metric)
        q, ep, eo = _solve(robot, goal, fid, init, iterations, damping,
                           q_ref if start else None, W if start else np.eye(robot.nv))  # fmt: skip
        if ep > goal.position_tolerance or eo > goal.orientation_tolerance:
            continue
        if any(np.abs(q - other).max() < DISTINCT for other in seen):
            continue
        seen.append(q)
        if accept is not None and (why := accept(q)):
            refused.append(why)
            continue
        found.append(IKSolution(q, ep, eo, "start" if k == 0 else f"random #{k}"))
    return found, refused


def _straight_energy(planner: Planner, q0: np.ndarray, q1: np.ndarray) -> float:
    """Energy of the straight joint line (midpoint metric) [J s]: the plans' order."""
    d = q1 - q0
    return float(d @ planner.metric.G(0.5 * (q0 + q1)) @ d)


def _acceptor(planner: Planner) -> Callable[[np.ndarray], str]:
    """The planner's end check (limits, clearance on its decisive geometry) and the
    file's self-collision pairs, as ``accept(q) -> reason or ""``."""
    selfc = planner.self_collision

    def accept(q: np.ndarray) -> str:
        try:
            planner._check_end(q, "goal")
        except PlanningError as err:
            return str(err)
        if selfc is not None and (d := selfc.clearance(q))[0] < 0.0:
            return f"goal self-collides: links {d[1]!r} and {d[2]!r} overlap by {-d[0]:.4f} m"
        return ""

    return accept


def plan_to_goal(planner: Planner, q0: np.ndarray, goal: EndEffectorGoal,
                 obstacles: Sequence[Shape], *, budget: float, seed: int) -> Plan:  # fmt: skip
    """The lowest-energy plan from ``q0`` (n,) [rad] to any of several IK solutions of
    ``goal`` (see the module docstring for the order and the budget rule).

    Raises:
        GoalUnreachable: no IK solution within the tolerances, the limits and clear.
        NoPathFound: no plan to any of them within the budget.
    """
    t0 = time.perf_counter()
    planner.term.set_obstacles(obstacles)
    planner._check_end(q0, "start")
    sols, refused = ik_solutions(planner.robot, goal, q0, accept=_acceptor(planner),
                                 seed=seed, deadline=t0 + IK_SHARE * budget,
                                 weight=planner.metric.G(q0))  # fmt: skip
    frame = goal.frame if goal.frame is not None else planner.robot.ee_frame
    if not sols:
        raise GoalUnreachable(
            f"goal: no configuration puts frame {frame!r} within {goal.position_tolerance:g} m"
            + ("" if goal.rotation is None else f" and {goal.orientation_tolerance:g} rad")
            + f" of the goal inside the joint limits and clear of the scene ({len(refused)} "
            f"solution(s) refused{': ' + refused[0] if refused else ''})",
            frame, goal.position, tuple(refused),
        )  # fmt: skip
    sols.sort(key=lambda s: _straight_energy(planner, q0, s.q))
    lines = [f"IK: {len(sols)} solution(s) for frame {frame!r} ({len(refused)} refused), "
             "planned in order of straight-line energy"]  # fmt: skip
    alternatives, planner.alternatives = planner.alternatives, 0
    try:
        plans = _plan_each(planner, q0, sols, obstacles, budget, seed, t0, lines)
    finally:
        planner.alternatives = alternatives
    wall = time.perf_counter() - t0
    if not plans:
        raise NoPathFound(f"no collision-free path to any IK solution of the goal within the "
                          f"{budget:g} s budget: " + "; ".join(lines), budget, wall,
                          tuple(lines))  # fmt: skip
    best, _, index = min(plans, key=lambda item: item[0].result.energy)
    first = min(s + p.first_feasible_time for p, s, _ in plans)
    lines.append(f"kept the lowest-energy plan: to IK solution {index}")
    return best._replace(wall_time=wall, attempts=(*lines, *best.attempts),
                         first_feasible_time=first)  # fmt: skip


def _plan_each(planner: Planner, q0: np.ndarray, sols: list[IKSolution],
               obstacles: Sequence[Shape], budget: float, seed: int, t0: float,
               lines: list[str]) -> list[tuple[Plan, float, int]]:  # fmt: skip
    """(plan, its start after ``t0`` [s], solution index) for each IK solution planned
    to within the budget rule (see the module docstring); ``lines`` says how each went."""
    plans: list[tuple[Plan, float, int]] = []
    first_took = math.nan
    for i, sol in enumerate(sols):
        left = budget - (time.perf_counter() - t0)
        if i and (left <= 0.0 or (plans and left < first_took)):
            lines.append(f"IK solution {i} not tried: {max(left, 0.0):.2f} s left")
            break
        share = left if i == len(sols) - 1 else 0.5 * left
        start = time.perf_counter() - t0
        try:
            plan = planner.plan(q0, sol.q, obstacles, budget=max(share, 1e-3), seed=seed + i)
        except PlanningError as err:
            lines.append(f"IK solution {i} ({sol.start}): {type(err).__name__}: {err}")
            continue
        first_took = plan.wall_time if math.isnan(first_took) else first_took
        lines.append(f"IK solution {i} ({sol.start}, position error {sol.position_error:.1e} m"
                     f", orientation error {sol.orientation_error:.1e} rad): plan of energy "
                     f"{plan.result.energy:.4f} ({plan.seed})")  # fmt: skip
        plans.append((plan, start, i))
    return plans
