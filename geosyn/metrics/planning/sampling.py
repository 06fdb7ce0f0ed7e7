"""`Sampling`: a planner's checks for sampling-based search, on its collision spheres.

What RRT-Connect, string pulling, shortcuts and the relaxation of a path ask many times
a query: is a configuration, a joint segment valid (sphere clearance to the query's
obstacles at least the sampling margin, no self pair below its floor), and the search
itself (`connect`). In C wherever the robot's joints allow
(`geosyn.metrics.planning.sphere_native`, about 1 us a configuration on the Panda), else
in numpy (`geosyn.metrics.planning.sphere_check`, said once).

A query sets its obstacles and ends (`start`): the self pairs' floors and the sampling
margin are lowered to the ends' own sphere distances (the spheres reach beyond the links:
an end clear of the exact geometry may sit nearer on the spheres), and the exact check
decides every returned plan. For a robot with a file, the file's fitted spheres also
give the exact check its aids (`aids`: joint placements in C and lower bounds of every
(collision object, obstacle) distance from the spheres that cover the object's link).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from geosyn.metrics.planning.exact_path import PathAids
from geosyn.metrics.planning.rrt import rrt_connect
from geosyn.metrics.planning.sphere_check import SphereCheck
from geosyn.metrics.planning.sphere_native import NativeSphereCheck, sphere_check
from geosyn.robots.robot import CollisionSphere, Robot
from geosyn.world.exact_clearance import ExactClearance
from geosyn.world.shapes import Shape

__all__ = ["SAMPLING_SLACK", "Sampling"]

SAMPLING_SLACK = 1e-6
"""[m] below the nearer end's sphere clearance: the lowest sampling margin of a query."""


class Sampling:
    """The sampling checks of one planner (module docstring).

    Args:
        robot: the robot.
        spheres: the planner's collision spheres (those its constraints use).
        exact: the exact checker of the robot's file geometry, or None (no file): then
            no self pairs and no aids.
        margin: the sampling margin outside a query [m] (the planner's margin / 2).

    Attributes:
        check: the sphere check (`NativeSphereCheck` or `SphereCheck`).
        note: why the check is in numpy ("" when in C).
        margin: the sampling margin in force [m].
        aids: the exact check's aids (`PathAids`; empty without a file or without C).
    """

    def __init__(self, robot: Robot, spheres: Sequence[CollisionSphere],
                 exact: ExactClearance | None, margin: float) -> None:  # fmt: skip
        self.robot, self.exact = robot, exact
        self.check: SphereCheck
        self.check, self.note = sphere_check(robot, spheres)
        self.base_margin = self.margin = margin
        self._cover: NativeSphereCheck | None = None
        self._cover_index: list[np.ndarray] = []
        self.aids = PathAids()
        if exact is None:
            return
        from geosyn.robots.collision_spheres import file_spheres  # cached on disk

        fitted = file_spheres(robot)
        self.check.set_self_pairs(fitted.spheres, fitted.links, fitted.self_pairs)
        if isinstance(self.check, NativeSphereCheck):
            self._cover = NativeSphereCheck(robot, fitted.spheres)
            self._cover_index = [
                np.array([i for i, link in enumerate(fitted.links) if link == o.link], dtype=int)
                for o in exact.objects
            ]
            self.aids = PathAids(self.exact_bounds, self._cover.joint_frames)
        self._obstacles: tuple[Shape, ...] = ()

    def start(self, obstacles: Sequence[Shape], q0: np.ndarray, q1: np.ndarray) -> None:
        """A query's obstacles and ends (n,) [rad]: self floors and sampling margin
        lowered to the ends' sphere distances (module docstring)."""
        self._obstacles = tuple(obstacles)
        self.check.set_obstacles(self._obstacles)
        self.check.set_self_floor(q0, q1)
        ends = float(self.check.clearances(np.array([q0, q1])).min())
        self.margin = min(self.base_margin, ends - SAMPLING_SLACK)

    def finish(self) -> None:
        """End of a query: the sampling margin back to the planner's."""
        self.margin = self.base_margin

    def set_obstacles(self, obstacles: Sequence[Shape]) -> None:
        """The obstacles the checks use (`start` sets them for a query)."""
        self._obstacles = tuple(obstacles)
        self.check.set_obstacles(self._obstacles)

    def valid(self, Q: np.ndarray) -> np.ndarray:
        """(K,) True where the configurations ``Q`` (K, n) [rad] keep sphere clearance >=
        ``margin`` to the obstacles and no self pair is below its floor."""
        return self.check.valid(Q, self.margin)

    def segment_valid(self, a: np.ndarray, b: np.ndarray, resolution: float) -> bool:
        """Whether the joint segment ``a`` -> ``b`` (n,) [rad] is valid (`valid`) every
        ``resolution`` [rad] (2-norm; ``a`` itself not checked), stopping at the first
        invalid configuration."""
        return self.check.segment_valid(a, b, resolution, self.margin)

    def connect(self, q0: np.ndarray, q1: np.ndarray, lo: np.ndarray, hi: np.ndarray,
                budget: float, seed: int) -> tuple[np.ndarray | None, int]:  # fmt: skip
        """RRT-Connect from ``q0`` to ``q1`` (n,) [rad] in the box ``[lo, hi]`` within
        ``budget`` [s] on `valid` (`geosyn.metrics.planning.rrt.rrt_connect`'s result):
        in C with the native check, else in Python."""
        if isinstance(self.check, NativeSphereCheck):
            return self.check.rrt_connect(q0, q1, lo, hi, margin=self.margin, budget=budget,
                                          seed=seed)  # fmt: skip
        return rrt_connect(self.valid, q0, q1, lo, hi, budget=budget, seed=seed)

    def exact_bounds(self, Q: np.ndarray) -> np.ndarray:
        """(K, L, O) lower bounds [m] of the exact distance of each collision object of
        the file (L, `ExactClearance.objects`) to each obstacle (O) at the configurations
        ``Q`` (K, n) [rad]: the smallest clearance of the fitted spheres of its link (they
        cover every point of the link's geometry, so no point is nearer; ``-inf`` for a
        link without spheres)."""
        Q = np.asarray(Q, dtype=float).reshape(-1, self.robot.model.nq)
        out = np.full((len(Q), len(self._cover_index), len(self._obstacles)), -math.inf)
        if self._cover is None or not self._obstacles:
            return out
        self._cover.set_obstacles(self._obstacles)
        d = self._cover.obstacle_distances(Q)
        for k, index in enumerate(self._cover_index):
            if index.size:
                out[:, k] = d[:, index].min(axis=1)
        return out
