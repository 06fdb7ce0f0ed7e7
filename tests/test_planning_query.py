"""One planning query (`geosyn.metrics.planning.query`, issue 22): the homotopy rule
(other seeds on by default, never a path longer than the straight line's) and the NLPs
of the query's own obstacle slot count.

References: metric lengths summed in the test with Pinocchio's mass matrix (``crba``) on
the paths resampled 16x; exact sphere-obstacle distances of `ObstacleTerm.clearances` on
the path checked 64x finer than its nodes; a planner built with exactly the slots a
query uses.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pinocchio as pin
import pytest

from geosyn.core.errors import GeosynError
from geosyn.metrics import KineticEnergyMetric
from geosyn.metrics.planning import Planner
from geosyn.metrics.planning.homotopy import kept_plan
from geosyn.metrics.planning.plan import Plan
from geosyn.metrics.planning.planner import densify
from geosyn.metrics.planning.verify import feasible_result
from geosyn.metrics.shaping import CapacityExceeded
from geosyn.robots import load_robot
from geosyn.world import Box, Sphere

ROBOT = dataclasses.replace(
    load_robot("planar2"), q_min=np.full(2, -np.pi), q_max=np.full(2, np.pi)
)
Q0, Q1 = np.array([-0.6, 0.4]), np.array([0.6, 0.4])


def tip_ball() -> Sphere:
    """A ball on the tip's path halfway along the straight joint line."""
    mid = 0.5 * (Q0 + Q1)
    return Sphere(
        (np.cos(mid[0]) + np.cos(mid.sum()), np.sin(mid[0]) + np.sin(mid.sum()), 0.0), 0.15
    )


def length(path: np.ndarray) -> float:
    """Metric length with Pinocchio's mass matrix (midpoint rule, 16x resampled)."""
    dense = densify(path, 16)
    data = ROBOT.model.createData()
    total = 0.0
    for a, b in zip(dense[:-1], dense[1:], strict=True):
        M = pin.crba(ROBOT.model, data, 0.5 * (a + b))
        M = np.triu(M) + np.triu(M, 1).T
        total += float(np.sqrt((b - a) @ M @ (b - a)))
    return total


def planner(**options: object) -> Planner:
    with pytest.warns(UserWarning, match="capsule spheres only"):
        return Planner(KineticEnergyMetric(ROBOT), nodes=16, margin=0.01, **options)  # type: ignore[arg-type]


def test_default_tries_other_seeds_and_never_returns_a_longer_path() -> None:
    obstacles = [tip_ball()]
    line = planner(capacity=1, alternatives=0).plan(Q0, Q1, obstacles, budget=20.0)
    assert line.seed == "straight line" and line.result.kind == "constrained"
    plan = planner(capacity=1).plan(Q0, Q1, obstacles, budget=20.0, seed=2)
    assert any(a.startswith("RRT-Connect") for a in plan.attempts)  # other seeds tried
    assert length(plan.q) <= length(line.q) * (1.0 + 1e-6)
    assert plan.result.energy <= line.result.energy * (1.0 + 1e-9)
    term = planner(capacity=1).term
    term.set_obstacles(obstacles)
    assert min(term.min_clearance(q) for q in densify(plan.q, 64)) > 0.0


def test_a_query_solves_the_nlps_of_its_own_slot_count() -> None:
    """A query builds the NLPs of its slot count on first use (``prebuild`` 4: those of
    one slot are not built with the planner) and keeps them; its nodes are those of a
    planner of that capacity (1e-9 rad); more obstacles than the capacity are refused.
    The default planner has those of one slot built with it."""
    big = planner(capacity=4, alternatives=0, prebuild=4)
    assert [big.slots(k) for k in range(6)] == [1, 1, 2, 4, 4, 4]
    ball = tip_ball()
    first = big.plan(Q0, Q1, [ball], budget=20.0)
    again = big.plan(Q0, Q1, [ball], budget=20.0)
    assert first.nlp_build_time > 0.0 and again.nlp_build_time == 0.0
    assert (
        planner(capacity=4, alternatives=0).plan(Q0, Q1, [ball], budget=20.0).nlp_build_time == 0.0
    )
    exact = planner(capacity=1, alternatives=0).plan(Q0, Q1, [ball], budget=20.0)
    np.testing.assert_allclose(first.result.nodes, exact.result.nodes, atol=1e-9)
    assert big.term.capacity == 4 and len(big.term.obstacles) == 1  # the last query's
    far = Box((5.0, 5.0, 0.0), (0.1, 0.1, 0.1))
    with pytest.raises(CapacityExceeded):
        big.plan(Q0, Q1, [ball, far, far, far, far], budget=5.0)


def test_a_lower_energy_way_round_replaces_the_straight_lines() -> None:
    """The ball moved 0.1 m towards the base from the tip's path: the straight line's
    plan swings the tip outside it; an RRT-Connect seed (seeded) goes round the other
    side with less energy than the plan made without other seeds, and is kept; it is
    clear of the ball on a check 64x finer than its nodes."""
    mid = 0.5 * (Q0 + Q1)
    tip = np.array([np.cos(mid[0]) + np.cos(mid.sum()), np.sin(mid[0]) + np.sin(mid.sum()), 0.0])
    ball = Sphere(tuple(tip - 0.1 * tip / np.linalg.norm(tip)), 0.15)
    # without other seeds: the straight line's constrained plan (energy 4.78) or the
    # sampled first plan, polished for the rest of its budget (3.71), whichever is lower
    line = planner(capacity=1, alternatives=0).plan(Q0, Q1, [ball], budget=3.0)
    default = planner(capacity=1)
    plan = default.plan(Q0, Q1, [ball], budget=20.0, seed=2)
    assert plan.seed.startswith("rrt-connect") and plan.result.kind == "constrained"
    assert plan.result.energy < line.result.energy  # the seeded collocation beats both
    assert min(default.term.min_clearance(q) for q in densify(plan.q, 64)) > 0.0


def test_a_negative_prebuild_is_refused_by_name() -> None:
    """``prebuild`` is an obstacle count: below 0 it is refused, naming it."""
    with pytest.raises(GeosynError, match="prebuild"):
        Planner(KineticEnergyMetric(ROBOT), capacity=1, prebuild=-1)


def _plan(path: np.ndarray, kind: str, energy: float, seed: str) -> Plan:
    """A `Plan` of ``path`` whose result says ``kind`` and ``energy`` (stated, not solved)."""
    res = feasible_result(KineticEnergyMetric(ROBOT), path, seed)._replace(kind=kind, energy=energy)
    return Plan(res, seed, 0.1, 0.0, ())


def test_kept_plan_is_the_lowest_energy_one_not_longer_than_the_straight_lines() -> None:
    """The homotopy rule on stated energies, with the lengths measured here (Pinocchio's
    mass matrix): a lower-energy plan that is longer than the straight line's is dropped,
    a shorter and lower one kept; within a relative 1e-6 the earlier plan stays; a sampled
    plan replaces a solved one only when 1e-3 lower (0.5e-3 lower: not; 2e-3: kept)."""
    metric = KineticEnergyMetric(ROBOT)
    s = np.linspace(0.0, 1.0, 25)[:, None]
    straight = Q0 + s * (Q1 - Q0)
    bent = straight + np.sin(np.pi * s) * np.array([0.0, -1.0])  # the arm stretched on the way
    assert length(bent) > 1.05 * length(straight)  # the premise, on crba
    line = _plan(bent, "constrained", 2.0, "straight line")
    longer = _plan(bent + np.sin(2 * np.pi * s) * np.array([0.3, 0.0]), "constrained", 1.0, "a")
    assert length(longer.q) > length(bent)
    attempts: list[str] = []
    assert kept_plan(metric, line, [longer], attempts) is line
    assert attempts == ["1 plan(s) from other seeds longer than the straight line's: not kept",
                        "kept the lowest-energy of 2 plans: straight line (energies 2.0000, "
                        "1.0000)"]  # fmt: skip
    shorter = _plan(straight, "constrained", 1.5, "b")
    assert kept_plan(metric, line, [longer, shorter], []) is shorter
    tie = _plan(straight, "constrained", 1.5 * (1.0 + 0.5e-6), "c")
    assert kept_plan(metric, line, [shorter, tie], []) is shorter
    assert kept_plan(metric, line, [tie, shorter], []) is tie
    near = _plan(straight, "feasible", 1.5 * (1.0 - 0.5e-3), "sampled")
    assert kept_plan(metric, line, [shorter, near], []) is shorter
    low = _plan(straight, "feasible", 1.5 * (1.0 - 2e-3), "sampled")
    assert kept_plan(metric, line, [shorter, low], []) is low
    assert kept_plan(metric, None, [low], []) is low  # without a straight line's plan
