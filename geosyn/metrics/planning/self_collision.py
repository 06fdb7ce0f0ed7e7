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
every returned plan (`geosyn.metrics.planning.self_path.path_self_contact`).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pinocchio as pin

from geosyn.core.errors import InvalidArgument
from geosyn.metrics.planning.certify import joint_weights
from geosyn.metrics.planning.errors import InCollision
from geosyn.metrics.planning.sphere_check import SphereCheck
from geosyn.robots.collision_geometry import CollisionObject, collision_objects, file_bvh
from geosyn.robots.errors import RobotFileError
from geosyn.robots.robot import Robot
from geosyn.world.exact_clearance import bounding_ball, coal_shape

__all__ = [
    "INTERSECTING",
    "Placements",
    "SelfCollision",
    "check_self_end",
]

INTERSECTING = -1e-6
"""Clearance [m] reported for two intersecting triangle meshes (coal gives no depth)."""


def _mesh_bvh(obj: CollisionObject) -> Any:
    """coal BVH of a mesh object's own triangles (in the object's frame): the one
    Pinocchio built reading the URDF (`file_bvh`), else built here."""
    import coal

    if (built := file_bvh(obj)) is not None:
        return built
    vertices = np.ascontiguousarray(obj.vertices, dtype=np.float64)
    faces = np.ascontiguousarray(obj.faces, dtype=np.int64)
    bvh = coal.BVHModelOBBRSS()
    bvh.beginModel(len(faces), len(vertices))
    bvh.addVertices(vertices)
    bvh.addTriangles(faces)
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
        self._joints = np.array([robot.joint_id(o.joint) if o.joint != "universe" else 0
                                 for o in self.objects], dtype=int)  # fmt: skip
        place = np.array([np.asarray(o.placement) for o in self.objects]).reshape(-1, 4, 4)
        self._rotations, self._translations = place[:, :3, :3], place[:, :3, 3]
        by_link: dict[str, list[int]] = {}
        for k, o in enumerate(self.objects):
            by_link.setdefault(o.link, []).append(k)
        self._checks = [(a, b, i, j) for a, b in self.pairs
                        for i in by_link.get(a, ()) for j in by_link.get(b, ())]  # fmt: skip
        self._of_pair = {ab: [c for c in self._checks if c[:2] == ab] for ab in self.pairs}
        self._request = coal.DistanceRequest()
        self._apart: dict[float, Any] = {}  # `placed_apart`'s requests by margin
        self._data = robot.model.createData()
        self._weights = {ab: self._pair_weights(by_link, ab) for ab in self.pairs}

    def pair_weights(self, pair: tuple[str, str]) -> np.ndarray | None:
        """(n,) ``w[j]``: the most the distance between the two links of ``pair`` (one of
        the pairs) changes [m] per unit of joint ``j`` [rad or m], at every configuration
        (`geosyn.metrics.planning.certify.joint_weights` of its objects, the joints that
        carry one link and not the other; those that carry both move them rigidly): along
        a path the pair's distance changes by at most ``sum_j w[j] |dq_j|``. None for a
        robot whose joints `joint_weights` does not bound."""
        return self._weights[pair]

    def _pair_weights(self, by_link: dict[str, list[int]],
                      pair: tuple[str, str]) -> np.ndarray | None:  # fmt: skip
        """`pair_weights` of ``pair`` (``by_link``: the objects' indices by link)."""
        objects = (*by_link.get(pair[0], ()), *by_link.get(pair[1], ()))
        balls = [bounding_ball(self.objects[k]) for k in objects]  # the hull's: holds the mesh
        try:
            w = joint_weights(self.robot, [int(self._joints[k]) for k in objects], balls)
        except InvalidArgument:  # e.g. a spherical joint: no bound, every item measured
            return None
        a = len(by_link.get(pair[0], ()))
        wa, wb = w[:a].max(axis=0, initial=0.0), w[a:].max(axis=0, initial=0.0)
        return np.where(wb > 0.0, 0.0, wa) + np.where(wa > 0.0, 0.0, wb)

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
        placed = self.placements(*self.joint_frames(q))
        best: tuple[float, str, str] = (math.inf, "", "")
        for a, b in self.pairs if pair is None else (pair,):
            if (d := self.placed_clearance(placed, (a, b))) < best[0]:
                best = (d, a, b)
        return best

    def joint_frames(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """World rotations (J + 1, 3, 3) and positions (J + 1, 3) of the joints at ``q``
        (n,) [rad] by Pinocchio index (``data.oMi``)."""
        pin.forwardKinematics(self.robot.model, self._data, np.asarray(q, dtype=float))
        R = np.array([M.rotation for M in self._data.oMi])  # oMi[0]: the universe
        return R, np.array([M.translation for M in self._data.oMi])

    def placements(self, R: np.ndarray, p: np.ndarray) -> Placements:
        """coal placement of every object with the joints at world rotations ``R``
        (J + 1, 3, 3) and positions ``p`` (J + 1, 3) by Pinocchio index (``data.oMi``;
        e.g. `NativeSphereCheck.joint_frames`): the argument of `placed_bound` and
        `placed_clearance`."""
        Rj, pj = R[self._joints], p[self._joints]
        rot = np.einsum("kab,kbc->kac", Rj, self._rotations)
        return Placements(rot, np.einsum("kab,kb->ka", Rj, self._translations) + pj)

    def placed_bound(self, placed: Placements, pair: tuple[str, str]) -> tuple[float, bool]:
        """(a lower bound [m] of `placed_clearance` of ``pair`` with its objects at
        ``placed`` (`placements`), whether it is that value): the smallest coal distance
        between the pair's convex shapes (a URDF mesh: its convex hull, which contains
        its triangles; exact when neither object is such a mesh). ``(inf, True)`` for a
        pair without objects."""
        import coal

        best, exact = math.inf, True
        for _, _, i, j in self._of_pair.get(pair, []):
            d = float(coal.distance(self._hulls[i], placed[i], self._hulls[j], placed[j],
                                    self._request, coal.DistanceResult()))  # fmt: skip
            best, exact = min(best, d), exact and not (self._bvh[i] or self._bvh[j])
        return best, exact

    def placed_apart(self, placed: Placements, pair: tuple[str, str], margin: float) -> bool:
        """Whether the objects of ``pair`` (one of the pairs) at ``placed`` (`placements`)
        are more than ``margin`` [m] apart: coal's collision test with that security
        margin (a URDF mesh: its triangles), 15-25x cheaper than their distance on the
        UR5's meshes (measured). True: `placed_clearance` is at least ``margin``."""
        import coal

        request = self._apart.get(margin)
        if request is None:
            request = self._apart[margin] = coal.CollisionRequest()
            request.security_margin = margin
        return not any(coal.collide(self._geoms[i], placed[i], self._geoms[j], placed[j],
                                    request, coal.CollisionResult())
                       for _, _, i, j in self._of_pair.get(pair, []))  # fmt: skip

    def placed_clearance(self, placed: Placements, pair: tuple[str, str]) -> float:
        """Smallest signed distance [m] of ``pair`` (one of the pairs) with its objects at
        ``placed`` (`placements`): `clearance` at that configuration without its forward
        kinematics (`INTERSECTING` alike). A pair of several objects measures their
        triangles nearest hulls first, and only while a hull distance (a lower bound) is
        below the least distance found."""
        import coal

        best, meshes, checks = math.inf, [], self._of_pair.get(pair, [])
        for _, _, i, j in checks:
            d = -math.inf  # one object pair: no ordering to make
            if len(checks) > 1 or not (self._bvh[i] or self._bvh[j]):
                d = float(coal.distance(self._hulls[i], placed[i], self._hulls[j], placed[j],
                                        self._request, coal.DistanceResult()))  # fmt: skip
            if self._bvh[i] or self._bvh[j]:
                meshes.append((d, i, j))
            else:  # convex shapes: their distance
                best = min(best, d)
        for bound, i, j in sorted(meshes):
            if bound >= best:
                break
            gi, gj = self._geoms[i], self._geoms[j]
            if coal.collide(gi, placed[i], gj, placed[j], coal.CollisionRequest(),
                            coal.CollisionResult()):  # fmt: skip
                d = INTERSECTING
            else:
                d = float(coal.distance(gi, placed[i], gj, placed[j], self._request,
                                        coal.DistanceResult()))  # fmt: skip
            best = min(best, d)
        return best


class Placements:
    """The coal placements of a robot's collision objects at one configuration
    (`SelfCollision.placements`), each made when first read: a path's self check measures
    a few objects' pairs at most of its configurations."""

    __slots__ = ("_placed", "_pos", "_rot")

    def __init__(self, rot: np.ndarray, pos: np.ndarray) -> None:
        """``rot`` (L, 3, 3) and ``pos`` (L, 3): the objects' world rotations and
        positions [m]."""
        self._rot, self._pos = rot, pos
        self._placed: list[Any] = [None] * len(rot)

    def __getitem__(self, k: int) -> Any:
        """Object ``k``'s placement (a ``coal.Transform3s``)."""
        if (tf := self._placed[k]) is None:
            import coal

            tf = self._placed[k] = coal.Transform3s(self._rot[k], self._pos[k])
        return tf


def check_self_end(
    checker: SelfCollision | None, spheres: SphereCheck, q: np.ndarray, which: str
) -> None:
    """Raise `InCollision` if ``q`` (n,) [rad], the ``which`` end of a query, is in
    self-collision, naming the deepest pair: coal only on the pairs whose sphere bound is
    negative, their convex hulls first, the triangles where the hulls intersect."""
    if checker is None:
        return
    bound = spheres.self_clearances(q)[0]
    near = np.flatnonzero(bound < 0.0)
    if not near.size:
        return
    placed = checker.placements(*checker.joint_frames(q))
    worst: tuple[float, str, str] = (0.0, "", "")
    for k in near:
        a, b = spheres.self_pairs[k]
        d, exact = checker.placed_bound(placed, (a, b))
        if d < 0.0 and not exact:
            d = checker.placed_clearance(placed, (a, b))
        if d < worst[0]:
            worst = (d, a, b)
    d, a, b = worst
    if d < 0.0:
        raise InCollision(
            f"{which} is in self-collision: links {a!r} and {b!r} of the robot's own "
            f"collision geometry intersect ({d:.4f} m); move the {which} configuration",
            which, -1, -1, f"{a}/{b}", d,
        )  # fmt: skip
