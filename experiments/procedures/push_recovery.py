"""Flagship: tracking a synergy combination under a push, an unknown payload change and
torque noise, with each configured controller (computed torque, QP, MPC, ...).

Per controller: RMS tracking error, RMS error from ``window`` after the push on, maximum
error, recovery time (time after the push starts until the tracking-error norm stays
below ``threshold``), effort ``integral ||tau||^2 dt``, saturated (tick, joint) pairs.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import numpy as np
from pydantic import Field

from geosyn.experiments import build as B
from geosyn.experiments.plots import torque_plot, tracking_error_plot
from geosyn.experiments.procedures.base import Procedure, RunContext, check_required, register
from geosyn.experiments.procedures.common import Duration, track_with_each_controller
from geosyn.experiments.schema import ExperimentConfig, Strict
from geosyn.sim import SimResult


class PushRecoveryParams(Strict):
    """Parameters of `PushRecovery`: error threshold [rad], window after the push [s]."""

    threshold: Annotated[float, Field(gt=0.0)] = 1e-2
    window: Duration = 1.0


def push_window(cfg: ExperimentConfig) -> tuple[float, float]:
    """(start, stop) of the first push [s]; (0, 0) without a push."""
    for d in cfg.disturbances:
        if d.type == "push":
            return d.start, d.start + d.duration
    return 0.0, 0.0


def recovery_time(t: np.ndarray, err_norm: np.ndarray, t_from: float, threshold: float) -> float:
    """Time after ``t_from`` until ``err_norm`` stays below ``threshold`` to the end [s].

    Returns 0 if it never exceeds it after ``t_from``, ``inf`` if it is above at the end.
    """
    sel = t >= t_from
    above = np.nonzero(sel & (err_norm > threshold))[0]
    if above.size == 0:
        return 0.0
    last = int(above[-1])
    if last == len(t) - 1:
        return float("inf")
    return float(t[last + 1] - t_from)


def controller_summary(
    label: str,
    r: dict[str, np.ndarray],
    dt: float,
    push_start: float,
    threshold: float,
    window: float,
) -> dict[str, float]:
    """The per-controller metrics of a stored run (see the module doc)."""
    t, e = r["t"], r["tracking_error"]
    norm = np.linalg.norm(e, axis=1)
    after = t >= push_start + window
    return {
        f"{label}.ok": float(str(r["status"]) == "ok"),
        f"{label}.rms_error": float(np.sqrt(np.mean(e**2))),
        f"{label}.rms_after_window": float(np.sqrt(np.mean(e[after] ** 2)))
        if after.any()
        else float("nan"),
        f"{label}.max_error": float(norm.max()),
        f"{label}.recovery_time": recovery_time(t, norm, push_start, threshold),
        f"{label}.effort": B.effort(r["tau_applied"], dt),
        f"{label}.saturations": float(np.count_nonzero(r["saturated"])),
        f"{label}.fallbacks": float(np.count_nonzero(r["fallback_used"]))
        if "fallback_used" in r
        else 0.0,
        f"{label}.wall_time": float(r["wall_time"]),
    }


@register
class PushRecovery(Procedure):
    """Each controller tracks the reference through the configured disturbances."""

    kind = "push_recovery"
    description = "track a synergy combination under a push, a payload change and torque noise; compare controllers"
    Params = PushRecoveryParams
    units = {
        "rms_error": "rad",
        "rms_after_window": "rad",
        "max_error": "rad",
        "recovery_time": "s",
        "effort": "N^2 m^2 s",
        "wall_time": "s",
        "push_start": "s",
        "threshold": "rad",
    }

    @classmethod
    def check(cls, cfg: ExperimentConfig, params: Any, robot: Any) -> list[tuple[str, str]]:
        return check_required(cfg, "reference", "controllers")

    def run(self, ctx: RunContext) -> dict[str, np.ndarray]:
        cfg, robot = ctx.config, ctx.robot
        metric = B.build_metric(cfg, robot)
        synergies = B.build_synergies(cfg, metric, robot)
        ref, geo = B.build_reference(cfg, metric, synergies)
        q0, v0, _ = ref.sample(0.0)
        advance = ctx.progress(f"{cfg.name}: controllers", len(cfg.controllers))
        out: dict[str, np.ndarray] = {"reference__t": geo.t, "reference__q": geo.q}

        def video(label: str, res: SimResult) -> None:
            if not ctx.video:
                return
            from geosyn.sim import render_video

            o = cfg.outputs
            render_video(
                res,
                ctx.out_dir / f"video_{label}.{o.video_format}",
                robot,
                o.fps,
                o.width,
                o.height,
                payloads=B.build_payloads(cfg, robot),
                obstacles=B.build_obstacles(cfg),
                trail=o.trail,
            )

        return out | track_with_each_controller(
            cfg, robot, metric, ref, q0, v0, "", advance, each=video
        )

    def summarize(
        self, cfg: ExperimentConfig, params: Any, results: dict[str, np.ndarray]
    ) -> dict[str, float]:
        start, stop = push_window(cfg)
        out: dict[str, float] = {}
        for label in cfg.controller_labels():
            r = B.sim_view(results, label)
            out.update(
                controller_summary(
                    label, r, cfg.simulation.control_dt, start, params.threshold, params.window
                )
            )
        out["push_start"] = start
        out["threshold"] = params.threshold
        return out

    def plot(
        self, cfg: ExperimentConfig, params: Any, results: dict[str, np.ndarray], out_dir: Path
    ) -> list[Path]:
        runs = {label: B.sim_view(results, label) for label in cfg.controller_labels()}
        windows = []
        for d in cfg.disturbances:
            if d.type == "push":
                windows.append((d.start, d.start + d.duration, "push"))
            if d.type == "payload_change":
                windows.append((d.time, d.time + 0.01, "payload"))
        return [
            tracking_error_plot(out_dir / "tracking_error.png", runs, params.threshold, windows),
            torque_plot(out_dir / "torques.png", runs),
        ]
