"""`anytime_plan`: when a budget ends before any solve converges, the lowest-energy
unfinished path (an interrupted IPOPT iterate or a seed) that passes a planner's checks,
as a ``"feasible"`` plan (`geosyn.metrics.planning.query.Query.run`)."""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np

from geosyn.metrics.planning.plan import Plan
from geosyn.metrics.planning.verify import deciding_clearance, exact_check, feasible_result
from geosyn.world.exact_clearance import PathClearance

if TYPE_CHECKING:
    from geosyn.metrics.planning.planner import Planner

Decide = Callable[[PathClearance, float], tuple[float, str]]
"""(a path's exact check, its smallest sphere clearance [m]) -> (the deciding clearance
[m], what measured it): `geosyn.metrics.planning.query.Query.decide`."""

__all__ = ["ANYTIME_CHECKS", "anytime_plan"]

ANYTIME_CHECKS = 3
"""Most unfinished paths checked when a budget ends without a converged plan."""


def anytime_plan(planner: Planner, unfinished: list[tuple[np.ndarray, str]], t0: float,
                 attempts: list[str], end: float = math.inf,
                 decide: Decide | None = None) -> Plan | None:  # fmt: skip
    """The lowest-energy path among ``unfinished`` (interrupted IPOPT iterates and
    seeds, (T, n) each) that passes the fine and exact checks before ``end``
    (perf_counter [s]), as a ``"feasible"`` plan; ``decide``: which clearance decides
    (None: the exact one, else the spheres', `deciding_clearance`)."""
    if decide is None:

        def decide(exact: PathClearance, spheres: float) -> tuple[float, str]:
            has = planner.exact is not None
            return deciding_clearance(exact if has else None, spheres, False, 0.0)

    results = [feasible_result(planner.metric, q, how) for q, how in unfinished
               if np.all(np.isfinite(q))]  # fmt: skip
    for res in sorted(results, key=lambda r: r.energy)[:ANYTIME_CHECKS]:
        if time.perf_counter() > end:
            attempts.append("no time left to check the unfinished paths")
            break
        coarse, fine = planner.check(res.q)
        exact = exact_check(planner.exact, res.q, planner.term.obstacles, planner.exact_resolution,
                            end, planner.sampling.aids)  # fmt: skip
        ok = decide(exact, min(coarse, fine))[0] >= 0.0
        own = planner.self_check(res.q, end) if ok else math.nan
        if ok and planner.self_ok(own):
            wall = time.perf_counter() - t0
            attempts.append(f"returned {res.message.split(': ', 1)[1]} (not converged)")
            return Plan(res, "anytime", coarse, wall, tuple(attempts), fine,
                        exact.clearance, planner.exact_resolution, wall,
                        self_clearance=own)  # fmt: skip
        if ok:
            attempts.append(f"{res.message.split(': ', 1)[1]}: self-collision check "
                            f"fails (self-clearance {own:.4f} m)")  # fmt: skip
    return None
