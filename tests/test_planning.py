"""The planner (`geosyn.metrics.planning`): collision-free minimum-energy paths, clear
errors for queries that cannot succeed, and the RRT-Connect seed.

References: the exact sphere-obstacle clearances of `ObstacleTerm.clearances` on a path
checked 4x finer than its samples.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from geosyn.core.errors import InvalidArgument
from geosyn.metrics import KineticEnergyMetric
from geosyn.metrics.planning import (
    InCollision,
    NoPathFound,
    OutsideJointLimits,
    Planner,
    rrt_connect,
)
from geosyn.metrics.planning.coarse import COARSE_RAMP
from geosyn.metrics.planning.planner import densify
from geosyn.metrics.shaping import CapacityExceeded
from geosyn.robots import load_robot
from geosyn.world import Box, HalfSpace, Sphere

# planar2 with joint limits [-pi, pi]: joint 1 cannot wrap round, so a wall across
# q1 = 0 separates q1 < 0 from q1 > 0.
ROBOT = dataclasses.replace(
    load_robot("planar2"), q_min=np.full(2, -np.pi), q_max=np.full(2, np.pi)
)
WALL = Box((0.6, 0.0, 0.0), (0.3, 0.05, 0.5))  # across link 1 at q1 = 0
POST = Box((1.5, 0.0, 0.0), (0.08, 0.08, 0.5))  # only the outer link reaches it


@pytest.fixture(scope="module")
def planner() -> Planner:
    return Planner(KineticEnergyMetric(ROBOT), capacity=2, nodes=24, margin=0.01)


def test_box_between_start_and_goal_is_avoided_on_a_4x_finer_check(planner: Planner) -> None:
    q0, q1 = np.array([-0.8, 0.3]), np.array([0.8, -0.3])
    term = planner.term
    term.set_obstacles([POST])
    line = densify(np.array([q0, q1]), 100)
    assert min(term.min_clearance(q) for q in line) < 0.0  # the straight line collides
    plan = planner.plan(q0, q1, [POST], budget=20.0)
    fine = densify(plan.q, 4)
    exact = np.array([term.min_clearance(q) for q in fine])
    assert exact.min() > 0.0
    assert abs(plan.check_clearance - exact.min()) < 1e-9
    assert plan.result.kind in ("constrained", "geodesic")
    np.testing.assert_allclose(plan.q[0], q0, atol=1e-12)
    np.testing.assert_allclose(plan.q[-1], q1, atol=1e-12)


def test_free_query_is_a_geodesic(planner: Planner) -> None:
    plan = planner.plan([0.2, 0.3], [1.0, 0.9], [], budget=20.0)
    assert plan.result.kind == "geodesic"
    assert plan.result.geodesic_residual < 1e-8


@pytest.mark.parametrize("which", ["start", "goal"])
def test_start_or_goal_in_collision_names_obstacle_and_sphere(planner: Planner, which: str) -> None:
    free, hit = np.array([-1.0, 0.0]), np.array([0.0, 0.0])  # q1 = 0: link 1 in the wall
    q0, q1 = (hit, free) if which == "start" else (free, hit)
    with pytest.raises(InCollision, match=f"{which} is in collision.*obstacle 1") as info:
        planner.plan(q0, q1, [Sphere((0.0, -2.5, 0.0), 0.1), WALL], budget=2.0)
    err = info.value
    assert err.which == which and err.obstacle == 1 and err.clearance < 0.0
    assert err.joint == ROBOT.collision_spheres()[err.sphere].joint


def test_outside_limits_and_capacity(planner: Planner) -> None:
    with pytest.raises(OutsideJointLimits, match="goal: joint 0"):
        planner.plan([0.0, 0.0], [4.0, 0.0], [], budget=2.0)
    with pytest.raises(CapacityExceeded, match="capacity is 2"):
        planner.plan([0.0, 0.0], [1.0, 0.0], [POST, WALL, Sphere((0, 2, 0), 0.1)], budget=2.0)


def test_unreachable_goal_fails_within_the_budget(planner: Planner) -> None:
    budget = 3.0
    with pytest.raises(NoPathFound, match="within the 3 s budget.*RRT-Connect") as info:
        planner.plan([-1.0, 0.0], [1.0, 0.0], [WALL], budget=budget, seed=3)
    # stops when the budget is spent (plus one IPOPT iteration or edge check)
    assert info.value.elapsed < budget + 1.0
    assert len(info.value.attempts) >= 2


def test_rrt_connect_path_is_valid_and_seeded() -> None:
    """Reference validity: a disc obstacle in a 2-D box, checked on the path 20x finer."""
    center, radius = np.array([0.0, 0.0]), 0.5

    def valid(Q: np.ndarray) -> np.ndarray:
        return np.linalg.norm(Q - center, axis=1) > radius

    lo, hi = np.full(2, -2.0), np.full(2, 2.0)
    q0, q1 = np.array([-1.0, 0.0]), np.array([1.0, 0.0])
    path, _ = rrt_connect(valid, q0, q1, lo, hi, step=0.3, resolution=0.01, budget=5.0, seed=1)
    again, _ = rrt_connect(valid, q0, q1, lo, hi, step=0.3, resolution=0.01, budget=5.0, seed=1)
    assert path is not None and again is not None
    np.testing.assert_array_equal(path, again)
    np.testing.assert_array_equal(path[0], q0)
    np.testing.assert_array_equal(path[-1], q1)
    assert np.all(valid(densify(path, 20)))


def test_alternative_seeds_find_both_sides_and_keep_the_lowest_energy() -> None:
    """A sphere on the tip's straight-line path: RRT-Connect seeds reach the other side of
    it too (a local minimum of higher energy); the plan kept is the lowest-energy one,
    collision-free on an exact check 64x finer than its nodes and on the fine check."""
    q0, q1 = np.array([-0.6, 0.4]), np.array([0.6, 0.4])
    mid = 0.5 * (q0 + q1)
    tip = (np.cos(mid[0]) + np.cos(mid.sum()), np.sin(mid[0]) + np.sin(mid.sum()), 0.0)
    obstacles = [Sphere(tip, 0.15)]
    metric = KineticEnergyMetric(ROBOT)
    single = Planner(metric, capacity=2, nodes=24, margin=0.01, alternatives=0).plan(
        q0, q1, obstacles
    )
    assert single.seed == "straight line" and single.result.kind == "constrained"
    planner = Planner(metric, capacity=2, nodes=24, margin=0.01, alternatives=2)
    # a seed whose RRT-Connect samples (the C sampler's sequence) go round the far side
    # too: 10 of seeds 0-39 do (13, 14, 18, 19, 26, 27, 29, 30, 35, 36), the others all
    # reach the near side
    plan = planner.plan(q0, q1, obstacles, budget=20.0, seed=13)
    # the sampled first plan, the straight line's and two alternatives
    assert plan.attempts[-1].startswith("kept the lowest-energy of 4 plans")
    energies = [float(e) for e in plan.attempts[-1].split("energies ")[1].rstrip(")").split(", ")]
    assert max(energies) > 1.1 * min(energies)  # another homotopy class was found
    assert plan.result.energy <= single.result.energy * (1 + 1e-9)
    assert plan.fine_clearance >= 0.0
    exact = [planner.term.min_clearance(q) for q in densify(plan.q, 64)]
    assert min(exact) > 0.0


def test_coarse_to_fine_plan_equals_the_direct_one(planner: Planner) -> None:
    """A sphere on the tip's straight-line path: the default plan comes from the coarse
    collocation's path (its attempts say so, nothing else was tried) and is the same
    minimum-energy path as the full collocation's from the straight line
    (``coarse_nodes=0``), collision-free on an exact check 64x finer than its nodes."""
    q0, q1 = np.array([-0.6, 0.4]), np.array([0.6, 0.4])
    mid = 0.5 * (q0 + q1)
    tip = (np.cos(mid[0]) + np.cos(mid.sum()), np.sin(mid[0]) + np.sin(mid.sum()), 0.0)
    obstacles = [Sphere(tip, 0.15)]
    plan = planner.plan(q0, q1, obstacles, budget=20.0)
    assert plan.attempts[0].startswith("sampled plan: ")  # the anytime first plan
    # then its polishing (`query.POLISH_FIRST`), then the collocations
    c = next(i for i, a in enumerate(plan.attempts) if a.startswith("coarse collocation"))
    assert all(a.startswith(("sampled plan: ", "polishing stopped")) for a in plan.attempts[:c])
    assert plan.attempts[c].startswith("coarse collocation (4 segments, 3 constrained")
    assert plan.attempts[c + 1].startswith("collocation from the coarse path: minimum-energy")
    # then only the alternative seeds of the homotopy rule (alternatives=2 by default)
    assert all(("RRT-Connect" in a) or a.startswith(("kept", "alternative seeds"))
               or "from other seeds" in a
               for a in plan.attempts[c + 2:]), plan.attempts  # fmt: skip
    assert plan.seed == "straight line" and plan.result.kind == "constrained"
    direct = Planner(KineticEnergyMetric(ROBOT), capacity=2, nodes=24, margin=0.01,
                     coarse_nodes=0, alternatives=0).plan(q0, q1, obstacles, budget=20.0)  # fmt: skip
    assert direct.attempts[0].startswith("sampled plan: ")
    c = next(i for i, a in enumerate(direct.attempts) if a.startswith("collocation from"))
    assert all(a.startswith(("sampled plan: ", "polishing stopped")) for a in direct.attempts[:c])
    assert direct.attempts[c] == "collocation from the straight line: " + direct.result.message
    assert all(a.startswith("kept") or "from other seeds" in a
               for a in direct.attempts[c + 1:]), direct.attempts  # fmt: skip
    np.testing.assert_allclose(plan.result.nodes, direct.result.nodes, atol=1e-5)
    assert plan.result.iterations < direct.result.iterations
    exact = [planner.term.min_clearance(q) for q in densify(plan.q, 64)]
    assert min(exact) > 0.0


def test_coarse_bounds_ramp_from_the_ends_and_stop_at_fixed_spheres(planner: Planner) -> None:
    """Coarse clearance bounds: ``coarse_margin`` mid-path, the ends' own clearance at the
    ends (reference: `ObstacleTerm.clearances` there, smooth minimum within log(spheres) /
    softmin below); against a floor under planar2 (every sphere keeps its height), capped
    at the margin (lower only near the ends, by the ramp)."""
    q0, q1 = np.array([-0.8, 0.3]), np.array([0.8, -0.3])
    tip = np.array([np.cos(q0[0]) + np.cos(q0.sum()), np.sin(q0[0]) + np.sin(q0.sum()), 0.0])
    ball = Sphere(tip + (0.0, -0.3, 0.0), 0.1)
    planner.term.set_obstacles([ball])
    gap = planner.term.clearances(q0).min() - 0.004  # move it to 4 mm from the start
    planner.term.set_obstacles([Sphere(tip + (0.0, -0.3 + gap, 0.0), 0.1)])
    exact = planner.term.clearances(q0).min()
    assert abs(exact - 0.004) < 1e-9
    col = planner.collocation(4, 3)
    bounds = planner.coarse_bounds(q0, q1)
    t = col.point_times
    assert bounds.shape == (len(t), 2)
    np.testing.assert_allclose(bounds[np.abs(t - 0.5) < 0.2, 0], planner.coarse_margin)
    assert np.all(bounds[:, 1] == planner.coarse_margin)  # the empty slot
    slack = np.log(len(planner.term.spheres)) / planner.softmin  # type: ignore[operator]
    first = bounds[np.argmin(t), 0] - planner.coarse_margin * t.min() / COARSE_RAMP
    assert exact - slack - 1e-12 <= first <= exact + 1e-12
    planner.term.set_obstacles([HalfSpace((0.0, 0.0, 1.0), -0.02)])  # 2 cm below the arm
    floor = planner.coarse_bounds(q0, q1)[:, 0]
    assert floor.max() == planner.margin and np.all(floor[np.abs(t - 0.5) < 0.2] == planner.margin)
    with pytest.raises(InvalidArgument, match="coarse_nodes"):
        Planner(KineticEnergyMetric(ROBOT), capacity=1, coarse_nodes=1)
    with pytest.raises(InvalidArgument, match="coarse_inflation"):
        Planner(KineticEnergyMetric(ROBOT), capacity=1, coarse_inflation=-0.01)
