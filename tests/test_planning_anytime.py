"""Anytime plans (issue 22): when a budget ends before any solve converges, the planner
returns the lowest-energy unfinished path that passes its checks, as kind "feasible".

Reference: the exact sphere-obstacle clearances of `ObstacleTerm.clearances` on the
returned path checked 16x finer, and the midpoint-rule energy summed in the test.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from geosyn.metrics import KineticEnergyMetric
from geosyn.metrics.planning import Planner
from geosyn.metrics.planning.planner import densify
from geosyn.robots import load_robot
from geosyn.world import Box

ROBOT = dataclasses.replace(
    load_robot("planar2"), q_min=np.full(2, -np.pi), q_max=np.full(2, np.pi)
)
POST = Box((1.5, 0.0, 0.0), (0.08, 0.08, 0.5))  # only the outer link reaches it


def test_anytime_keeps_the_lowest_energy_path_that_passes_the_checks() -> None:
    metric = KineticEnergyMetric(ROBOT)
    planner = Planner(metric, capacity=1, nodes=12, coarse_nodes=0)
    q0, q1 = np.array([-0.8, 0.3]), np.array([0.8, -0.3])
    planner.term.set_obstacles([POST])
    line = densify(np.array([q0, q1]), 12)  # through the post: lowest energy, refused
    assert min(planner.term.min_clearance(q) for q in line) < 0.0
    bend = np.array([q0, [0.0, 1.6], q1])  # the outer link folded away from the post
    detour = densify(bend, 6)
    far = densify(np.array([q0, [0.0, 2.6], q1]), 6)  # free too, but more energy
    plan = planner._anytime([(line, "line"), (far, "far"), (detour, "detour")], 0.0, [])
    assert plan is not None and plan.seed == "anytime"
    assert plan.result.kind == "feasible" and "detour" in plan.result.message
    np.testing.assert_array_equal(plan.q, detour)
    fine = densify(plan.q, 16)
    assert min(planner.term.min_clearance(q) for q in fine) >= 0.0
    dq, mid = np.diff(detour, axis=0), 0.5 * (detour[1:] + detour[:-1])
    energy = (len(detour) - 1) * sum(d @ metric.G(m) @ d for d, m in zip(dq, mid, strict=True))
    assert abs(plan.result.energy - energy) < 1e-12 * energy
    assert planner._anytime([(line, "line")], 0.0, []) is None  # nothing passes: none
