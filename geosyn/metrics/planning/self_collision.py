"""`SelfCollision`: exact clearance of a robot's own links to each other (coal).

The link pairs are the file's self-collision pairs (`geosyn.robots.collision_spheres`:
links on joints that are neither the same nor parent and child, minus those whose hulls
already overlap at the neutral configuration); each collision object of the file
(`geosyn.robots.collision_geometry`) becomes a coal shape: a URDF mesh its own triangles
(a BVH: two links' convex hulls may overlap where the meshes are centimetres apart, e.g.
the UR5's forearm and wrist 3), an MJCF mesh its convex hull (what MuJoCo collides), a
primitive itself (`geosyn.world.exact_clearance.coal_shape`); `clearance` returns the
smallest coal distance over the pairs. Triangle meshes that intersect have no
penetration depth in coal: such a pair counts as `INTERSECTING`. The planner checks IK
goals with it (`geosyn.metrics.planning.goals`).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pinocchio as pin

from geosyn.robots.collision_geometry import CollisionObject, collision_objects
from geosyn.robots.errors import RobotFileError
from geosyn.robots.robot import Robot
from geosyn.world.exact_clearance import coal_shape

__all__ = ["INTERSECTING", "SelfCollision"]

INTERSECTING = -1e-6
"""Clearance [m] reported for two intersecting triangle meshes (coal gives no depth)."""


def _mesh_bvh(obj: CollisionObject) -> Any:
    """coal BVH of a mesh object's own triangles (in the object's frame)."""
    import coal

    vertices, triangles = coal.StdVec_Vec3s(), coal.StdVec_Triangle()
    for v in np.asarray(obj.vertices, dtype=np.float64):
        vertices.append(v)
    for a, b, c in np.asarray(obj.faces, dtype=int):
        triangles.append(coal.Triangle(int(a), int(b), int(c)))
    bvh = coal.BVHModelOBBRSS()
    bvh.beginModel(len(triangles), len(vertices))
    bvh.addSubModel(vertices, triangles)
    bvh.endModel()
    return bvh


class SelfCollision:
    """Smallest exact distance between the robot's self-collision link pairs.

    Args:
        robot: a robot loaded from a URDF or MJCF file.
        pairs: link-name pairs to check.

    Builds the coal shapes once (allocates); `clearance` only evaluates.

    Raises:
        geosyn.robots.RobotFileError: no readable collision geometry.
    """

    def __init__(self, robot: Robot, pairs: tuple[tuple[str, str], ...]) -> None:
        import coal

        self.robot = robot
        self.pairs = tuple(pairs)
        self.objects = collision_objects(robot)
        urdf = str(getattr(robot, "source_file", "") or "").lower().endswith(".urdf")
        self._bvh = [urdf and o.kind == "mesh" for o in self.objects]
        self._geoms = [_mesh_bvh(o) if b else coal_shape(o)
                       for o, b in zip(self.objects, self._bvh, strict=True)]  # fmt: skip
        self._joint = [robot.joint_id(o.joint) if o.joint != "universe" else 0
                       for o in self.objects]  # fmt: skip
        self._place = [pin.SE3(o.placement) for o in self.objects]
        by_link: dict[str, list[int]] = {}
        for k, o in enumerate(self.objects):
            by_link.setdefault(o.link, []).append(k)
        self._checks = [(a, b, i, j) for a, b in self.pairs
                        for i in by_link.get(a, ()) for j in by_link.get(b, ())]  # fmt: skip
        self._request = coal.DistanceRequest()
        self._data = robot.model.createData()

    @classmethod
    def for_robot(cls, robot: Robot) -> SelfCollision | None:
        """The checker on the file's own pairs (`geosyn.robots.collision_spheres.
        file_spheres`, cached on disk), or None for a robot without file geometry."""
        from geosyn.robots.collision_spheres import file_spheres

        try:
            return cls(robot, file_spheres(robot).self_pairs)
        except RobotFileError:
            return None

    def clearance(self, q: np.ndarray) -> tuple[float, str, str]:
        """(smallest signed distance [m], link a, link b) over the pairs at ``q`` (n,)
        [rad] (`INTERSECTING` for intersecting triangle meshes); ``(inf, "", "")``
        without pairs."""
        import coal

        model, data = self.robot.model, self._data
        pin.forwardKinematics(model, data, np.asarray(q, dtype=float))
        poses: dict[int, Any] = {}

        def placed(k: int) -> Any:
            if k not in poses:
                j = self._joint[k]
                M = (data.oMi[j] if j else pin.SE3.Identity()) * self._place[k]
                poses[k] = coal.CollisionObject(
                    self._geoms[k], coal.Transform3s(M.rotation, M.translation)
                )
            return poses[k]

        best: tuple[float, str, str] = (math.inf, "", "")
        for a, b, i, j in self._checks:
            if (self._bvh[i] or self._bvh[j]) and coal.collide(
                placed(i), placed(j), coal.CollisionRequest(), coal.CollisionResult()
            ):
                d = INTERSECTING
            else:
                d = float(coal.distance(placed(i), placed(j), self._request, coal.DistanceResult()))
            if d < best[0]:
                best = (d, a, b)
        return best
