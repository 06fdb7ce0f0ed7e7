"""Synergy extraction from demonstrations: principal geodesic analysis (PGA) against
Euclidean PCA, reconstruction error against the number of synergies k.

Demonstrations are ``exp(q0, sum_j c_j e_j)`` with ``c ~ N(0, spread^2)`` over ``latent``
G-orthonormal directions: they lie on a ``latent``-dimensional geodesic submanifold,
which PGA recovers with ``latent`` components while PCA needs more (curvature). Both
errors are measured the same way: the mean joint-space distance [rad] between each
demonstration and its reconstruction from the first k components (PGA:
``exp(mean, V_k V_k^T G u_i)``; PCA: the affine projection). PGA's own mean Riemannian
distance is reported too.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import numpy as np
from pydantic import Field

from geosyn.experiments.procedures.base import Procedure, RunContext, register
from geosyn.experiments.procedures.common import Steps
from geosyn.experiments.results.plots import COLORS, figure, save
from geosyn.experiments.run import build as B
from geosyn.experiments.schema import ExperimentConfig, JointVector, Strict
from geosyn.metrics import exp
from geosyn.synergies import pca_synergies, pga


class PGAvsPCAParams(Strict):
    """Parameters of `PGAvsPCA`: base [rad], demonstrations, their spread [rad/s] and
    latent dimension, the largest k, integration steps."""

    q0: JointVector
    n_demos: Annotated[int, Field(ge=3, le=500)] = 20
    spread: Annotated[float, Field(gt=0.0)] = 0.6
    latent: Annotated[int, Field(ge=1)] = 2
    k_max: Annotated[int, Field(ge=1)] = 4
    steps: Steps = 100


@register
class PGAvsPCA(Procedure):
    """Reconstruction error of PGA and PCA synergies of the same demonstrations."""

    kind = "pga_vs_pca"
    sections = ("robot", "metric", "outputs", "params")
    description = "PGA vs PCA synergy extraction: reconstruction error against k"
    Params = PGAvsPCAParams
    units = {
        "pga_error": "rad",
        "pca_error": "rad",
        "pga_riemannian_error": "rad",
        "pca_over_pga_at_latent_k": "1",
    }

    @classmethod
    def check(cls, cfg: ExperimentConfig, params: Any, robot: Any) -> list[tuple[str, str]]:
        out = []
        if params.k_max > robot.nv:
            out.append(("params.k_max", f"must be <= nv={robot.nv}, got {params.k_max}"))
        if params.latent > robot.nv:
            out.append(("params.latent", f"must be <= nv={robot.nv}, got {params.latent}"))
        return out

    def run(self, ctx: RunContext) -> dict[str, np.ndarray]:
        cfg, robot, p = ctx.config, ctx.robot, ctx.params
        metric = B.build_metric(cfg, robot, scene=ctx.scene)
        q0 = np.array(p.q0)
        advance = ctx.progress(f"{cfg.name}: k", p.k_max + 1)
        X = B.pga_demonstrations(metric, robot, q0, p.n_demos, p.spread, p.latent, cfg.seed)
        res = pga(metric, X, p.k_max, steps=p.steps)
        pca = pca_synergies(X, p.k_max)
        advance()
        G = metric.G(res.mean)
        C = res.log_vectors @ G @ res.V  # (N, k) coordinates <u_i, v_j>_G
        pga_err = np.zeros(p.k_max)
        for k in range(1, p.k_max + 1):
            rec = [
                exp(metric, res.mean, res.V[:, :k] @ C[i, :k], 1.0, p.steps).q[-1]
                for i in range(len(X))
            ]
            pga_err[k - 1] = float(np.mean(np.linalg.norm(np.array(rec) - X, axis=1)))
            advance()
        return {
            "demos": X,
            "pga_mean": res.mean,
            "pga_error_joint": pga_err,
            "pga_error_riemannian": np.asarray(res.reconstruction_error),
            "pca_error_joint": np.asarray(pca.reconstruction_error),
        }

    def summarize(
        self, cfg: ExperimentConfig, params: Any, results: dict[str, np.ndarray]
    ) -> dict[str, float]:
        out: dict[str, float] = {}
        for k in range(1, params.k_max + 1):
            out[f"k={k}.pga_error"] = float(results["pga_error_joint"][k - 1])
            out[f"k={k}.pca_error"] = float(results["pca_error_joint"][k - 1])
            out[f"k={k}.pga_riemannian_error"] = float(results["pga_error_riemannian"][k - 1])
        if params.latent <= params.k_max:
            j = params.latent - 1
            out["pca_over_pga_at_latent_k"] = float(
                results["pca_error_joint"][j] / max(results["pga_error_joint"][j], 1e-300)
            )
        return out

    def plot(
        self, cfg: ExperimentConfig, params: Any, results: dict[str, np.ndarray], out_dir: Path
    ) -> list[Path]:
        k = np.arange(1, params.k_max + 1)
        fig, ax = figure((6, 4))
        ax.semilogy(
            k,
            np.maximum(results["pga_error_joint"], 1e-16),
            "o-",
            color=COLORS[0],
            label="PGA (geodesic)",
        )
        ax.semilogy(
            k,
            np.maximum(results["pca_error_joint"], 1e-16),
            "s--",
            color=COLORS[1],
            label="PCA (linear)",
        )
        ax.axvline(params.latent, color="0.6", ls=":", label=f"latent dimension {params.latent}")
        ax.set_xticks(k)
        ax.set_xlabel("number of synergies k")
        ax.set_ylabel("mean reconstruction error [rad]")
        ax.set_title("synergy extraction from demonstrations")
        ax.legend(fontsize=8)
        ax.grid(True, which="both", alpha=0.3)
        return [save(fig, out_dir / "reconstruction_error.png")]
