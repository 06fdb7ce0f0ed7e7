"""The homotopy rule of a query: which of its verified plans is kept (`kept_plan`).

After a constrained plan from the straight line, other seeds (RRT-Connect paths: other
ways round the obstacles; `alternative_plans`) are solved
too. A plan from another seed replaces the straight line's only when its energy is lower
and its metric length (midpoint rule on its nodes) is not longer, so the returned path is
never longer than the straight-line seed's solution. A sampled plan (no NLP: a path
pulled taut and tightened) is one of the other seeds; it is kept over a solved plan only
when its energy is lower by `SAME_SAMPLED`, as the two are measured with other
quadratures.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from geosyn.metrics.planning.smoothing import metric_length

if TYPE_CHECKING:
    from geosyn.metrics.base import Metric
    from geosyn.metrics.planning.plan import Plan
    from geosyn.metrics.planning.query import Query

__all__ = ["SAME", "SAME_SAMPLED", "alternative_plans", "kept_plan"]

SAME = 1e-6
"""Relative difference of energy or length below which two plans count as the same path
(seeds that converge to one minimum differ by the solver's tolerance)."""


SAME_SAMPLED = 1e-3
"""Relative energy by which a sampled plan (midpoint rule on its samples) must be lower
than a collocation's (its own quadrature) to be kept instead: below it the two are the
same path within their discretisations (a sampled path tightened to the margin reaches
the collocation's optimum to 6e-5 on planar2 round a ball, measured), and the solved
one is kept."""


def alternative_plans(query: Query, line: Plan) -> list[Plan]:
    """Plans of ``query`` from RRT-Connect seeds after its constrained ``line`` plan
    (`geosyn.metrics.planning.query`'s homotopy rule: each tried while the time left is
    at least the time ``line`` took, its sampling bounded by that time and its
    collocation by twice), in the order they were found."""
    plans: list[Plan] = []
    for index in range(query.p.alternatives):
        if query.left() < line.wall_time:
            query.attempts.append(
                f"alternative seeds stopped after {index}: {max(query.left(), 0.0):.2f} s "
                f"left, less than the first plan took ({line.wall_time:.2f} s)"
            )
            break
        if (plan := query.from_rrt(index, cap=line.wall_time)) is not None:
            plans.append(plan)
    return plans


def kept_plan(metric: Metric, line: Plan | None, others: list[Plan], attempts: list[str]) -> Plan:
    """The kept plan among ``line`` (the straight line's, if any) and ``others`` (at
    least one plan in all): the lowest-energy one not longer than ``line`` (both within a
    relative `SAME`: seeds that converge to the same path keep the earlier plan; a
    sampled plan only when lower than every solved one by `SAME_SAMPLED`).

    Args:
        metric: the planner's metric (the lengths).
        line: the plan from the straight line, or None.
        others: the plans from other seeds, in the order they were found.
        attempts: the query's list of what was tried (what was dropped and kept is added).

    Returns:
        The kept plan, unchanged.
    """
    candidates = ([line] if line is not None else []) + others
    plans = candidates
    if line is not None and others:
        cap = metric_length(metric, line.q) * (1.0 + SAME)
        plans = [line] + [o for o in others if metric_length(metric, o.q) <= cap]
    lowest = min(p.result.energy for p in plans)
    best = next(p for p in plans if p.result.energy <= lowest + SAME * abs(lowest))
    solved = [p for p in plans if p.result.kind != "feasible"]
    if best.result.kind == "feasible" and solved:  # a sampled plan: another quadrature
        top = min(solved, key=lambda p: p.result.energy)
        if best.result.energy > (1.0 - SAME_SAMPLED) * top.result.energy:
            best = top
    if dropped := len(candidates) - len(plans):
        attempts.append(f"{dropped} plan(s) from other seeds longer than the straight "
                        "line's: not kept")  # fmt: skip
    if len(candidates) > 1:
        energies = ", ".join(f"{p.result.energy:.4f}" for p in candidates)
        attempts.append(f"kept the lowest-energy of {len(candidates)} plans: {best.seed} "
                        f"(energies {energies})")  # fmt: skip
    return best
