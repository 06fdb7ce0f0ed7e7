"""Figures of the human-synergy study (PNG, Agg canvas, no pyplot, nothing global changed).

Each function takes the measured numbers (the records the study writes) and saves one
figure: IK residuals per keypoint, geodesic vs straight-line fit of the segments, PGA vs
PCA against k, and the robot's hand paths against the scaled human wrist path.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from geosyn.synergies.figures import agg_figure

if TYPE_CHECKING:
    from matplotlib.figure import Figure

_LABELS = {
    "RightArm": "shoulder",
    "RightForeArm": "elbow",
    "RightHand": "wrist",
    "RightHandIndex1": "index MCP",
    "RightHandMiddle1": "middle MCP",
    "RightHandPinky1": "little MCP",
}


def _save(fig: Figure, path: Path) -> Path:
    fig.tight_layout()
    fig.savefig(path, dpi=130)
    return path


def ik_residuals(residuals: np.ndarray, names: Sequence[str], path: Path) -> Path:
    """Box plot of keypoint residuals.

    Args:
        residuals: (T, K) keypoint distances [m].
        names: (K,) keypoint names.
        path: PNG file.
    """
    fig = agg_figure((6.4, 3.4))
    ax = fig.add_subplot(1, 1, 1)
    ax.boxplot([100 * residuals[:, k] for k in range(residuals.shape[1])], showfliers=False)
    ax.set_xticks(range(1, len(names) + 1), [_LABELS.get(n, n) for n in names], fontsize=8)
    ax.axhline(1.0, color="k", lw=0.8, ls="--", label="1 cm")
    med = 100 * float(np.median(residuals))
    ax.set_ylabel("keypoint residual [cm]")
    ax.set_title(f"MyoArm IK on {len(residuals):,} frames: median {med:.2f} cm")
    ax.legend(loc="upper right")
    return _save(fig, path)


def segment_fit(geodesic: np.ndarray, line: np.ndarray, path: Path, unit: str = "rad") -> Path:
    """Scatter of each segment's deviation from its geodesic against its straight line.

    Args:
        geodesic: (S,) mean closest-point deviation from the geodesic.
        line: (S,) from the straight line.
        path: PNG file.
        unit: axis unit.
    """
    fig = agg_figure((4.4, 4.2))
    ax = fig.add_subplot(1, 1, 1)
    ax.loglog(line, geodesic, ".", alpha=0.7)
    lim = [min(line.min(), geodesic.min()) * 0.8, max(line.max(), geodesic.max()) * 1.2]
    ax.plot(lim, lim, "k--", lw=0.8)
    ax.set_xlabel(f"deviation from straight line in z [{unit}]")
    ax.set_ylabel(f"deviation from geodesic [{unit}]")
    closer = int(np.sum(geodesic < line))
    ax.set_title(f"{len(line)} segments: geodesic closer in {closer}")
    return _save(fig, path)


def pga_vs_pca(rows: Sequence[Mapping[str, float]], path: Path) -> Path:
    """Reconstruction error of PGA and PCA against k, under the metric and in joints."""
    k = [int(r["k"]) for r in rows]
    fig = agg_figure((8.0, 3.2))
    for i, (key, label) in enumerate(
        (("metric", "under the arm's metric"), ("plain", "plain joint coordinates [rad]"))
    ):
        ax = fig.add_subplot(1, 2, i + 1)
        ax.plot(k, [r[f"pga_{key}"] for r in rows], "o-", label="exact PGA")
        ax.plot(k, [r[f"pca_{key}"] for r in rows], "s--", label="PCA")
        ax.set_xlabel("number of synergies k")
        ax.set_title(f"reconstruction error, {label}", fontsize=9)
        ax.set_yscale("log")
        ax.legend()
    return _save(fig, path)


def hand_paths(
    target: np.ndarray, kinematic: np.ndarray, geodesic: np.ndarray, path: Path, title: str
) -> Path:
    """Robot hand paths (kinematic retargeting, geodesic) against the mapped human path.

    Args:
        target, kinematic, geodesic: (T, 3) positions [m].
        path: PNG file.
        title: figure title.
    """
    fig = agg_figure((8.0, 3.4))
    for i, (a, b) in enumerate(((0, 1), (0, 2))):
        ax = fig.add_subplot(1, 2, i + 1)
        ax.plot(target[:, a], target[:, b], "k-", lw=2, label="human wrist (scaled)")
        ax.plot(kinematic[:, a], kinematic[:, b], "--", label="kinematic retargeting")
        ax.plot(geodesic[:, a], geodesic[:, b], "-", label="robot geodesic")
        ax.set_xlabel("xyz"[a] + " [m]")
        ax.set_ylabel("xyz"[b] + " [m]")
        ax.set_aspect("equal", adjustable="datalim")
    fig.axes[0].legend(fontsize=7)
    fig.suptitle(title, fontsize=9)
    return _save(fig, path)
