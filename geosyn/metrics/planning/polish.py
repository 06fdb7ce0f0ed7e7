"""A sampled plan's polishing on the planner's covering spheres
(`geosyn.metrics.planning.query.Query.polish`): `taut_seeds`, the shortest path in the
metric among seeds pulled taut by turns, until the time is spent or the seeds stop
paying; `sphere_polish`, that search's path tightened on the exact geometry and verified.

The seeds, in turn: the sampled plan's own path (relaxed further), then a straight
joint line bent by a random bump (`geosyn.metrics.planning.sampled.relaxed_line` #1,
2, ...) and a new RRT-Connect path (seeds ``seed + 1, 2, ...``,
`geosyn.metrics.planning.sampled.pull_taut`) by turns. Each is pulled taut in at most
half the time left; the search stops after `POLISH_PATIENCE` seeds in a row that
shorten the best by less than `POLISH_GAIN`, when the straight line is free, or after a
given number of seeds (a short polishing: `SHORT_SEEDS`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np

from geosyn.metrics.planning.sampled import (
    POLISH_GAIN,
    POLISH_PATIENCE,
    SphereSearch,
    pull_taut,
    relaxed_line,
)
from geosyn.metrics.planning.smoothing import metric_length
from geosyn.metrics.planning.tighten import (
    EXACT_KEEP,
    EXACT_MIN_TIME,
    exact_movable,
    exact_tighten,
)

if TYPE_CHECKING:
    from geosyn.metrics.planning.plan import Plan
    from geosyn.metrics.planning.query import Query

__all__ = ["SHORT_SEEDS", "sphere_polish", "taut_seeds"]

SHORT_SEEDS = 1
"""Seeds after the sampled plan's own path that a polishing too short to keep
`geosyn.metrics.planning.tighten.EXACT_KEEP` back for its exact tightening pulls taut
(the first bumped line), before the rest of its time goes to that tightening and the
thinner spheres' seeds. Without a limit the seeds took all of a 0.1-0.2 s budget and
left none for them: on the 14 Panda benchmark scenes the returned length stayed flat
from 0.1 to 0.2 s; with one seed it fell by up to 5 % (table_box 1.310 -> 1.258 at
0.13 s, sphere_cluster 1.814 -> 1.729 at 0.16 s), longer on slot only (+0.5-0.8 %,
measured)."""


def taut_seeds(planner: SphereSearch, q0: np.ndarray, q1: np.ndarray, seed: int,
               path: np.ndarray | None, length: float, left: Callable[[], float],
               reserve: float, rrt: Callable[[int, float], np.ndarray | None],
               attempts: list[str], start: int = 1, most: int | None = None,
               ) -> tuple[np.ndarray | None, float, str, int]:  # fmt: skip
    """(shortest, its metric length, how it was made, the next seed's number) of the
    seeds (module docstring) from ``q0`` to ``q1`` (n,) [rad] shorter than ``length``,
    or (None, ``length``, "", the next seed's number).

    Args:
        planner: the planner (or a thinner sphere model of it), its query set (obstacles,
            ends: `Sampling.start`).
        q0: (n,) start [rad].
        q1: (n,) goal [rad].
        seed: the query's seed (the bumps' and the RRT-Connect paths').
        path: (T, n) the sampled plan's path [rad] (the first seed), or None.
        length: the sampled plan's metric length (what a seed must beat).
        left: time left to the search [s] (the polishing's, one exact check kept back).
        reserve: time kept back for the final checks [s] (a seed is begun only while
            more than twice that is left).
        rrt: ``rrt(index, budget)``: RRT-Connect path of seed ``seed + index`` within
            ``budget`` [s], or None.
        attempts: the query's list of what was tried (the stop is added to it).
        start: the number of the first seed after ``path`` (1: bumped line #1; 2: the
            RRT-Connect path of ``seed + 1``; ...): a later search goes on from where
            an earlier one stopped instead of pulling the same seeds taut again.
        most: the most seeds made after ``path`` (None: until the time or the
            patience runs out).
    """
    p, shortest, how, stale, name = planner, None, "", 0, "RRT-Connect path #0"
    bump = 0  # a bumped line's index, instead of ``path``, when > 0
    for restart in range(start, 10**6):  # the last one is returned
        if path is not None or bump:
            if left() <= reserve:
                break
            budget = 0.5 * (left() - reserve)
            taut = (relaxed_line(p, q0, q1, seed, bump, budget)
                    if path is None else pull_taut(p, path, budget, seed)[0])  # fmt: skip
            new = metric_length(p.metric, taut) if taut is not None else math.inf
            stale = 0 if new < (1.0 - POLISH_GAIN) * length else stale + 1
            if new < length:
                shortest, length, how = taut, new, f"{name} pulled taut in the metric"
        if left() <= 2.0 * reserve or (path is not None and len(path) == 2):
            break  # no time left, or the straight line is free: no other way round
        if most is not None and restart - start >= most:  # `SHORT_SEEDS`
            attempts.append(f"polishing stopped after {most} seed(s): the time left "
                            "is for the tightening")  # fmt: skip
            break
        if stale >= POLISH_PATIENCE:
            attempts.append(f"polishing stopped: {stale} seeds in a row no shorter "
                            f"by {POLISH_GAIN:.1%}")  # fmt: skip
            break
        if restart % 2:  # a bumped straight line
            path, bump = None, (restart + 1) // 2
            name = f"the straight line bumped #{bump}"
        else:
            path = rrt(restart // 2, (left() - reserve) / 3.0)
            bump, name = 0, f"RRT-Connect path #{restart // 2}"
    return shortest, length, how, restart  # seed ``restart`` not made yet


def sphere_polish(q: Query, plan: Plan, left: Callable[[], float]) -> Plan:
    """``plan`` (query ``q``'s sampled plan) polished on the planner's covering spheres
    (`taut_seeds` from the query's sampled path; when the paths can be moved on the exact
    geometry, `geosyn.metrics.planning.tighten.exact_movable`, keeping `EXACT_KEEP` back
    when `Query.ample`, else only `SHORT_SEEDS` seeds), its shortest path tightened on
    the exact geometry when movable and more than `EXACT_MIN_TIME` (and two exact checks'
    time) is left beyond the final check's reserve (`exact_tighten`) and verified once,
    kept if it passes and is shorter (else the untightened one, verified in turn); else
    ``plan``. ``left()``: the time left [s].
    Updates the query's sampled path and next seed."""
    p = q.p

    def rrt(index: int, seconds: float) -> np.ndarray | None:
        return q.connect(index, seconds)[0]

    reserve, movable = q.reserve(), exact_movable(p)  # not movable: no tightening
    ample = movable and q.ample(left())
    keep = EXACT_KEEP if ample else 0.0  # for `exact_tighten`
    most = SHORT_SEEDS if movable and not ample else None
    shortest, length, how, q.restart = taut_seeds(
        p, q.q0, q.q1, q.seed, q.sampled_path, metric_length(p.metric, plan.q),
        lambda: left() - keep, reserve, rrt, q.attempts, q.restart, most,
    )  # fmt: skip
    base = shortest if shortest is not None else np.asarray(plan.q)
    if (
        movable
        and len(base) > 2
        and (spare := left() - reserve) > max(EXACT_MIN_TIME, 2.0 * q.check_time)
    ):  # nearer on the robot's own geometry (its set-up runs whatever the budget)
        tight = exact_tighten(p, base, spare)
        if metric_length(p.metric, tight) < length:
            told = f"{how or 'the sampled plan'}, tightened on the exact geometry"
            # its own samples: the path whose every checked configuration kept the floor
            if (better := q.verified(tight, told, resample=False)) is not None:
                q.sampled_path = tight
                return better
    if shortest is not None and (better := q.verified(shortest, how)) is not None:
        q.sampled_path = shortest
        return better
    return plan
