"""A sampled plan's path pulled taut in the metric (`pull_taut`), and the shares of a
query's budget its stages take (`geosyn.metrics.planning.query.Query.sampled` and
`Query.polish` use them).

`pull_taut`: string pulling of an RRT-Connect path (`geosyn.metrics.planning.rrt`),
`SAMPLED_TRIES` partial shortcuts in the metric (`geosyn.metrics.planning.smoothing`),
then `geosyn.metrics.planning.relax.metric_relax` twice: with its penalty below 3 cm,
then below the planner's margin with only valid steps (segments checked at the margin).
"""

from __future__ import annotations

import time
from typing import TYPE_CHECKING

import numpy as np

from geosyn.metrics.planning.relax import metric_relax
from geosyn.metrics.planning.rrt import string_pull
from geosyn.metrics.planning.smoothing import even_in_metric, metric_shortcut

if TYPE_CHECKING:
    from geosyn.metrics.planning.planner import Planner

__all__ = [
    "POLISH_GAIN",
    "POLISH_PATIENCE",
    "SAMPLED_CHECK_SHARE",
    "SAMPLED_RELAX",
    "SAMPLED_RELAX_MAX",
    "SAMPLED_SEARCH",
    "SAMPLED_SMALL",
    "SAMPLED_TRIES",
    "TIGHTEN_AFTER",
    "pull_taut",
]

SAMPLED_SEARCH = (0.7, 0.3, 0.1)
"""RRT-Connect for the sampled first plan (`Query.sampled`) stops after
``min(a T, b + c T)`` [s] of a budget ``T`` [s] for ``(a, b, c)`` = this (it stops
sooner when the trees connect, within 0.01-0.5 s on the Panda benchmark scenes: at small
budgets it may take most of the time, at large ones it leaves most to collocation)."""

POLISH_PATIENCE = 8
"""Paths in a row that shorten the best by less than `POLISH_GAIN` before `Query.polish`
returns (a plan need not take its whole budget). 3 left half of a 1-2 s budget unused on
the Panda scenes; 8 found shorter ways round on sphere_cluster (1.024 -> 1.012x
geodex's length), pillar (0.942 -> 0.896x) and shelf (0.746 -> 0.734x) at 1-2 s, the
plans returned in 0.57-1.25 s (measured)."""

POLISH_GAIN = 0.005
"""Relative shortening that counts as progress in `Query.polish`."""

SAMPLED_TRIES = 30
"""Partial shortcuts in the metric of a sampled path before it is relaxed (`Query.taut`):
they straighten RRT-Connect's detours, which the relaxation (a local method) keeps."""

SAMPLED_RELAX = 0.15
"""Share of the budget (at most `SAMPLED_RELAX_MAX`) for pulling the sampled plan taut."""

SAMPLED_CHECK_SHARE = 0.5
"""Largest share of the time left after RRT-Connect that pulling the sampled plan taut
may take (all of it when the budget is too small for collocation): the rest is for its
checks (3-25 ms on the Panda scenes). Capping it by the checks' expected time instead
(per checked configuration, from the last check) gave longer paths at 0.05-0.1 s
budgets and no more returned plans (measured)."""

SAMPLED_RELAX_MAX = 0.2
"""Longest relaxation of the sampled plan [s] (it converges in 0.03-0.3 s on the Panda
benchmark scenes, `benchmarks/RESULTS.md`)."""

SAMPLED_SMALL = 0.8
"""Share of a budget too small for collocation (less than `MIN_COLLOCATION` would be
left after `SAMPLED_SEARCH`) that RRT-Connect may take for the sampled plan."""

TIGHTEN_AFTER = 0.7
"""Share of the relaxation's time for its first stage (`Query.taut`; penalty below
`geosyn.metrics.planning.relax.RELAX_DELTA`). The second starts from its result with
the penalty below the planner's margin and only steps whose segments all pass the
sampling check (`metric_relax`'s ``stay_valid``), in the rest of the time: on the Panda
scenes it shortened relaxed paths by 1-5 % in 25-70 ms, their exact clearance staying
at 14 mm or more (measured)."""


def pull_taut(planner: Planner, path: np.ndarray, budget: float,
              seed: int) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """(taut, rough): ``path`` (T, n) [rad] with its vertices skipped (`string_pull`),
    shortened by `SAMPLED_TRIES` partial shortcuts in the metric (rough), then
    relaxed (`metric_relax` on ``nodes + 1`` samples even in the metric, in
    `TIGHTEN_AFTER` of the time left) and tightened (penalty below the planner's
    margin, every step valid) within ``budget`` [s] in all."""
    p, end = planner, time.perf_counter() + budget
    check = p.sampling  # the query's obstacles and ends set (`Sampling.start`)
    rough = string_pull(check.segment_valid, path)
    rough = metric_shortcut(check.valid, p.metric, rough, budget=0.3 * budget,
                            tries=SAMPLED_TRIES, seed=seed, segment=check.segment_valid)  # fmt: skip
    if time.perf_counter() >= end:  # no time for the relaxation
        return rough, rough
    taut = metric_relax(check.segment_valid, check.check.clearances, p.metric,
                        even_in_metric(p.metric, rough, p.nodes + 1),
                        budget=TIGHTEN_AFTER * max(end - time.perf_counter(), 0.0))  # fmt: skip
    if p.margin > 0.0 and time.perf_counter() < end:  # nearer, valid steps, to the margin

        def at_margin(a: np.ndarray, b: np.ndarray, resolution: float) -> bool:
            return check.check.segment_valid(a, b, resolution, p.margin)

        taut = metric_relax(at_margin, check.check.clearances, p.metric, taut,
                            budget=max(end - time.perf_counter(), 0.0), delta=p.margin,
                            stay_valid=True)  # fmt: skip
    return taut, rough
