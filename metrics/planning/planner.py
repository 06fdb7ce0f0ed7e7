"""`Planner`: minimum-energy, collision-free motion between two configurations.

One query, within a stated time budget:

1. checks the input: start and goal within the joint limits and collision-free (else
   `OutsideJointLimits` / `InCollision` naming the obstacle and the robot sphere), at most
   ``capacity`` obstacles (else `geosyn.metrics.shaping.CapacityExceeded`);
2. collocation (`geosyn.metrics.geodesic.collocation.Collocation`) from the straight line;
3. if that fails, RRT-Connect (`geosyn.metrics.planning.rrt`) for a global seed around
   the obstacles, then collocation from it;
4. checks the result between the nodes (``check_factor`` times finer, linear between
   nodes); a path that touches an obstacle there is solved again with twice the nodes.

A query that cannot succeed raises `NoPathFound` once the budget is spent, listing what
was tried. The NLP is built once per node count (its obstacle poses are parameters), so
every scene of one robot and capacity reuses it.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np

from geosyn.core.errors import InvalidArgument
from geosyn.core.types import Vector
from geosyn.core.validation import check_float, check_int, check_positive, check_vector
from geosyn.metrics.base import Metric, check_metric
from geosyn.metrics.geodesic.collocation import Collocation, CollocationResult
from geosyn.metrics.planning.errors import InCollision, NoPathFound, OutsideJointLimits
from geosyn.metrics.planning.rrt import rrt_connect, shortcut
from geosyn.metrics.shaping.obstacle import ObstacleTerm
from geosyn.robots.robot import CollisionSphere
from geosyn.world.shapes import Shape

__all__ = ["Plan", "Planner"]


class Plan(NamedTuple):
    """A planned path and how it was found.

    Attributes:
        result: the collocation result (path, kind, energy, clearance, ...).
        seed: the initial path of the final collocation: ``"straight line"`` or
            ``"rrt-connect"``.
        check_clearance: smallest clearance [m] on the path checked ``check_factor``
            times finer than its samples (linear in between).
        wall_time: wall-clock time of the query [s].
        attempts: one line per method tried.
    """

    result: CollocationResult
    seed: str
    check_clearance: float
    wall_time: float
    attempts: tuple[str, ...]

    @property
    def q(self) -> np.ndarray:
        """(T, n) the path [rad]."""
        return self.result.q


def densify(path: np.ndarray, factor: int) -> np.ndarray:
    """(factor (T - 1) + 1, n): ``path`` (T, n) with ``factor - 1`` linear points per segment."""
    path = np.asarray(path, dtype=float)
    s = np.arange(factor)[:, None, None] / factor
    inner = path[:-1][None] + s * np.diff(path, axis=0)[None]
    return np.vstack([inner.transpose(1, 0, 2).reshape(-1, path.shape[1]), path[-1:]])


class Planner:
    """Collision-free minimum-energy paths of one robot among up to ``capacity`` obstacles.

    Args:
        metric: velocity-independent metric with a ``robot`` (e.g. `KineticEnergyMetric`).
        capacity: obstacle slots, >= 1.
        spheres: robot collision spheres; None uses ``robot.collision_spheres()``.
        margin: node clearance of the collocation [m], >= 0.
        nodes: segments of the collocation, >= 2.
        check_factor: refinement of the between-node check, >= 1.
        compile: what to compile to C (cached on disk): see `Collocation`.
        distance: signed distance of the clearance constraints, ``"exact"`` or
            ``"smooth"`` (see `geosyn.metrics.shaping.obstacle.DISTANCES`).
        hessian, tol, softmin: see `Collocation`.

    Builds the collocation NLP (allocates; see `Collocation`).
    """

    def __init__(
        self,
        metric: Metric,
        *,
        capacity: int = 8,
        spheres: Sequence[CollisionSphere] | None = None,
        margin: float = 0.01,
        nodes: int = 24,
        check_factor: int = 4,
        compile: bool | str = False,
        distance: str = "exact",
        hessian: str = "exact",
        tol: float = 1e-8,
        softmin: float | None = 1000.0,
    ) -> None:
        t0 = time.perf_counter()
        self.metric = check_metric(metric)
        robot = getattr(metric, "robot", None)
        if robot is None:
            raise InvalidArgument("metric: the planner needs a metric with a robot")
        self.robot = robot
        self.term = ObstacleTerm((), capacity=capacity, spheres=spheres, distance=distance)
        self.term.bind(robot)
        self.margin = check_float(margin, "margin", low=0.0)
        self.nodes = check_int(nodes, "nodes", low=2)
        self.check_factor = check_int(check_factor, "check_factor", low=1)
        self.compile = compile
        self.hessian = hessian
        self.tol = check_positive(tol, "tol")
        self.softmin = softmin
        self._collocations: dict[int, Collocation] = {}
        self.collocation(self.nodes)
        self.build_time = time.perf_counter() - t0

    def collocation(self, nodes: int) -> Collocation:
        """The collocation with ``nodes`` segments (built on first use, then kept)."""
        if nodes not in self._collocations:
            self._collocations[nodes] = Collocation(
                self.metric, nodes=nodes, clearance=self.term, margin=self.margin,
                compile=self.compile, hessian=self.hessian, tol=self.tol,
                softmin=self.softmin,
            )  # fmt: skip
        return self._collocations[nodes]

    def valid(self, Q: np.ndarray) -> np.ndarray:
        """(K,) True where the configurations ``Q`` (K, n) keep clearance >= margin / 2."""
        return self.collocation(self.nodes).node_clearances(Q) >= 0.5 * self.margin

    def _check_end(self, q: np.ndarray, which: str) -> None:
        bad = np.flatnonzero((q < self.robot.q_min - 1e-9) | (q > self.robot.q_max + 1e-9))
        if bad.size:
            j = int(bad[0])
            raise OutsideJointLimits(
                f"{which}: joint {j} ({self.robot.joint_names[j]}) = {q[j]:.4f} rad is outside "
                f"its limits [{self.robot.q_min[j]:.4f}, {self.robot.q_max[j]:.4f}] rad",
                which,
                tuple(int(i) for i in bad),
            )
        if not self.term.obstacles:
            return
        c = self.term.clearances(q)  # (spheres, obstacles)
        s, o = np.unravel_index(int(np.argmin(c)), c.shape)
        if c[s, o] < 0.0:
            sphere = self.term.spheres[s]
            raise InCollision(
                f"{which} is in collision: robot sphere {s} (on joint {sphere.joint!r}, radius "
                f"{sphere.radius:g} m) is {-c[s, o]:.4f} m inside obstacle {o} "
                f"({self.term.obstacles[o]!r}); move the {which} configuration or the "
                "obstacle, or use a robot sphere model that fits the links more tightly",
                which, int(o), int(s), sphere.joint, float(c[s, o]),
            )  # fmt: skip

    def plan(
        self,
        q0: Vector,
        q1: Vector,
        obstacles: Sequence[Shape] = (),
        *,
        budget: float = 5.0,
        seed: int = 0,
    ) -> Plan:
        """Plan from ``q0`` to ``q1`` around ``obstacles`` within ``budget`` seconds.

        Args:
            q0: (n,) start [rad].
            q1: (n,) goal [rad].
            obstacles: shapes of `geosyn.world`, at most ``capacity``.
            budget: wall-time limit of the query [s], > 0 (a shooting refinement of a
                free geodesic may add its own bounded iterations).
            seed: seed of the sampling fallback.

        Returns:
            The plan; ``plan.result.kind`` says whether it is a geodesic or a
            minimum-energy constrained path.

        Raises:
            OutsideJointLimits: start or goal outside the limits.
            InCollision: start or goal in collision (names obstacle and sphere).
            geosyn.metrics.shaping.CapacityExceeded: more obstacles than ``capacity``.
            NoPathFound: no collision-free path within the budget.
        """
        t0 = time.perf_counter()
        n = self.metric.n
        q0 = check_vector(q0, n, "q0")
        q1 = check_vector(q1, n, "q1")
        budget = check_positive(budget, "budget", "s")
        seed = check_int(seed, "seed")
        self.term.set_obstacles(obstacles)
        self._check_end(q0, "start")
        self._check_end(q1, "goal")
        attempts: list[str] = []

        def left() -> float:
            return budget - (time.perf_counter() - t0)

        def finish(res: CollocationResult, seed_name: str, share: float) -> Plan | None:
            """The plan if ``res`` is clear between its nodes, else refined (within the
            first ``share`` of the budget) while that halves the penetration."""
            nodes, previous = self.nodes, -math.inf
            while True:
                check = float(self.collocation(nodes).node_clearances(
                    densify(res.q, self.check_factor)).min())  # fmt: skip
                if check >= 0.0:
                    return Plan(res, seed_name, check, time.perf_counter() - t0, tuple(attempts))
                attempts.append(
                    f"{res.kind} path with {nodes} segments crosses an obstacle between nodes "
                    f"(clearance {check:.4f} m)"
                )
                if check <= 0.5 * previous:  # refining does not help: it tunnels through
                    return None
                previous, nodes = check, 2 * nodes
                if nodes > 8 * self.nodes:
                    return None
                col = self.collocation(nodes)  # built once, kept for later queries
                if left() - (1.0 - share) * budget <= 0:
                    attempts.append(f"no time left for collocation with {nodes} segments")
                    return None
                res = col.solve(q0, q1, init=res.q, budget=left() - (1.0 - share) * budget)
                if not res.success:
                    attempts.append(f"collocation ({nodes} segments): {res.message}")
                    return None

        res = self.collocation(self.nodes).solve(q0, q1, budget=0.5 * budget)
        attempts.append(f"collocation from the straight line: {res.message}")
        if res.success and (plan := finish(res, "straight line", 0.75)) is not None:
            return plan
        if left() > 0:
            # the sampling box: the limits, or within pi of start and goal where infinite
            lo = np.maximum(self.robot.q_min, np.minimum(q0, q1) - np.pi)
            hi = np.minimum(self.robot.q_max, np.maximum(q0, q1) + np.pi)
            path, grown = rrt_connect(self.valid, q0, q1, lo, hi, budget=0.6 * left(), seed=seed)
            if path is None:
                attempts.append(f"RRT-Connect: no connection after {grown} nodes")
            else:
                path = shortcut(self.valid, path, budget=0.05 * left(), seed=seed)
                attempts.append(f"RRT-Connect: path of {len(path)} vertices ({grown} nodes)")
                if left() > 0:
                    res = self.collocation(self.nodes).solve(q0, q1, init=path, budget=left())
                    attempts.append(f"collocation from the RRT-Connect path: {res.message}")
                    if res.success and (plan := finish(res, "rrt-connect", 1.0)) is not None:
                        return plan
        elapsed = time.perf_counter() - t0
        raise NoPathFound(
            f"no collision-free path from the start to the goal within the {budget:g} s "
            f"budget ({elapsed:.2f} s spent): " + "; ".join(attempts) + ". Try a larger "
            "budget, a smaller margin, or check that the goal is reachable (not enclosed "
            "by obstacles)",
            budget, elapsed, tuple(attempts),
        )  # fmt: skip
