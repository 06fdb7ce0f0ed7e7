"""Combining synergies based at different configurations, with and without parallel
transport to the common start ``q_start``.

- transported: ``combine(synergies, w, q_start)``: each ``v0_i`` is parallel-transported
  from its base to ``q_start`` (G-norms and inner products preserved), then combined;
- naive: the raw ``v0_i`` are added at ``q_start`` as if they were tangent there (their
  G-norms change with the base);
- superposition: ``q(t) = q_start + sum_i w_i (q_i(t) - q_i(0))``, the synergies' own
  motions added joint-wise (not a geodesic).

Reported: geodesic residual of each motion, energy, endpoint offset from the transported
combination, and the relative change of the synergies' G-norms at ``q_start``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import numpy as np
from pydantic import Field

from geosyn.experiments.procedures.base import Procedure, RunContext, register
from geosyn.experiments.procedures.common import Duration, Steps, geodesic_residual
from geosyn.experiments.results.plots import COLORS, RESIDUAL_LABEL, figure, save
from geosyn.experiments.run import build as B
from geosyn.experiments.schema import ExperimentConfig, FiniteFloat, JointVector, Strict
from geosyn.metrics import path_energy
from geosyn.synergies import GeodesicSynergy, combine, orthonormal_synergies, transported_velocities

MOTIONS = ("transported", "naive", "superposition")


class SynergyTransportParams(Strict):
    """Parameters of `SynergyTransport`: synergy bases and common start [rad], weights,
    time [s], steps."""

    bases: Annotated[list[JointVector], Field(min_length=2)]
    q_start: JointVector
    weights: Annotated[list[FiniteFloat], Field(min_length=2)]
    duration: Duration = 1.0
    steps: Steps = 400


def _norm(G: np.ndarray, v: np.ndarray) -> float:
    return float(np.sqrt(v @ G @ v))


@register
class SynergyTransport(Procedure):
    """Synergies based at different configurations, combined with and without transport."""

    kind = "synergy_transport"
    sections = ("robot", "metric", "outputs", "params")
    description = "combine synergies from different bases with vs without parallel transport"
    Params = SynergyTransportParams
    units = {"residual": "N m", "energy": "J s", "endpoint_offset": "rad", "norm_change": "1"}

    @classmethod
    def check(cls, cfg: ExperimentConfig, params: Any, robot: Any) -> list[tuple[str, str]]:
        if len(params.weights) != len(params.bases):
            return [
                (
                    "params.weights",
                    f"expected one weight per base ({len(params.bases)}), got {len(params.weights)}",
                )
            ]
        if len(params.bases) > robot.nv:
            return [("params.bases", f"at most nv={robot.nv} bases")]
        return []

    def run(self, ctx: RunContext) -> dict[str, np.ndarray]:
        cfg, robot, p = ctx.config, ctx.robot, ctx.params
        metric = B.build_metric(cfg, robot, scene=ctx.scene)
        m = len(p.bases)
        syns = []
        for i, base in enumerate(p.bases):  # the i-th designed direction at the i-th base
            basis = orthonormal_synergies(metric, np.array(base), m, robot=robot)
            syns.append(GeodesicSynergy(metric, np.array(base), basis.V[:, i]))
        q_s = np.array(p.q_start)
        w = np.asarray(p.weights)
        advance = ctx.progress(f"{cfg.name}: motions", 3)
        V_t = transported_velocities(syns, q_s, steps=p.steps)
        V_n = np.column_stack([s.v0 for s in syns])
        G_s = metric.G(q_s)
        out: dict[str, np.ndarray] = {
            "norm_at_base": np.array([_norm(metric.G(s.q0), s.v0) for s in syns]),
            "norm_transported": np.array([_norm(G_s, V_t[:, i]) for i in range(m)]),
            "norm_naive": np.array([_norm(G_s, V_n[:, i]) for i in range(m)]),
        }
        trajs = {
            "transported": combine(syns, w, q_s, steps=p.steps).trajectory(p.duration, p.steps),
            "naive": GeodesicSynergy(metric, q_s, V_n @ w).trajectory(p.duration, p.steps),
        }
        advance()
        own = [s.trajectory(p.duration, p.steps) for s in syns]
        t = own[0].t
        q_sup = q_s + sum(wi * (tr.q - tr.q[0]) for wi, tr in zip(w, own, strict=True))
        for name, (tt, q) in {
            "transported": (trajs["transported"].t, trajs["transported"].q),
            "naive": (trajs["naive"].t, trajs["naive"].q),
            "superposition": (t, q_sup),
        }.items():
            out[f"{name}__t"], out[f"{name}__q"] = tt, q
            out[f"{name}__residual"] = np.array(geodesic_residual(metric, tt, q))
            out[f"{name}__energy"] = np.array(path_energy(metric, tt, q))
            advance() if name != "transported" else None
        return out

    def summarize(
        self, cfg: ExperimentConfig, params: Any, results: dict[str, np.ndarray]
    ) -> dict[str, float]:
        base = results["norm_at_base"]
        end = results["transported__q"][-1]
        norm_err = {
            "transported": float(np.max(np.abs(results["norm_transported"] / base - 1.0))),
            "naive": float(np.max(np.abs(results["norm_naive"] / base - 1.0))),
        }  # not defined for the superposition (no initial velocities are combined)
        out: dict[str, float] = {}
        for name in MOTIONS:
            out[f"{name}.residual"] = float(results[f"{name}__residual"])
            out[f"{name}.energy"] = float(results[f"{name}__energy"])
            out[f"{name}.endpoint_offset"] = float(np.linalg.norm(results[f"{name}__q"][-1] - end))
            if name in norm_err:
                out[f"{name}.norm_change"] = norm_err[name]
        return out

    def plot(
        self, cfg: ExperimentConfig, params: Any, results: dict[str, np.ndarray], out_dir: Path
    ) -> list[Path]:
        fig, axes = figure((10, 3.8), 1, 2)
        # Distances from the transported motion: the motions nearly coincide from q_start,
        # so plotted from q_start their curves would overlap.
        ref = results["transported__q"]
        for name, c in zip(MOTIONS[1:], COLORS[1:], strict=False):
            d = np.linalg.norm(results[f"{name}__q"] - ref, axis=1)[1:]  # all start at q_start
            t = results[f"{name}__t"][1:]
            axes[0].semilogy(t, np.maximum(d, 1e-12), color=c, label=name)
        axes[0].set_xlabel("t [s]")
        axes[0].set_ylabel(r"$\|q(t) - q_{transported}(t)\|$ [rad] (log)")
        axes[0].legend(fontsize=8)
        axes[0].set_title("distance from the transported synergy")
        axes[0].grid(True, which="both", alpha=0.3)
        residuals = [max(float(results[f"{n}__residual"]), 1e-16) for n in MOTIONS]
        axes[1].bar(list(MOTIONS), residuals, color=COLORS[:3])
        for i, r in enumerate(residuals):
            axes[1].annotate(
                f"{r:.2g}", (i, r), xytext=(0, 2), textcoords="offset points", ha="center",
                fontsize=8,
            )  # fmt: skip
        axes[1].set_yscale("log")
        axes[1].set_ylabel(RESIDUAL_LABEL + " (log)")
        axes[1].set_title("geodesic-equation residual")
        return [save(fig, out_dir / "transport.png")]
