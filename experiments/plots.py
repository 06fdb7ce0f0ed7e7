"""Plot helpers shared by the procedures: matplotlib figures written as PNG files.

Figures are `matplotlib.figure.Figure` objects drawn on their own Agg canvas, never
pyplot's: plotting needs no global backend and leaves no open figure behind, so
importing or calling this module changes nothing in matplotlib's global state.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

COLORS = ("#1f5fbf", "#d9541e", "#2a9d3a", "#8e44ad", "#c0392b", "#7f8c8d")

#: Axis label of the geodesic-equation residual [N m].
RESIDUAL_LABEL = r"max $\|G\ddot q + C\dot q\|$ [N m]"


def figure(
    figsize: tuple[float, float], nrows: int = 1, ncols: int = 1, **kw: Any
) -> tuple[Figure, Any]:
    """A new figure on its own Agg canvas and its axes (``Figure.subplots(nrows, ncols, **kw)``).

    Args:
        figsize: (width, height) [inch].
        nrows: rows of axes.
        ncols: columns of axes.
        **kw: passed to `matplotlib.figure.Figure.subplots` (``sharex``, ``squeeze``, ...).

    Returns:
        (the figure, one `Axes` or an array of them as `Figure.subplots` returns).
    """
    fig = Figure(figsize=figsize)
    FigureCanvasAgg(fig)
    return fig, fig.subplots(nrows, ncols, **kw)


def save(fig: Figure, path: Path) -> Path:
    """Lay out and write a figure as PNG (110 dpi); returns ``path``."""
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    return path


def tracking_error_plot(
    path: Path,
    runs: dict[str, dict[str, np.ndarray]],
    threshold: float | None = None,
    windows: Sequence[tuple[float, float, str]] = (),
) -> Path:
    """Tracking error norm ``||q_ref - q||`` [rad] against time, one line per run.

    Args:
        path: PNG to write.
        runs: label -> arrays with ``t`` (T,) [s] and ``tracking_error`` (T, n) [rad].
        threshold: horizontal line [rad].
        windows: (start, stop, label) time windows to shade [s] (pushes, ...).
    """
    fig, ax = figure((8, 4))
    for (label, r), c in zip(runs.items(), COLORS * 4, strict=False):
        err = np.linalg.norm(r["tracking_error"], axis=1)
        ax.semilogy(r["t"], np.maximum(err, 1e-12), color=c, lw=1.4, label=label)
    for start, stop, text in windows:
        ax.axvspan(start, stop, color="0.85", zorder=0)
        ax.text(start, ax.get_ylim()[1], text, fontsize=8, va="top")
    ax.set_ylim(bottom=1e-6)
    if threshold is not None:
        ax.axhline(threshold, color="k", ls="--", lw=0.8, label=f"threshold {threshold:g} rad")
    ax.set_xlabel("t [s]")
    ax.set_ylabel(r"$\|q_{ref} - q\|$ [rad]")
    ax.set_title("tracking error")
    ax.legend(fontsize=8)
    ax.grid(True, which="both", alpha=0.3)
    return save(fig, path)


def torque_plot(path: Path, runs: dict[str, dict[str, np.ndarray]]) -> Path:
    """Applied joint torques ``tau_applied`` (T, nv) [N m] against ``t`` (T,) [s], one
    panel per run."""
    fig, axes = figure((8, 2.4 * len(runs)), len(runs), 1, sharex=True, squeeze=False)
    for ax, (label, r) in zip(axes[:, 0], runs.items(), strict=True):
        tau = r["tau_applied"]
        for j in range(tau.shape[1]):
            ax.plot(r["t"], tau[:, j], lw=0.9, label=f"joint {j + 1}")
        ax.set_ylabel(r"$\tau$ [N m]")
        ax.set_title(label, fontsize=9)
        ax.grid(True, alpha=0.3)
    axes[0, 0].legend(fontsize=6, ncol=4)
    axes[-1, 0].set_xlabel("t [s]")
    return save(fig, path)


def bar_plot(
    path: Path, labels: Sequence[str], values: Sequence[float], ylabel: str, title: str
) -> Path:
    """One bar per label."""
    fig, ax = figure((5, 3.5))
    ax.bar(list(labels), list(values), color=COLORS[: len(labels)])
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    ax.grid(True, axis="y", alpha=0.3)
    return save(fig, path)


__all__ = [
    "COLORS",
    "RESIDUAL_LABEL",
    "bar_plot",
    "figure",
    "save",
    "torque_plot",
    "tracking_error_plot",
]
