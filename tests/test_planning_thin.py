"""Seeds searched on a thinner sphere model, pushed out and tightened on the exact geometry
(`geosyn.metrics.planning.thin`).

Referees: coal's distance between every collision object of the Panda URDF (placed by
Pinocchio's own kinematics) and the block, by brute force (`test_planning_tighten._brute`,
no bounds, no pruning), and the geodesic between the ends (the log map by shooting): no
path is shorter in the metric.
"""

from __future__ import annotations

import time

import numpy as np
import pytest
from test_planning_anytime import _metric_length
from test_planning_tighten import BLOCK, HOME, _brute, block_query

from geosyn.metrics import KineticEnergyMetric
from geosyn.metrics.geodesic.energy import distance
from geosyn.metrics.planning import Planner
from geosyn.metrics.planning import query as query_module
from geosyn.metrics.planning.exact_path import checked_configurations
from geosyn.metrics.planning.query import Query
from geosyn.metrics.planning.thin import THIN_FIRST, THIN_MIN_RADIUS, THIN_SHRINKS
from geosyn.metrics.planning.tighten import EXACT_FLOOR, exact_push
from geosyn.robots import load_robot
from geosyn.world import Sphere


@pytest.fixture(scope="module")
def planner() -> Planner:
    return Planner(KineticEnergyMetric(load_robot("panda")), capacity=1)


def _ends() -> tuple[np.ndarray, np.ndarray]:
    q0, q1 = HOME.copy(), HOME.copy()
    q0[0], q1[0] = -0.9, 0.9  # the straight line swings the hand through the block
    return q0, q1


def test_the_thinner_models_are_the_covering_spheres_shrunk(planner: Planner) -> None:
    """One model a shrink of `THIN_SHRINKS`: same centres; radii less the shrink, at least
    `THIN_MIN_RADIUS` (the check's own arrays; the Panda's covering spheres are 22-78 mm);
    a far ball's sphere clearance is larger by exactly the shrink (1e-12 m)."""
    thick = planner.sampling.check
    far = [Sphere((2.0, 0.0, 0.5), 0.1)]
    thick.set_obstacles(far)
    assert len(planner.thin) == len(THIN_SHRINKS)
    for model, shrink in zip(planner.thin, THIN_SHRINKS, strict=True):
        thin = model.sampling.check
        np.testing.assert_array_equal(thin._centre, thick._centre)
        expected = np.maximum(thick._radius - shrink, THIN_MIN_RADIUS)
        np.testing.assert_array_equal(thin._radius, expected)
        thin.set_obstacles(far)
        gap = thin.clearances(HOME[None])[0] - thick.clearances(HOME[None])[0]
        assert abs(gap - shrink) < 1e-12


def test_a_path_through_the_block_is_pushed_out_on_the_meshes(planner: Planner) -> None:
    """The straight line through the block (its middle 1-2 cm deep in it), pushed out:
    every configuration of the exact check keeps the floor on the brute-force referee
    (1e-6 m), the ends are kept, the path stays within the limits."""
    robot, exact = planner.robot, planner.exact
    assert exact is not None
    q0, q1 = _ends()
    line = np.linspace(q0, q1, planner.nodes + 1)
    assert _brute(robot, exact, 0.5 * (q0 + q1)) < 0.0
    with block_query(planner, q0, q1):
        pushed = exact_push(planner, line, 2.0)
    assert pushed is not None
    np.testing.assert_array_equal(pushed[[0, -1]], line[[0, -1]])
    floor = EXACT_FLOOR * planner.margin
    lowest = min(
        _brute(robot, exact, q) for q in checked_configurations(pushed, planner.exact_resolution)
    )
    assert lowest >= floor - 1e-6
    assert np.all(pushed >= robot.q_min) and np.all(pushed <= robot.q_max)


def test_a_plan_from_the_thinner_spheres_is_verified_and_says_so(planner: Planner) -> None:
    """At a 1 s budget round the block the plan comes through the thinner search's rounds
    (its attempts say so); whatever it keeps keeps the floor on the brute-force referee at
    every configuration of its exact check, and is no shorter than the geodesic between
    its ends (1 % for the midpoint rule on its samples)."""
    robot, exact = planner.robot, planner.exact
    assert exact is not None
    q0, q1 = _ends()
    plan = planner.plan(q0, q1, [BLOCK], budget=1.0, seed=0)
    assert any(a.startswith("thinner spheres:") for a in plan.attempts)
    lowest = min(
        _brute(robot, exact, q) for q in checked_configurations(plan.q, planner.exact_resolution)
    )
    assert lowest >= EXACT_FLOOR * planner.margin - 1e-6
    assert _metric_length(planner.metric, plan.q) >= 0.99 * distance(planner.metric, q0, q1)


class _ShortQuery(Query):
    """A query whose clock always shows `SHORT_LEFT` [s] left: less than `THIN_FIRST`
    and too short to keep `EXACT_KEEP` back (a short polishing: `SHORT_SEEDS`), long
    enough for the thinner search. Its
    real budget is long, so no check is skipped for lack of time: what it tries does not
    depend on how busy the machine is."""

    def left(self) -> float:
        return SHORT_LEFT


SHORT_LEFT = 0.19


def _short_polish(planner: Planner) -> tuple[float, object, float]:
    """(the sampled plan's length, the polished plan, its length) round the block."""
    q0, q1 = _ends()
    with block_query(planner, q0, q1):
        query = _ShortQuery(planner, q0, q1, 100.0, 0, time.perf_counter())
        assert query.left() < THIN_FIRST and not query.ample(query.left())
        sampled = query.sampled()
        assert sampled is not None
        polished = query.polish(sampled)
    m = planner.metric
    return _metric_length(m, sampled.q), polished, _metric_length(m, polished.q)


def test_a_short_polishing_takes_the_thinner_spheres_first(planner: Planner) -> None:
    """Round the block, a polishing with less than `THIN_FIRST` left returns the
    thinner search's path when it is shorter, without pulling the covering spheres'
    seeds taut (its attempts: no "polishing stopped after"); the plan is shorter than the
    sampled one and keeps the floor on the brute-force referee at every configuration
    of its exact check (1e-6 m)."""
    robot, exact = planner.robot, planner.exact
    assert exact is not None
    before, plan, after = _short_polish(planner)
    assert after < before
    assert "the thinner spheres' path" in plan.attempts[-1]  # the plan kept
    assert not any("polishing stopped after" in a for a in plan.attempts)
    lowest = min(
        _brute(robot, exact, q) for q in checked_configurations(plan.q, planner.exact_resolution)
    )
    assert lowest >= EXACT_FLOOR * planner.margin - 1e-6


def test_a_short_polishing_falls_back_on_the_covering_spheres(
    planner: Planner, monkeypatch: pytest.MonkeyPatch
) -> None:
    """When the thinner search finds nothing shorter (here: replaced by one that returns
    the plan it is given), the covering spheres' seeds are pulled taut (`SHORT_SEEDS`:
    "polishing stopped after 1 seed(s)") and the plan is shorter than the sampled one,
    keeping the floor on the brute-force referee (1e-6 m)."""
    robot, exact = planner.robot, planner.exact
    assert exact is not None
    monkeypatch.setattr(query_module, "thinner_plan", lambda query, plan, left: plan)
    before, plan, after = _short_polish(planner)
    assert any(a.startswith("polishing stopped after 1 seed") for a in plan.attempts)
    assert after < before
    lowest = min(
        _brute(robot, exact, q) for q in checked_configurations(plan.q, planner.exact_resolution)
    )
    assert lowest >= EXACT_FLOOR * planner.margin - 1e-6


def test_without_a_margin_a_short_polishing_skips_the_thinner_spheres() -> None:
    """With margin 0 there is nothing to push a thinner path out to, nor a floor to
    tighten to (`exact_movable`): a short polishing goes to the covering spheres at once
    (no "thinner spheres" line in its attempts), keeps no time back for a tightening (its
    seeds are not cut at `SHORT_SEEDS`: it stops on its patience) and its plan is clear of
    the block on the brute-force referee (1e-6 m)."""
    bare = Planner(KineticEnergyMetric(load_robot("panda")), capacity=1, margin=0.0)
    robot, exact = bare.robot, bare.exact
    assert exact is not None
    _, plan, _ = _short_polish(bare)
    assert not any("thinner spheres" in a for a in plan.attempts)
    assert not any(a.startswith("polishing stopped after") for a in plan.attempts)
    assert any(a.startswith("polishing stopped: ") for a in plan.attempts)
    lowest = min(
        _brute(robot, exact, q) for q in checked_configurations(plan.q, bare.exact_resolution)
    )
    assert lowest >= -1e-6
