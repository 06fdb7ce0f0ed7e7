"""Self-clearance on a robot's own link pairs (`geosyn.metrics.planning.self_collision`).

Reference: Pinocchio's own GeometryModel of the UR5 URDF (its meshes as coal BVHs, built
by the test from the file) with ``pinocchio.computeDistance`` and
``pinocchio.computeCollision`` for the same link pairs, at seeded random configurations.
The UR5's forearm and wrist-3 convex hulls overlap by ~1 cm where the meshes are ~1 cm
apart: the meshes, not their hulls, decide for a URDF.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

from geosyn.metrics.planning.self_collision import INTERSECTING, SelfCollision
from geosyn.robots import load_robot
from geosyn.robots.collision_geometry import CollisionObject

PAIRS = (
    ("forearm_link", "wrist_3_link"),
    ("upper_arm_link", "wrist_2_link"),
    ("upper_arm_link", "wrist_3_link"),
    ("shoulder_link", "wrist_1_link"),
    ("base_link", "wrist_3_link"),
)


def test_self_clearance_matches_pinocchio_on_the_ur5_meshes() -> None:
    robot = load_robot("ur5_joint_limited_robot")
    urdf = Path(str(robot.source_file))
    full = pin.buildModelFromUrdf(str(urdf))
    share = [str(p) for p in urdf.parents if p.name == "share"]
    gm = pin.buildGeomFromUrdf(full, str(urdf), pin.GeometryType.COLLISION, package_dirs=share)
    link_of = {i: full.frames[g.parentFrame].name for i, g in enumerate(gm.geometryObjects)}
    index = {v: k for k, v in link_of.items()}
    for a, b in PAIRS:
        gm.addCollisionPair(pin.CollisionPair(index[a], index[b]))
    gd = gm.createData()
    data = full.createData()
    checker = SelfCollision(robot, PAIRS)
    rng = np.random.default_rng(4)
    for _ in range(40):
        q = robot.random_q(rng)
        qf = pin.neutral(full)
        qf[: robot.nq] = q
        pin.updateGeometryPlacements(full, data, gm, gd, qf)
        ref = np.inf
        for k in range(len(gm.collisionPairs)):
            if pin.computeCollision(gm, gd, k):
                ref = min(ref, INTERSECTING)
            else:
                ref = min(ref, pin.computeDistance(gm, gd, k).min_distance)
        d, _, _ = checker.clearance(q)
        assert abs(d - ref) <= 1e-6, (d, ref)


def test_overlapping_hulls_of_clear_meshes_are_not_a_self_collision() -> None:
    """The forearm and wrist-3 hulls (coal's distance between the convex hulls of the
    file's vertices) overlap at a seeded configuration where the meshes are clear: the
    checker follows the meshes (equal to Pinocchio's mesh distance: the test above)."""
    import coal
    from scipy.spatial import ConvexHull

    robot = load_robot("ur5_joint_limited_robot")
    checker = SelfCollision(robot, PAIRS[:1])
    objs = {o.link: o for o in checker.objects}
    fa, w3 = objs["forearm_link"], objs["wrist_3_link"]

    def hull(o: CollisionObject) -> Any:
        V = np.asarray(o.vertices, dtype=float)
        verts = coal.StdVec_Vec3s()
        for v in V[ConvexHull(V).vertices]:
            verts.append(v)
        return coal.Convex.convexHull(verts, False, None)

    hf, hw = hull(fa), hull(w3)
    data = robot.model.createData()
    rng = np.random.default_rng(0)
    for _ in range(60):
        q = robot.random_q(rng, 0.3)
        pin.forwardKinematics(robot.model, data, q)
        T = []
        for o in (fa, w3):
            M = data.oMi[robot.joint_id(o.joint)] * pin.SE3(o.placement)
            T.append(coal.Transform3s(M.rotation, M.translation))
        d_hull = coal.distance(coal.CollisionObject(hf, T[0]), coal.CollisionObject(hw, T[1]),
                               coal.DistanceRequest(), coal.DistanceResult())  # fmt: skip
        if d_hull < -0.005:
            break
    else:
        raise AssertionError("no seeded configuration with overlapping hulls")
    d, a, b = checker.clearance(q)
    assert (a, b) == PAIRS[0] and d > 0.005  # the meshes are clear by more than 5 mm
