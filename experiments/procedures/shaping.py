"""Shaped against unshaped geodesics on a robot, executed in MuJoCo.

The unshaped metric is the robot's kinetic-energy metric; the shaped one adds the
config's ``metric.terms``. For each, the geodesic from ``reference.q_start`` to
``reference.goal`` (``log`` then ``exp``) is tracked by each controller in a scene with
the config's payloads and obstacles (the controllers' model does not include the payload).

- `PayloadShaping` (``payload_shaping``): with a load term the shaped metric is the
  kinetic energy of robot plus payload, so the shaped geodesic has the least energy of
  the true plant; reported: path energy under both metrics, executed kinetic energy
  integral, effort, tracking error.
- `ObstacleShaping` (``obstacle_shaping``): a barrier term keeps the geodesic away from
  the obstacles; reported: minimum clearance (planned path and executed run), energy.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from geosyn.experiments import build as B
from geosyn.experiments.plots import bar_plot, torque_plot, tracking_error_plot
from geosyn.experiments.procedures.base import Procedure, RunContext, check_required, register
from geosyn.experiments.schema import ExperimentConfig
from geosyn.metrics.geodesic import exp, log, path_energy
from geosyn.metrics.shaping import ObstacleTerm

PATHS = ("unshaped", "shaped")


def _geodesic(metric: Any, ref: Any, v_init: np.ndarray | None = None) -> tuple[Any, np.ndarray]:
    q0, q1 = np.array(ref.q_start), np.array(ref.goal)
    u = log(metric, q0, q1, steps=ref.steps, v_init=v_init)
    return exp(metric, q0, u / ref.duration, ref.duration, ref.steps), u


class _Shaping(Procedure):
    units = {
        "energy_shaped_metric": "J s",
        "energy_unshaped_metric": "J s",
        "kinetic_energy_integral": "J s",
        "effort": "N^2 m^2 s",
        "rms_error": "rad",
        "planned_clearance": "m",
        "executed_clearance": "m",
    }

    @classmethod
    def check(cls, cfg: ExperimentConfig, params: Any, robot: Any) -> list[tuple[str, str]]:
        out = check_required(cfg, "reference", "controllers")
        if cfg.reference is not None and cfg.reference.type != "log":
            out.append(
                ("reference.type", f"kind {cfg.kind!r} needs a 'log' reference (q_start to goal)")
            )
        if not cfg.metric.terms:
            out.append(
                (
                    "metric.terms",
                    f"kind {cfg.kind!r} compares against shaping terms; give at least one",
                )
            )
        return out

    def run(self, ctx: RunContext) -> dict[str, np.ndarray]:
        cfg, robot = ctx.config, ctx.robot
        metrics = {
            "unshaped": B.build_metric(cfg, robot, terms=[]),
            "shaped": B.build_metric(cfg, robot),
        }
        labels = cfg.controller_labels()
        advance = ctx.progress(f"{cfg.name}: runs", 2 * len(labels))
        geo_u, u = _geodesic(metrics["unshaped"], cfg.reference)
        geo_s, _ = _geodesic(metrics["shaped"], cfg.reference, v_init=u)
        geos = {"unshaped": geo_u, "shaped": geo_s}
        obstacle_terms = [
            t for t in getattr(metrics["shaped"], "terms", ()) if isinstance(t, ObstacleTerm)
        ]
        out: dict[str, np.ndarray] = {}
        for name, geo in geos.items():
            out[f"path_{name}__t"], out[f"path_{name}__q"] = geo.t, geo.q
            for mname, metric in metrics.items():
                out[f"path_{name}__energy_{mname}"] = np.array(path_energy(metric, geo.t, geo.q))
            clear = (
                np.array([min(t.min_clearance(q) for t in obstacle_terms) for q in geo.q])
                if obstacle_terms
                else np.full(len(geo.t), np.inf)
            )
            out[f"path_{name}__clearance"] = clear
            ref = B.tracked_reference(geo, metrics[name], cfg.reference.time_scale)
            q0, v0, _ = ref.sample(0.0)
            for label, ccfg in zip(labels, cfg.controllers, strict=True):
                ctrl = B.build_controller(
                    ccfg, robot, metrics["unshaped"], cfg.simulation.control_dt
                )
                res = B.simulate(cfg, robot, ctrl, ref, q0, v0)
                out.update(B.sim_arrays(f"{name}_{label}", res))
                advance()
        return out

    def summarize(
        self, cfg: ExperimentConfig, params: Any, results: dict[str, np.ndarray]
    ) -> dict[str, float]:
        dt = cfg.simulation.control_dt
        out: dict[str, float] = {}
        single = len(cfg.controllers) == 1
        for name in PATHS:
            for label in cfg.controller_labels():
                r = B.sim_view(results, f"{name}_{label}")
                row = name if single else f"{name}_{label}"
                out[f"{row}.energy_shaped_metric"] = float(results[f"path_{name}__energy_shaped"])
                out[f"{row}.energy_unshaped_metric"] = float(
                    results[f"path_{name}__energy_unshaped"]
                )
                out[f"{row}.kinetic_energy_integral"] = float(np.sum(r["kinetic_energy"]) * dt)
                out[f"{row}.effort"] = B.effort(r["tau_applied"], dt)
                out[f"{row}.rms_error"] = float(np.sqrt(np.mean(r["tracking_error"] ** 2)))
                if np.isfinite(results[f"path_{name}__clearance"]).any():
                    out[f"{row}.planned_clearance"] = float(
                        results[f"path_{name}__clearance"].min()
                    )
                    out[f"{row}.executed_clearance"] = float(r["clearance"].min())
                out[f"{row}.ok"] = float(str(r["status"]) == "ok")
        return out

    def plot(
        self, cfg: ExperimentConfig, params: Any, results: dict[str, np.ndarray], out_dir: Path
    ) -> list[Path]:
        import matplotlib.pyplot as plt

        from geosyn.experiments.plots import COLORS, save

        label = cfg.controller_labels()[0]
        runs = {name: B.sim_view(results, f"{name}_{label}") for name in PATHS}
        dt = cfg.simulation.control_dt
        paths = [
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
        if np.isfinite(runs["shaped"]["clearance"]).any():
            fig, ax = plt.subplots(figsize=(7, 3.5))
            for (name, r), c in zip(runs.items(), COLORS, strict=False):
                ax.plot(r["t"], r["clearance"], color=c, label=name)
            ax.axhline(0.0, color="k", lw=0.8)
            ax.set_xlabel("t [s]")
            ax.set_ylabel("min clearance [m]")
            ax.legend(fontsize=8)
            ax.set_title("robot-obstacle clearance (executed)")
            paths.append(save(fig, out_dir / "clearance.png"))
        return paths


@register
class PayloadShaping(_Shaping):
    kind = "payload_shaping"
    description = "unshaped vs load-shaped geodesic carrying a payload in MuJoCo: energy, effort"


@register
class ObstacleShaping(_Shaping):
    kind = "obstacle_shaping"
    description = "unshaped vs obstacle-shaped geodesic: clearance and energy"
