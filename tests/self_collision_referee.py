"""Pinocchio's own collision model of a robot's URDF, the referee of the self-collision
tests (`test_planning_self_collision.py`, `test_self_collision_robots.py`)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin


class SelfCollisionReferee:
    """Pinocchio's own collision model of a robot's URDF (coal on its collision
    geometry), with the self pairs of the robot's file, link by link."""

    def __init__(self, robot: Any, pairs: tuple[tuple[str, str], ...]) -> None:
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
        # the robot's model (bounded); joints the robot leaves out stay at neutral
        model, self.joints = robot.model, []
        for j in range(1, self.full.njoints):
            name = self.full.names[j]
            if model.existJointName(name):
                ours = model.joints[model.getJointId(name)]
                theirs = self.full.joints[j]
                self.joints.append((ours.idx_q, theirs.idx_q, theirs.nq))

    def _place(self, q: np.ndarray) -> None:
        qf = pin.neutral(self.full)
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
