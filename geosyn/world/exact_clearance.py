"""Exact clearance of a robot's own collision geometry to the world's shapes (coal).

Every collision object of the robot's file (`geosyn.robots.collision_geometry`: URDF
meshes and primitives read by Pinocchio, MJCF geoms compiled by MuJoCo) becomes a coal
shape: a mesh its convex hull (what MuJoCo collides for an MJCF; for a URDF mesh exact
when the mesh is convex, as the Panda's collision meshes are, and conservative
otherwise), a primitive itself. Obstacles (`geosyn.world.shapes`) become coal's sphere,
box, capsule, cylinder and half-space. Distances are coal's signed distances (GJK, EPA
inside): negative is penetration depth.

`ExactClearance.path_clearance` checks a piecewise-linear joint path at configurations at
most ``resolution`` apart (joint-space max-norm) and returns the smallest clearance. A
per-link bounding ball (a lower bound of the exact distance) skips the far pairs; pairs
nearer than ``near`` get coal's distance.
"""

from __future__ import annotations

import math
import time
import weakref
from collections.abc import Sequence
from typing import Any, NamedTuple

import numpy as np
import pinocchio as pin

from geosyn.core.validation import check_positive
from geosyn.robots.collision_geometry import CollisionObject, collision_objects
from geosyn.robots.robot import Robot
from geosyn.world.shapes import Box, Capsule, Cylinder, HalfSpace, Shape, Sphere, check_shape

__all__ = [
    "ExactClearance",
    "PathClearance",
    "PlacedObstacle",
    "bounding_ball",
    "checked_configurations",
    "coal_shape",
]


def checked_configurations(path: np.ndarray, resolution: float) -> np.ndarray:
    """(K, n) the configurations `ExactClearance.path_clearance` checks on ``path``
    (T, n) [rad]: its first sample, then each segment's linear points at most
    ``resolution`` [rad] apart (max-norm), its end included."""
    path = np.asarray(path, dtype=float)
    seg = np.abs(np.diff(path, axis=0)).max(axis=1) if len(path) > 1 else np.zeros(0)
    steps = np.maximum(1, np.ceil(seg / resolution).astype(int))
    pts = [path[:1]]
    for a, b, k in zip(path[:-1], path[1:], steps, strict=True):
        s = np.arange(1, k + 1)[:, None] / k
        pts.append(a + s * (b - a))
    return np.vstack(pts)


class PlacedObstacle(NamedTuple):
    """An obstacle as `ExactClearance` measures it.

    Attributes:
        geom: its coal geometry (in its own frame).
        obj: the coal collision object (geometry and pose).
        pose: (4, 4) its pose in the world frame [m].
        shape: the `geosyn.world` shape it was made from.
    """

    geom: Any
    obj: Any
    pose: np.ndarray
    shape: Shape


class PathClearance(NamedTuple):
    """The smallest exact clearance along a path.

    Attributes:
        clearance: smallest signed distance [m] between a collision object of the robot
            and an obstacle over the checked configurations (negative: penetration;
            ``near`` or more when every pair stays farther than ``near``).
        where: which checked configuration, as a path parameter in [0, 1].
        link: the robot link of the closest pair.
        obstacle: index of the obstacle of the closest pair (-1 if none is near).
        checked: number of configurations checked.
        resolution: largest joint-space step between checked configurations (max-norm) [rad].
    """

    clearance: float
    where: float
    link: str
    obstacle: int
    checked: int
    resolution: float


def _obstacle_geometry(shape: Shape) -> tuple[Any, np.ndarray]:
    """(coal geometry, (4, 4) world pose) of an obstacle."""
    import coal

    T = np.eye(4)
    if isinstance(shape, Sphere):
        T[:3, 3] = shape.center
        return coal.Sphere(shape.radius), T
    if isinstance(shape, Box):
        T[:3, :3], T[:3, 3] = np.asarray(shape.rotation), shape.center
        return coal.Box(*(2.0 * np.asarray(shape.half_extents))), T
    if isinstance(shape, Cylinder):
        T[:3, :3], T[:3, 3] = np.asarray(shape.rotation), shape.center
        return coal.Cylinder(shape.radius, 2.0 * shape.half_length), T
    if isinstance(shape, Capsule):
        p0, p1 = np.asarray(shape.p0), np.asarray(shape.p1)
        axis, length = p1 - p0, float(np.linalg.norm(p1 - p0))
        if length > 0.0:
            z = axis / length
            x = np.cross(z, [1.0, 0.0, 0.0] if abs(z[0]) < 0.9 else [0.0, 1.0, 0.0])
            x /= np.linalg.norm(x)
            T[:3, :3] = np.column_stack([x, np.cross(z, x), z])
        T[:3, 3] = 0.5 * (p0 + p1)
        return coal.Capsule(shape.radius, length), T
    if isinstance(shape, HalfSpace):  # coal's half-space is n . x <= d, as ours
        return coal.Halfspace(np.asarray(shape.normal, dtype=float), float(shape.offset)), T
    raise TypeError(f"unknown shape {type(shape).__name__}")  # check_shape ran before


#: Each collision object's coal geometry, made once per process (the exact clearance and
#: the self-collision check of one robot share them; coal only reads them).
_SHAPES: weakref.WeakKeyDictionary[CollisionObject, Any] = weakref.WeakKeyDictionary()


def bounding_ball(obj: CollisionObject) -> tuple[np.ndarray, float]:
    """((3,) centre in the frame of the object's joint [m], radius [m]) of a ball holding
    the object's `coal_shape` (the axis-aligned box of its own frame, placed)."""
    shape = coal_shape(obj)
    shape.computeLocalAABB()
    centre = obj.placement[:3, :3] @ np.asarray(shape.aabb_center) + obj.placement[:3, 3]
    return centre, float(shape.aabb_radius)


def coal_shape(obj: CollisionObject) -> Any:
    """The coal geometry of a robot collision object (a mesh: its convex hull), made
    once per object."""
    if (shape := _SHAPES.get(obj)) is None:
        shape = _SHAPES[obj] = _make_shape(obj)
    return shape


def _make_shape(obj: CollisionObject) -> Any:
    import coal

    s = obj.size
    if obj.kind == "mesh":
        pts = coal.StdVec_Vec3s()
        pts.extend([np.asarray(v, dtype=float) for v in obj.vertices])
        return coal.Convex.convexHull(pts, False, None)
    if obj.kind == "box":
        return coal.Box(*(2.0 * s))
    if obj.kind == "sphere":
        return coal.Sphere(float(s[0]))
    if obj.kind == "capsule":
        return coal.Capsule(float(s[0]), 2.0 * float(s[1]))
    if obj.kind == "cylinder":
        return coal.Cylinder(float(s[0]), 2.0 * float(s[1]))
    return coal.Ellipsoid(*s)


class ExactClearance:
    """Exact distances between a robot's collision geometry and obstacles.

    Args:
        robot: a robot loaded from a URDF or MJCF file.
        near: pairs whose bounding balls are farther apart than this [m] are not measured
            exactly (their clearance is then known to be > ``near``), > 0.

    Builds coal shapes once (allocates); `clearance` and `path_clearance` only evaluate.

    Attributes (read-only, for batched checks such as
    `geosyn.metrics.planning.exact_path`; one entry per collision object of ``objects``):
        geoms: coal geometry of each object (a mesh: its convex hull).
        joints: Pinocchio joint index each object moves with (0: the world).
        placements: (pin.SE3) each object's placement in its joint's frame.
        balls: ((3,) centre in the joint's frame [m], radius [m]) of each object's
            bounding ball.
        request: the coal distance request used.
        data: Pinocchio data of ``robot.model``: a workspace, overwritten by every
            evaluation.

    Raises:
        geosyn.robots.RobotFileError: no readable collision geometry.
    """

    def __init__(self, robot: Robot, *, near: float = 0.05) -> None:
        import coal

        self.robot = robot
        self.near = check_positive(near, "near", "m")
        self.objects = collision_objects(robot)
        self.geoms = tuple(coal_shape(o) for o in self.objects)
        self.joints = tuple(
            robot.joint_id(o.joint) if o.joint != "universe" else 0 for o in self.objects
        )
        self.placements = tuple(pin.SE3(o.placement) for o in self.objects)
        # bounding ball of each object in its joint frame (centre, radius)
        self.balls: tuple[tuple[np.ndarray, float], ...] = tuple(
            bounding_ball(o) for o in self.objects
        )
        self.request = coal.DistanceRequest()
        self.data = robot.model.createData()
        self._obstacles: tuple[PlacedObstacle, ...] = ()

    @property
    def obstacles(self) -> tuple[PlacedObstacle, ...]:
        """The obstacles set (`set_obstacles`), with their coal geometry and pose."""
        return self._obstacles

    def set_obstacles(self, obstacles: Sequence[Shape]) -> None:
        """Replace the obstacles (shapes of `geosyn.world`)."""
        import coal

        placed = []
        for i, ob in enumerate(obstacles):
            ob = check_shape(ob, f"obstacles[{i}]")
            geom, T = _obstacle_geometry(ob)
            obj = coal.CollisionObject(geom, coal.Transform3s(T[:3, :3], T[:3, 3]))
            placed.append(PlacedObstacle(geom, obj, T, ob))
        self._obstacles = tuple(placed)

    def clearance(self, q: np.ndarray) -> tuple[float, str, int]:
        """Smallest exact clearance [m] at ``q`` (n,) [rad], its link and obstacle
        (``(inf, "", -1)`` without obstacles; ``near`` or more when none is near)."""
        import coal

        from geosyn.world.distance import signed_distance

        if not self._obstacles:
            return math.inf, "", -1
        model, data = self.robot.model, self.data
        pin.forwardKinematics(model, data, np.asarray(q, dtype=float))
        oMj = [data.oMi[j] if j else pin.SE3.Identity() for j in self.joints]
        centres = np.array(
            [M.rotation @ c + M.translation for M, (c, _) in zip(oMj, self.balls, strict=True)]
        )
        radii = np.array([r for _, r in self.balls])
        # lower bounds of every (object, obstacle) distance: the objects' bounding balls
        bound = (
            np.column_stack([signed_distance(ob.shape, centres) for ob in self._obstacles])
            - radii[:, None]
        )
        best, link, which = math.inf, "", -1
        for k, o in zip(*np.nonzero(bound < self.near), strict=True):
            if bound[k, o] >= best:
                continue  # the exact distance is at least this lower bound
            oMg = oMj[k] * self.placements[k]
            tf = coal.CollisionObject(
                self.geoms[k], coal.Transform3s(oMg.rotation, oMg.translation)
            )
            d = float(
                coal.distance(tf, self._obstacles[o].obj, self.request, coal.DistanceResult())
            )
            if d < best:
                best, link, which = d, self.objects[k].link, int(o)
        if which < 0:
            return self.near, "", -1
        return best, link, which

    def path_clearance(
        self, path: np.ndarray, resolution: float = 0.005, deadline: float = math.inf
    ) -> PathClearance:
        """Smallest exact clearance of the linear interpolation of ``path`` (T, n) [rad],
        checked at configurations at most ``resolution`` [rad] apart (max-norm); NaN when
        ``time.perf_counter()`` passes ``deadline`` [s] before every one is checked."""
        resolution = check_positive(resolution, "resolution", "rad")
        Q = checked_configurations(path, resolution)
        best = PathClearance(math.inf, 0.0, "", -1, len(Q), resolution)
        for i, q in enumerate(Q):
            if i % 16 == 15 and time.perf_counter() > deadline:
                return best._replace(clearance=math.nan, checked=i)
            c, link, o = self.clearance(q)
            if c < best.clearance:
                best = best._replace(
                    clearance=c, where=i / max(len(Q) - 1, 1), link=link, obstacle=o
                )
        return best
