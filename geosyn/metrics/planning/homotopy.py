"""The homotopy rule of a query: which of its verified plans is kept (`kept_plan`).

After a constrained plan from the straight line, other seeds (RRT-Connect paths: other
ways round the obstacles; `geosyn.metrics.planning.query.Query.alternatives`) are solved
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

__all__ = ["SAME", "SAME_SAMPLED", "kept_plan"]

SAME = 1e-6
"""Relative difference of energy or length below which two plans count as the same path
(seeds that converge to one minimum differ by the solver's tolerance)."""


SAME_SAMPLED = 1e-3
"""Relative energy by which a sampled plan (midpoint rule on its samples) must be lower
than a collocation's (its own quadrature) to be kept instead: below it the two are the
same path within their discretisations (a sampled path tightened to the margin reaches
the collocation's optimum to 6e-5 on planar2 round a ball, measured), and the solved
one is kept."""


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
