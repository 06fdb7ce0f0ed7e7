"""Paper Figure 1 on planar2 and MuJoCo torque tracking of the geodesic and of the straight
joint-space line between the same configurations, in the same time.

Both paths start at their own initial velocity (the robot is already moving), so the
torque only keeps the robot on its path: along a geodesic of the kinetic-energy metric
``M qdd + C qd = 0``, and gravity does no work on the horizontal planar2, so the geodesic
needs (almost) no torque while the straight line needs ``M qdd + C qd != 0``.
Effort is ``integral ||tau||^2 dt`` [N^2 m^2 s]; energy is the path energy
``1/2 integral qd^T M qd dt`` [J s].
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import numpy as np
from pydantic import Field

from geosyn.controllers import JointTrajectoryReference
from geosyn.experiments.procedures.base import RunContext, check_required, register
from geosyn.experiments.procedures.common import (
    Duration,
    PathComparison,
    Steps,
    robot_and_metric,
    track_with_each_controller,
)
from geosyn.experiments.run import build as B
from geosyn.experiments.run import references as R
from geosyn.experiments.schema import ExperimentConfig, FiniteFloat, Strict
from geosyn.metrics import exp, log, path_energy, straight_line
from geosyn.synergies.figures import figure_configuration_space

Pair = Annotated[list[FiniteFloat], Field(min_length=2, max_length=2)]


class GeodesicVsEuclideanParams(Strict):
    """Parameters of `GeodesicVsEuclidean`: end configurations [rad], time [s], steps."""

    q0: Pair = [-1.2, 1.6]
    q1: Pair = [1.4, -0.9]
    duration: Duration = 1.0
    steps: Steps = 200


@register
class GeodesicVsEuclidean(PathComparison):
    """Geodesic against straight joint line, both tracked by each controller."""

    kind = "geodesic_vs_euclidean"
    sections = (
        "robot",
        "metric",
        "scene",
        "controllers",
        "disturbances",
        "simulation",
        "outputs",
        "params",
    )
    description = "planar2: geodesic vs straight joint line (paper Fig. 1), torque tracking effort"
    Params = GeodesicVsEuclideanParams
    units = {"path_energy": "J s", "max_torque": "N m"}
    paths = ("geodesic", "straight")

    @classmethod
    def check(cls, cfg: ExperimentConfig, params: Any, robot: Any) -> list[tuple[str, str]]:
        out = check_required(cfg, "controllers")
        if robot.nv != 2:
            out.append(
                (
                    "robot.name",
                    f"kind {cfg.kind!r} needs a 2-DoF robot, {robot.name!r} has {robot.nv}",
                )
            )
        return out

    def run(self, ctx: RunContext) -> dict[str, np.ndarray]:
        cfg, robot, p = ctx.config, ctx.robot, ctx.params
        metric = B.build_metric(cfg, robot, scene=ctx.scene)
        q0, q1, T = np.array(p.q0), np.array(p.q1), p.duration
        v0 = log(metric, q0, q1, steps=p.steps) / T
        paths = {
            "geodesic": exp(metric, q0, v0, T, p.steps),
            "straight": straight_line(q0, q1, T, p.steps),
        }
        out: dict[str, np.ndarray] = {}
        advance = ctx.progress(f"{cfg.name}: tracking", len(cfg.controllers) * 2)
        for name, geo in paths.items():
            out[f"path_{name}__t"], out[f"path_{name}__q"] = geo.t, geo.q
            out[f"path_{name}__energy"] = np.array(path_energy(metric, geo.t, geo.q))
            ref = (
                R.tracked_reference(geo, metric)
                if name == "geodesic"
                else JointTrajectoryReference(geo.t, geo.q, geo.v)
            )
            out |= track_with_each_controller(
                cfg, ctx.scene, metric, ref, q0, geo.v[0], f"{name}_", advance, duration=T
            )
        return out

    def path_summary(
        self, results: dict[str, np.ndarray], name: str, run: dict[str, np.ndarray], dt: float
    ) -> dict[str, float]:
        tau = run["tau_applied"]
        return {
            "path_energy": float(results[f"path_{name}__energy"]),
            "effort": B.effort(tau, dt),
            "max_torque": float(np.abs(tau).max()),
            "rms_error": float(np.sqrt(np.mean(run["tracking_error"] ** 2))),
            "ok": float(str(run["status"]) == "ok"),
        }

    def summarize(
        self, cfg: ExperimentConfig, params: Any, results: dict[str, np.ndarray]
    ) -> dict[str, float]:
        out = super().summarize(cfg, params, results)
        first = cfg.controller_labels()[0]
        geo_row, line_row = (
            ("geodesic", "straight")
            if len(cfg.controllers) == 1
            else (f"geodesic_{first}", f"straight_{first}")
        )
        out["effort_ratio_straight_over_geodesic"] = out[f"{line_row}.effort"] / max(
            out[f"{geo_row}.effort"], 1e-300
        )
        out["energy_ratio_straight_over_geodesic"] = (
            out[f"{line_row}.path_energy"] / out[f"{geo_row}.path_energy"]
        )
        return out

    def plot(
        self, cfg: ExperimentConfig, params: Any, results: dict[str, np.ndarray], out_dir: Path
    ) -> list[Path]:
        robot, metric = robot_and_metric(cfg)
        fig = figure_configuration_space(
            metric, params.q0, params.q1, out_dir / "figure1_configuration_space.png", robot
        )
        return [fig.path, *self.comparison_plots(cfg, results, out_dir)[1]]
