"""`ThinSearch`: more seeds for a sampled plan's polishing, searched on a thinner sphere
model and then pushed out and tightened on the robot's own collision geometry.

The planner's spheres cover every point of the file's meshes and reach up to 2 cm beyond
them (`geosyn.robots.collision_spheres`): a passage that is open on the meshes can be shut
on the spheres, and the path the sampled search pulls taut round them is the one the
exact tightening (`geosyn.metrics.planning.tighten`) starts from and only moves locally.
Here the same search (`geosyn.metrics.planning.polish.taut_seeds`: RRT-Connect paths and
bumped straight lines, pulled taut) runs on the covering spheres shrunk (`THIN_SHRINKS`:
they no longer cover the meshes, a guide, not a check) at a margin of `THIN_MARGIN`; its
shortest path is then pushed out of the obstacles and tightened on the exact geometry
(`geosyn.metrics.planning.tighten.exact_push`). The query verifies it like every plan and
keeps it only when it is shorter (`geosyn.metrics.planning.query.Query.polish`).

On the Panda benchmark scenes (`benchmarks/RESULTS.md`, issue 22, twelfth round) this
found ways round that the covering spheres had shut: at a 2 s budget, 1.006 of geodex's
length on table_box (1.033 before), 0.996 on pillar_pipe_panel (1.014).

First: a polishing with less than `THIN_FIRST` left runs this search first, and the
covering spheres' seeds only when it found nothing shorter (`Query.polish`); with more,
the spheres' seeds and their tightening come first.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from geosyn.metrics.base import Metric
from geosyn.metrics.planning.polish import taut_seeds
from geosyn.metrics.planning.sampled import POLISH_GAIN
from geosyn.metrics.planning.sampling import Sampling, sampling_box
from geosyn.metrics.planning.smoothing import metric_length
from geosyn.metrics.planning.tighten import exact_movable, exact_push
from geosyn.robots.robot import CollisionSphere, Robot

if TYPE_CHECKING:
    from geosyn.metrics.planning.plan import Plan
    from geosyn.metrics.planning.planner import Planner
    from geosyn.metrics.planning.query import Query

__all__ = [
    "THIN_FIRST",
    "THIN_MARGIN",
    "THIN_MIN_RADIUS",
    "THIN_MIN_TIME",
    "THIN_PATIENCE",
    "THIN_SEARCH",
    "THIN_SEED_STRIDE",
    "THIN_SHRINKS",
    "ThinSearch",
    "thinner_plan",
]

THIN_SHRINKS = (0.015, 0.025)
"""Radius [m] taken off every covering sphere for the thinner models, one a round by turns.
On the Panda scenes (largest length against geodex's at 0.3 / 1 / 2 s, measured): 5 mm
changed little; 15 mm alone 1.004 / 1.005 / 1.003; 20 mm alone 1.021 / 0.998 / 1.003;
25 mm alone 1.029 / 0.998 / 1.004: the first round, all a 0.3 s budget has, is best at
15 mm, later rounds find more at 25 mm."""

THIN_FIRST = 0.6
"""Time left [s] below which a polishing searches the thinner spheres before the covering
ones. The other way round, a 0.08-0.23 s query's one covering-sphere seed and its
tightening took the time and left 25-55 ms of it unused, and a 0.25-0.45 s query spent
its time on seeds that the tightening could not bring near the meshes. On the 14 Panda
scenes (fourteenth round, measured), scenes <= geodex's length, spheres first -> this
first: 10 -> 13 at 0.1 s, 10 -> 14 at 0.13 s, 12 -> 13 at 0.16 s, 12 -> 14 at 0.35 s,
13 -> 14 at 0.45 s (0.25 and 0.3 s: 12 either way); largest ratio 1.014 -> 1.012,
1.014 -> 0.998, 1.010 -> 1.000, 1.003 -> 0.997, 1.007 -> 0.998 (0.25 / 0.3 s: 1.002 ->
1.001, 1.013 -> 1.006); from 0.6 s on, the same counts either way."""

THIN_MIN_RADIUS = 0.005
"""Least radius [m] of a thinner sphere."""

THIN_MARGIN = 0.001
"""Sampling margin [m] on the thinner spheres (the path is tightened to twice it there)."""

THIN_MIN_TIME = 0.04
"""Least time [s] left of a polishing for the thinner search (its search, the push-out,
the tightening and a check). On the Panda scenes at a 0.3 s budget, 0.1 left it out
(largest length 1.022 of geodex's), 0.04 brought it in (1.004), the plans returned
within 0.302 s (measured)."""

THIN_SEARCH = 0.4
"""Share of that time for the search on the thinner spheres; the rest pushes its path
out and tightens it on the exact geometry."""

THIN_PATIENCE = 2
"""Rounds of the thinner search in a row that shorten the best by less than
`geosyn.metrics.planning.sampled.POLISH_GAIN` before it stops."""

THIN_SEED_STRIDE = 1000
"""Seed offset between two rounds of the thinner search (their RRT-Connect paths and
bumped lines differ)."""


@dataclass
class ThinSearch:
    """A planner's thinner sphere model, in the form the sampled search reads
    (`geosyn.metrics.planning.sampled.SphereSearch`). Built by `for_planner`.

    Attributes:
        sampling: the sampling checks on the thinner spheres (no self pairs, no aids).
        margin: the margin its paths are tightened to [m] (twice `THIN_MARGIN`).
        nodes: the planner's samples of a path less one.
        metric: the planner's metric.
        robot: the planner's robot.
    """

    sampling: Sampling
    margin: float
    nodes: int
    metric: Metric
    robot: Robot

    @classmethod
    def for_planner(cls, planner: Planner, shrink: float) -> ThinSearch:
        """The model of ``planner``'s spheres less ``shrink`` [m] (allocates the sampling
        check)."""
        spheres = tuple(
            CollisionSphere(s.joint, s.center, max(s.radius - shrink, THIN_MIN_RADIUS))
            for s in planner.term.spheres
        )
        sampling = Sampling(planner.robot, spheres, None, THIN_MARGIN)
        return cls(sampling, 2.0 * THIN_MARGIN, planner.nodes, planner.metric, planner.robot)

    def shortest(self, q0: np.ndarray, q1: np.ndarray, obstacles: tuple, seed: int,
                 budget: float, attempts: list[str]) -> np.ndarray | None:  # fmt: skip
        """(T, n) [rad] the shortest path from ``q0`` to ``q1`` (n,) the polishing's
        search pulls taut on the thinner spheres round ``obstacles`` within ``budget``
        [s], or None (nothing found)."""
        end = time.perf_counter() + budget
        lo, hi = sampling_box(self.robot, q0, q1)

        def left() -> float:
            return end - time.perf_counter()

        def rrt(index: int, seconds: float) -> np.ndarray | None:
            return self.sampling.connect(q0, q1, lo, hi, seconds, seed + index)[0]

        self.sampling.start(obstacles, q0, q1)
        own: list[str] = []  # the search's own lines, said as this model's
        try:
            first = rrt(0, 0.3 * budget)
            if first is None:
                own.append("RRT-Connect found no path")
                return None
            path, _, _, _ = taut_seeds(self, q0, q1, seed, first, math.inf, left, 0.0, rrt, own)
        finally:
            self.sampling.finish()
            attempts.extend(f"thinner spheres: {line}" for line in own)
        return path


def thinner_plan(query: Query, plan: Plan, left: Callable[[], float]) -> Plan:
    """``plan`` (the polishing's result), or the shortest of the thinner search's paths
    (module docstring) that passes the query's checks and is shorter in the metric.
    Rounds of that search (other seeds each) run while `THIN_MIN_TIME` is left beyond
    two final checks (``left()``: the time left [s]), until `THIN_PATIENCE` rounds in a
    row shorten the best by less than `POLISH_GAIN`; only for a robot with file geometry
    and a margin.
    Says in the query's attempts what it found."""
    p, best, stale = query.p, plan, 0
    if not exact_movable(p):  # nothing to push out to (`exact_push`)
        return plan
    length, rounds = metric_length(p.metric, plan.q), 0
    while stale < THIN_PATIENCE:
        reserve = query.reserve()
        spare = left() - 2.0 * reserve
        if spare < THIN_MIN_TIME:
            break
        model = p.thin[rounds % len(p.thin)]
        path = model.shortest(query.q0, query.q1, tuple(p.term.obstacles),
                              query.seed + THIN_SEED_STRIDE * rounds, THIN_SEARCH * spare,
                              query.attempts)  # fmt: skip
        rounds += 1
        pushed = None if path is None else exact_push(p, path, left() - 2.0 * reserve)
        new = math.inf if pushed is None else metric_length(p.metric, pushed)
        how = f"the thinner spheres' path (round {rounds}) pushed out and tightened on the exact geometry"
        better = None
        if pushed is not None and new < length:
            better = query.verified(pushed, how, resample=False)
        if pushed is None or better is None:
            stale += 1
            continue
        stale = stale + 1 if new > (1.0 - POLISH_GAIN) * length else 0
        query.sampled_path, best, length = pushed, better, new
    if rounds:
        query.attempts.append(f"thinner spheres: {rounds} round(s), the plan "
                              + ("shortened" if best is not plan else "not shortened"))  # fmt: skip
    return best
