"""Paper Figure 2 on talos_arm: two geodesic synergies and their combinations, against
linear (PCA) synergies.

Geodesic combinations ``combine(synergies, w, q0)`` are geodesics: they satisfy
``G(q) qdd + C(q, qd) qd = 0`` (residual ~ finite-difference error). The linear baseline
takes the two PCA components ``u1, u2`` of the geodesic motions (each scaled to unit
G(q0)-norm, like the synergies) and moves along ``q(t) = q0 + t (w1 u1 + w2 u2)``:
a constant joint velocity, whose residual ``||C(q, qd) qd||`` is the Coriolis and
centrifugal torque the robot must supply to stay on it.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import numpy as np
from pydantic import Field

from geosyn.experiments.procedures.base import Procedure, RunContext, check_required, register
from geosyn.experiments.procedures.common import (
    Duration,
    Steps,
    geodesic_residual,
    robot_and_metric,
)
from geosyn.experiments.results.plots import COLORS, RESIDUAL_LABEL, figure, save
from geosyn.experiments.run import build as B
from geosyn.experiments.schema import ExperimentConfig, FiniteFloat, Strict
from geosyn.metrics import path_energy
from geosyn.synergies import combine, pca_synergies
from geosyn.synergies.figures import figure_synergy_combinations

Pair = Annotated[list[FiniteFloat], Field(min_length=2, max_length=2)]


class SynergyCombinationsParams(Strict):
    """Parameters of `SynergyCombinations`: weight pairs, time [s], steps."""

    weights: Annotated[list[Pair], Field(min_length=1)] = [
        [1.2, 0.7],
        [1.2, -0.5],
        [-0.5, 1.0],
        [-0.5, -0.5],
    ]
    duration: Duration = 1.0
    steps: Steps = 400


@register
class SynergyCombinations(Procedure):
    """Combinations of two designed synergies against linear combinations of PCA ones."""

    kind = "synergy_combinations"
    sections = ("robot", "metric", "synergies", "outputs", "params")
    description = "paper Fig. 2: geodesic synergy combinations vs PCA linear combinations"
    Params = SynergyCombinationsParams
    units = {
        "residual_geodesic": "N m",
        "residual_pca_linear": "N m",
        "energy_geodesic": "J s",
        "energy_pca_linear": "J s",
        "max_residual_geodesic": "N m",
        "min_residual_pca_linear": "N m",
    }

    @classmethod
    def check(cls, cfg: ExperimentConfig, params: Any, robot: Any) -> list[tuple[str, str]]:
        out = check_required(cfg, "synergies")
        if cfg.synergies is not None:
            m = len(cfg.synergies.items) if cfg.synergies.type == "explicit" else cfg.synergies.k
            if m != 2:
                out.append(("synergies", f"kind {cfg.kind!r} needs exactly 2 synergies, got {m}"))
        return out

    def run(self, ctx: RunContext) -> dict[str, np.ndarray]:
        cfg, robot, p = ctx.config, ctx.robot, ctx.params
        metric = B.build_metric(cfg, robot, scene=ctx.scene)
        syns = B.build_synergies(cfg, metric, robot)
        q0 = np.array(syns[0].q0)
        advance = ctx.progress(f"{cfg.name}: combinations", 2 * len(p.weights))
        out: dict[str, np.ndarray] = {"q0": q0}
        trajs = []
        for i, w in enumerate(p.weights):
            tr = combine(syns, w, q0).trajectory(p.duration, p.steps)
            trajs.append(tr.q)
            out[f"geodesic{i}__t"], out[f"geodesic{i}__q"] = tr.t, tr.q
            out[f"geodesic{i}__residual"] = np.array(geodesic_residual(metric, tr.t, tr.q))
            out[f"geodesic{i}__energy"] = np.array(path_energy(metric, tr.t, tr.q))
            advance()
        pca = pca_synergies(trajs, 2)
        G0 = metric.G(q0)
        U = pca.components / np.sqrt(np.einsum("ij,ik,kj->j", pca.components, G0, pca.components))
        out["pca_components"] = U
        t = np.linspace(0.0, p.duration, p.steps + 1)
        for i, w in enumerate(p.weights):
            q = q0 + (t / p.duration)[:, None] * (U @ np.asarray(w))[None, :]
            out[f"linear{i}__t"], out[f"linear{i}__q"] = t, q
            out[f"linear{i}__residual"] = np.array(geodesic_residual(metric, t, q))
            out[f"linear{i}__energy"] = np.array(path_energy(metric, t, q))
            advance()
        return out

    def summarize(
        self, cfg: ExperimentConfig, params: Any, results: dict[str, np.ndarray]
    ) -> dict[str, float]:
        out: dict[str, float] = {}
        n = len(params.weights)
        for i, w in enumerate(params.weights):
            row = f"w=({w[0]:g},{w[1]:g})"
            out[f"{row}.residual_geodesic"] = float(results[f"geodesic{i}__residual"])
            out[f"{row}.residual_pca_linear"] = float(results[f"linear{i}__residual"])
            out[f"{row}.energy_geodesic"] = float(results[f"geodesic{i}__energy"])
            out[f"{row}.energy_pca_linear"] = float(results[f"linear{i}__energy"])
        geo = max(float(results[f"geodesic{i}__residual"]) for i in range(n))
        lin = min(float(results[f"linear{i}__residual"]) for i in range(n))
        out["max_residual_geodesic"] = geo
        out["min_residual_pca_linear"] = lin
        out["residual_ratio"] = lin / max(geo, 1e-300)
        return out

    def plot(
        self, cfg: ExperimentConfig, params: Any, results: dict[str, np.ndarray], out_dir: Path
    ) -> list[Path]:
        robot, metric = robot_and_metric(cfg)
        syns = B.build_synergies(cfg, metric, robot)
        fig2 = figure_synergy_combinations(
            metric,
            robot,
            results["q0"],
            syns,
            params.weights,
            out_dir / "figure2_synergy_combinations.png",
            duration=params.duration,
            steps=min(params.steps, 200),
        )
        n = len(params.weights)
        fig, ax = figure((7, 3.5))
        x = np.arange(n)
        ax.bar(
            x - 0.2,
            [float(results[f"geodesic{i}__residual"]) for i in range(n)],
            0.4,
            color=COLORS[0],
            label="geodesic combination",
        )
        ax.bar(
            x + 0.2,
            [float(results[f"linear{i}__residual"]) for i in range(n)],
            0.4,
            color=COLORS[1],
            label="PCA linear combination",
        )
        ax.set_yscale("log")
        ax.set_xticks(x, [f"({w[0]:g}, {w[1]:g})" for w in params.weights])
        ax.set_xlabel("weights")
        ax.set_ylabel(RESIDUAL_LABEL)
        ax.set_title("geodesic-equation residual")
        ax.legend(fontsize=8)
        return [fig2.path, save(fig, out_dir / "residuals.png")]
