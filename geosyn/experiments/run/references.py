"""The references of a config: every ``reference`` section type becomes a library
reference (`geosyn.controllers.reference`) here and nowhere else.

``combination`` and ``log`` sections give a geodesic (`reference_geodesic`) tracked as a
`GeodesicReference` (`tracked_reference`); ``goals`` a `SequenceReference` of geodesics
through the goals (`goals_reference`); ``planned`` the planner's collision-free path
around the scene's obstacles (`planned_reference`).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import numpy as np

from geosyn.controllers import GeodesicReference
from geosyn.controllers.reference import SequenceReference
from geosyn.experiments import schema as S
from geosyn.experiments.errors import ProcedureFailed
from geosyn.metrics import Metric
from geosyn.metrics.geodesic import Geodesic, exp, log
from geosyn.metrics.planning import Plan, Planner
from geosyn.synergies import GeodesicSynergy, combine
from geosyn.world import Shape


def reference_geodesic(
    ref: S.ReferenceConfig, metric: Metric, synergies: Sequence[GeodesicSynergy]
) -> Geodesic:
    """The geodesic of a reference section over ``ref.duration`` (before time scaling)."""
    if ref.type == "goals" or ref.type == "planned":
        raise ProcedureFailed(f"a {ref.type!r} reference is built by kind tracking")
    if ref.type == "combination":
        q_start = None if ref.q_start is None else np.array(ref.q_start)
        syn = combine(list(synergies), ref.weights, q_start)
        return syn.trajectory(ref.duration, ref.steps)
    v0 = log(metric, np.array(ref.q_start), np.array(ref.goal), steps=ref.steps) / ref.duration
    return exp(metric, np.array(ref.q_start), v0, ref.duration, ref.steps)


def build_reference(
    cfg: S.ExperimentConfig, metric: Metric, synergies: Sequence[GeodesicSynergy]
) -> tuple[GeodesicReference, Geodesic]:
    """(the tracked reference, its geodesic) of the config's reference section."""
    if cfg.reference is None:
        raise ProcedureFailed(f"experiment {cfg.name!r} has no reference section")
    geo = reference_geodesic(cfg.reference, metric, synergies)
    ref = tracked_reference(geo, metric, cfg.reference.time_scale, cfg.reference.rest_to_rest)
    return ref, geo


def tracked_reference(
    geo: Geodesic, metric: Metric, time_scale: float = 1.0, rest_to_rest: bool = False
) -> GeodesicReference:
    """The reference a controller tracks along ``geo`` (``rest_to_rest``: the quintic
    rest-to-rest time law of `GeodesicReference`).

    Accelerations are the metric's exact geodesic accelerations at the samples, interpolated
    between them: a shaped metric's exact geodesic acceleration is too costly to evaluate at
    every control tick.
    """
    return GeodesicReference(
        geo, metric, time_scale=time_scale, rest_to_rest=rest_to_rest, exact_acceleration=False
    )


def goals_reference(ref: S.GoalsReference, metric: Metric) -> tuple[SequenceReference, np.ndarray]:
    """The geodesics from ``q_start`` through every goal, as one reference.

    Returns:
        (the reference, (K, n) the planned configurations at the segment ends [rad]).
    """
    q = np.array(ref.q_start, dtype=np.float64)
    t0 = 0.0
    segments = []
    ends = []
    for goal, duration in zip(ref.goals, ref.durations(), strict=True):
        q1 = np.array(goal, dtype=np.float64)
        v0 = log(metric, q, q1, steps=ref.steps) / duration
        geo = exp(metric, q, v0, duration, ref.steps)
        seg = GeodesicReference(
            geo,
            metric,
            t0=t0,
            time_scale=ref.time_scale,
            rest_to_rest=ref.rest_to_rest,
            exact_acceleration=False,
        )
        segments.append(seg)
        t0 += seg.duration
        q = geo.q[-1].copy()
        ends.append(q)
    return SequenceReference(segments), np.array(ends)


class _Samples(NamedTuple):
    t: np.ndarray  # (T,) [s]
    q: np.ndarray  # (T, n) [rad]
    v: np.ndarray  # (T, n) [rad/s]


def planned_reference(
    ref: S.PlannedReference, metric: Metric, obstacles: Sequence[Shape], seed: int
) -> tuple[GeodesicReference, Plan]:
    """The planner's collision-free path from ``ref.q_start`` to ``ref.goal`` as a reference.

    The path's samples, uniform in the planner's time, are stretched over ``ref.duration``
    [s]; velocities are their central differences (one-sided at the ends), interpolated
    by cubic Hermite splines; ``time_scale`` and ``rest_to_rest`` act as for a geodesic.

    Raises:
        PlanningError: start or goal outside the limits or in collision, or no path.
    """
    planner = Planner(metric, capacity=max(1, len(obstacles)), margin=ref.margin, nodes=ref.nodes)
    plan = planner.plan(
        np.array(ref.q_start), np.array(ref.goal), obstacles, budget=ref.budget, seed=seed
    )
    t = np.asarray(plan.result.t, dtype=np.float64)
    t = (t - t[0]) * (ref.duration / (t[-1] - t[0]))
    q = np.asarray(plan.q, dtype=np.float64)
    samples = _Samples(t, q, np.gradient(q, t, axis=0))
    reference = GeodesicReference(
        samples, None, time_scale=ref.time_scale, rest_to_rest=ref.rest_to_rest
    )
    return reference, plan


__all__ = [
    "build_reference",
    "goals_reference",
    "planned_reference",
    "reference_geodesic",
    "tracked_reference",
]
