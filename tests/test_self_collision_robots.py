"""Self-collision on other robots' own meshes, against Pinocchio's collision model of
their URDFs (`self_collision_referee.SelfCollisionReferee`): seeded random UR10 queries,
and the SO-101's pairs of several fine meshes. Outside `test_planning_self_collision.py`'s
worker group (its Panda planner is built once there), so that they spread over the
workers."""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest
from self_collision_referee import SelfCollisionReferee

from geosyn.core.errors import InvalidArgument
from geosyn.metrics import KineticEnergyMetric
from geosyn.metrics.planning.errors import NoPathFound
from geosyn.metrics.planning.exact_path import checked_configurations
from geosyn.metrics.planning.plan import Plan
from geosyn.metrics.planning.planner import Planner
from geosyn.metrics.planning.self_collision import INTERSECTING, SelfCollision
from geosyn.robots import load_robot
from geosyn.robots.collision_spheres import file_spheres


def _planner_and_referee(name: str) -> tuple[Planner, SelfCollisionReferee]:
    """The default planner of catalogue robot ``name`` and Pinocchio's collision model of
    its URDF on the planner's self pairs (the referee)."""
    planner = Planner(KineticEnergyMetric(load_robot(name)))
    return planner, SelfCollisionReferee(planner.robot, planner.sphere_check.self_pairs)


def _self_clear(referee: SelfCollisionReferee, plan: Plan) -> bool:
    """Whether the referee finds no self-collision at every 5th configuration of the plan's
    exact resolution and at its goal."""
    Q = checked_configurations(plan.q, plan.exact_resolution)
    return not any(referee.collides(q) for q in (*Q[::5], Q[-1]))


def test_pairs_of_several_fine_meshes_match_pinocchio() -> None:
    """SO-101 (2-4 STL meshes per link, 17,000-54,000 triangles each): per self pair,
    `SelfCollision.clearance` (the object pairs' triangles measured nearest hulls first,
    only while a hull distance is below the least found) equals Pinocchio's smallest
    distance over the same mesh pairs (1e-9 m; intersecting: `INTERSECTING` against
    Pinocchio's collision) at 4 seeded configurations. (The Panda's fingers, 4 boxes
    each, cannot tell: measuring only the nearest hull's pair gives the same there.)"""
    robot = load_robot("so101")
    several = (("base_link", "lower_arm_link"), ("base_link", "wrist_link"),
               ("base_link", "gripper_link"), ("shoulder_link", "wrist_link"),
               ("shoulder_link", "gripper_link"), ("upper_arm_link", "gripper_link"))  # fmt: skip
    checker, referee = SelfCollision(robot, several), SelfCollisionReferee(robot, several)
    assert min(len(checker._of_pair[ab]) for ab in several) >= 4  # object pairs each
    rng = np.random.default_rng(4)
    for _ in range(4):
        q = robot.random_q(rng)
        ref = referee.distances(q)
        for pair in several:
            ours = checker.clearance(q, pair)[0]
            if ref[pair] == -math.inf:
                assert ours == INTERSECTING
            else:
                assert abs(ours - ref[pair]) < 1e-9, (pair, ours, ref[pair])


def test_continuous_joints_pairs_match_pinocchio_on_the_files_own_model() -> None:
    """Kinova Gen2 (its URDF's joints 1, 4 and 6 are continuous: a (cos, sin) pair each in
    Pinocchio's model of the file, one bounded angle in the robot's): per self pair of
    its file, `SelfCollision.clearance` equals Pinocchio's distance on the file's own
    model and geometry (1e-9 m; intersecting: `INTERSECTING` against Pinocchio's
    collision) at 6 seeded configurations with those joints beyond +-pi/2; the nearest
    pair comes within 5 cm. With the angles padded into the file's coordinates (the
    referee until this round) the distances differ by up to 0.4 m, and the benchmark's
    referee found a link_2 / base contact where the links are 5 cm apart."""
    robot = load_robot("kinova")
    pairs = file_spheres(robot).self_pairs
    checker, referee = SelfCollision(robot, pairs), SelfCollisionReferee(robot, pairs)
    assert referee.full.nq == robot.nq + 3  # the three continuous joints
    rng = np.random.default_rng(5)
    nearest = math.inf
    for _ in range(6):
        q = robot.random_q(rng)
        q[[0, 3, 5]] = rng.choice([-1.0, 1.0], 3) * rng.uniform(1.6, 3.1, 3)
        ref = referee.distances(q)
        for pair in pairs:
            ours = checker.clearance(q, pair)[0]
            if ref[pair] == -math.inf:
                assert ours == INTERSECTING, (pair, ours)
            else:
                assert abs(ours - ref[pair]) < 1e-9, (pair, ours, ref[pair])
            nearest = min(nearest, ref[pair])
    assert nearest < 0.05


def test_random_ur10_queries_are_planned_past_the_spheres_excess() -> None:
    """Eight seeded random UR10 queries, no obstacles, 2 s each: at least 5 are planned
    (8 measured with the seventeenth round's sphere fits, 7 before; 6 with both cores
    busy). Before the self floors were calibrated on the
    meshes, and before a sampled plan that failed its checks was tried again, 1 was: the
    spheres' excess blocked 47 % of the joint box where the links are apart. Pinocchio's
    collision model of the URDF (the referee) finds no self-collision on any returned
    path, at every 5th configuration of its exact resolution and at its ends."""
    planner, referee = _planner_and_referee("ur10_robot")
    robot = planner.robot
    rng, plans, tried = np.random.default_rng(0), [], 0
    while tried < 8:
        q0, q1 = robot.random_q(rng), robot.random_q(rng)
        if referee.collides(q0) or referee.collides(q1):
            continue
        tried += 1
        try:
            plans.append(planner.plan(q0, q1, budget=2.0, seed=0))
        except NoPathFound:
            pass
    assert len(plans) >= 5, len(plans)
    for plan in plans:
        assert _self_clear(referee, plan)
        assert plan.self_clearance >= 0.0


UR5_START = np.array([-0.7492, 5.7126, -0.0007, -0.9396, 1.5106, 6.2216])
UR5_GOAL = np.array([5.6416, -0.5021, 1.6194, -0.0324, 0.3683, 3.5913])
"""A seeded random UR5 query whose straight line passes the spheres (the base and upper
arm's floor is lowered by their reach: their spheres overlap on most of the joint box) and
crosses the links' meshes."""


def _pair_sphere_distance(robot: object, fitted: object, pair: tuple[str, str],
                          q: np.ndarray) -> float:  # fmt: skip
    """Smallest distance [m] between the fitted spheres of the two links of ``pair`` at
    ``q``, placed by Pinocchio's forward kinematics (centre distance less both radii)."""
    model = robot.model
    data = model.createData()
    pin.forwardKinematics(model, data, q)
    placed = {a: [] for a in pair}
    for s, link in zip(fitted.spheres, fitted.links, strict=True):
        if link in placed:
            centre = data.oMi[model.getJointId(s.joint)].act(np.asarray(s.center, dtype=float))
            placed[link].append((centre, s.radius))
    return min(float(np.linalg.norm(ca - cb)) - ra - rb
               for ca, ra in placed[pair[0]] for cb, rb in placed[pair[1]])  # fmt: skip


def test_raised_self_floors_hold_only_within_their_radius() -> None:
    """UR5's sampling check (in C; and the numpy one), no obstacles, no ends: with two
    local raises (`Raises`) of one self pair's floor, 1 and 0.5 rad round two seeded
    configurations, to 2 and 3 cm above its sphere distance at the first, a configuration
    is valid exactly when every pair's sphere distance (Pinocchio's forward kinematics on
    the fitted spheres, the referee) is at least its floor in force: the calibrated one
    (``min(0, -self_slack)``), the larger raise whose ball holds it. At 60 seeded
    configurations within 1.5 rad of the first (both kinds of verdict occur, and
    configurations inside and outside the balls). `Raises.none` drops them."""
    from geosyn.metrics.planning.sphere_check import Raises, SphereCheck
    from geosyn.robots.collision_spheres import file_spheres

    robot = load_robot("ur5")
    planner = Planner(KineticEnergyMetric(robot))
    native = planner.sampling.check
    fitted = file_spheres(robot)
    plain = SphereCheck(robot, fitted.spheres)
    plain.set_self_pairs(fitted.spheres, fitted.links, fitted.self_pairs)
    plain.self_slack = native.self_slack.copy()
    base = np.minimum(-native.self_slack, 0.0)
    rng = np.random.default_rng(7)
    at = np.array([robot.random_q(rng), robot.random_q(rng)])
    k = int(np.argmax(native.self_slack))  # the pair with the lowest calibrated floor
    pair = native.self_pairs[k]
    d0 = _pair_sphere_distance(robot, fitted, pair, at[0])
    raises = Raises(np.array([k, k]), at, np.array([1.0, 0.5]), np.array([d0 + 0.02, d0 + 0.03]))
    Q = np.clip(at[0] + rng.uniform(-1.5, 1.5, (60, robot.nq)) / math.sqrt(robot.nq),
                robot.q_min, robot.q_max)  # fmt: skip
    verdicts, inside = [], 0
    for check in (native, plain):
        check.set_ends([], [], 0.0)
        check.set_raises(raises)
        got = check.valid(Q, -1.0)  # margin -1 m: no obstacle, only the self pairs decide
        for q, valid in zip(Q, got, strict=True):
            floors = base.copy()
            for r in range(2):
                if np.linalg.norm(q - at[r]) < raises.radius[r]:
                    floors[k] = max(floors[k], raises.floor[r])
                    inside += 1
            dist = [_pair_sphere_distance(robot, fitted, ab, q) for ab in native.self_pairs]
            assert min(abs(a - b) for a, b in zip(dist, floors, strict=True)) > 1e-9
            assert bool(valid) == all(a >= b for a, b in zip(dist, floors, strict=True))
            verdicts.append(bool(valid))
        check.set_raises(Raises.none(robot.nq))
        assert np.array_equal(check.self_floors(Q), np.tile(base, (len(Q), 1)))
    assert 0 < sum(verdicts) < len(verdicts) and 0 < inside < 2 * len(verdicts)


def test_a_self_contact_raises_its_pairs_floor_for_the_query_only(monkeypatch) -> None:
    """UR5, `UR5_START` -> `UR5_GOAL`, no obstacles, the default budget (5 s):
    Pinocchio's collision model of the URDF finds the straight line's links intersecting,
    where the sampling check (the calibrated floors) passes it. The exact self check's
    contact is a configuration Pinocchio finds colliding; `Sampling.learn_floor` raises
    that pair's floor to its sphere distance there (Pinocchio's forward kinematics on the
    fitted spheres, 1e-9 m) plus `SELF_LEARN_STEP`, after which the check refuses it,
    within `SELF_LEARN_RADIUS` of it only (the floor in force beyond it is unchanged); the
    query's end (`finish`) drops the raise. The query is planned (its first
    plan after 0.6-0.85 s, measured with the other core busy; the sampled plans are tried
    again after a self-collision even when collocation has time: its NLP has no term for
    it, and its geodesic crosses the links), no configuration of its path at the exact
    resolution colliding for Pinocchio; without the raised floors (2 s) every retry is the
    same straight line and the query is refused."""
    from geosyn.metrics.planning.query import Query
    from geosyn.metrics.planning.sampling import SELF_LEARN_RADIUS, SELF_LEARN_STEP
    from geosyn.robots.collision_spheres import file_spheres

    planner, referee = _planner_and_referee("ur5")
    robot = planner.robot
    line = checked_configurations(np.array([UR5_START, UR5_GOAL]), planner.exact_resolution)
    assert any(referee.collides(q) for q in line)
    calibrated = planner.sampling.check.self_slack.copy()
    sampling = planner.sampling
    sampling.start((), UR5_START, UR5_GOAL)
    try:
        assert sampling.segment_valid(UR5_START, UR5_GOAL, 0.005)  # the spheres pass it
        value, contact = planner.self_contact(np.array([UR5_START, UR5_GOAL]))
        assert value < 0.0 and contact is not None and referee.collides(contact.q)
        assert sampling.valid(contact.q[None])[0]
        pair = planner.sphere_check.self_pairs[contact.pair]
        d = _pair_sphere_distance(robot, file_spheres(robot), pair, contact.q)
        u = np.random.default_rng(0).standard_normal(robot.nq)
        far = contact.q + (SELF_LEARN_RADIUS + 0.1) * u / np.linalg.norm(u)
        before = sampling.check.self_floors(np.array([contact.q, far]))[:, contact.pair]
        with pytest.raises(InvalidArgument, match="radius"):
            sampling.learn_floor(contact, radius=-1.0)
        floor, _ = sampling.learn_floor(contact)
        assert floor is not None and abs(floor - (d + SELF_LEARN_STEP)) < 1e-9
        assert not sampling.valid(contact.q[None])[0]
        after = sampling.check.self_floors(np.array([contact.q, far]))[:, contact.pair]
        assert after[0] == floor > before[0] and after[1] == before[1]
    finally:
        sampling.finish()
    assert len(sampling.check.raises.pair) == 0
    np.testing.assert_array_equal(sampling.check.self_slack, calibrated)
    plan = planner.plan(UR5_START, UR5_GOAL, seed=0)  # the default 5 s: time to collocate
    Q = checked_configurations(plan.q, plan.exact_resolution)
    assert not any(referee.collides(q) for q in Q)
    assert len(sampling.check.raises.pair) == 0
    monkeypatch.setattr(Query, "retry", Query.sampled)  # no floor raised
    with pytest.raises(NoPathFound):
        planner.plan(UR5_START, UR5_GOAL, budget=2.0, seed=0)


def test_a_learned_floor_is_capped_at_an_ends_pair_distance() -> None:
    """UR5, the straight line's contact of `UR5_START` -> `UR5_GOAL`: with a query start
    within `SELF_LEARN_RADIUS` of it whose pair sphere distance D lies between the
    contact's d and d + `SELF_LEARN_STEP` (Pinocchio's forward kinematics on the fitted
    spheres, found along seeded directions), `Sampling.learn_floor` raises the floor to D
    exactly (1e-9 m), not above: the contact is refused, the start stays valid. With the
    contact itself as the start (D = d) nothing can be raised, and it says why."""
    from geosyn.metrics.planning.sampling import SELF_LEARN_RADIUS, SELF_LEARN_STEP
    from geosyn.robots.collision_spheres import file_spheres

    robot = load_robot("ur5")
    planner, fitted = Planner(KineticEnergyMetric(robot)), file_spheres(robot)
    _, contact = planner.self_contact(np.array([UR5_START, UR5_GOAL]))
    assert contact is not None
    pair = planner.sphere_check.self_pairs[contact.pair]
    d = _pair_sphere_distance(robot, fitted, pair, contact.q)
    rng, start = np.random.default_rng(3), None
    for _ in range(20):  # a start 0.02-3 rad away whose pair distance is in (d, d + step)
        u = rng.standard_normal(robot.nq)
        for t in np.linspace(0.02, 3.0, 150):
            q = contact.q + t * u / np.linalg.norm(u)
            D = _pair_sphere_distance(robot, fitted, pair, q)
            if d + 0.2 * SELF_LEARN_STEP < D < d + 0.8 * SELF_LEARN_STEP:
                start = q
                break
        if start is not None:
            break
    assert start is not None and np.linalg.norm(start - contact.q) < SELF_LEARN_RADIUS
    sampling = planner.sampling
    sampling.start((), start, UR5_GOAL)
    try:
        floor, line = sampling.learn_floor(contact)
        assert floor is not None and abs(floor - D) < 1e-9, line
        assert not sampling.valid(contact.q[None])[0] and sampling.valid(start[None])[0]
    finally:
        sampling.finish()
    sampling.start((), contact.q, UR5_GOAL)
    try:
        floor, line = sampling.learn_floor(contact)
        assert floor is None and f"an end within {SELF_LEARN_RADIUS:g} rad" in line
        assert len(sampling.check.raises.pair) == 0
    finally:
        sampling.finish()


UR5_GRIPPER_SHUT_START = np.array([1.807845188718367, 0.7651541503587347, -1.649305871226725,
                                   0.03702803123664067, -2.692858726904864, 1.2571857110253295])  # fmt: skip
UR5_GRIPPER_GOAL = np.array([0.16792099206172262, 1.2858404535258985, -2.587608141595996,
                             0.9098996256255947, -0.8147036729623105, -0.004344407984882004])  # fmt: skip
"""A seeded random query of the UR5 with its gripper (`benchmarks/planning_random.py`,
seed 4, query 2) whose start sits with its forearm and tool0 spheres 13.5 mm into each
other, the links apart: at `SELF_FLOOR_RAMP` no segment of `RRT_STEP` leaves it."""


def test_an_end_shut_in_by_the_self_floors_ramp_has_them_eased(monkeypatch) -> None:
    """`UR5_GRIPPER_SHUT_START` -> `UR5_GRIPPER_GOAL`, no obstacles: `Sampling.start`
    finds the start shut in at `SELF_FLOOR_RAMP` and halves the ramp for the query (said
    in the plan's attempts); the query is then planned (5 s allowed; 0.9 s measured) and
    Pinocchio's collision model of the URDF finds no self-collision at every 5th
    configuration of the exact resolution and at the goal. Without the easing
    (`shut_in` always False) RRT-Connect grows 3 nodes and the query is refused in 2 s."""
    from geosyn.metrics.planning.sampling import SELF_FLOOR_RAMP, Sampling

    planner, referee = _planner_and_referee("ur5_gripper")
    q0, q1 = UR5_GRIPPER_SHUT_START, UR5_GRIPPER_GOAL
    assert not referee.collides(q0) and not referee.collides(q1)
    sampling = planner.sampling
    sampling.start((), q0, q1)
    try:
        assert sampling.ramp < SELF_FLOOR_RAMP and sampling.ramp_line
        line = sampling.ramp_line
        assert not sampling.shut_in(q0)  # the eased ramp lets it out
    finally:
        sampling.finish()
    plan = planner.plan(q0, q1, seed=0)
    assert line in plan.attempts and sampling.ramp_line == ""  # said, and reset by `finish`
    assert _self_clear(referee, plan)
    monkeypatch.setattr(Sampling, "shut_in", lambda self, q: False)
    with pytest.raises(NoPathFound):
        planner.plan(q0, q1, budget=2.0, seed=0)


UR5_MANY_CONTACTS_START = np.array([3.8480153374847603, -2.306531095167333, -2.2051556153290433,
                                    2.494575241734138, -0.6466139001402773, 3.756584434710863])  # fmt: skip
UR5_MANY_CONTACTS_GOAL = np.array([-3.323598218889556, -2.2646528242314163, 1.884198632032585,
                                   0.08882085326511824, 0.08023629423667611, -3.315082352821848])  # fmt: skip
"""A seeded random UR5 query (`benchmarks/planning_random.py`, seed 5, query 3) whose
sampled paths touched the forearm / wrist 2 and base / upper arm meshes 9 times before one
passed: with at most `SAMPLED_RETRIES` retries it was refused after 2.1-2.9 s of the
default 5 s budget."""


def test_retries_after_self_contacts_go_on_while_time_is_left() -> None:
    """`UR5_MANY_CONTACTS_START` -> `UR5_MANY_CONTACTS_GOAL`, no obstacles, 8 s allowed
    (3.7 s measured at 5 s): planned after more than `SAMPLED_RETRIES` learned floors
    (the retries after a self-contact are not capped, only timed), and Pinocchio's
    collision model of the URDF finds no self-collision at every 5th configuration of the
    exact resolution and at the goal."""
    from geosyn.metrics.planning.sampled import SAMPLED_RETRIES

    planner, referee = _planner_and_referee("ur5")
    q0, q1 = UR5_MANY_CONTACTS_START, UR5_MANY_CONTACTS_GOAL
    assert not referee.collides(q0) and not referee.collides(q1)
    plan = planner.plan(q0, q1, budget=8.0, seed=0)
    assert sum("floor raised" in line for line in plan.attempts) > SAMPLED_RETRIES
    assert _self_clear(referee, plan)


UR3_SHUT_START = np.array([-5.227417362430961, 4.1801296421104865, 1.803891867329141,
                           -3.275180172777645, 4.731040374829556, -5.547197675663192])  # fmt: skip
UR3_SHUT_GOAL = np.array([-2.059413754553953, -4.3947178304510075, -0.31202696181445333,
                          3.723720602459924, -3.3848498296498946, -5.6294663581634286])  # fmt: skip
"""A seeded random UR3 query (`benchmarks/planning_random.py`, seed 0, query 0) whose goal
is still shut in by the self floors' ramp after two halvings."""


def test_an_end_still_shut_in_after_two_halvings_is_eased_further(monkeypatch) -> None:
    """`UR3_SHUT_START` -> `UR3_SHUT_GOAL`: with at most two halvings an end is left shut
    in; with `SELF_RAMP_HALVINGS` the ramp is halved three times and neither end is; the
    query is planned (8 s allowed; 3.0-3.2 s measured at 5 s, where two halvings were
    refused) and Pinocchio's collision model of the URDF finds no self-collision at every
    5th configuration of the exact resolution and at the goal."""
    from geosyn.metrics.planning import sampling as sampling_module

    planner, referee = _planner_and_referee("ur3_robot")
    q0, q1 = UR3_SHUT_START, UR3_SHUT_GOAL
    assert not referee.collides(q0) and not referee.collides(q1)
    sampling = planner.sampling
    with monkeypatch.context() as patch:
        patch.setattr(sampling_module, "SELF_RAMP_HALVINGS", 2)
        sampling.start((), q0, q1)
        try:
            assert sampling.shut_in(q0) or sampling.shut_in(q1)
        finally:
            sampling.finish()
    sampling.start((), q0, q1)
    try:
        assert sampling.ramp == sampling_module.SELF_FLOOR_RAMP / 8
        assert not sampling.shut_in(q0) and not sampling.shut_in(q1)
    finally:
        sampling.finish()
    plan = planner.plan(q0, q1, budget=8.0, seed=0)
    assert _self_clear(referee, plan)


UR10_LIMITED_START = np.array([-0.5997184776307374, -1.8942984090458777, -2.571374450774097,
                               0.5047432673232928, -1.2648295005506598, 1.0806756900856147])  # fmt: skip
UR10_LIMITED_GOAL = np.array([-1.8880001474934276, 2.7778786000460745, -0.8475378089720755,
                              -2.4787462630174875, 0.81121044079147, 2.683891211731064])  # fmt: skip
"""A seeded random query of the UR10 with +-pi limits (`benchmarks/planning_random.py
--robots ur10_joint_limited_robot`, seed 0, query 2): its straight line is 11 mm clear of
itself on the meshes, but 29 % of it lies below the self floors of the spheres."""


def test_a_straight_line_the_spheres_block_is_planned_on_the_meshes() -> None:
    """`UR10_LIMITED_START` -> `UR10_LIMITED_GOAL`, no obstacles, 3 s: the straight line is
    invalid on the sampling spheres and RRT-Connect finds no connection on them (before,
    the query was refused after 3.4 s of 5 s, and a 30 s RRT-Connect grew 30,003 nodes
    without one); the plan is the straight line checked on the exact geometry, said in its
    attempts, and Pinocchio's collision model of the URDF finds no self-collision at every
    5th configuration of the exact resolution and at the goal."""
    planner, referee = _planner_and_referee("ur10_joint_limited_robot")
    q0, q1 = UR10_LIMITED_START, UR10_LIMITED_GOAL
    planner.sampling.start((), q0, q1)
    try:
        assert not planner.sampling.segment_valid(q0, q1, 0.05)
    finally:
        planner.sampling.finish()
    plan = planner.plan(q0, q1, budget=3.0, seed=0)
    assert any("RRT-Connect found no connection" in line for line in plan.attempts)
    said = "the straight line (no connection on the spheres) checked on the exact geometry"
    assert plan.seed == "sampled" and said in plan.result.message, plan.result.message
    direction = (q1 - q0) / np.linalg.norm(q1 - q0)
    off = [np.linalg.norm((q - q0) - ((q - q0) @ direction) * direction) for q in plan.q]
    assert max(off) < 1e-9  # on the straight line
    assert _self_clear(referee, plan)


class _FakeClock:
    """``time.perf_counter`` of `path_self_contact` on a fake clock [s]: a hull item
    (`SelfCollision.placed_bound`) takes ``hull`` and a triangle item
    (`SelfCollision.placed_clearance`) ``triangles``; each item's start and end are kept."""

    def __init__(self, checker: SelfCollision, hull: float, triangles: float) -> None:
        self.now, self.items = 0.0, []
        bound, clearance = checker.placed_bound, checker.placed_clearance

        def timed(measure: object, seconds: float, kind: str) -> object:
            def run(*args: object) -> object:
                start, self.now = self.now, self.now + seconds
                self.items.append((kind, start, self.now))
                return measure(*args)  # type: ignore[operator]

            return run

        checker.placed_bound = timed(bound, hull, "hull")  # type: ignore[method-assign]
        checker.placed_clearance = timed(clearance, triangles, "triangles")  # type: ignore[method-assign]

    def perf_counter(self) -> float:
        return self.now


class _EveryItem:
    """The sphere bounds of a check with every (configuration, pair) item at -1 m: every
    item is measured (a stand-in for `SphereCheck`'s self part), in the order of the
    items, or with ``shuffle`` (a seed) in a random order (bounds -1 to -1.001 m)."""

    def __init__(self, pairs: tuple[tuple[str, str], ...], shuffle: int | None = None) -> None:
        self.self_pairs, self.shuffle = pairs, shuffle

    def self_clearances(self, Q: np.ndarray) -> np.ndarray:
        shape = (len(Q), len(self.self_pairs))
        if self.shuffle is None:
            return np.full(shape, -1.0)
        return -1.0 - 1e-3 * np.random.default_rng(self.shuffle).random(shape)


def test_a_self_check_begins_no_item_past_its_deadline(monkeypatch: pytest.MonkeyPatch) -> None:
    """SO-101 (its fine meshes' triangles take 0.2-7 ms an item, measured): the self check
    reads the clock before every item and begins a triangle item only when the slowest so
    far would end by the deadline. On a fake clock (a hull item 1 ms, a triangle item
    10 ms), a 5-configuration path with every item measured (20 items, 5 of them
    triangles, 65 ms): with a 40 ms deadline it stops after 17 items (35 ms), before the
    third triangle item, every item ending by the deadline, and returns a lower bound of
    the exact minimum. (Reading the clock every 16 items, it measured all 20; reading it
    before every item but beginning any triangle item, it ended at 45 ms.) Without a deadline
    its value is Pinocchio's smallest distance over the pairs and configurations
    (1e-9 m)."""
    from geosyn.metrics.planning import self_path

    robot = load_robot("so101")
    pairs = (
        ("moving_jaw_so101_v1_link", "wrist_link"),
        ("base_link", "upper_arm_link"),
        ("gripper_link", "lower_arm_link"),
    )  # the nearest at random configurations
    rng = np.random.default_rng(0)
    path = np.array([robot.random_q(rng), robot.random_q(rng)])
    resolution = float(np.max(np.abs(path[1] - path[0]))) / 4.0  # 5 configurations
    Q = checked_configurations(path, resolution)
    referee = SelfCollisionReferee(robot, pairs)
    reference = min(min(referee.distances(q).values()) for q in Q)
    checker = SelfCollision(robot, pairs)
    clock = _FakeClock(checker, hull=1e-3, triangles=10e-3)
    runs = {}
    with monkeypatch.context() as m:
        m.setattr(self_path, "time", clock)
        m.setattr(self_path, "SELF_REFINE_TIME", math.inf)  # the deadline alone
        for deadline in (math.inf, 0.04):
            clock.now, clock.items = 0.0, []
            value, _ = self_path.path_self_contact(checker, _EveryItem(pairs), path,
                                                        resolution, deadline)  # fmt: skip
            runs[deadline] = (value, clock.items)
    (full, every), (cut, items) = runs[math.inf], runs[0.04]
    assert len(Q) == 5 and 0.0 < reference < self_path.SELF_NEAR
    assert abs(full - reference) < 1e-9, (full, reference)
    triangles = [item for item in every if item[0] == "triangles"]
    print(f"{len(every)} items, {len(triangles)} triangles, to {every[-1][2] * 1e3:.0f} ms; "
          f"cut at {items[-1][2] * 1e3:.0f} ms after {len(items)}")  # fmt: skip
    assert len(triangles) >= 3 and every[-1][2] > 0.05  # the set-up: past the deadline
    within = [item for item in triangles if item[2] <= 0.04]  # those that end by it
    assert [item for item in items if item[0] == "triangles"] == within
    assert 2 <= len(within) < len(triangles)
    assert max(end for _, _, end in items) <= 0.04
    assert 0.0 <= cut <= full


@pytest.mark.parametrize("name", ["ur5", "panda"])
def test_a_self_pairs_distance_moves_no_more_than_its_weights(name: str) -> None:
    """`SelfCollision.pair_weights`, every self pair of the file: between 20 seeded random
    configurations and a step of up to 0.05 rad from each, Pinocchio's distance of the
    pair (the referee) changes by at most ``sum_j w[j] |dq_j|`` (measured: up to 0.61 of
    it on the UR5, 0.42 on the Panda), and by nothing (1e-9 m) when only joints of
    weight 0 move (those that carry both links or neither). Pairs intersecting at either
    end are left out (no distance)."""
    robot = load_robot(name)
    pairs = file_spheres(robot).self_pairs
    checker, referee = SelfCollision(robot, pairs), SelfCollisionReferee(robot, pairs)
    rng = np.random.default_rng(3)
    ratios = []
    for _ in range(20):
        q = robot.random_q(rng)
        dq = np.clip(q + rng.uniform(-0.05, 0.05, robot.nq), robot.q_min, robot.q_max) - q
        before, after = referee.distances(q), referee.distances(q + dq)
        for pair in pairs:
            if math.isinf(before[pair]) or math.isinf(after[pair]):
                continue
            w = checker.pair_weights(pair)
            assert w is not None and np.all(w >= 0.0)
            change = abs(after[pair] - before[pair])
            assert change <= float(w @ np.abs(dq)) + 1e-9, (pair, change, w, dq)
            ratios.append(change / float(w @ np.abs(dq)) if np.any(w > 0.0) else 0.0)
            if np.any(w == 0.0) and not math.isinf(
                d := referee.distances(q + np.where(w == 0.0, dq, 0.0))[pair]
            ):
                assert abs(d - before[pair]) < 1e-9, (pair, d, before[pair])
    assert len(ratios) > 100 and 0.2 < max(ratios) <= 1.0


@pytest.mark.parametrize("seed", [2, 3])
def test_a_self_check_advances_along_the_path(monkeypatch: pytest.MonkeyPatch, seed: int) -> None:
    """UR5, every self pair of its file, a seeded 0.3 rad line (48-55 configurations at
    5 mrad) with every item below its sphere bound (the -1 m stand-in, in a random order),
    no refinement limit: every bound the advancement gives an item from its pair's
    measured neighbours is at most Pinocchio's distance there (the referee, 1e-9 m); the
    exact minimum, skipping the items so bounded above it, equals Pinocchio's smallest
    distance over the pairs and configurations (1e-9 m; 6.1 and 6.5 mm), as without
    advancement, measuring under a quarter of the items (measured: 162 of 1,155 and 147
    of 1,022)."""
    from geosyn.metrics.planning import self_path

    robot = load_robot("ur5")
    pairs = file_spheres(robot).self_pairs
    rng = np.random.default_rng(seed)
    q0 = robot.random_q(rng)
    q1 = np.clip(q0 + rng.uniform(-0.3, 0.3, robot.nq), robot.q_min, robot.q_max)
    path, resolution = np.array([q0, q1]), 0.005
    Q = checked_configurations(path, resolution)
    referee = SelfCollisionReferee(robot, pairs)
    truth = [referee.distances(q) for q in Q]
    reference = min(min(d.values()) for d in truth)
    checker = SelfCollision(robot, pairs)
    clock = _FakeClock(checker, hull=0.0, triangles=0.0)  # counts the items
    given, bound = [], self_path._Advance.bound

    def kept(advance: object, i: int, k: int) -> float:
        given.append((i, k, value := bound(advance, i, k)))  # type: ignore[arg-type]
        return value

    counts = []
    with monkeypatch.context() as m:
        m.setattr(self_path, "SELF_REFINE_TIME", math.inf)
        for advance in (True, False):
            m.setattr(self_path._Advance, "bound", kept if advance else lambda *_: -math.inf)
            clock.items = []
            bounds = _EveryItem(pairs, shuffle=seed)  # the items in a random order
            value, _ = self_path.path_self_contact(checker, bounds, path, resolution)
            assert abs(value - reference) < 1e-9, (advance, value, reference)
            counts.append(len(clock.items))
    assert 0.0 < reference < self_path.SELF_NEAR
    assert counts[0] < 0.25 * counts[1], counts
    finite = [(i, k, b) for i, k, b in given if b > -math.inf]
    assert len(finite) > 100
    assert all(b <= truth[i][pairs[k]] + 1e-9 for i, k, b in finite)


def _near_line(robot: object, referee: SelfCollisionReferee, seed: int) -> np.ndarray:
    """A seeded 2-configuration line (2, n) [rad] of ``robot`` whose end has a self pair
    0.5-1.5 mm apart on Pinocchio's distance: from a configuration where every pair is
    apart to one where a pair intersects, bisected on that pair."""
    rng = np.random.default_rng(seed)
    for _ in range(1000):  # seeded: the same line every run
        q0 = robot.random_q(rng)  # type: ignore[attr-defined]
        q1 = np.clip(q0 + rng.uniform(-0.6, 0.6, len(q0)), robot.q_min, robot.q_max)  # type: ignore[attr-defined]
        d0, d1 = referee.distances(q0), referee.distances(q1)
        hit = [pair for pair, d in d1.items() if d < 0.0]
        if min(d0.values()) > 0.01 and hit:
            break
    else:
        raise AssertionError("no line from clear to intersecting in 1,000 draws")
    lo, hi = 0.0, 1.0  # bisect the pair's distance along the line to ~1 mm
    for _ in range(60):
        t = 0.5 * (lo + hi)
        d = referee.distances(q0 + t * (q1 - q0))[hit[0]]
        if 0.5e-3 <= d <= 1.5e-3:
            return np.array([q0, q0 + t * (q1 - q0)])
        lo, hi = (t, hi) if d > 1e-3 else (lo, t)
    raise AssertionError("no configuration 0.5-1.5 mm apart on the line")


def test_a_self_check_measures_triangle_distances_only_where_they_are_near(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """UR5, every self pair of its file, a seeded line (5 mrad) to where a pair is ~1 mm
    apart (bisected on Pinocchio's distance), every item below its sphere bound (the -1 m
    stand-in), no refinement limit. Every `SelfCollision.placed_apart` answer agrees with
    Pinocchio's distance against `SELF_APART` (the referee; 1e-9 m), with both answers
    given; the triangles' distance is measured only at items Pinocchio puts within
    `SELF_APART` (+1e-9 m), and the check's value equals Pinocchio's smallest distance
    over the pairs and configurations (1e-9 m). Without the test (margin -inf) the same
    value takes many more triangle distances."""
    from geosyn.metrics.planning import self_path

    robot = load_robot("ur5")
    pairs = file_spheres(robot).self_pairs
    referee = SelfCollisionReferee(robot, pairs)
    path, resolution = _near_line(robot, referee, seed=4), 0.005
    Q = checked_configurations(path, resolution)
    reference = min(min(referee.distances(q).values()) for q in Q)
    assert 0.0 < reference < self_path.SELF_APART  # the test means something
    checker = SelfCollision(robot, pairs)
    at: dict[int, np.ndarray] = {}  # id of a configuration's placements -> configuration
    frames, place = checker.joint_frames, checker.placements
    last: list[np.ndarray] = []

    def framed(q: np.ndarray) -> object:
        last[:] = [np.array(q)]
        return frames(q)

    def placed(*args: object) -> object:
        out = place(*args)  # type: ignore[arg-type]
        at[id(out)] = last[0]
        return out

    calls: list[tuple[str, np.ndarray, tuple[str, str], object]] = []
    apart, clearance = checker.placed_apart, checker.placed_clearance

    def tested(p: object, pair: tuple[str, str], margin: float) -> bool:
        calls.append(("apart", at[id(p)], pair, out := apart(p, pair, margin)))  # type: ignore[arg-type]
        return out

    def measured(p: object, pair: tuple[str, str]) -> float:
        calls.append(("distance", at[id(p)], pair, out := clearance(p, pair)))  # type: ignore[arg-type]
        return out

    monkeypatch.setattr(checker, "joint_frames", framed)
    monkeypatch.setattr(checker, "placements", placed)
    monkeypatch.setattr(checker, "placed_apart", tested)
    monkeypatch.setattr(checker, "placed_clearance", measured)
    monkeypatch.setattr(self_path, "SELF_REFINE_TIME", math.inf)
    counts = []
    for margin in (self_path.SELF_APART, -math.inf):
        monkeypatch.setattr(self_path, "SELF_APART", margin)
        calls.clear()
        value, _ = self_path.path_self_contact(checker, _EveryItem(pairs, shuffle=1),
                                                    path, resolution)  # fmt: skip
        assert abs(value - reference) < 1e-9, (margin, value, reference)
        counts.append(sum(kind == "distance" for kind, *_ in calls))
        if margin > 0.0:
            answers = [(referee.distances(q)[pair], out)
                       for kind, q, pair, out in calls if kind == "apart"]  # fmt: skip
            assert all((d > margin - 1e-9) if out else (d <= margin + 1e-9) for d, out in answers)
            assert {out for _, out in answers} == {True, False}
            near = [referee.distances(q)[pair] for kind, q, pair, _ in calls if kind == "distance"]
            assert near and max(near) <= margin + 1e-9, near
    print(f"triangle distances: {counts[0]} with the test, {counts[1]} without")
    assert 5 * counts[0] < counts[1], counts
