"""Flagship: tracking a synergy combination under a push, an unknown payload change and
torque noise, with each configured controller (computed torque, QP, MPC, ...).

Per controller: RMS tracking error, RMS error from ``window`` after the push on, maximum
error, recovery time (time after the push starts until the tracking-error norm stays
below ``threshold``, measured in the push's window: `geosyn.experiments.run.run_metrics`), effort ``integral ||tau||^2 dt``, saturated (tick, joint) pairs.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import numpy as np
from pydantic import Field

from geosyn.experiments.procedures.base import (
    SECTIONS,
    Procedure,
    RunContext,
    check_required,
    register,
)
from geosyn.experiments.procedures.common import Duration, track_with_each_controller
from geosyn.experiments.results.plots import torque_plot, tracking_error_plot
from geosyn.experiments.run import build as B
from geosyn.experiments.run import references as R
from geosyn.experiments.run.run_metrics import (
    Window,
    disturbance_windows,
    recovery_times,
    standard_metrics,
)
from geosyn.experiments.schema import ExperimentConfig, Strict


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


def controller_summary(
    cfg: ExperimentConfig,
    label: str,
    r: dict[str, np.ndarray],
    threshold: float,
    window: float,
) -> dict[str, float]:
    """The per-controller metrics of a stored run (see the module doc).

    ``recovery_time`` is that of the first push's window
    (`geosyn.experiments.run.run_metrics`: measured per disturbance window, never counting the
    end of the reference); the standard metrics add one per disturbance window.
    """
    dt = cfg.simulation.control_dt
    windows = disturbance_windows(cfg.disturbances)
    std = standard_metrics(r, dt, windows, threshold)
    push = next((w for w in windows if w.kind == "push"), None)
    t, e = r["t"], r["tracking_error"]
    push_start = push.start if push is not None else 0.0
    after = t >= push_start + window
    if push is not None:
        recovery = std[f"recovery_time_d{push.disturbance}"]
    else:
        recovery = recovery_times(
            t, np.linalg.norm(e, axis=1), [Window(-1, "start", 0.0, 0.0)], threshold
        )[0]
    return {
        f"{label}.ok": std["ok"],
        f"{label}.rms_error": std["rms_error"],
        f"{label}.rms_after_window": float(np.sqrt(np.mean(e[after] ** 2)))
        if after.any()
        else float("nan"),
        f"{label}.max_error": std["max_error"],
        f"{label}.recovery_time": recovery,
        f"{label}.effort": std["effort"],
        f"{label}.saturations": std["saturations"],
        f"{label}.fallbacks": std["fallbacks"],
        f"{label}.wall_time": std["wall_time"],
    }


@register
class PushRecovery(Procedure):
    """Each controller tracks the reference through the configured disturbances."""

    kind = "push_recovery"
    sections = tuple(s for s in SECTIONS if s != "stance")  # fixed-base robots: no stance
    description = "track a synergy combination under a push, a payload change and torque noise; compare controllers"
    Params = PushRecoveryParams
    units = {
        "rms_after_window": "rad",
        "push_start": "s",
        "threshold": "rad",
    }

    @classmethod
    def check(cls, cfg: ExperimentConfig, params: Any, robot: Any) -> list[tuple[str, str]]:
        out = check_required(cfg, "reference", "controllers")
        if cfg.reference is not None and cfg.reference.type in ("goals", "planned"):
            kind = cfg.reference.type
            reason = (
                f"kind {cfg.kind!r} takes a combination or log reference ({kind}: kind tracking)"
            )
            out.append(("reference.type", reason))
        return out

    def run(self, ctx: RunContext) -> dict[str, np.ndarray]:
        cfg, robot = ctx.config, ctx.robot
        metric = B.build_metric(cfg, robot, scene=ctx.scene)
        synergies = B.build_synergies(cfg, metric, robot)
        ref, geo = R.build_reference(cfg, metric, synergies)
        q0, v0, _ = ref.sample(0.0)
        advance = ctx.progress(f"{cfg.name}: controllers", len(cfg.controllers))
        out: dict[str, np.ndarray] = {"reference__t": geo.t, "reference__q": geo.q}

        return out | track_with_each_controller(cfg, ctx.scene, metric, ref, q0, v0, "", advance)

    def summarize(
        self, cfg: ExperimentConfig, params: Any, results: dict[str, np.ndarray]
    ) -> dict[str, float]:
        start, stop = push_window(cfg)
        out: dict[str, float] = {}
        for label in cfg.controller_labels():
            r = B.sim_view(results, label)
            out.update(controller_summary(cfg, label, r, params.threshold, params.window))
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
            torque_plot(out_dir / "torques.png", runs, B.build_robot(cfg).tau_max, windows),
        ]
