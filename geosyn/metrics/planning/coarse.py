"""A planner's clearance bounds and its coarse-to-fine stage (stage 2 of
`geosyn.metrics.planning.planner`).

`clearance_bounds` are the lower bounds a collocation's clearance constraints keep:
the level asked for, lowered near the ends to their own clearances and capped where no
path could raise a clearance. `coarse_to_fine` solves a collocation with few nodes at an
inflated clearance from the straight line, then the full one from its path.
"""

from __future__ import annotations

import math
import time
from typing import TYPE_CHECKING

import numpy as np

from geosyn.metrics.geodesic.collocation import Collocation, CollocationResult
from geosyn.metrics.geodesic.collocation_parts import interpolate_path

if TYPE_CHECKING:
    from geosyn.metrics.planning.planner import Planner

COARSE_RAMP = 0.25
"""Fraction of the path over which the coarse clearance bound rises from the start's
(goal's) own clearance to ``coarse_margin``."""


def clearance_bounds(
    p: Planner, col: Collocation, q0: np.ndarray, q1: np.ndarray, level: float
) -> np.ndarray:
    """(P, m) clearance bounds [m] of the collocation ``col`` of planner ``p`` at its points.

    Per constraint, ``level``, lowered near the ends to the start's (goal's) clearance
    plus ``level`` times the fraction of `COARSE_RAMP` travelled (the sphere model is
    conservative: an end may sit inside it while clear of the robot's exact geometry,
    which `geosyn.metrics.planning.verify` checks), and capped (never below
    ``p.margin``) where a robot sphere keeps the same clearance to an obstacle at start,
    goal and halfway (e.g. a base sphere above a floor: no path could raise it).
    """
    t = col.point_times[:, None]
    c0, c1 = col.slot_clearances(q0)[None], col.slot_clearances(q1)[None]
    k = max(level, p.margin) / COARSE_RAMP
    bounds = np.minimum(np.minimum(c0 + k * t, c1 + k * (1.0 - t)), level)
    n_obs, cap = len(p.term.obstacles), p.term.capacity
    if n_obs:
        C = np.stack([p.term.clearances(q) for q in (q0, q1, 0.5 * (q0 + q1))])
        slack = 0.0 if p.softmin is None else math.log(C.shape[1]) / p.softmin
        fixed = np.ptp(C, axis=0) < 1e-9  # (spheres, obstacles)
        caps = np.full((C.shape[1], cap), math.inf)
        caps[:, :n_obs] = np.where(fixed, np.maximum(p.margin, C[0] - slack), math.inf)
        per_row = caps.min(axis=0) if p.softmin is not None else caps.ravel()
        bounds = np.minimum(bounds, np.maximum(per_row[None], p.margin))
    return bounds


def coarse_to_fine(
    p: Planner, q0: np.ndarray, q1: np.ndarray, budget: float, attempts: list[str]
) -> tuple[CollocationResult, np.ndarray]:
    """The full collocation of planner ``p`` from its coarse one's path (``q0``, ``q1``:
    (n,) [rad]; ``budget`` [s], half of it for the coarse solve; what was tried appended
    to ``attempts``), and that path (its nodes, interpolated to the full node count:
    (nodes + 1, n) [rad])."""
    t0 = time.perf_counter()
    coarse = p.collocation(p.coarse_nodes, p.coarse_subdivisions)
    seed = coarse.solve(q0, q1, budget=0.5 * budget, refine=False,
                        lower=clearance_bounds(p, coarse, q0, q1, p.coarse_margin))  # fmt: skip
    # a failed coarse solve still leaves a path round the obstacles (its last iterate):
    # only a seed, the full collocation and the checks decide
    attempts.append(f"coarse collocation ({p.coarse_nodes} segments, "
                    f"{p.coarse_subdivisions} constrained point(s) inside each, "
                    f"clearance {p.coarse_margin:g} m) from the straight line: "
                    f"{seed.message}")  # fmt: skip
    times = np.linspace(0.0, 1.0, len(seed.nodes))
    init = interpolate_path(seed.nodes, times, p.nodes, p.metric.n)
    left = max(budget - (time.perf_counter() - t0), 1e-3)
    res = p.solve(p.collocation(p.nodes), q0, q1, init=init, budget=left,
                  mu_init=p.seeded_mu_init)  # fmt: skip
    attempts.append(f"collocation from the coarse path: {res.message}")
    return res, init
