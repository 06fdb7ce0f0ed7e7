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
from pydantic import BaseModel, ConfigDict, Field

from geosyn.controllers import JointTrajectoryReference
from geosyn.experiments import build as B
from geosyn.experiments.plots import bar_plot, torque_plot, tracking_error_plot
from geosyn.experiments.procedures.base import Procedure, RunContext, check_required, register
from geosyn.experiments.schema import ExperimentConfig, FiniteFloat
from geosyn.metrics.geodesic import exp, log, path_energy, straight_line

PATHS = ("geodesic", "straight")


class GeodesicVsEuclideanParams(BaseModel):
    model_config = ConfigDict(extra="forbid")
    q0: Annotated[list[FiniteFloat], Field(min_length=2, max_length=2)] = [-1.2, 1.6]
    q1: Annotated[list[FiniteFloat], Field(min_length=2, max_length=2)] = [1.4, -0.9]
    duration: Annotated[float, Field(gt=0.0)] = 1.0
    steps: Annotated[int, Field(ge=10, le=10_000)] = 200


@register
class GeodesicVsEuclidean(Procedure):
    kind = "geodesic_vs_euclidean"
    description = "planar2: geodesic vs straight joint line (paper Fig. 1), torque tracking effort"
    Params = GeodesicVsEuclideanParams
    units = {"path_energy": "J s", "effort": "N^2 m^2 s", "max_torque": "N m", "rms_error": "rad"}

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
        metric = B.build_metric(cfg, robot)
        q0, q1, T = np.array(p.q0), np.array(p.q1), p.duration
        v0 = log(metric, q0, q1, steps=p.steps) / T
        paths = {
            "geodesic": exp(metric, q0, v0, T, p.steps),
            "straight": straight_line(q0, q1, T, p.steps),
        }
        out: dict[str, np.ndarray] = {}
        labels = cfg.controller_labels()
        advance = ctx.progress(f"{cfg.name}: tracking", len(labels) * 2)
        for name, geo in paths.items():
            out[f"path_{name}__t"], out[f"path_{name}__q"] = geo.t, geo.q
            out[f"path_{name}__energy"] = np.array(path_energy(metric, geo.t, geo.q))
            ref = (
                B.tracked_reference(geo, metric)
                if name == "geodesic"
                else JointTrajectoryReference(geo.t, geo.q, geo.v)
            )
            for label, ccfg in zip(labels, cfg.controllers, strict=True):
                ctrl = B.build_controller(ccfg, robot, metric, cfg.simulation.control_dt)
                res = B.simulate(cfg, robot, ctrl, ref, q0, geo.v[0], duration=T)
                out.update(B.sim_arrays(f"{name}_{label}", res))
                advance()
        return out

    def summarize(
        self, cfg: ExperimentConfig, params: Any, results: dict[str, np.ndarray]
    ) -> dict[str, float]:
        dt = cfg.simulation.control_dt
        out: dict[str, float] = {}
        for name in PATHS:
            for label in cfg.controller_labels():
                r = B.sim_view(results, f"{name}_{label}")
                row = name if len(cfg.controllers) == 1 else f"{name}_{label}"
                out[f"{row}.path_energy"] = float(results[f"path_{name}__energy"])
                out[f"{row}.effort"] = B.effort(r["tau_applied"], dt)
                out[f"{row}.max_torque"] = float(np.abs(r["tau_applied"]).max())
                out[f"{row}.rms_error"] = float(np.sqrt(np.mean(r["tracking_error"] ** 2)))
                out[f"{row}.ok"] = float(str(r["status"]) == "ok")
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
        from geosyn.synergies.figures import figure_configuration_space

        robot = B.build_robot(cfg)
        metric = B.build_metric(cfg, robot)
        fig = figure_configuration_space(
            metric, params.q0, params.q1, out_dir / "figure1_configuration_space.png", robot
        )
        label = cfg.controller_labels()[0]
        runs = {name: B.sim_view(results, f"{name}_{label}") for name in PATHS}
        dt = cfg.simulation.control_dt
        return [
            fig.path,
            torque_plot(out_dir / "torques.png", runs),
            tracking_error_plot(out_dir / "tracking_error.png", runs),
            bar_plot(
                out_dir / "effort.png",
                list(PATHS),
                [B.effort(r["tau_applied"], dt) for r in runs.values()],
                r"$\int \|\tau\|^2 dt$ [N$^2$m$^2$s]",
                "effort",
            ),
        ]
