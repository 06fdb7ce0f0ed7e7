"""Plans within the joint limits (issue 22): `metric_relax`'s ``bounds`` (projected
Gauss-Newton steps) and the planner's refusal of a path that leaves the limits.

The relaxations of a sampled plan once took no account of the limits: on five of the
benchmark's 14 Panda scenes the returned path left them by up to 0.81 rad (joint 6 of
the shelf scene at 4.48 rad at a 1 s budget, its upper limit 3.7525), found by geodex's
checker, which tests the limits too.

Referees: the box itself (every sample within it, the held samples exactly on it); a
point robot among a disk in the plane, whose clearance is the closed form ``|x - c| -
r``; the Panda URDF's position limits as Pinocchio reads them.
"""

from __future__ import annotations

import time

import numpy as np
import pinocchio as pin
import pytest

from geosyn.core.errors import GeosynError
from geosyn.metrics import KineticEnergyMetric
from geosyn.metrics.base import Metric
from geosyn.metrics.planning import Planner
from geosyn.metrics.planning.query import Query
from geosyn.metrics.planning.relax import metric_relax
from geosyn.metrics.planning.sampled import bumped_line, relax_taut
from geosyn.metrics.planning.verify import outside_limits
from geosyn.robots import load_robot
from geosyn.world import Box

CENTER, RADIUS = np.array([0.0, 0.45]), 0.5  # the disk; its lowest point at y = -0.05
FLOOR = -0.06  # the lower bound of y: below the disk, above where the penalty pushes
A, B = np.array([-1.0, 0.0]), np.array([1.0, 0.0])


class Flat(Metric):
    """The Euclidean metric of the plane: G = I (geodesics are straight lines)."""

    n = 2

    def G(self, q: np.ndarray) -> np.ndarray:
        return np.eye(2)

    def quadratic_gradient(self, q: np.ndarray, d: np.ndarray) -> np.ndarray:
        return np.zeros(2)


def _disk(Q: np.ndarray) -> np.ndarray:
    """(K,) closed-form clearance [m] of the points ``Q`` (K, 2) to the disk."""
    return np.linalg.norm(np.atleast_2d(Q) - CENTER, axis=1) - RADIUS


def _clear(a: np.ndarray, b: np.ndarray, resolution: float) -> bool:
    s = np.linspace(0.0, 1.0, 200)[:, None]
    return bool(np.all(_disk(a + s * (b - a)) > 0.0))


def _seed() -> np.ndarray:
    """(21, 2) a valid path from A to B under the disk: y = -0.06 sin(pi s)^(1/4)."""
    s = np.linspace(0.0, 1.0, 21)
    y = FLOOR * np.sin(np.pi * s) ** 0.25
    y[[0, -1]] = 0.0
    return np.stack([A[0] + s * (B[0] - A[0]), y], axis=1)


def test_bounded_relaxation_keeps_the_box_and_rests_on_it() -> None:
    """Under the disk the penalty (below 0.05 m of clearance) pushes the samples down past
    y = -0.06; with that lower bound every sample keeps y >= -0.06 exactly (a sample
    held at it sits on it to 0), several sit on it, every segment stays clear of the
    disk (closed form, 200 points per segment) and the energy is no higher than the
    seed's. Without the bound the same relaxation goes below it: the bound is what
    holds them."""
    seed = _seed()
    assert all(_clear(a, b, 0.0) for a, b in zip(seed[:-1], seed[1:], strict=True))
    lo, hi = np.array([-2.0, FLOOR]), np.array([2.0, 2.0])
    kw = {"budget": 5.0, "delta": 0.05, "max_iter": 200}
    free = metric_relax(_clear, _disk, Flat(), seed, **kw)
    held = metric_relax(_clear, _disk, Flat(), seed, bounds=(lo, hi), **kw)
    assert free[:, 1].min() < FLOOR - 1e-3
    assert held[:, 1].min() >= FLOOR  # exactly: clipped onto the bound
    assert np.sum(held[:, 1] == FLOOR) >= 3
    assert all(_clear(a, b, 0.0) for a, b in zip(held[:-1], held[1:], strict=True))
    np.testing.assert_array_equal(held[[0, -1]], seed[[0, -1]])

    def energy(p: np.ndarray) -> float:
        return (len(p) - 1) * float(np.sum(np.diff(p, axis=0) ** 2))

    assert energy(held) <= energy(seed)


def test_bounds_are_checked_by_name() -> None:
    """Bounds of the wrong shape, crossed bounds or a seed outside them are refused,
    naming the argument."""
    seed = _seed()
    for bounds, name in (
        ((np.zeros(3), np.ones(3)), "bounds"),
        ((np.array([1.0, 1.0]), np.array([0.0, 0.0])), "bounds"),
        ((np.array([-2.0, 0.0]), np.array([2.0, 2.0])), "path"),
    ):
        with pytest.raises(GeosynError, match=name):
            metric_relax(_clear, _disk, Flat(), seed, bounds=bounds)


def test_ends_within_the_tolerance_are_kept_as_given() -> None:
    """A seed whose start lies 5e-10 rad below the lower bound (inside `OUTSIDE_TOL`, an
    NLP's bound tolerance): relaxed with those bounds, its ends are returned bit for bit
    and every interior sample keeps the bound."""
    seed = _seed()
    seed[0, 1] = FLOOR - 5e-10
    lo, hi = np.array([-2.0, FLOOR]), np.array([2.0, 2.0])
    out = metric_relax(_clear, _disk, Flat(), seed, bounds=(lo, hi), budget=5.0, delta=0.05)
    np.testing.assert_array_equal(out[[0, -1]], seed[[0, -1]])
    assert out[1:-1, 1].min() >= FLOOR


SLOT = [  # the benchmark's slot scene: a 0.17 m slot between two blocks, into it
    Box((0.65, 0.0, 0.25), (0.15, 0.30, 0.10)),
    Box((0.65, 0.0, 0.62), (0.15, 0.30, 0.10)),
]
ENDS = (  # joint 2 of both 0.8 mrad inside its lower limit (-1.7628 rad)
    np.array([0.873, -1.762, -0.784, -2.126, -1.129, 2.373, -2.468]),
    np.array([1.604, -1.762, -1.35, -2.428, -2.868, 2.233, -1.155]),
)


@pytest.fixture(scope="module")
def panda() -> Planner:
    return Planner(KineticEnergyMetric(load_robot("panda")), capacity=2)


def _urdf_limits(planner: Planner) -> tuple[np.ndarray, np.ndarray]:
    """The position limits of the Panda URDF's arm joints as Pinocchio reads the file
    itself (the fingers, locked in geosyn's model, left out), by joint name."""
    model = pin.buildModelFromUrdf(planner.robot.source_file)
    rows = [model.joints[model.getJointId(j)].idx_q for j in planner.robot.joint_names]
    return model.lowerPositionLimit[rows], model.upperPositionLimit[rows]


def test_relaxed_bumped_lines_keep_the_urdf_limits(panda: Planner) -> None:
    """On the benchmark's slot scene (`SLOT`, `ENDS`), bumped straight lines relaxed and
    tightened (`relax_taut`, indices 1-6) keep every sample within the URDF's position
    limits (Pinocchio's reading of the file), while the same relaxation without the
    bounds takes at least one of them outside."""
    lo, hi = _urdf_limits(panda)
    q0, q1 = ENDS
    panda.term.set_obstacles(SLOT)
    panda.sampling.start(SLOT, q0, q1)
    outside = 0
    try:
        for index in range(1, 7):
            x = bumped_line(q0, q1, panda.nodes + 1, lo, hi, seed=0, index=index)
            out = relax_taut(panda, x, 0.3, seed_valid=False)
            if out is not None:
                assert np.all(out >= lo) and np.all(out <= hi), index
            free = metric_relax(panda.sampling.segment_valid, panda.sampling.check.clearances,
                                panda.metric, x, budget=0.2, seed_valid=False)  # fmt: skip
            outside += bool(np.any(free < lo - 1e-6) or np.any(free > hi + 1e-6))
    finally:
        panda.sampling.finish()
    assert outside >= 1  # the case needs the bounds


def test_plans_keep_the_urdf_limits_and_a_planted_excursion_is_named(panda: Planner) -> None:
    """The default planner's plans on the slot scene at 0.5 and 1 s keep every sample
    within the URDF's limits; a path with one sample 0.1 rad past joint 6's upper limit
    is named by `outside_limits` (sample, joint, value, limits) and refused by the
    planner's verification, which says so in its attempts."""
    lo, hi = _urdf_limits(panda)
    q0, q1 = ENDS
    for budget in (0.5, 1.0):
        plan = panda.plan(q0, q1, SLOT, budget=budget, seed=0)
        q = np.asarray(plan.q)
        assert np.all(q >= lo) and np.all(q <= hi), budget
        assert outside_limits(panda.robot, q) == ""
    bad = np.array(plan.q, dtype=float)
    k = len(bad) // 2
    bad[k, 5] = hi[5] + 0.1
    why = outside_limits(panda.robot, bad)
    assert f"sample {k} has joint 5" in why and f"{hi[5] + 0.1:.4f}" in why
    panda.term.set_obstacles(SLOT)
    panda.sampling.start(SLOT, q0, q1)
    try:
        query = Query(panda, q0, q1, 1.0, 0, time.perf_counter())
        assert query.verified(bad, "a planted excursion", resample=False) is None
    finally:
        panda.sampling.finish()
    assert "leaves the joint limits" in query.attempts[-1]


def test_collocations_resting_on_a_joint_limit_end_within_it(panda: Planner) -> None:
    """Six seeded Panda collocations (16 nodes, no obstacles) whose ends both sit on a
    joint's limit: every node within the URDF's limits as Pinocchio reads them, to 0 rad,
    and `outside_limits` finds nothing; at least 3 of them rest on the limit
    (``constrained``). IPOPT relaxes its bounds by 1e-8 (relative): before the solution
    was projected onto them (``honor_original_bounds``), 3 of these six came back
    6e-10-3.3e-8 rad beyond, more than `LIMIT_TOL`, and the planner refused such paths
    (a UR3 query's constrained path 5.3e-9 rad past its elbow's limit, measured)."""
    from geosyn.metrics.geodesic.collocation import Collocation

    lo, hi = _urdf_limits(panda)
    col = Collocation(panda.metric, nodes=16)
    rng = np.random.default_rng(3)
    resting = 0
    for k in range(6):
        q0, q1 = panda.robot.random_q(rng), panda.robot.random_q(rng)
        j = k % len(lo)
        q0[j] = q1[j] = hi[j] if k % 2 else lo[j]
        res = col.solve(q0, q1)
        assert np.all(res.nodes >= lo) and np.all(res.nodes <= hi), (k, res.kind)
        assert outside_limits(panda.robot, res.nodes) == ""
        resting += res.kind == "constrained"
    assert resting >= 3
