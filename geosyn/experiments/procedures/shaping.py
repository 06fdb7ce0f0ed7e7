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
  the obstacles; reported: minimum clearance (planned path and executed run), energy, and
  with ``scene.contact: true`` (the obstacles collide in MuJoCo) the largest obstacle
  contact force and the time in contact of each run. A run that the contact stops (it
  diverges after the robot hit an obstacle) keeps its stop as its status, with the contact
  named as the cause.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from geosyn.experiments.errors import ProcedureFailed
from geosyn.experiments.procedures.base import RunContext, check_required, register
from geosyn.experiments.procedures.common import PathComparison, track_with_each_controller
from geosyn.experiments.procedures.outcomes import contact_reason, fail_run, run_status
from geosyn.experiments.results.plots import COLORS, figure, save
from geosyn.experiments.run import build as B
from geosyn.experiments.run import references as R
from geosyn.experiments.schema import ExperimentConfig, LogReference
from geosyn.metrics import Geodesic, Metric, exp, log, path_energy
from geosyn.metrics.shaping import ObstacleTerm, ShapedMetric


def _geodesic(
    metric: Metric, ref: LogReference, v_init: np.ndarray | None = None
) -> tuple[Geodesic, np.ndarray]:
    """(the geodesic from ``ref.q_start`` to ``ref.goal``, its initial velocity over a unit
    time (n,) [rad/s]); ``v_init`` warm-starts the log."""
    q0, q1 = np.array(ref.q_start), np.array(ref.goal)
    u = log(metric, q0, q1, steps=ref.steps, v_init=v_init)
    return exp(metric, q0, u / ref.duration, ref.duration, ref.steps), u


def _contact_cause(status: str, run: dict[str, np.ndarray]) -> str | None:
    """The obstacle contact named as the cause of a stopped run, or None (the run
    completed, or touched nothing: an unshaped path may touch an obstacle, which the
    comparison reports as contact force and time, not as a failure).

    Args:
        status: the run's status (``ok``, ``diverged: ...``, ``controller failed: ...``).
        run: its arrays by field name (``t`` [s], ``contact_force`` [N]).
    """
    contact = contact_reason(run)
    if status == "ok" or contact is None:
        return None
    return f"cause: the robot hit an obstacle (scene.contact: true): {contact}"


class _Shaping(PathComparison):
    """The geodesic of the robot's kinetic-energy metric against that of the shaped one."""

    paths = ("unshaped", "shaped")
    sections = (
        "robot",
        "metric",
        "scene",
        "reference",
        "controllers",
        "disturbances",
        "simulation",
        "outputs",
    )
    units = {
        "energy_shaped_metric": "J s",
        "energy_unshaped_metric": "J s",
        "kinetic_energy_integral": "J s",
        "planned_clearance": "m",
        "executed_clearance": "m",
        "contact_time": "s",
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
        cfg, robot, reference = ctx.config, ctx.robot, ctx.config.reference
        if not isinstance(reference, LogReference):  # `check` refuses such a config
            raise ProcedureFailed(f"kind {cfg.kind!r} needs a 'log' reference, got {reference!r}")
        metrics = {
            "unshaped": B.build_metric(cfg, robot, terms=[], scene=ctx.scene),
            "shaped": B.build_metric(cfg, robot, scene=ctx.scene),
        }
        advance = ctx.progress(f"{cfg.name}: runs", 2 * len(cfg.controllers))
        geo_u, u = _geodesic(metrics["unshaped"], reference)
        geo_s, _ = _geodesic(metrics["shaped"], reference, v_init=u)
        geos = {"unshaped": geo_u, "shaped": geo_s}
        shaped = metrics["shaped"]
        terms = shaped.terms if isinstance(shaped, ShapedMetric) else ()
        obstacle_terms = [t for t in terms if isinstance(t, ObstacleTerm)]
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
            ref = R.tracked_reference(
                geo, metrics[name], reference.time_scale, reference.rest_to_rest
            )
            q0, v0, _ = ref.sample(0.0)
            # the controllers' model is the robot alone: the unshaped metric
            runs = track_with_each_controller(
                cfg, ctx.scene, metrics["unshaped"], ref, q0, v0, f"{name}_", advance
            )
            out |= runs
            for prefix in [k[: -len("__status")] for k in runs if k.endswith("__status")]:
                cause = _contact_cause(run_status(runs, prefix), B.sim_view(runs, prefix))
                if cause is not None:
                    fail_run(out, prefix, cause)
        return out

    def path_summary(
        self, results: dict[str, np.ndarray], name: str, run: dict[str, np.ndarray], dt: float
    ) -> dict[str, float]:
        out = {
            "energy_shaped_metric": float(results[f"path_{name}__energy_shaped"]),
            "energy_unshaped_metric": float(results[f"path_{name}__energy_unshaped"]),
            "kinetic_energy_integral": float(np.sum(run["kinetic_energy"]) * dt),
            "effort": B.effort(run["tau_applied"], dt),
            "rms_error": float(np.sqrt(np.mean(run["tracking_error"] ** 2))),
        }
        planned = results[f"path_{name}__clearance"]
        if np.isfinite(planned).any():
            out["planned_clearance"] = float(planned.min())
            out["executed_clearance"] = float(run["clearance"].min())
            force = run["contact_force"]
            out["max_contact_force"] = float(force.max()) if force.size else 0.0
            out["contact_time"] = float(np.count_nonzero(force > 0.0) * dt)
        out["ok"] = float(str(run["status"]) == "ok")
        return out

    def plot(
        self, cfg: ExperimentConfig, params: Any, results: dict[str, np.ndarray], out_dir: Path
    ) -> list[Path]:
        runs, paths = self.comparison_plots(cfg, results, out_dir)
        if np.isfinite(runs["shaped"]["clearance"]).any():
            fig, ax = figure((7, 3.5))
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
