"""A sampled plan's path pulled taut in the metric (`pull_taut`), and the shares of a
query's budget its stages take (`geosyn.metrics.planning.query.Query.sampled` and
`Query.polish` use them).

`pull_taut`: string pulling of an RRT-Connect path (`geosyn.metrics.planning.rrt`),
`SAMPLED_TRIES` partial shortcuts in the metric (`geosyn.metrics.planning.smoothing`),
then `geosyn.metrics.planning.relax.metric_relax` twice (`relax_taut`): with its
penalty below 3 cm, then below the planner's margin with only valid steps (segments
checked at the margin).

`relaxed_line`: the other seeds of a sampled plan's polishing. The straight joint line
bent by a random bump (`bumped_line`) crosses the obstacles; the same relaxation,
started there, pushes its samples out (the penalty) and pulls it taut: trajectory
optimisation from random restarts, as CHOMP (Ratliff et al., ICRA 2009) and TrajOpt
(Schulman et al., RSS 2013) do, where RRT-Connect's paths are the other seeds.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Protocol

import numpy as np

from geosyn.metrics.planning.relax import metric_relax
from geosyn.metrics.planning.rrt import string_pull
from geosyn.metrics.planning.smoothing import even_in_metric, metric_shortcut

if TYPE_CHECKING:
    from geosyn.metrics.base import Metric
    from geosyn.metrics.planning.plan import Plan
    from geosyn.metrics.planning.query import Query
    from geosyn.metrics.planning.sampling import Sampling
    from geosyn.robots.robot import Robot


class SphereSearch(Protocol):
    """What the sampled search reads of a planner (`geosyn.metrics.planning.planner.Planner`,
    or `geosyn.metrics.planning.thin.ThinSearch`'s thinner sphere model): its sampling
    checks, the margin its paths are tightened to [m], the samples of a path less one,
    the metric and the robot."""

    sampling: Sampling
    margin: float
    nodes: int
    metric: Metric
    robot: Robot


__all__ = [
    "POLISH_GAIN",
    "POLISH_PATIENCE",
    "BUMP_SIGMA",
    "RELAX_RESOLUTION",
    "SAMPLED_CHECK_SHARE",
    "SAMPLED_RELAX",
    "SAMPLED_RELAX_MAX",
    "SAMPLED_RETRIES",
    "SAMPLED_SEARCH",
    "SAMPLED_SMALL",
    "SAMPLED_TRIES",
    "TIGHTEN_AFTER",
    "SphereSearch",
    "bumped_line",
    "exact_line",
    "pull_taut",
    "relax_taut",
    "relaxed_line",
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
"""Partial shortcuts in the metric of a sampled path before it is relaxed (`pull_taut`):
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

SAMPLED_RETRIES = 8
"""Most further sampled first plans (other RRT-Connect seeds,
`geosyn.metrics.planning.query.Query.sampled`) after one that failed its checks, each
while the time left is more than the first attempt took and no collocation would take
it. Before, a query refused at once: on a UR5, random queries whose first RRT-Connect
path self-collided on the meshes were refused after 0.11-0.13 s of a 1 s budget
(`benchmarks/RESULTS.md`, issue 22, sixteenth round). After a self-collision there is no
such limit: the retries go on while that time is left (each raises a floor where the
last path touched; the NLP has no self-collision term). Capped at 8, seeded random UR5
queries (`benchmarks/planning_random.py`, seeds 0-5) were refused 3 of 48 times at the
default 5 s with 1.4-3.0 s unspent; uncapped, 0 (measured)."""

BUMP_SIGMA = 0.5
"""Standard deviation [rad] per joint of a `bumped_line`'s bump. Relaxed, such lines
reach other local minima than RRT-Connect's paths (which come round the obstacles
with detours that the relaxation keeps). On the 14 Panda benchmark scenes, of 6 lines
per scene relaxed for 0.1 s each, at least one came out valid on 13 (none through
shelf_compartments' openings), the shortest 0.77-1.05x geodex's 1 s length before the
exact tightening; on pillar_pipe_panel 1.025x, where 8 RRT-Connect paths pulled taut
alike gave 1.31-3.2x. 0.3 and 1.0 gave longer shortest paths on 5 and 6 of the scenes,
shorter ones on 3 and 1 (measured)."""

RELAX_RESOLUTION = 0.02
"""Segment check step [rad] of the relaxations (`metric_relax`'s default)."""

TIGHTEN_AFTER = 0.7
"""Share of the relaxation's time for its first stage (`pull_taut`; penalty below
`geosyn.metrics.planning.relax.RELAX_DELTA`). The second starts from its result with
the penalty below the planner's margin and only steps whose segments all pass the
sampling check (`metric_relax`'s ``stay_valid``), in the rest of the time: on the Panda
scenes it shortened relaxed paths by 1-5 % in 25-70 ms, their exact clearance staying
at 14 mm or more (measured)."""


def pull_taut(planner: SphereSearch, path: np.ndarray, budget: float,
              seed: int) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """(taut, rough): ``path`` (T, n) [rad] with its vertices skipped (`string_pull`),
    shortened by `SAMPLED_TRIES` partial shortcuts in the metric (rough), then
    relaxed and tightened (`relax_taut` on ``nodes + 1`` samples even in the metric)
    within ``budget`` [s] in all (a stage is not begun once it is spent)."""
    p, end = planner, time.perf_counter() + budget
    check = p.sampling  # the query's obstacles and ends set (`Sampling.start`)
    rough = string_pull(check.segment_valid, path, deadline=end)
    if time.perf_counter() >= end:  # no time for the shortcuts (their set-up: 1-6 ms)
        return rough, rough
    rough = metric_shortcut(check.valid, p.metric, rough, budget=0.3 * budget,
                            tries=SAMPLED_TRIES, seed=seed, segment=check.segment_valid)  # fmt: skip
    if time.perf_counter() >= end:  # no time for the relaxation
        return rough, rough
    x = even_in_metric(p.metric, rough, p.nodes + 1)
    taut = relax_taut(p, x, max(end - time.perf_counter(), 0.0))
    return (taut if taut is not None else x), rough  # None only for an invalid seed


def relax_taut(planner: SphereSearch, x: np.ndarray, budget: float,
               seed_valid: bool = True) -> np.ndarray | None:  # fmt: skip
    """The samples ``x`` (T, n) [rad] relaxed (`metric_relax`, penalty below
    `geosyn.metrics.planning.relax.RELAX_DELTA`, in `TIGHTEN_AFTER` of ``budget`` [s])
    and tightened (penalty below the planner's margin, every step valid at it) in the
    rest: valid on the spheres and within the joint limits. ``seed_valid`` False: ``x``
    may cross the obstacles (`relaxed_line`); None when the relaxation did not bring it
    out (no tightening)."""
    p, end = planner, time.perf_counter() + budget
    check, box = p.sampling, (p.robot.q_min, p.robot.q_max)  # every iterate within the limits
    grads = check.check.gradients  # None: central differences (the numpy check)
    taut = metric_relax(None, check.check.clearances, p.metric, x, gradients=grads,
                        budget=TIGHTEN_AFTER * budget, seed_valid=seed_valid, bounds=box,
                        path_ok=_valid(p, check.margin))  # fmt: skip
    if not seed_valid and not _valid(p, check.margin)(taut):
        return None
    if p.margin > 0.0 and time.perf_counter() < end:  # nearer, valid steps, to the margin
        taut = metric_relax(None, check.check.clearances, p.metric, taut, gradients=grads,
                            budget=max(end - time.perf_counter(), 0.0), delta=p.margin,
                            stay_valid=True, bounds=box, path_ok=_valid(p, p.margin))  # fmt: skip
    return taut


def _valid(planner: SphereSearch, margin: float) -> Callable[[np.ndarray], bool]:
    """Whether every segment of a path (T, n) passes the sampling check at ``margin``
    [m] and the relaxation's resolution (one call of the check)."""
    return lambda x: planner.sampling.check.path_valid(x, RELAX_RESOLUTION, margin)


def bumped_line(q0: np.ndarray, q1: np.ndarray, samples: int, q_min: np.ndarray,
                q_max: np.ndarray, seed: int, index: int) -> np.ndarray:  # fmt: skip
    """(samples, n) [rad] the straight joint line from ``q0`` to ``q1`` (n,) plus the
    bump ``sin(pi s) v`` (s in [0, 1] evenly), ``v ~ N(0, BUMP_SIGMA^2 I)`` drawn
    from the generator seeded ``(seed, index)``, clipped to the limits."""
    v = BUMP_SIGMA * np.random.default_rng((seed, index)).standard_normal(q0.size)
    s = np.linspace(0.0, 1.0, samples)[:, None]
    x = np.clip(q0 + s * (q1 - q0) + np.sin(np.pi * s) * v, q_min, q_max)
    x[0], x[-1] = q0, q1  # exactly (sin(pi) is not 0 in floating point)
    return x


def relaxed_line(planner: SphereSearch, q0: np.ndarray, q1: np.ndarray, seed: int,
                 index: int, budget: float) -> np.ndarray | None:  # fmt: skip
    """`bumped_line` ``index`` (``nodes + 1`` samples) pushed out of the obstacles and
    pulled taut (`relax_taut`) within ``budget`` [s]: (nodes + 1, n) [rad] valid on the
    spheres, or None when it did not come out."""
    p = planner
    x = bumped_line(q0, q1, p.nodes + 1, p.robot.q_min, p.robot.q_max, seed, index)
    return relax_taut(p, x, budget, seed_valid=False)


def exact_line(query: Query) -> Plan | None:
    """The straight joint line from ``query``'s start to its goal as its sampled plan
    (`Query.verified`: the exact check decides, self-collision included), or None: for a
    query whose RRT-Connect found no connection on the spheres (`Query.sampled` keeps the
    line as the polishing's seed). A self pair's floor may
    block configurations where its links are apart (the spheres reach beyond them): on
    the UR10 with +-pi limits, 3 of 8 seeded random queries were refused whose straight
    line is 4-11 mm clear of itself on the meshes, 10-29 % of it below the floors
    (`benchmarks/RESULTS.md`, issue 22, twenty-third round). Without file geometry:
    None (the spheres are all there is)."""
    if query.p.exact is None:
        return None
    how = "the straight line (no connection on the spheres) checked on the exact geometry"
    return query.verified(np.array([query.q0, query.q1]), how)
