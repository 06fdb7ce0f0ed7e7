"""The general closed-loop experiment (``kind: tracking``): any robot, metric (with any
shaping terms), scene, reference, list of controllers and disturbances.

The reference is any reference section: a synergy combination, the geodesic to a goal
(``log``), a sequence of geodesics through goals (``goals``) or a collision-free path
planned around the scene's obstacles (``planned``), each with or without the
rest-to-rest time law. Every controller tracks it from the reference's initial state
through the configured disturbances; each run is reported with the standard metrics of
`geosyn.experiments.run.run_metrics` (tracking RMS/max, recovery per disturbance window, effort,
mechanical energy, saturations, fallbacks, clearance, wall time), one row per controller.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Annotated, Any

import numpy as np
from pydantic import Field

from geosyn.controllers import Reference
from geosyn.experiments.procedures.base import (
    SECTIONS,
    Procedure,
    RunContext,
    check_required,
    register,
)
from geosyn.experiments.procedures.common import track_with_each_controller
from geosyn.experiments.results.plots import torque_plot, tracking_error_plot
from geosyn.experiments.run import build as B
from geosyn.experiments.run import floating as F
from geosyn.experiments.run import references as R
from geosyn.experiments.run.run_metrics import (
    DEFAULT_THRESHOLD,
    UNITS,
    disturbance_windows,
    standard_metrics,
)
from geosyn.experiments.schema import (
    ExperimentConfig,
    GoalsReference,
    PlannedReference,
    Strict,
)


class TrackingParams(Strict):
    """Parameters of `Tracking`: the error threshold of the recovery times [rad]."""

    threshold: Annotated[float, Field(gt=0.0)] = DEFAULT_THRESHOLD


@register
class Tracking(Procedure):
    """Every controller tracks the reference through the disturbances; standard metrics."""

    kind = "tracking"
    sections = SECTIONS  # every section
    description = "general closed loop: any robot, metric, scene, reference, controllers and disturbances; standard metrics"
    Params = TrackingParams
    units = UNITS | {
        "threshold": "rad",
        "reference_end": "s",
        "reference_coupling_residual": "rad",
        "planned_clearance": "m",
        "planned_sphere_clearance": "m",
        "planned_certified_clearance": "m",
    }

    @classmethod
    def check(cls, cfg: ExperimentConfig, params: Any, robot: Any) -> list[tuple[str, str]]:
        return check_required(cfg, "reference", "controllers") + F.floating_problems(cfg, robot)

    def run(self, ctx: RunContext) -> dict[str, np.ndarray]:
        cfg, robot = ctx.config, ctx.robot
        if robot.floating:  # standing on the floor, base free: geosyn.experiments.run.floating
            advance = ctx.progress(f"{cfg.name}: controllers", len(cfg.controllers))
            return F.track_floating(cfg, robot, advance)
        metric = B.build_metric(cfg, robot, scene=ctx.scene)
        out: dict[str, np.ndarray] = {}
        ref: Reference
        if isinstance(cfg.reference, GoalsReference):
            ref, ends = R.goals_reference(cfg.reference, metric)
            out["reference__goals"] = ends
        elif isinstance(cfg.reference, PlannedReference):
            ref, plan = R.planned_reference(cfg.reference, metric, ctx.scene.obstacles, cfg.seed)
            out["reference__t"], out["reference__q"] = plan.result.t, plan.q
            # the robot's own geometry where it has one (the plan's exact check), else
            # the planner's spheres; the spheres' value kept beside it
            exact = plan.exact_clearance
            out["reference__planned_clearance"] = np.array(
                exact if math.isfinite(exact) else plan.check_clearance
            )
            out["reference__planned_sphere_clearance"] = np.array(plan.check_clearance)
            # between the checked configurations too (NaN without file geometry)
            out["reference__planned_certified_clearance"] = np.array(plan.certified_clearance)
        else:
            synergies = B.build_synergies(cfg, metric, robot)
            ref, geo = R.build_reference(cfg, metric, synergies)
            out["reference__t"], out["reference__q"] = geo.t, geo.q
        out["reference__end"] = np.array(ref.t0 + ref.duration)
        out["reference__coupling_residual"] = np.array(R.reference_coupling_residual(ref, metric))
        q0, v0, _ = ref.sample(0.0)
        advance = ctx.progress(f"{cfg.name}: controllers", len(cfg.controllers))

        return out | track_with_each_controller(cfg, ctx.scene, metric, ref, q0, v0, "", advance)

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
        residual = float(results.get("reference__coupling_residual", np.nan))
        if np.isfinite(residual):  # a coupled robot: the reference's own constraint residual
            out["reference_coupling_residual"] = residual
        if "reference__planned_clearance" in results:
            out["planned_clearance"] = float(results["reference__planned_clearance"])
        if "reference__planned_sphere_clearance" in results:
            out["planned_sphere_clearance"] = float(results["reference__planned_sphere_clearance"])
        certified = float(results.get("reference__planned_certified_clearance", np.nan))
        if np.isfinite(certified):
            out["planned_certified_clearance"] = certified
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
