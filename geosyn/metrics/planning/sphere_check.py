"""`SphereCheck`: the planner's collision spheres against the obstacles, many
configurations at once, for sampling (RRT-Connect, shortcuts).

The collocation's clearance function (`Collocation.node_clearances`, a CasADi SX function
interpreted per configuration) costs about 70 us per configuration on the Panda with 8
obstacle slots (measured), most of a sampling planner's time. Here one Pinocchio forward
kinematics per configuration places every sphere (centre in its joint's frame) and the
signed distances (`geosyn.world.distance.signed_distance`; all boxes in one array
operation) to the active obstacles are array work over all spheres and configurations. The distances are the exact sphere
clearances (no smooth minimum), of the same spheres.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import pinocchio as pin

from geosyn.robots.robot import CollisionSphere, Robot
from geosyn.world.distance import signed_distance
from geosyn.world.shapes import Box, Shape

__all__ = ["SphereCheck"]


class SphereCheck:
    """Smallest clearance [m] of a robot's collision spheres to obstacles.

    Args:
        robot: the robot (its Pinocchio model places the spheres).
        spheres: the spheres, each on a joint of ``robot`` (``"universe"``: the world).

    Allocates its Pinocchio data once; `clearances` allocates only its result arrays.
    """

    def __init__(self, robot: Robot, spheres: Sequence[CollisionSphere]) -> None:
        self.robot = robot
        ids = [robot.joint_id(s.joint) if s.joint != "universe" else 0 for s in spheres]
        self._joints = sorted(set(ids))
        self._slot = np.array([self._joints.index(j) for j in ids], dtype=int)
        self._centre = np.array([s.center for s in spheres], dtype=float).reshape(-1, 3)
        self._radius = np.array([s.radius for s in spheres], dtype=float)
        self._data = robot.model.createData()
        self.obstacles: tuple[Shape, ...] = ()

    def set_obstacles(self, obstacles: Sequence[Shape]) -> None:
        """Replace the obstacles (shapes of `geosyn.world`, already checked)."""
        self.obstacles = tuple(obstacles)
        boxes = [ob for ob in self.obstacles if isinstance(ob, Box)]
        self._others = [ob for ob in self.obstacles if not isinstance(ob, Box)]
        self._box_centre = np.array([b.center for b in boxes], dtype=float).reshape(-1, 3)
        self._box_rotation = np.array([b.rotation for b in boxes], dtype=float).reshape(-1, 3, 3)
        self._box_half = np.array([b.half_extents for b in boxes], dtype=float).reshape(-1, 3)

    def _box_distances(self, points: np.ndarray) -> np.ndarray:
        """(P,) smallest signed distance of ``points`` (P, 3) [m] to the boxes (the
        formula of `geosyn.world.distance`, every box at once)."""
        rel = points[:, None, :] - self._box_centre[None]  # (P, B, 3)
        local = np.abs(np.einsum("pba,bac->pbc", rel, self._box_rotation)) - self._box_half
        outside = np.linalg.norm(np.maximum(local, 0.0), axis=2)
        inside = np.minimum(local.max(axis=2), 0.0)
        return np.asarray((outside + inside).min(axis=1))

    def clearances(self, Q: np.ndarray) -> np.ndarray:
        """(K,) smallest sphere-obstacle signed distance [m] at each configuration of
        ``Q`` (K, n) [rad]; inf without obstacles or spheres. O(K (n + S O))."""
        Q = np.asarray(Q, dtype=float).reshape(-1, self.robot.model.nq)
        if not self.obstacles or not self._radius.size:
            return np.full(len(Q), math.inf)
        model, data, joints = self.robot.model, self._data, self._joints
        H = np.empty((len(Q), len(joints), 4, 4))
        for i, q in enumerate(Q):
            pin.forwardKinematics(model, data, q)
            for a, j in enumerate(joints):  # joint 0 is the universe: the identity
                H[i, a] = data.oMi[j].homogeneous
        R, p = H[:, :, :3, :3], H[:, :, :3, 3]
        centres = np.einsum("ksab,sb->ksa", R[:, self._slot], self._centre) + p[:, self._slot]
        flat = centres.reshape(-1, 3)
        nearest = np.full(len(flat), math.inf)  # (K S,) to the nearest obstacle
        if len(self._box_half):
            nearest = self._box_distances(flat)
        for ob in self._others:
            nearest = np.minimum(nearest, signed_distance(ob, flat))
        return np.asarray((nearest.reshape(len(Q), -1) - self._radius).min(axis=1))
