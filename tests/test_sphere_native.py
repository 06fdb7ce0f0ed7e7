"""The C sphere check (`geosyn.metrics.planning.sphere_native`) against independent
referees: Pinocchio's forward kinematics (sphere centres placed by ``data.oMi``), the
closed-form signed distances of `geosyn.world.distance`, and the validity rule written
out by hand. Trees with unaligned hinges, a slide joint and two root joints included.
Tolerances: 1e-12 m (round-off of the kinematics summed in another order)."""

from __future__ import annotations

import math
from pathlib import Path
from types import SimpleNamespace
from unittest import mock

import numpy as np
import pinocchio as pin
import pytest

from geosyn.core.errors import InvalidArgument
from geosyn.metrics.planning.rrt import RRT_STEP, string_pull
from geosyn.metrics.planning.sphere_check import SphereCheck
from geosyn.metrics.planning.sphere_native import (
    NATIVE_MAX_NQ,
    NativeSphereCheck,
    joint_table,
    sphere_check,
)
from geosyn.robots import load_robot
from geosyn.robots.robot import CollisionSphere
from geosyn.world import shapes
from geosyn.world.distance import signed_distance

FIXTURES = Path(__file__).parent / "fixtures"
TOL = 1e-12


def _spheres(robot, rng, per_joint: int = 3) -> list[CollisionSphere]:
    """Random spheres on every joint and two on the world (seeded)."""
    out = [CollisionSphere("universe", tuple(rng.uniform(-0.3, 0.3, 3)), 0.02)]
    for name in robot.model.names[1:]:
        for _ in range(per_joint):
            out.append(CollisionSphere(name, tuple(rng.uniform(-0.1, 0.1, 3)),
                                       float(rng.uniform(0.01, 0.05))))  # fmt: skip
    return out


def _world_centres(robot, spheres, q) -> np.ndarray:
    """(S, 3) sphere centres placed by Pinocchio's own kinematics (the referee)."""
    data = robot.model.createData()
    pin.forwardKinematics(robot.model, data, q)
    out = []
    for s in spheres:
        M = pin.SE3.Identity() if s.joint == "universe" else data.oMi[robot.joint_id(s.joint)]
        out.append(M.act(np.asarray(s.center)))
    return np.array(out)


def _pair_distances(robot, fitted, pairs, Q: np.ndarray) -> np.ndarray:
    """(K, P) each link pair's smallest sphere distance [m] at each configuration of Q,
    from centres placed by Pinocchio (the referee)."""
    radius = np.array([s.radius for s in fitted.spheres])
    links = list(fitted.links)
    out = np.empty((len(Q), len(pairs)))
    for k, q in enumerate(Q):
        c = _world_centres(robot, fitted.spheres, q)
        for p, (a, b) in enumerate(pairs):
            ia = [i for i, link in enumerate(links) if link == a]
            ib = [j for j, link in enumerate(links) if link == b]
            out[k, p] = min(np.linalg.norm(c[i] - c[j]) - radius[i] - radius[j]
                            for i in ia for j in ib)  # fmt: skip
    return out


def _obstacles(rng) -> list[shapes.Shape]:
    R = pin.rpy.rpyToMatrix(*rng.uniform(-1.0, 1.0, 3))
    return [
        shapes.Sphere(tuple(rng.uniform(-0.3, 0.3, 3)), 0.05),
        shapes.Box(tuple(rng.uniform(-0.3, 0.3, 3)), (0.05, 0.1, 0.02), R),
        shapes.Capsule(tuple(rng.uniform(-0.3, 0.3, 3)), tuple(rng.uniform(-0.3, 0.3, 3)), 0.03),
        shapes.Cylinder(tuple(rng.uniform(-0.3, 0.3, 3)), 0.04, 0.1, R.T),
        shapes.HalfSpace((0.0, 0.0, 1.0), -0.2),
    ]


@pytest.mark.parametrize(
    "robot_name", ["panda", str(FIXTURES / "arm_root_quat.xml"), str(FIXTURES / "two_fingers.xml")]
)
def test_clearances_match_pinocchio_kinematics_and_closed_form_distances(robot_name: str) -> None:
    """Every shape at once and each alone, 200 seeded configurations within the limits."""
    robot = load_robot(robot_name)
    assert not isinstance(joint_table(robot), str)
    rng = np.random.default_rng(3)
    spheres = _spheres(robot, rng)
    check = NativeSphereCheck(robot, spheres)
    radius = np.array([s.radius for s in spheres])
    lo = np.where(np.isfinite(robot.q_min), robot.q_min, -np.pi)
    hi = np.where(np.isfinite(robot.q_max), robot.q_max, np.pi)
    Q = rng.uniform(lo, hi, size=(200, robot.nq))
    centres = np.array([_world_centres(robot, spheres, q) for q in Q])  # (K, S, 3)
    obstacles = _obstacles(rng)
    for chosen in [obstacles, *([ob] for ob in obstacles)]:
        check.set_obstacles(chosen)
        expected = np.array([
            min(float((signed_distance(ob, c) - radius).min()) for ob in chosen) for c in centres
        ])  # fmt: skip
        assert np.abs(check.clearances(Q) - expected).max() < TOL


def test_group_distances_are_the_closed_form_minimum_per_group() -> None:
    """Per group of spheres and obstacle, the smallest clearance of the group's spheres
    placed by Pinocchio with the closed-form distances (1e-12 m); a sphere in no group
    (-1) counts nowhere, an empty group is +inf; an out-of-range group is refused."""
    robot = load_robot("panda")
    rng = np.random.default_rng(11)
    spheres = _spheres(robot, rng)
    check = NativeSphereCheck(robot, spheres)
    radius = np.array([s.radius for s in spheres])
    group = rng.integers(-1, 4, size=len(spheres))  # groups 0-3, group 4 left empty
    Q = rng.uniform(robot.q_min, robot.q_max, size=(50, robot.nq))
    obstacles = _obstacles(rng)
    check.set_obstacles(obstacles)
    got = check.group_distances(Q, group, 5)
    assert got.shape == (50, 5, len(obstacles))
    for k, q in enumerate(Q):
        c = _world_centres(robot, spheres, q)
        for o, ob in enumerate(obstacles):
            d = signed_distance(ob, c) - radius
            for g in range(4):
                assert abs(got[k, g, o] - d[group == g].min()) < TOL
    assert np.all(np.isinf(got[:, 4]))
    with pytest.raises(InvalidArgument, match="group"):
        check.group_distances(Q, group, 3)


def test_self_clearances_and_validity_follow_the_rule() -> None:
    """Self pairs on the Panda's fitted spheres: each pair's smallest sphere distance
    from Pinocchio-placed centres; `valid` = clearance >= margin and every pair >= its
    floor, with margins and floors near the values the bounding balls prune at."""
    from geosyn.robots.collision_spheres import file_spheres

    robot = load_robot("panda")
    fitted = file_spheres(robot)
    check = NativeSphereCheck(robot, fitted.spheres)
    check.set_self_pairs(fitted.spheres, fitted.links, fitted.self_pairs)
    rng = np.random.default_rng(5)
    Q = rng.uniform(robot.q_min, robot.q_max, size=(300, 7))
    own = _pair_distances(robot, fitted, check.self_pairs, Q)
    assert np.abs(check.self_clearances(Q) - own).max() < TOL
    check.set_obstacles([shapes.Box((0.5, 0.0, 0.4), (0.1, 0.3, 0.3), np.eye(3))])
    clear = check.clearances(Q)
    own = check.self_clearances(Q)  # equal to the referee's; the floors come from it
    folded = int(np.argmin(own.min(axis=1)))  # a configuration with sphere overlaps
    assert own[folded].min() < 0.0
    for ends in ((), (Q[folded],)):
        # floors: min(0, each pair's distance at the ends); the margin unchanged there
        check.set_ends(ends, np.full(len(ends), np.inf), 0.0)
        floor = np.minimum(0.0, own[folded]) if ends else np.zeros(len(check.self_pairs))
        for margin in (0.0, 0.01, float(np.median(clear))):
            expected = (clear >= margin) & np.all(own >= floor, axis=1)
            if ends:  # valid at its own floors
                assert expected[folded] == (clear[folded] >= margin)
            assert 0 < expected.sum() < len(Q)  # both answers occur
            np.testing.assert_array_equal(check.valid(Q, margin), expected)
            assert check.all_valid(Q[expected], margin)
            assert not check.all_valid(Q, margin)


def test_segment_check_stops_at_an_obstacle_the_numpy_check_agrees() -> None:
    """A Panda joint-1 sweep through a post is refused, its free half accepted; the
    same answers as the numpy `SphereCheck` on the same points."""
    robot = load_robot("panda")
    rng = np.random.default_rng(0)
    spheres = _spheres(robot, rng, per_joint=2)
    native, slow = NativeSphereCheck(robot, spheres), SphereCheck(robot, spheres)
    q = np.array([0.0, 0.3, 0.0, -1.5, 0.0, 1.8, 0.8])
    c = _world_centres(robot, spheres, q)[-1]  # a sphere of the hand
    post = shapes.Box((-c[0], -c[1], c[2]), (0.03, 0.03, 0.5), np.eye(3))  # joint 1 at pi
    for check in (native, slow):
        check.set_obstacles([post])
    a, b = q.copy(), q.copy()
    b[0] = 2.0 * np.pi - 0.2
    mid = q.copy()
    mid[0] = 2.0
    for res in (0.05, 0.01):
        assert not native.segment_valid(a, b, res, 0.0)
        assert native.segment_valid(a, mid, res, 0.0)
        assert native.segment_valid(a, b, res, 0.0) == slow.segment_valid(a, b, res, 0.0)


def _path_valid_by_hand(robot, spheres, post, X: np.ndarray, res: float) -> bool:
    """The path rule written out: every point ``a + (i / k) (b - a)``, i = 1 .. k,
    ``k = max(1, ceil(|b - a| / res))``, of every segment keeps each sphere (placed by
    Pinocchio) clear of the post (closed-form distance minus radius >= 0)."""
    radii = np.array([s.radius for s in spheres])
    for a, b in zip(X[:-1], X[1:], strict=True):
        k = max(1, math.ceil(np.linalg.norm(b - a) / res))
        for i in range(1, k + 1):
            centres = _world_centres(robot, spheres, a + (i / k) * (b - a))
            if np.min(signed_distance(post, centres) - radii) < 0.0:
                return False
    return True


def test_path_check_is_every_segment_by_the_rule() -> None:
    """A Panda path of three segments, its last through a post, and its free first two:
    the C path check (one call) and the numpy one answer as the rule written out by hand,
    at two resolutions."""
    robot = load_robot("panda")
    spheres = _spheres(robot, np.random.default_rng(0), per_joint=2)
    native, slow = NativeSphereCheck(robot, spheres), SphereCheck(robot, spheres)
    q = np.array([0.0, 0.3, 0.0, -1.5, 0.0, 1.8, 0.8])
    c = _world_centres(robot, spheres, q)[-1]
    post = shapes.Box((-c[0], -c[1], c[2]), (0.03, 0.03, 0.5), np.eye(3))  # joint 1 at pi
    for check in (native, slow):
        check.set_obstacles([post])
    X = np.array([q, q + [1.0, 0.1, 0, 0, 0, 0, 0], q + [2.0, 0, 0, 0.1, 0, 0, 0], q])
    X[3, 0] = 2.0 * np.pi - 0.2
    answers = []
    for path in (X, X[:3]):
        for res in (0.05, 0.01):
            expected = _path_valid_by_hand(robot, spheres, post, path, res)
            assert native.path_valid(path, res, 0.0) == expected
            assert slow.path_valid(path, res, 0.0) == expected
            answers.append(expected)
    assert answers == [False, False, True, True]


def test_a_robot_of_more_coordinates_than_the_c_check_takes_gets_numpy() -> None:
    """A chain of 65 revolute joints (one more than `NATIVE_MAX_NQ`): the C check's table
    refuses it with the reason (its buffers hold 64 coordinates)."""
    model = pin.Model()
    parent = 0
    for j in range(NATIVE_MAX_NQ + 1):
        parent = model.addJoint(parent, pin.JointModelRZ(), pin.SE3.Identity(), f"j{j}")
    reason = joint_table(SimpleNamespace(model=model))
    assert isinstance(reason, str) and "65 coordinates" in reason


def _wall_scene() -> tuple[NativeSphereCheck, SphereCheck, np.ndarray, np.ndarray,
                           np.ndarray, np.ndarray]:  # fmt: skip
    """(C check, numpy check, start, goal, joint limits lo, hi): the Panda's fitted
    spheres round a wall, start and goal on either side of it."""
    from geosyn.robots.collision_spheres import file_spheres

    robot = load_robot("panda")
    fitted = file_spheres(robot)
    native, slow = NativeSphereCheck(robot, fitted.spheres), SphereCheck(robot, fitted.spheres)
    wall = [shapes.Box((0.45, 0.0, 0.35), (0.02, 0.25, 0.35), np.eye(3))]
    for check in (native, slow):
        check.set_obstacles(wall)
    q0 = np.array([-0.9, 0.4, 0.0, -1.6, 0.0, 2.0, 0.8])
    q1 = np.array([0.9, 0.4, 0.0, -1.6, 0.0, 2.0, 0.8])
    return native, slow, q0, q1, robot.q_min, robot.q_max


def test_rrt_connect_in_c_finds_a_valid_path_round_a_wall_and_is_seeded() -> None:
    """Start and goal on either side of a wall: the path joins them, each of its edges
    passes the numpy check 10x finer than RRT's resolution, and the same seed gives
    the same path; `string_pull` keeps it valid and makes it shorter."""
    native, slow, q0, q1, lo, hi = _wall_scene()
    assert not native.segment_valid(q0, q1, 0.05, 0.0)
    path, grown = native.rrt_connect(q0, q1, lo, hi, margin=0.0, budget=5.0, seed=7)
    assert path is not None and grown > 2
    np.testing.assert_array_equal(path[0], q0)
    np.testing.assert_array_equal(path[-1], q1)
    assert np.all(np.linalg.norm(np.diff(path, axis=0), axis=1) <= RRT_STEP + 1e-12)
    for x, y in zip(path[:-1], path[1:], strict=True):
        assert slow.segment_valid(x, y, 0.005, 0.0)
    again, _ = native.rrt_connect(q0, q1, lo, hi, margin=0.0, budget=5.0, seed=7)
    np.testing.assert_array_equal(path, again)
    # a near box of share 0: no draw for it, the same path
    same, _ = native.rrt_connect(q0, q1, lo, hi, margin=0.0, budget=5.0, seed=7,
                                 near=(lo, hi, 0.0))  # fmt: skip
    np.testing.assert_array_equal(path, same)
    # string pulling: fewer vertices, no longer in joint space, every edge still valid
    pulled = string_pull(lambda a, b, r: native.segment_valid(a, b, r, 0.0), path)
    joint = [float(np.linalg.norm(np.diff(p, axis=0), axis=1).sum()) for p in (path, pulled)]
    assert len(pulled) < len(path) and joint[1] <= joint[0] + 1e-12
    np.testing.assert_array_equal(pulled[[0, -1]], path[[0, -1]])
    for x, y in zip(pulled[:-1], pulled[1:], strict=True):
        assert slow.segment_valid(x, y, 0.005, 0.0)
    # a deadline that passes mid-way (after 3 segment checks): a prefix pulled, the
    # vertices left kept as they are; every edge still valid, no longer in joint space
    calls = [0]

    def counted(a: np.ndarray, b: np.ndarray, r: float) -> bool:
        calls[0] += 1
        return native.segment_valid(a, b, r, 0.0)

    def clock() -> float:
        return 0.0 if calls[0] < 3 else 2.0  # past the deadline 1.0 from then on

    with mock.patch("geosyn.metrics.planning.rrt.time.perf_counter", clock):
        cut = string_pull(counted, path, deadline=1.0)
    assert calls[0] == 3 and len(pulled) <= len(cut) <= len(path)
    at = [next(i for i, v in enumerate(path) if np.array_equal(v, c)) for c in cut]
    assert at[0] == 0 and at[-1] == len(path) - 1 and all(np.diff(at) > 0)  # a subsequence
    assert at[-4:] == list(range(len(path) - 4, len(path)))  # its tail kept as it was
    for x, y in zip(cut[:-1], cut[1:], strict=True):
        assert slow.segment_valid(x, y, 0.005, 0.0)
    assert np.linalg.norm(np.diff(cut, axis=0), axis=1).sum() <= joint[0] + 1e-12


def test_a_robot_the_c_kinematics_cannot_model_falls_back_to_numpy_and_says_so() -> None:
    """A free-floating base (a 7-coordinate joint): the numpy check, and the note names
    the joint."""
    robot = load_robot(str(FIXTURES / "floating_arm.xml"))
    reason = joint_table(robot)
    assert isinstance(reason, str)
    spheres = [CollisionSphere(robot.model.names[1], (0.0, 0.0, 0.0), 0.05)]
    with pytest.warns(UserWarning, match="numpy"):
        check, note = sphere_check(robot, spheres)
    assert type(check) is SphereCheck and robot.model.names[1] in note
    assert math.isinf(check.clearances(np.zeros(robot.nq))[0])


def test_rrt_connect_in_c_samples_the_near_box_its_share_of_the_time() -> None:
    """Round the wall of the test above, with every sample from the box of the ends
    widened by 0.5 rad (share 1): each tree grows from an end towards points of that
    convex box, so every vertex of every path (6 seeds) lies in it, and each edge is
    valid on the numpy check 10x finer; with share 0, every path leaves it (the same
    seeds)."""
    native, slow, q0, q1, lo, hi = _wall_scene()
    near_lo = np.maximum(lo, np.minimum(q0, q1) - 0.5)
    near_hi = np.minimum(hi, np.maximum(q0, q1) + 0.5)
    for seed in range(6):
        inside, _ = native.rrt_connect(q0, q1, lo, hi, margin=0.0, budget=5.0, seed=seed,
                                       near=(near_lo, near_hi, 1.0))  # fmt: skip
        assert inside is not None
        assert np.all((inside >= near_lo) & (inside <= near_hi))
        for x, y in zip(inside[:-1], inside[1:], strict=True):
            assert slow.segment_valid(x, y, 0.005, 0.0)
        whole, _ = native.rrt_connect(q0, q1, lo, hi, margin=0.0, budget=5.0, seed=seed,
                                      near=(near_lo, near_hi, 0.0))  # fmt: skip
        assert whole is not None and not np.all((whole >= near_lo) & (whole <= near_hi))


def test_the_ramp_lowers_the_margin_only_near_the_ends_in_c_and_numpy() -> None:
    """With a ramp from two ends, `valid` is ``clearance >= min(margin, c_e + slope
    |q - e|)`` (written out here), the same in C and numpy, on 400 seeded configurations
    around the ends; without it, the margin everywhere."""
    robot = load_robot("panda")
    rng = np.random.default_rng(11)
    spheres = _spheres(robot, rng, per_joint=2)
    native, slow = NativeSphereCheck(robot, spheres), SphereCheck(robot, spheres)
    wall = [shapes.Box((0.45, 0.0, 0.35), (0.02, 0.25, 0.35), np.eye(3))]
    ends = rng.uniform(robot.q_min, robot.q_max, size=(2, 7))
    Q = np.concatenate([e + rng.normal(0.0, 0.3, size=(200, 7)) for e in ends])
    margin, slope = 0.05, 0.1
    for check in (native, slow):
        check.set_obstacles(wall)
    clear = slow.clearances(Q)
    c_end = slow.clearances(ends) - 0.03
    force = np.minimum(margin, np.min([c + slope * np.linalg.norm(Q - e, axis=1)
                                       for e, c in zip(ends, c_end, strict=True)], axis=0))  # fmt: skip
    for check in (native, slow):
        check.set_ends(ends, c_end, slope)
        expected = clear >= force
        assert 0 < expected.sum() < len(Q) and (clear >= margin).sum() < expected.sum()
        np.testing.assert_array_equal(check.valid(Q, margin), expected)
        check.set_ends([], [], 0.0)
        np.testing.assert_array_equal(check.valid(Q, margin), clear >= margin)


def test_self_floors_ramp_back_up_away_from_the_ends_in_c_and_numpy() -> None:
    """Self floors set from two ends with a slope: pair ``i`` must keep its sphere
    distance (from Pinocchio-placed centres, the referee) at or above ``min(0, min_e
    d_i(e) + slope |q - e|)`` (written out here), in C and numpy alike, on 400 seeded
    configurations around two folded ends; with slope 0, the ends' distances everywhere
    (more configurations valid)."""
    from geosyn.robots.collision_spheres import file_spheres

    robot = load_robot("panda")
    fitted = file_spheres(robot)
    native, slow = NativeSphereCheck(robot, fitted.spheres), SphereCheck(robot, fitted.spheres)
    for check in (native, slow):
        check.set_self_pairs(fitted.spheres, fitted.links, fitted.self_pairs)
    rng = np.random.default_rng(12)
    pool = rng.uniform(robot.q_min, robot.q_max, size=(400, 7))
    ends = pool[np.argsort(slow.self_clearances(pool).min(axis=1))[:2]]  # most overlap
    Q = np.concatenate([e + rng.normal(0.0, 0.4, size=(200, 7)) for e in ends])
    d = _pair_distances(robot, fitted, slow.self_pairs, Q)
    d_end = _pair_distances(robot, fitted, slow.self_pairs, ends)
    assert d_end.min() < -0.01  # the ends overlap their spheres
    for slope in (0.05, 0.0):
        away = np.linalg.norm(Q[:, None, :] - ends[None], axis=2)  # (K, 2)
        floor = np.minimum(0.0, (d_end[None] + slope * away[:, :, None]).min(axis=1))
        expected = np.all(d >= floor - 1e-12, axis=1)
        for check in (native, slow):
            check.set_ends(ends, np.full(2, np.inf), 0.0, floor_slope=slope)
            np.testing.assert_array_equal(check.valid(Q, 0.0), expected)
        assert 0 < expected.sum() < len(Q)
        if slope:
            ramped = expected
    assert ramped.sum() < expected.sum()  # the ramp refuses what the flat floors let by
    # both ramps from the one set of ends, round a wall: the margin and the floors
    wall = [shapes.Box((0.45, 0.0, 0.35), (0.02, 0.25, 0.35), np.eye(3))]
    radius = np.array([s.radius for s in fitted.spheres])
    clear = np.array(
        [
            np.min(signed_distance(wall[0], _world_centres(robot, fitted.spheres, q)) - radius)
            for q in Q
        ]
    )  # Pinocchio-placed centres: the referee
    margin, slope = 0.05, 0.2

    def valid(slope: float, floor_slope: float) -> np.ndarray:  # written out
        force = np.minimum(margin, (c_end[None] + slope * away).min(axis=1))
        floor = np.minimum(0.0, (d_end[None] + floor_slope * away[:, :, None]).min(axis=1))
        return (clear >= force - 1e-12) & np.all(d >= floor - 1e-12, axis=1)

    c_end = np.minimum(slow.clearances(ends), margin) - 0.15
    both = valid(slope, 0.05)
    assert (both != valid(0.05, slope)).any()  # each ramp has its own slope
    for check in (native, slow):
        check.set_obstacles(wall)
        check.set_ends(ends, c_end, slope, floor_slope=0.05)
        np.testing.assert_array_equal(check.valid(Q, margin), both)
        check.set_ends([], [], 0.0)  # no ends: the margin and floors 0 everywhere
        flat = (clear >= margin) & np.all(d >= 0.0, axis=1)
        np.testing.assert_array_equal(check.valid(Q, margin), flat)
    assert 0 < both.sum() < len(Q) and both.sum() != ramped.sum()


def test_a_query_takes_at_most_two_ends_with_one_clearance_each() -> None:
    """`set_ends` refuses three ends, or a clearance count that is not the ends', in C
    and numpy, with `InvalidArgument` naming what it takes; the ends set before stay."""
    robot = load_robot("panda")
    spheres = _spheres(robot, np.random.default_rng(13), per_joint=1)
    q = np.zeros((3, 7))
    for check in (NativeSphereCheck(robot, spheres), SphereCheck(robot, spheres)):
        check.set_ends(q[:1], [0.01], 0.1)
        for ends, clear in ((q, [0.0, 0.0, 0.0]), (q[:2], [0.0])):
            with pytest.raises(InvalidArgument, match="set_ends: at most 2 ends"):
                check.set_ends(ends, clear, 0.1)
        assert check.margins(q[:1], 0.05)[0] == 0.01


def test_self_pairs_whose_spheres_overlap_often_are_calibrated_on_the_meshes() -> None:
    """UR5: the pairs whose spheres overlap on more than `SELF_UNINFORMATIVE` of 1,000
    seeded configurations (counted here on the numpy check) get the two links' reach;
    those above `SELF_CALIBRATE` a calibrated slack; no Panda pair gets any. At 400 other
    seeded configurations, coal on the URDF's meshes (the referee) finds the links of a
    calibrated pair apart on at least 99 % of those where its sphere distance is at
    least minus its slack (an estimate from seeded configurations; the exact check
    decides every plan), and the slack admits at least 75 % of the configurations where
    the links are apart (97 % measured for the UR5's one calibrated pair, forearm and
    wrist 3; a floor at 0 admitted 66 %)."""
    from geosyn.metrics.planning.sampling import (
        SELF_CALIBRATE,
        SELF_UNINFORMATIVE,
        calibrated_slack,
    )
    from geosyn.metrics.planning.self_collision import SelfCollision
    from geosyn.robots.collision_spheres import file_spheres

    for name, counts in (("ur5", (3, 1)), ("panda", (0, 0))):
        robot = load_robot(name)
        fitted = file_spheres(robot)
        check = SphereCheck(robot, fitted.spheres)
        check.set_self_pairs(fitted.spheres, fitted.links, fitted.self_pairs)
        slack = calibrated_slack(check, fitted.links, fitted.reach)
        lo = np.where(np.isfinite(robot.q_min), robot.q_min, -np.pi)
        hi = np.where(np.isfinite(robot.q_max), robot.q_max, np.pi)
        Q = np.random.default_rng(0).uniform(lo, hi, size=(1000, robot.nq))
        overlap = np.mean(check.self_clearances(Q) < 0.0, axis=0)
        reach = dict(zip(dict.fromkeys(fitted.links), fitted.reach, strict=True))
        np.testing.assert_array_equal(slack > 0.0, overlap > SELF_CALIBRATE)
        blind = np.flatnonzero(overlap > SELF_UNINFORMATIVE)
        for k in blind:
            a, b = check.self_pairs[k]
            assert slack[k] == pytest.approx(reach[a] + reach[b], abs=1e-15)
        calibrated = np.setdiff1d(np.flatnonzero(slack > 0.0), blind)
        assert (len(blind), len(calibrated)) == counts
        exact = SelfCollision(robot, fitted.self_pairs)
        fresh = np.random.default_rng(11).uniform(lo, hi, size=(400, robot.nq))
        spheres = check.self_clearances(fresh)
        for k in calibrated:
            pair = check.self_pairs[k]
            apart = np.array([exact.clearance(q, pair)[0] > 0.0 for q in fresh])
            admitted = spheres[:, k] >= -slack[k]
            assert np.mean(apart[admitted]) >= 0.99, (pair, slack[k])
            assert np.mean(admitted[apart]) >= 0.75, (pair, np.mean(admitted[apart]))


def test_the_calibrated_slack_is_kept_on_disk(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """UR5: `cached_slack` writes the calibration beside the sphere fits, a second call
    reads the same values back without measuring, and a damaged entry is warned (named)
    and measured again."""
    from geosyn.metrics.planning import sampling
    from geosyn.robots.collision_spheres import file_spheres, sphere_cache_dir

    robot = load_robot("ur5")
    fitted = file_spheres(robot)  # the suite's cache: no new fit
    check = SphereCheck(robot, fitted.spheres)
    check.set_self_pairs(fitted.spheres, fitted.links, fitted.self_pairs)
    monkeypatch.setenv("GEOSYN_CACHE_DIR", str(tmp_path / "cache"))
    first = sampling.cached_slack(check, fitted)
    (entry,) = sphere_cache_dir().glob("slack_*.json")
    measured = mock.Mock(side_effect=sampling.calibrated_slack)
    monkeypatch.setattr(sampling, "calibrated_slack", measured)
    np.testing.assert_array_equal(sampling.cached_slack(check, fitted), first)
    assert measured.call_count == 0 and np.sum(first > 0.0) == 4  # 2 calibrated
    entry.write_text(entry.read_text()[:10])
    with pytest.warns(RuntimeWarning, match=entry.name):
        np.testing.assert_array_equal(sampling.cached_slack(check, fitted), first)
    assert measured.call_count == 1
