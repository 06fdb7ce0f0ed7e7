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
goals with it (`geosyn.metrics.planning.goals`), the start and goal of every query, and
every returned plan (`path_self_clearance`).

Rule for plans: a path is checked at the configurations of
`geosyn.metrics.planning.exact_path.checked_configurations` (the exact check's
resolution); at each, every pair's sphere distance (`SphereCheck.self_clearances`: a
lower bound of the exact one) is computed, then coal's exact distance for the
(configuration, pair) items whose bound is below `SELF_NEAR`, closest bound first,
stopping as soon as the next bound is not below the smallest exact distance found (or
that distance is negative: the plan is then refused or repaired, never returned).
"""

from __future__ import annotations

import math
import time
from typing import Any

import numpy as np
import pinocchio as pin

from geosyn.metrics.planning.errors import InCollision
from geosyn.metrics.planning.exact_path import Kinematics, checked_configurations
from geosyn.metrics.planning.sphere_check import SphereCheck
from geosyn.robots.collision_geometry import CollisionObject, collision_objects
from geosyn.robots.errors import RobotFileError
from geosyn.robots.robot import Robot
from geosyn.world.exact_clearance import coal_shape

__all__ = ["INTERSECTING", "SELF_NEAR", "SelfCollision", "check_self_end", "path_self_clearance"]

SELF_NEAR = 0.02
"""Self-clearance [m] beyond which the sphere bound is not refined: a plan whose pairs'
sphere distances all exceed it reports this value ("at least")."""

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
        self._hulls = [coal_shape(o) for o in self.objects]  # a mesh: its convex hull
        self._geoms = [_mesh_bvh(o) if b else hull
                       for o, b, hull in zip(self.objects, self._bvh, self._hulls, strict=True)]  # fmt: skip
        self._joint = [robot.joint_id(o.joint) if o.joint != "universe" else 0
                       for o in self.objects]  # fmt: skip
        self._place = [pin.SE3(o.placement) for o in self.objects]
        by_link: dict[str, list[int]] = {}
        for k, o in enumerate(self.objects):
            by_link.setdefault(o.link, []).append(k)
        self._checks = [(a, b, i, j) for a, b in self.pairs
                        for i in by_link.get(a, ()) for j in by_link.get(b, ())]  # fmt: skip
        self._of_pair = {ab: [c for c in self._checks if c[:2] == ab] for ab in self.pairs}
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

    def clearance(
        self, q: np.ndarray, pair: tuple[str, str] | None = None
    ) -> tuple[float, str, str]:
        """(smallest signed distance [m], link a, link b) over the pairs (or only
        ``pair``, one of them) at ``q`` (n,) [rad] (`INTERSECTING` for intersecting
        triangle meshes); ``(inf, "", "")`` without pairs."""
        pin.forwardKinematics(self.robot.model, self._data, np.asarray(q, dtype=float))
        R = np.array([M.rotation for M in self._data.oMi])  # oMi[0]: the universe
        p = np.array([M.translation for M in self._data.oMi])
        best: tuple[float, str, str] = (math.inf, "", "")
        for a, b in self.pairs if pair is None else (pair,):
            if (d := self.placed_clearance(R, p, (a, b))) < best[0]:
                best = (d, a, b)
        return best

    def placed_clearance(self, R: np.ndarray, p: np.ndarray, pair: tuple[str, str],
                         above: float = math.inf) -> float:  # fmt: skip
        """Smallest signed distance [m] of ``pair`` (one of the pairs) with the joints at
        world rotations ``R`` (J + 1, 3, 3) and positions ``p`` (J + 1, 3) by Pinocchio
        index (``data.oMi``; e.g. `NativeSphereCheck.joint_frames`): `clearance` at that
        configuration without its forward kinematics (`INTERSECTING` alike). Two triangle
        meshes whose convex hulls are at least ``above`` [m] apart are not measured on
        their triangles (the hulls' distance, a lower bound, stands for them: the result
        is then exact only when below ``above``)."""
        import coal

        best = math.inf
        for _, _, i, j in self._of_pair.get(pair, []):
            tf = [coal.Transform3s(R[self._joint[k]] @ self._place[k].rotation,
                                   R[self._joint[k]] @ self._place[k].translation
                                   + p[self._joint[k]]) for k in (i, j)]  # fmt: skip
            gi, gj = self._geoms[i], self._geoms[j]
            mesh = self._bvh[i] or self._bvh[j]
            if mesh and above < math.inf:  # the hulls first: a lower bound
                hull = float(coal.distance(self._hulls[i], tf[0], self._hulls[j], tf[1],
                                           self._request, coal.DistanceResult()))  # fmt: skip
                if hull >= above:
                    best = min(best, hull)
                    continue
            if mesh and coal.collide(gi, tf[0], gj, tf[1], coal.CollisionRequest(),
                                     coal.CollisionResult()):  # fmt: skip
                d = INTERSECTING
            else:
                d = float(coal.distance(gi, tf[0], gj, tf[1], self._request,
                                        coal.DistanceResult()))  # fmt: skip
            best = min(best, d)
        return best


def path_self_clearance(
    checker: SelfCollision | None,
    spheres: SphereCheck,
    path: np.ndarray,
    resolution: float,
    deadline: float = math.inf,
    kinematics: Kinematics | None = None,
) -> float:
    """Smallest exact self-clearance [m] of the linear interpolation of ``path`` (T, n)
    [rad] at most ``resolution`` [rad] apart (the module's rule; ``spheres`` has the same
    pairs set, `SphereCheck.set_self_pairs`).

    Returns the exact minimum when it is below `SELF_NEAR` and not negative, else
    `SELF_NEAR` ("at least"); a negative value (some exact penetration, not
    necessarily the deepest) when the path self-collides; NaN without ``checker`` or
    when ``time.perf_counter()`` passes ``deadline`` [s] first. ``kinematics``: the
    joints' placements of every checked configuration at once (e.g. in C): the same
    result without one Pinocchio call per measured item.
    """
    if checker is None:
        return math.nan
    Q = checked_configurations(path, resolution)
    bound = spheres.self_clearances(Q)  # (K, P)
    near = np.flatnonzero(bound.ravel() < SELF_NEAR)
    order = near[np.argsort(bound.ravel()[near], kind="stable")]
    low = SELF_NEAR
    frames, rows = None, {}
    if kinematics is not None and order.size:  # the configurations with an item to measure
        at = np.unique(order // bound.shape[1])
        frames, rows = kinematics(Q[at]), {int(i): r for r, i in enumerate(at)}
    for count, index in enumerate(order):
        i, k = (int(x) for x in np.unravel_index(int(index), bound.shape))
        if bound[i, k] >= low:
            break  # every item left is at least this far
        if count % 16 == 15 and time.perf_counter() > deadline:
            return math.nan
        pair = spheres.self_pairs[k]
        if frames is not None:
            d = checker.placed_clearance(frames[0][rows[i]], frames[1][rows[i]], pair, low)
        else:
            d = checker.clearance(Q[i], pair)[0]
        low = min(low, d)
        if low < 0.0:
            break
    return low


def check_self_end(
    checker: SelfCollision | None, spheres: SphereCheck, q: np.ndarray, which: str
) -> None:
    """Raise `InCollision` if ``q`` (n,) [rad], the ``which`` end of a query, is in
    self-collision (coal on the pairs, only where a pair's sphere bound is negative)."""
    if checker is None or spheres.self_clearances(q).min(initial=math.inf) >= 0.0:
        return
    d, a, b = checker.clearance(q)
    if d < 0.0:
        raise InCollision(
            f"{which} is in self-collision: links {a!r} and {b!r} of the robot's own "
            f"collision geometry intersect ({d:.4f} m); move the {which} configuration",
            which, -1, -1, f"{a}/{b}", d,
        )  # fmt: skip
