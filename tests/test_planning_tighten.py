"""Sampled plans tightened on the robot's own collision geometry (issue 22):
`geosyn.metrics.planning.exact_path.configuration_clearances` and
`geosyn.metrics.planning.tighten.exact_tighten`, and the deadline of
`geosyn.metrics.planning.exact_path.path_clearance`.

Referee: coal's distance between the convex hull of every collision object of the Panda
URDF, placed by Pinocchio's own forward kinematics, and every obstacle, by brute force
(no bounds, no pruning, coal's default request). Tolerance 1e-6 m (coal's default GJK
tolerance in the referee).
"""

from __future__ import annotations

import contextlib
import math
import time
from collections.abc import Iterator

import coal
import numpy as np
import pinocchio as pin
import pytest

from geosyn.metrics import KineticEnergyMetric
from geosyn.metrics.planning import Planner, polish, query
from geosyn.metrics.planning.exact_path import (
    checked_configurations,
    configuration_clearances,
    path_clearance,
)
from geosyn.metrics.planning.polish import SHORT_SEEDS, taut_seeds
from geosyn.metrics.planning.sampling import sampling_box
from geosyn.metrics.planning.smoothing import metric_length
from geosyn.metrics.planning.tighten import EXACT_FLOOR, exact_tighten
from geosyn.robots import Robot, load_robot
from geosyn.world import Box
from geosyn.world.exact_clearance import ExactClearance, coal_shape

HOME = np.array([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785])
BLOCK = Box((0.36, 0.0, 0.52), (0.05, 0.05, 0.05))  # where the hand passes at joint 1 = 0


@pytest.fixture(scope="module")
def planner() -> Planner:
    return Planner(KineticEnergyMetric(load_robot("panda")), capacity=1)


@contextlib.contextmanager
def block_query(planner: Planner, q0: np.ndarray, q1: np.ndarray) -> Iterator[None]:
    """The planner set up as in a query from ``q0`` to ``q1`` round `BLOCK` (its term's
    obstacles, its sampling's ends), for the stages a query calls."""
    planner.term.set_obstacles([BLOCK])
    planner.sampling.start([BLOCK], q0, q1)
    try:
        yield
    finally:
        planner.sampling.finish()


def _brute(robot: Robot, exact: ExactClearance, q: np.ndarray) -> float:
    """coal's smallest distance [m] at ``q`` over every (object, BLOCK) pair."""
    box = coal.CollisionObject(coal.Box(*(2.0 * np.asarray(BLOCK.half_extents))),
                               coal.Transform3s(np.eye(3), np.asarray(BLOCK.center)))  # fmt: skip
    data = robot.model.createData()
    pin.forwardKinematics(robot.model, data, q)
    best = math.inf
    for o in exact.objects:
        j = robot.joint_id(o.joint) if o.joint != "universe" else 0
        M = data.oMi[j] * pin.SE3(o.placement)
        obj = coal.CollisionObject(coal_shape(o), coal.Transform3s(M.rotation, M.translation))
        best = min(best, coal.distance(obj, box, coal.DistanceRequest(), coal.DistanceResult()))
    return best


def test_configuration_clearances_are_coals_smallest_distance(planner: Planner) -> None:
    """At 40 seeded configurations round the block (some in it): the smallest exact
    distance per configuration is the brute-force one where below ``near`` (else
    ``near``), to 1e-6 m; with the planner's aids too where clear, and negative where
    the brute force finds a penetration."""
    robot, exact = planner.robot, planner.exact
    assert exact is not None
    exact.set_obstacles([BLOCK])
    planner.sampling.set_obstacles([BLOCK])
    rng = np.random.default_rng(5)
    Q = HOME + rng.normal(0.0, 0.25, size=(40, 7))
    Q[:, 0] = rng.uniform(-0.3, 0.3, 40)  # the hand near the block
    brute = np.minimum([_brute(robot, exact, q) for q in Q], exact.near)
    clear = brute >= 0.0
    assert np.sum(~clear) >= 3 and np.sum(clear & (brute < exact.near)) >= 5
    plain = configuration_clearances(exact, Q)
    aided = configuration_clearances(exact, Q, planner.sampling.aids)
    assert np.abs(plain - brute).max() < 1e-6
    # the aids' sphere bounds say nothing of penetration depths: there only the sign
    assert np.abs(aided - brute)[clear].max() < 1e-6 and np.all(aided[~clear] < 0.0)


def test_tightening_shortens_and_keeps_the_floor_on_the_meshes(
    planner: Planner, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A plan round the block, made without the query's own tightening (on the spheres
    only, whatever the machine's speed), tightened on the exact geometry: shorter in the
    metric (midpoint rule, ``metric_length``), nearer the block, and at least
    ``EXACT_FLOOR * margin`` from it at every configuration of the exact check, all on
    the brute-force referee."""
    robot, exact = planner.robot, planner.exact
    assert exact is not None
    q0, q1 = HOME.copy(), HOME.copy()
    q0[0], q1[0] = -0.9, 0.9  # the straight line swings the hand through the block
    with monkeypatch.context() as m:  # a 0.2 s plan was tightened already on a fast machine
        m.setattr(polish, "exact_tighten", lambda p, path, budget: np.asarray(path, dtype=float))
        m.setattr(query, "thinner_plan", lambda q, plan, left: plan)  # it tightens too
        path = np.asarray(planner.plan(q0, q1, [BLOCK], budget=0.2, seed=0).q)
    with block_query(planner, q0, q1):
        tight = exact_tighten(planner, path, 2.0)

    def lowest(p: np.ndarray) -> float:
        return min(_brute(robot, exact, q)
                   for q in checked_configurations(p, planner.exact_resolution))  # fmt: skip

    before, after = lowest(path), lowest(tight)
    assert after >= EXACT_FLOOR * planner.margin - 1e-6
    assert after < before - 1e-3  # it came nearer
    assert metric_length(planner.metric, tight) < (1.0 - 1e-3) * metric_length(planner.metric, path)
    np.testing.assert_array_equal(tight[[0, -1]], path[[0, -1]])


def test_a_tightened_plan_keeps_the_floor_it_was_checked_at(planner: Planner) -> None:
    """The default planner at a 1 s budget round the block: its plan is tightened on the
    meshes (its message says so), and both its reported exact clearance and the
    brute-force referee at every configuration of its exact check keep
    ``EXACT_FLOOR * margin`` (the returned samples are those the tightening checked)."""
    robot, exact = planner.robot, planner.exact
    assert exact is not None
    q0, q1 = HOME.copy(), HOME.copy()
    q0[0], q1[0] = -0.9, 0.9
    plan = planner.plan(q0, q1, [BLOCK], budget=1.0, seed=0)
    assert plan.seed == "sampled" and "tightened on the exact geometry" in plan.result.message
    floor = EXACT_FLOOR * planner.margin
    assert plan.exact_clearance >= floor
    Q = checked_configurations(plan.q, planner.exact_resolution)
    assert min(_brute(robot, exact, q) for q in Q) >= floor - 1e-6


def test_a_passed_deadline_leaves_the_exact_check_undecided(planner: Planner) -> None:
    """The batched exact check of a path through the block: with no deadline, the
    brute-force referee's smallest distance over its checked configurations (to 1e-6
    m); with a deadline already passed, NaN (undecided, nothing checked), never a
    number."""
    robot, exact = planner.robot, planner.exact
    assert exact is not None
    exact.set_obstacles([BLOCK])
    planner.sampling.set_obstacles([BLOCK])  # its aids' bounds: not the last query's
    q0, q1 = HOME.copy(), HOME.copy()
    q0[0], q1[0] = -0.9, 0.9  # the hand swings through the block
    path = np.array([q0, q1])
    full = path_clearance(exact, path, 0.05, aids=planner.sampling.aids)
    brute = min(_brute(robot, exact, q) for q in checked_configurations(path, 0.05))
    assert abs(full.clearance - brute) < 1e-6 and full.clearance < 0.0
    late = path_clearance(exact, path, 0.05, time.perf_counter() - 1.0, planner.sampling.aids)
    assert math.isnan(late.clearance) and late.checked == 0


def _seeds(planner: Planner, path: np.ndarray, most: int) -> tuple[list[int], int, list[str]]:
    """(the RRT-Connect seeds' indices made, the next seed's number, the attempts) of
    `taut_seeds` from ``path`` round the block with ``most``, 20 s on its clock (far more
    than the seeds take, < 1 s)."""
    q0, q1 = path[0], path[-1]
    lo, hi = sampling_box(planner.robot, q0, q1)
    made: list[int] = []

    def rrt(index: int, seconds: float) -> np.ndarray | None:
        made.append(index)
        return planner.sampling.connect(q0, q1, lo, hi, seconds, index)[0]

    attempts: list[str] = []
    end = time.perf_counter() + 20.0
    shortest, _, _, after = taut_seeds(
        planner, q0, q1, 0, path, math.inf, lambda: end - time.perf_counter(), 0.0, rrt,
        attempts, 1, most,
    )  # fmt: skip
    assert shortest is not None  # the sampled path at least, pulled taut
    return made, after, attempts


def test_a_short_polishing_pulls_only_its_seeds_taut(planner: Planner) -> None:
    """`taut_seeds` with ``most`` (a query too short to keep `EXACT_KEEP` back for the
    tightening passes `SHORT_SEEDS`): the sampled path and ``most`` seeds after it are
    pulled taut, bumped lines and RRT-Connect paths by turns (1: the first bump, no
    RRT-Connect path; 3: bump, RRT-Connect path #1, bump), never more however much time
    is left, and the next seed's number says where a later search goes on."""
    q0, q1 = HOME.copy(), HOME.copy()
    q0[0], q1[0] = -0.9, 0.9
    assert SHORT_SEEDS == 1
    with block_query(planner, q0, q1):
        lo, hi = sampling_box(planner.robot, q0, q1)
        path, _ = planner.sampling.connect(q0, q1, lo, hi, 5.0, 0)
        assert path is not None and len(path) > 2  # round the block
        for most, rrts in ((1, []), (3, [1])):
            made, after, attempts = _seeds(planner, path, most)
            assert made == rrts and after == 1 + most
            assert attempts[-1].startswith("polishing stopped after")
