"""Self-clearance on a robot's own link pairs (`geosyn.metrics.planning.self_collision`,
`geosyn.metrics.planning.self_path`).

Reference: Pinocchio's own GeometryModel of the UR5 URDF (its meshes as coal BVHs, built
by the test from the file) with ``pinocchio.computeDistance`` and
``pinocchio.computeCollision`` for the same link pairs, at seeded random configurations.
The UR5's forearm and wrist-3 convex hulls overlap by ~1 cm where the meshes are ~1 cm
apart: the meshes, not their hulls, decide for a URDF.

Plans (`Planner`): Pinocchio's collision model of the Panda URDF with the file's self
pairs referees that no returned plan self-collides, that the spheres' self distances are
lower bounds of the exact ones, and that a self-colliding start is refused.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin
import pytest
from self_collision_referee import SelfCollisionReferee

from geosyn.metrics import KineticEnergyMetric
from geosyn.metrics.planning.errors import InCollision
from geosyn.metrics.planning.exact_path import checked_configurations
from geosyn.metrics.planning.planner import Planner
from geosyn.metrics.planning.self_collision import INTERSECTING, SelfCollision, check_self_end
from geosyn.metrics.planning.self_path import SELF_NEAR
from geosyn.robots import load_robot
from geosyn.robots.collision_geometry import CollisionObject

# with `pytest -n`, one worker: the module's Panda planner is built once (~8 s cold)
pytestmark = pytest.mark.xdist_group("planning_self_collision")

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


# Panda: the straight line between these two self-clear configurations folds the hand
# into link 2 halfway (found by a seeded search: a self-colliding random configuration
# plus and minus 0.3 rad along a random direction; both ends >= 16 mm clear).
FOLD_START = np.array([-2.43, -0.95, 1.23, -2.67, 0.62, 0.59, 1.39])
FOLD_GOAL = np.array([-2.42, -0.92, 1.6, -2.8, 0.04, 1.19, 1.38])


@pytest.fixture(scope="module")
def panda_planner() -> Planner:
    return Planner(KineticEnergyMetric(load_robot("panda")))


@pytest.fixture(scope="module")
def panda_referee(panda_planner: Planner) -> SelfCollisionReferee:
    return SelfCollisionReferee(panda_planner.robot, panda_planner.sphere_check.self_pairs)


def test_sphere_self_distances_are_lower_bounds_of_pinocchios(
    panda_planner: Planner, panda_referee: SelfCollisionReferee
) -> None:
    """Per self pair, the spheres' distance is at most Pinocchio's exact one (the fitted
    spheres cover the meshes), at seeded random configurations (1e-9 m)."""
    check, rng = panda_planner.sphere_check, np.random.default_rng(7)
    assert len(check.self_pairs) >= 30
    for _ in range(15):
        q = panda_planner.robot.random_q(rng)
        bounds = check.self_clearances(q)[0]
        ref = panda_referee.distances(q)
        for k, pair in enumerate(check.self_pairs):
            assert bounds[k] <= ref[pair] + 1e-9, (pair, bounds[k], ref[pair])


def test_a_plan_never_folds_the_panda_into_itself(
    panda_planner: Planner, panda_referee: SelfCollisionReferee
) -> None:
    """The straight line (and the unconstrained geodesic near it) folds the hand into
    link 2; the returned plan goes round: Pinocchio finds no self-collision at any
    configuration of the plan at its exact resolution, and its reported self-clearance
    is not negative and not above Pinocchio's distance at those configurations."""
    line = checked_configurations(np.array([FOLD_START, FOLD_GOAL]), 0.02)
    assert any(panda_referee.collides(q) for q in line)  # the test means something
    assert not panda_referee.collides(FOLD_START) and not panda_referee.collides(FOLD_GOAL)
    plan = panda_planner.plan(FOLD_START, FOLD_GOAL, budget=1.0, seed=0)
    Q = checked_configurations(plan.q, plan.exact_resolution)
    assert not any(panda_referee.collides(q) for q in Q)
    assert 0.0 <= plan.self_clearance <= SELF_NEAR
    lowest = min(min(panda_referee.distances(q).values()) for q in Q[:: max(len(Q) // 40, 1)])
    assert plan.self_clearance <= lowest + 1e-6
    np.testing.assert_allclose(plan.q[0], FOLD_START, atol=1e-9)
    np.testing.assert_allclose(plan.q[-1], FOLD_GOAL, atol=1e-9)


HAND_ON_BASE_START = np.array([2.2595, 1.1366, -0.116, -2.3742, 1.7493, 3.4642, -1.3552])
HAND_ON_BASE_GOAL = np.array([0.2256, -0.2018, 2.4976, -2.9502, 1.3444, 2.2987, -2.7329])


def test_an_end_whose_spheres_overlap_lowers_the_floor_only_near_it(
    panda_planner: Planner, panda_referee: SelfCollisionReferee
) -> None:
    """At this goal (seeded random query 5 of `benchmarks/planning_random.py`) the hand's
    spheres overlap the base's by 69 mm while the meshes are 2.7 mm apart. A floor
    lowered to that overlap along the whole path let the sampled paths touch hand and base
    3.1 rad from the goal, and the query was refused (8 times the same path); the floor
    ramps back up away from the ends (`SELF_FLOOR_RAMP`), and the query is planned within
    2 s, self-clear for Pinocchio's collision model at its exact resolution."""
    check = panda_planner.sphere_check
    k = check.self_pairs.index(("panda_hand", "panda_link0"))
    assert check.self_clearances(HAND_ON_BASE_GOAL)[0, k] < -0.06  # the test means something
    assert panda_referee.distances(HAND_ON_BASE_GOAL)[("panda_hand", "panda_link0")] > 0.0
    plan = panda_planner.plan(HAND_ON_BASE_START, HAND_ON_BASE_GOAL, budget=2.0, seed=0)
    Q = checked_configurations(plan.q, plan.exact_resolution)
    assert not any(panda_referee.collides(q) for q in Q)
    assert plan.self_clearance >= 0.0


def test_the_verification_catches_a_self_colliding_path(
    panda_planner: Planner, panda_referee: SelfCollisionReferee
) -> None:
    """The straight line, which Pinocchio finds self-colliding, gets a negative
    self-clearance (refused); each half of it up to the last configuration Pinocchio
    finds clear is accepted."""
    line = np.array([FOLD_START, FOLD_GOAL])
    assert panda_planner.self_check(line) < 0.0
    assert not panda_planner.self_ok(panda_planner.self_check(line))
    Q = checked_configurations(line, panda_planner.exact_resolution)
    first_hit = next(i for i, q in enumerate(Q) if panda_referee.collides(q))
    clear_part = np.array([FOLD_START, Q[max(first_hit - 2, 0)]])
    assert panda_planner.self_ok(panda_planner.self_check(clear_part))


def test_a_self_colliding_start_is_refused(
    panda_planner: Planner, panda_referee: SelfCollisionReferee
) -> None:
    mid = 0.5 * (FOLD_START + FOLD_GOAL)
    rng = np.random.default_rng(0)
    hit = next(q for q in (mid + 0.05 * s * rng.uniform(-1, 1, 7) for s in range(20))
               if panda_referee.collides(q))  # fmt: skip
    with pytest.raises(InCollision, match="self-collision"):
        panda_planner.plan(hit, FOLD_GOAL, budget=0.5)


def test_an_end_is_refused_exactly_where_pinocchio_finds_a_self_collision() -> None:
    """UR5 (its forearm and wrist 3 hulls overlap where the meshes are apart): at 150
    seeded configurations, `check_self_end` (hulls first, triangles only where they
    intersect) refuses exactly those where Pinocchio's collision model of the URDF finds
    a self-collision on the same pairs; both answers occur."""
    robot = load_robot("ur5")
    planner = Planner(KineticEnergyMetric(robot))
    referee = SelfCollisionReferee(robot, planner.sphere_check.self_pairs)
    rng, refused, agree = np.random.default_rng(3), 0, 0
    for _ in range(150):
        q = robot.random_q(rng)
        try:
            check_self_end(planner.self_collision, planner.sphere_check, q, "start")
            hit = False
        except InCollision:
            hit = True
        agree += hit == referee.collides(q)
        refused += hit
    assert agree == 150
    assert 5 <= refused <= 145, refused


def test_the_self_check_with_joint_frames_from_c_is_pinocchios_minimum(
    panda_planner: Planner, panda_referee: SelfCollisionReferee
) -> None:
    """A path up to just before the fold's self-collision: its self-clearance, computed
    with the joints placed in C for every checked configuration (the planner's default),
    is Pinocchio's smallest pair distance over those configurations (1e-6 m), and the
    same as without the C placements (Pinocchio's forward kinematics per item)."""
    from geosyn.metrics.planning.self_path import path_self_contact

    assert panda_planner.sampling.aids.kinematics is not None  # the C check is in use
    line = np.array([FOLD_START, FOLD_GOAL])
    Q = checked_configurations(line, panda_planner.exact_resolution)
    first_hit = next(i for i, q in enumerate(Q) if panda_referee.collides(q))
    part = np.array([FOLD_START, Q[max(first_hit - 2, 0)]])
    ours = panda_planner.self_check(part)
    lowest = min(min(panda_referee.distances(q).values())
                 for q in checked_configurations(part, panda_planner.exact_resolution))  # fmt: skip
    assert 0.0 < lowest < SELF_NEAR  # the test means something
    assert abs(ours - lowest) < 1e-6
    plain, contact = path_self_contact(panda_planner.self_collision,
                                       panda_planner.sphere_check, part,
                                       panda_planner.exact_resolution)  # fmt: skip
    assert abs(plain - ours) < 1e-12 and contact is None


def test_the_ur5_self_check_measures_triangles_only_where_the_hulls_do_not_decide(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """A pan of the UR5 (joint 1 alone moves): three pairs stay 14-16 mm apart at every
    checked configuration, nearer than `SELF_NEAR`, and their spheres overlap. The path's
    self-clearance is Pinocchio's smallest pair distance over those configurations
    (1e-6 m); coal measures the triangles once, where the hulls do not decide (the rule
    before this one measured them at every near (configuration, pair) item: 483)."""
    robot = load_robot("ur5")
    planner = Planner(KineticEnergyMetric(robot))
    q0 = np.array([0.0, -1.2, 1.6, -1.9, -1.57, 0.0])
    line = np.array([q0, q0 + np.array([0.8, 0.0, 0.0, 0.0, 0.0, 0.0])])
    Q = checked_configurations(line, planner.exact_resolution)
    near = int(np.sum(planner.sphere_check.self_clearances(Q) < SELF_NEAR))
    assert near >= 3 * len(Q) > 300  # the test means something
    calls = []
    measured = SelfCollision.placed_clearance
    monkeypatch.setattr(SelfCollision, "placed_clearance",
                        lambda self, *a: calls.append(a[-1]) or measured(self, *a))  # fmt: skip
    ours = planner.self_check(line)
    referee = SelfCollisionReferee(robot, planner.sphere_check.self_pairs)
    lowest = min(min(referee.distances(q).values()) for q in Q)
    assert 0.0 < lowest < SELF_NEAR
    assert abs(ours - lowest) < 1e-6, (ours, lowest)
    assert len(calls) <= 3, calls


def test_a_decided_path_cut_short_reports_a_lower_bound_and_a_crossing_is_still_found(
    monkeypatch: pytest.MonkeyPatch, panda_planner: Planner, panda_referee: SelfCollisionReferee
) -> None:
    """With no time to refine (`SELF_REFINE_TIME` 0): the UR5 pan above, self-clear,
    reports a value between 0 and Pinocchio's smallest pair distance over its checked
    configurations (a lower bound, not NaN); the Panda's folding line, which Pinocchio
    finds self-colliding, is still found negative (the items that could intersect are
    refined first, whatever the time)."""
    from geosyn.metrics.planning import self_path

    monkeypatch.setattr(self_path, "SELF_REFINE_TIME", 0.0)
    robot = load_robot("ur5")
    planner = Planner(KineticEnergyMetric(robot))
    q0 = np.array([0.0, -1.2, 1.6, -1.9, -1.57, 0.0])
    line = np.array([q0, q0 + np.array([0.8, 0.0, 0.0, 0.0, 0.0, 0.0])])
    referee = SelfCollisionReferee(robot, planner.sphere_check.self_pairs)
    Q = checked_configurations(line, planner.exact_resolution)
    lowest = min(min(referee.distances(q).values()) for q in Q)
    cut = planner.self_check(line)
    assert 0.0 <= cut <= lowest + 1e-9, (cut, lowest)
    fold = np.array([FOLD_START, FOLD_GOAL])
    assert any(panda_referee.collides(q) for q in checked_configurations(fold, 0.02))
    assert panda_planner.self_check(fold) < 0.0
