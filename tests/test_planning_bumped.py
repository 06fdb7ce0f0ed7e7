"""Sampled plans from bumped straight lines (issue 22): `metric_relax` started through an
obstacle (``seed_valid=False``) and `geosyn.metrics.planning.sampled.relaxed_line`.

Referees: the shaping term's own sphere-obstacle clearance (`ObstacleTerm`) on the
returned path checked 16x finer; a hand-made detour round the post, free on that check,
as an upper bound of the energy (midpoint rule, summed in the test); the geodesic
distance between the ends (geosyn's log map, shooting) as a lower bound of the length.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from geosyn.core.errors import GeosynError
from geosyn.metrics import KineticEnergyMetric
from geosyn.metrics.geodesic.energy import distance
from geosyn.metrics.planning import Planner
from geosyn.metrics.planning.planner import densify
from geosyn.metrics.planning.relax import metric_relax
from geosyn.metrics.planning.sampled import BUMP_SIGMA, bumped_line, relaxed_line
from geosyn.metrics.planning.smoothing import metric_length
from geosyn.robots import load_robot
from geosyn.world import Box

ROBOT = dataclasses.replace(
    load_robot("planar2"), q_min=np.full(2, -np.pi), q_max=np.full(2, np.pi)
)
POST = Box((1.5, 0.0, 0.0), (0.08, 0.08, 0.5))  # only the outer link reaches it
Q0, Q1 = np.array([-0.8, 0.3]), np.array([0.8, -0.3])


@pytest.fixture(scope="module")
def planner() -> Planner:
    with pytest.warns(UserWarning, match="planar2"):  # built in code: capsule spheres
        planner = Planner(KineticEnergyMetric(ROBOT), capacity=1, nodes=12, coarse_nodes=0)
    return planner


def _energy(planner: Planner, p: np.ndarray) -> float:
    G = planner.metric.G
    dq, mid = np.diff(p, axis=0), 0.5 * (p[1:] + p[:-1])
    return (len(p) - 1) * float(sum(d @ G(m) @ d for d, m in zip(dq, mid, strict=True)))


def _nearest(planner: Planner, p: np.ndarray) -> float:
    return min(planner.term.min_clearance(q) for q in densify(p, 16))


def test_relaxation_started_through_the_post_comes_out_clear(planner: Planner) -> None:
    """A bumped line (seed 0, index 1) crosses the post; relaxed with ``seed_valid=False``
    it comes out clear of the post 16x finer, every segment passing the planner's check,
    with its ends and sample count, below the energy of a free detour through (0, 1.6)
    [rad] on the same 12 segments and no shorter than the geodesic distance."""
    planner.term.set_obstacles([POST])
    planner.sphere_check.set_obstacles([POST])
    line = bumped_line(Q0, Q1, 13, ROBOT.q_min, ROBOT.q_max, seed=0, index=1)
    assert _nearest(planner, line) < 0.0
    detour = densify(np.array([Q0, [0.0, 1.6], Q1]), 6)
    assert _nearest(planner, detour) > 0.0
    out = metric_relax(planner.segment_valid, planner.sphere_check.clearances,
                       planner.metric, line, budget=2.0, seed_valid=False)  # fmt: skip
    assert out.shape == line.shape
    np.testing.assert_array_equal(out[[0, -1]], line[[0, -1]])
    assert _nearest(planner, out) > 0.0
    assert all(planner.segment_valid(a, b, 0.02) for a, b in zip(out[:-1], out[1:], strict=True))
    assert _energy(planner, out) < _energy(planner, detour)
    assert metric_length(planner.metric, out) >= distance(planner.metric, Q0, Q1)


def test_stay_valid_needs_a_valid_seed(planner: Planner) -> None:
    """Taking only valid steps from a path that is not valid is refused by name."""
    line = densify(np.array([Q0, Q1]), 4)
    with pytest.raises(GeosynError, match="seed_valid"):
        metric_relax(planner.segment_valid, planner.sphere_check.clearances, planner.metric,
                     line, stay_valid=True, seed_valid=False)  # fmt: skip


def test_bumped_line_is_the_line_plus_a_sine_bump_within_the_limits() -> None:
    """Ends exact; at s = 1/2 the line's midpoint plus the seeded draw (closed form),
    inside the limits; another index draws another bump; clipped where it would leave
    them."""
    n, lo, hi = 7, np.full(7, -3.0), np.full(7, 3.0)
    q0, q1 = np.linspace(-1.0, 1.0, n), np.linspace(0.5, -0.5, n)
    x = bumped_line(q0, q1, 25, lo, hi, seed=3, index=2)
    assert x.shape == (25, n)
    np.testing.assert_array_equal(x[[0, -1]], [q0, q1])
    v = BUMP_SIGMA * np.random.default_rng((3, 2)).standard_normal(n)
    np.testing.assert_allclose(x[12], 0.5 * (q0 + q1) + v, atol=1e-12)
    assert not np.allclose(bumped_line(q0, q1, 25, lo, hi, seed=3, index=1), x)
    tight = bumped_line(q0, q1, 25, lo, np.full(n, 0.2), seed=3, index=2)
    assert tight[1:-1].max() == 0.2


def test_relaxed_lines_come_out_clear_or_say_none(planner: Planner) -> None:
    """Bumped lines 1-6 round the post: each returned one is clear of the post 16x finer
    and passes the planner's check on every segment; at least one comes out."""
    planner.term.set_obstacles([POST])
    planner.sampling.start([POST], Q0, Q1)
    try:
        outs = [relaxed_line(planner, Q0, Q1, 0, k, 0.5) for k in range(1, 7)]
    finally:
        planner.sampling.finish()
    planner.sphere_check.set_obstacles([POST])
    kept = [x for x in outs if x is not None]
    assert kept
    for x in kept:
        assert x.shape == (planner.nodes + 1, 2)
        np.testing.assert_array_equal(x[[0, -1]], [Q0, Q1])
        assert _nearest(planner, x) > 0.0
        assert all(planner.segment_valid(a, b, 0.02) for a, b in zip(x[:-1], x[1:], strict=True))


def test_a_push_out_stops_at_its_first_valid_iterate(planner: Planner) -> None:
    """``first_valid`` from the bumped line through the post: the path check is passed
    once, by the iterate returned (no later one is made), which is clear of the post 16x
    finer with its ends kept; without it the relaxation goes on to lower energies (the
    full relaxation's energy is below the first valid iterate's)."""
    planner.term.set_obstacles([POST])
    planner.sphere_check.set_obstacles([POST])
    line = bumped_line(Q0, Q1, 13, ROBOT.q_min, ROBOT.q_max, seed=0, index=1)
    verdicts: list[bool] = []

    def path_ok(y: np.ndarray) -> bool:
        ok = all(planner.segment_valid(a, b, 0.02) for a, b in zip(y[:-1], y[1:], strict=True))
        verdicts.append(ok)
        return ok

    def relax(first: bool) -> np.ndarray:
        verdicts.clear()
        return metric_relax(None, planner.sphere_check.clearances, planner.metric, line,
                            budget=30.0, seed_valid=False, path_ok=path_ok,
                            first_valid=first)  # fmt: skip

    out = relax(True)
    assert verdicts.count(True) == 1 and verdicts[-1]
    np.testing.assert_array_equal(out[[0, -1]], line[[0, -1]])
    assert _nearest(planner, out) > 0.0
    full = relax(False)
    assert verdicts.count(True) > 1
    assert _energy(planner, full) < _energy(planner, out)


def test_a_floor_spares_the_path_check_and_changes_nothing(planner: Planner) -> None:
    """``floor`` in a tightening (valid steps, penalty below 1 cm): a path check that
    also asks every sample to keep 2 cm (on the sphere clearances the relaxation knows)
    is never called on an iterate whose samples do not, where without the floor it is,
    and the relaxation returns the same path as without it."""
    planner.term.set_obstacles([POST])
    planner.sphere_check.set_obstacles([POST])
    floor, clear = 0.02, planner.sphere_check.clearances
    line = bumped_line(Q0, Q1, 13, ROBOT.q_min, ROBOT.q_max, seed=0, index=1)
    start = metric_relax(planner.segment_valid, clear, planner.metric, line, budget=30.0,
                         seed_valid=False)  # fmt: skip
    asked: list[float] = []

    def path_ok(y: np.ndarray) -> bool:
        asked.append(float(clear(y[1:-1]).min()))
        return asked[-1] >= floor and all(
            planner.segment_valid(a, b, 0.02) for a, b in zip(y[:-1], y[1:], strict=True)
        )

    def relax(with_floor: float) -> np.ndarray:
        asked.clear()
        return metric_relax(None, clear, planner.metric, start, budget=30.0, delta=0.01,
                            stay_valid=True, path_ok=path_ok, floor=with_floor)  # fmt: skip

    plain = relax(-np.inf)
    below = sum(c < floor for c in asked)
    screened = relax(floor)
    assert below > 0 and all(c >= floor for c in asked)  # without the floor: asked about some
    np.testing.assert_array_equal(screened, plain)
    assert not np.array_equal(plain, start)  # it moved
