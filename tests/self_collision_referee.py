"""Pinocchio's own collision model of a robot's URDF (coal on its triangle meshes), the
referee of the self-collision tests (`test_planning_self_collision.py`,
`test_self_collision_robots.py`) and, with obstacles (`MeshObstacleReferee`), of the
benchmarks' clearance on the real meshes (`benchmarks/planning_robots.py`,
`benchmarks/planning_anytime.py`): geosyn's exact check measures a mesh's convex hull,
which contains it."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin


class SelfCollisionReferee:
    """Pinocchio's own collision model of a robot's URDF (coal on its collision
    geometry), with the self pairs of the robot's file, link by link."""

    def __init__(self, robot: Any, pairs: tuple[tuple[str, str], ...],
                 lock: dict[str, float] | None = None) -> None:  # fmt: skip
        """``lock``: positions [rad or m] of the file's joints the robot's model left out
        (locked there; others stay at neutral)."""
        urdf = Path(str(robot.source_file))
        self.full = pin.buildModelFromUrdf(str(urdf))
        share = [str(p) for p in urdf.parents if p.name == "share"]
        self.gm = pin.buildGeomFromUrdf(self.full, str(urdf), pin.GeometryType.COLLISION,
                                        package_dirs=share)  # fmt: skip
        by_link: dict[str, list[int]] = {}
        for i, g in enumerate(self.gm.geometryObjects):
            by_link.setdefault(self.full.frames[g.parentFrame].name, []).append(i)
        for a, b in pairs:
            for i in by_link.get(a, []):
                for j in by_link.get(b, []):
                    self.gm.addCollisionPair(pin.CollisionPair(i, j))
        self.gd, self.data = self.gm.createData(), self.full.createData()
        # (the robot's coordinate, the file model's first coordinate, its count) per joint
        # by name: the file's continuous joints are (cos, sin) pairs there, one angle in
        # the robot's model (bounded); joints the robot leaves out stay at neutral or ``lock``
        model, self.joints = robot.model, []
        self.q_neutral = pin.neutral(self.full)
        for name, value in (lock or {}).items():
            j = self.full.getJointId(name)
            self.q_neutral[self.full.joints[j].idx_q] = value
        for j in range(1, self.full.njoints):
            name = self.full.names[j]
            if model.existJointName(name):
                ours = model.joints[model.getJointId(name)]
                theirs = self.full.joints[j]
                self.joints.append((ours.idx_q, theirs.idx_q, theirs.nq))

    def _place(self, q: np.ndarray) -> None:
        qf = self.q_neutral.copy()
        for ours, theirs, nq in self.joints:
            qf[theirs : theirs + nq] = (
                (math.cos(q[ours]), math.sin(q[ours])) if nq == 2 else q[ours : ours + nq]
            )
        pin.updateGeometryPlacements(self.full, self.data, self.gm, self.gd, qf)

    def collides(self, q: np.ndarray) -> bool:
        self._place(q)
        return bool(pin.computeCollisions(self.gm, self.gd, False))

    def distances(self, q: np.ndarray) -> dict[tuple[str, str], float]:
        """Smallest distance [m] per link pair (-inf where the meshes intersect)."""
        self._place(q)
        pin.computeCollisions(self.gm, self.gd, False)
        pin.computeDistances(self.gm, self.gd)
        out: dict[tuple[str, str], float] = {}
        for k, cp in enumerate(self.gm.collisionPairs):
            key = (self.full.frames[self.gm.geometryObjects[cp.first].parentFrame].name,
                   self.full.frames[self.gm.geometryObjects[cp.second].parentFrame].name)  # fmt: skip
            hit = self.gd.collisionResults[k].isCollision()
            d = -math.inf if hit else self.gd.distanceResults[k].min_distance
            out[key] = min(out.get(key, math.inf), d)
        return out


class MeshObstacleReferee(SelfCollisionReferee):
    """The distance of a robot's URDF collision geometry (Pinocchio's: coal BVHs of the
    triangle meshes, not their convex hulls) to obstacles (coal shapes made here), per
    configuration; an object whose bounding ball (a coal sphere) is farther from an
    obstacle than the nearest found so far on a path is not measured against it."""

    def __init__(self, robot: Any, lock: dict[str, float] | None = None) -> None:
        import coal

        super().__init__(robot, (), lock)
        self._obstacles: list[tuple[Any, Any, np.ndarray | None, float]] = []
        self._balls = []  # (coal sphere, centre in the object's frame) per object
        for g in self.gm.geometryObjects:
            g.geometry.computeLocalAABB()
            ball = coal.Sphere(float(g.geometry.aabb_radius))
            self._balls.append((ball, np.array(g.geometry.aabb_center)))

    def set_obstacles(self, obstacles: list[Any]) -> None:
        """Boxes, spheres, capsules and half-spaces of `geosyn.world`."""
        import coal

        self._obstacles = []
        for ob in obstacles:
            name, normal, offset = type(ob).__name__, None, 0.0
            if name == "HalfSpace":  # a mesh measured on its vertices (`clearance`)
                normal, offset = np.array(ob.normal, dtype=float), float(ob.offset)
                geom, tf = coal.Halfspace(normal, offset), coal.Transform3s()
            elif name == "Capsule":
                p0, p1 = np.array(ob.p0, dtype=float), np.array(ob.p1, dtype=float)
                axis, length = p1 - p0, float(np.linalg.norm(p1 - p0))
                z = axis / length if length > 0.0 else np.array([0.0, 0.0, 1.0])
                x = np.cross(z, [1.0, 0.0, 0.0] if abs(z[0]) < 0.9 else [0.0, 1.0, 0.0])
                x /= np.linalg.norm(x)
                geom = coal.Capsule(float(ob.radius), length)
                tf = coal.Transform3s(np.column_stack([x, np.cross(z, x), z]), 0.5 * (p0 + p1))
            elif name == "Box":
                geom = coal.Box(*(2.0 * np.array(ob.half_extents, dtype=float)))
                tf = coal.Transform3s(np.array(ob.rotation, dtype=float),
                                      np.array(ob.center, dtype=float))  # fmt: skip
            elif name == "Sphere":
                geom = coal.Sphere(float(ob.radius))
                tf = coal.Transform3s(np.eye(3), np.array(ob.center, dtype=float))
            else:
                raise ValueError(f"MeshObstacleReferee: no {name}")
            self._obstacles.append((geom, tf, normal, offset))

    def clearance(self, q: np.ndarray, below: float = math.inf) -> float:
        """Smallest distance [m] of the collision geometry to the obstacles at ``q``
        (the robot's coordinates; -inf where they intersect); pairs whose balls are at
        least ``below`` apart are left out (then at least ``below``). A mesh to a
        half-space: its nearest vertex (exact for triangles)."""
        import coal

        self._place(q)
        best = below
        for k, obj in enumerate(self.gm.geometryObjects):
            M, (ball, centre) = self.gd.oMg[k], self._balls[k]
            tf = coal.Transform3s(M.rotation, M.translation)
            tf_ball = coal.Transform3s(M.rotation, M.rotation @ centre + M.translation)
            for geom, tf_o, normal, offset in self._obstacles:
                if coal.distance(ball, tf_ball, geom, tf_o, coal.DistanceRequest(),
                                 coal.DistanceResult()) >= best:  # fmt: skip
                    continue
                g = obj.geometry
                if normal is not None and hasattr(g, "vertices"):
                    world = np.asarray(g.vertices()) @ M.rotation.T + M.translation
                    d = float((world @ normal).min() - offset)
                elif coal.collide(g, tf, geom, tf_o, coal.CollisionRequest(),
                                  coal.CollisionResult()):  # fmt: skip
                    return -math.inf
                else:
                    d = float(coal.distance(g, tf, geom, tf_o, coal.DistanceRequest(),
                                            coal.DistanceResult()))  # fmt: skip
                if d < 0.0:
                    return -math.inf
                best = min(best, d)
        return best

    def path_clearance(self, Q: np.ndarray) -> float:
        """Smallest `clearance` [m] over the configurations ``Q`` (K, n)."""
        best = math.inf
        for q in Q:
            best = min(best, self.clearance(q, best))
            if best == -math.inf:
                break
        return best
