"""The general closed-loop experiment (``kind: tracking``): any robot, metric (with any
shaping terms), scene, reference, list of controllers and disturbances.

The reference is any reference section: a synergy combination, the geodesic to a goal
(``log``), a sequence of geodesics through goals (``goals``) or a collision-free path
planned around the scene's obstacles (``planned``), each with or without the
rest-to-rest time law. Every controller tracks it from the reference's initial state
through the configured disturbances; each run is reported with the standard metrics of
`geosyn.experiments.metrics` (tracking RMS/max, recovery per disturbance window, effort,
mechanical energy, saturations, fallbacks, clearance, wall time), one row per controller.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Annotated, Any, NamedTuple

import numpy as np
from pydantic import Field

from geosyn.controllers import GeodesicReference, Reference, ReferenceSample
from geosyn.experiments import build as B
from geosyn.experiments.metrics import (
    DEFAULT_THRESHOLD,
    UNITS,
    disturbance_windows,
    standard_metrics,
)
from geosyn.experiments.plots import torque_plot, tracking_error_plot
from geosyn.experiments.procedures.base import (
    SECTIONS,
    Procedure,
    RunContext,
    check_required,
    register,
)
from geosyn.experiments.procedures.common import track_with_each_controller
from geosyn.experiments.schema import (
    ExperimentConfig,
    GoalsReference,
    PlannedReference,
    Strict,
)
from geosyn.metrics import Metric, exp, log
from geosyn.metrics.planning import Plan, Planner
from geosyn.world import Shape


class TrackingParams(Strict):
    """Parameters of `Tracking`: the error threshold of the recovery times [rad]."""

    threshold: Annotated[float, Field(gt=0.0)] = DEFAULT_THRESHOLD


class SequenceReference(Reference):
    """References played one after the other: segment ``i`` starts when ``i - 1`` ends.

    Args:
        segments: the references, each with ``t0`` set to the end of the previous one
            (`goals_reference` builds them so).
    """

    def __init__(self, segments: Sequence[GeodesicReference]) -> None:
        self.segments = list(segments)
        self.n = self.segments[0].n
        self.t0 = self.segments[0].t0
        last = self.segments[-1]
        self.duration = last.t0 + last.duration - self.t0

    def sample(self, t: float) -> ReferenceSample:
        """Reference ``(q, v, a)`` at controller time ``t`` [s] (that of the segment
        running at ``t``; the goal at rest after the last)."""
        for seg in self.segments:
            if t < seg.t0 + seg.duration:
                return seg.sample(t)
        return self.segments[-1].sample(t)

    def goal(self) -> np.ndarray:
        """(n,) the last goal [rad]."""
        return self.segments[-1].goal()


def goals_reference(ref: GoalsReference, metric: Metric) -> tuple[SequenceReference, np.ndarray]:
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
    ref: PlannedReference, metric: Metric, obstacles: Sequence[Shape], seed: int
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


@register
class Tracking(Procedure):
    """Every controller tracks the reference through the disturbances; standard metrics."""

    kind = "tracking"
    sections = SECTIONS  # every section
    description = "general closed loop: any robot, metric, scene, reference, controllers and disturbances; standard metrics"
    Params = TrackingParams
    units = UNITS | {"threshold": "rad", "reference_end": "s", "planned_clearance": "m"}

    @classmethod
    def check(cls, cfg: ExperimentConfig, params: Any, robot: Any) -> list[tuple[str, str]]:
        return check_required(cfg, "reference", "controllers")

    def run(self, ctx: RunContext) -> dict[str, np.ndarray]:
        cfg, robot = ctx.config, ctx.robot
        metric = B.build_metric(cfg, robot)
        out: dict[str, np.ndarray] = {}
        ref: Reference
        if isinstance(cfg.reference, GoalsReference):
            ref, ends = goals_reference(cfg.reference, metric)
            out["reference__goals"] = ends
        elif isinstance(cfg.reference, PlannedReference):
            ref, plan = planned_reference(cfg.reference, metric, B.build_obstacles(cfg), cfg.seed)
            out["reference__t"], out["reference__q"] = plan.result.t, plan.q
            out["reference__planned_clearance"] = np.array(plan.check_clearance)
        else:
            synergies = B.build_synergies(cfg, metric, robot)
            ref, geo = B.build_reference(cfg, metric, synergies)
            out["reference__t"], out["reference__q"] = geo.t, geo.q
        out["reference__end"] = np.array(ref.t0 + ref.duration)
        q0, v0, _ = ref.sample(0.0)
        advance = ctx.progress(f"{cfg.name}: controllers", len(cfg.controllers))

        return out | track_with_each_controller(cfg, robot, metric, ref, q0, v0, "", advance)

    def summarize(
        self, cfg: ExperimentConfig, params: Any, results: dict[str, np.ndarray]
    ) -> dict[str, float]:
        windows = disturbance_windows(cfg.disturbances)
        out: dict[str, float] = {}
        for label in cfg.controller_labels():
            run = B.sim_view(results, label)
            metrics = standard_metrics(run, cfg.simulation.control_dt, windows, params.threshold)
            out |= {f"{label}.{k}": v for k, v in metrics.items()}
        out["threshold"] = params.threshold
        out["reference_end"] = float(results["reference__end"])
        if "reference__planned_clearance" in results:
            out["planned_clearance"] = float(results["reference__planned_clearance"])
        return out

    def plot(
        self, cfg: ExperimentConfig, params: Any, results: dict[str, np.ndarray], out_dir: Path
    ) -> list[Path]:
        runs = {label: B.sim_view(results, label) for label in cfg.controller_labels()}
        windows = [
            (w.start, max(min(w.stop, cfg.simulation.duration), w.start + 0.01), w.kind)
            for w in disturbance_windows(cfg.disturbances)
        ]
        return [
            tracking_error_plot(out_dir / "tracking_error.png", runs, params.threshold, windows),
            torque_plot(out_dir / "torques.png", runs, B.build_robot(cfg).tau_max, windows),
        ]
