"""Plot helpers shared by the procedures: matplotlib figures written as PNG files.

Figures are `matplotlib.figure.Figure` objects drawn on their own Agg canvas, never
pyplot's: plotting needs no global backend and leaves no open figure behind, so
importing or calling this module changes nothing in matplotlib's global state.

A time series longer than `PLOT_POINTS` ticks (a long run, whose log may be a map of its
spool file, `geosyn.sim.log_spool`) is drawn as its min/max envelope over buckets of
consecutive ticks (`envelope`), read a block at a time: the pixels show the same band
(a spike stays visible) and memory does not grow with the run.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from geosyn.sim import blocks
from geosyn.sim.blocks import row_blocks
from geosyn.synergies.figures import agg_figure

if TYPE_CHECKING:
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
    fig = agg_figure(figsize)
    return fig, fig.subplots(nrows, ncols, **kw)


def save(fig: Figure, path: Path) -> Path:
    """Lay out and write a figure as PNG (110 dpi); returns ``path``."""
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    return path


#: Smallest value a log axis shows [same unit as the data]: zeros are drawn there.
LOG_FLOOR = 1e-12

#: Most points of a plotted time series; a longer one is drawn as its envelope (20,000: a
#: 20 s run at 1 kHz is drawn tick by tick; a figure is ~900 pixels wide).
PLOT_POINTS = 20_000


def envelope(
    t: np.ndarray,
    y: np.ndarray,
    transform: Callable[[np.ndarray], np.ndarray] | None = None,
    points: int | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """The points to draw of a time series: itself up to ``points`` ticks, else the min and
    the max of each bucket of consecutive ticks, both at the bucket's first time.

    Read a block of ticks at a time (`geosyn.sim.blocks.row_blocks`): O(T) time, memory
    O(points) beyond a block.

    Args:
        t: (T,) times [s].
        y: (T,) or (T, k) values (any unit).
        transform: applied to each block of ``y`` rows before the envelope (e.g. a row
            norm); None: the values themselves.
        points: most points drawn; None: `PLOT_POINTS`.

    Returns:
        ``(t', y')``: ``(T,)`` and ``transform(y)`` for a short series, else ``(2B,)`` and
        ``(2B, ...)`` for ``B`` buckets (min, max, min, max, ...).
    """
    limit = PLOT_POINTS if points is None else points
    f = (lambda a: a) if transform is None else transform
    n = len(t)
    if n <= limit:
        return np.asarray(t), f(np.asarray(y))
    bucket = -(-n // max(1, limit // 2))
    per_block = bucket * max(1, blocks.SCAN_BLOCK // bucket)
    times, values = [], []
    for rows in row_blocks(n, t, y, size=per_block):
        yb, starts = f(np.asarray(y[rows])), np.arange(0, rows.stop - rows.start, bucket)
        lo, hi = np.minimum.reduceat(yb, starts, axis=0), np.maximum.reduceat(yb, starts, axis=0)
        times.append(np.repeat(np.asarray(t[rows])[starts], 2))
        values.append(np.stack([lo, hi], axis=1).reshape(-1, *yb.shape[1:]))
    return np.concatenate(times), np.concatenate(values)


def reference_end(run: dict[str, np.ndarray], rtol: float = 1e-12) -> float | None:
    """Time [s] at which a run's reference stops moving, if that is before the run ends.

    A reference that ends is held at its last configuration (`GeodesicReference`), so the
    velocity steps to zero there: the tracking error and torques may jump at that time.

    Args:
        run: arrays with ``t`` (T,) [s] and ``q_ref`` (T, nq) [rad] (NaN: no reference).
        rtol: changes smaller than this (relative to the reference's range) are "held".

    Returns:
        The first time of the held tail, or None (no reference, or it moves to the end).
    """
    q_ref, t = run.get("q_ref"), run.get("t")
    if q_ref is None or t is None or len(t) < 3 or not np.all(np.isfinite(q_ref[-1])):
        return None
    first, last, n = np.asarray(q_ref[0]), np.asarray(q_ref[-1]), len(t)
    spread = 0.0
    for rows in row_blocks(n, q_ref):  # a long run's log a block at a time
        block = np.abs(np.asarray(q_ref[rows]) - first)
        if np.any(~np.isnan(block)):
            spread = max(spread, float(np.nanmax(block)))
    scale = max(spread, 1.0)
    final = -1  # the last row that differs from the held configuration
    for rows in row_blocks(n, q_ref):
        moving = np.nonzero(np.any(np.abs(np.asarray(q_ref[rows]) - last) > rtol * scale, axis=1))[
            0
        ]
        if moving.size:
            final = rows.start + int(moving[-1])
    if final < 0 or final >= n - 2:
        return None
    return float(t[final + 1])


def log_floor(values: Sequence[np.ndarray]) -> float:
    """A log axis bottom just below the smallest positive value (at least `LOG_FLOOR`)."""
    pos = np.concatenate([np.ravel(v)[np.ravel(v) > 0] for v in values] or [np.ones(1)])
    if pos.size == 0:
        return 1e-6
    return max(LOG_FLOOR, 10.0 ** np.floor(np.log10(np.percentile(pos, 0.5))))


def shade_windows(ax: Any, windows: Sequence[tuple[float, float, str]]) -> None:
    """Shade (start, stop, label) time windows [s] and label each at the top of the axes."""
    for start, stop, text in windows:
        ax.axvspan(start, max(stop, start + 0.005), color="0.85", zorder=0)
        ax.annotate(
            text,
            (start, 1.0),
            xycoords=("data", "axes fraction"),
            xytext=(2, -2),
            textcoords="offset points",
            fontsize=8,
            va="top",
        )


def mark_reference_end(ax: Any, t_end: float | None) -> None:
    """A dotted vertical line where the reference stops (its velocity steps to zero)."""
    if t_end is None:
        return
    ax.axvline(t_end, color="0.35", ls=":", lw=1.2, label=f"reference ends ({t_end:g} s)")


def tracking_error_plot(
    path: Path,
    runs: dict[str, dict[str, np.ndarray]],
    threshold: float | None = None,
    windows: Sequence[tuple[float, float, str]] = (),
    t_ref_end: float | None = None,
) -> Path:
    """Tracking error norm ``||q_ref - q||`` [rad] against time, one line per run (log axis;
    a run longer than `PLOT_POINTS` ticks as its `envelope`).

    The axis bottom sits just below the smallest positive error, so no series is hidden
    below it (exact zeros are drawn at the bottom). Where the reference ends before the
    run (`reference_end`, found from the runs when ``t_ref_end`` is None) a dotted line
    explains the step there.

    Args:
        path: PNG to write.
        runs: label -> arrays with ``t`` (T,) [s] and ``tracking_error`` (T, n) [rad]
            (and ``q_ref`` (T, n) [rad] to find the reference's end).
        threshold: horizontal line [rad] (the recovery threshold).
        windows: (start, stop, label) time windows to shade [s] (pushes, ...).
        t_ref_end: time the reference ends [s]; None: found from the runs.
    """
    fig, ax = figure((8, 4))
    norms = {
        label: envelope(r["t"], r["tracking_error"], lambda e: np.linalg.norm(e, axis=1))
        for label, r in runs.items()
    }
    floor = log_floor([norm for _, norm in norms.values()])
    for label, c in zip(runs, COLORS * 4, strict=False):
        t, norm = norms[label]
        ax.semilogy(t, np.maximum(norm, floor), color=c, lw=1.4, label=label)
    ax.set_ylim(bottom=floor)
    shade_windows(ax, windows)
    if t_ref_end is None:
        t_ref_end = next((e for e in map(reference_end, runs.values()) if e is not None), None)
    mark_reference_end(ax, t_ref_end)
    if threshold is not None:
        ax.axhline(threshold, color="k", ls="--", lw=0.8, label=f"threshold {threshold:g} rad")
    ax.set_xlabel("t [s]")
    ax.set_ylabel(r"$\|q_{ref} - q\|$ [rad] (log)")
    ax.set_title("tracking error")
    ax.legend(fontsize=8, loc="upper right", framealpha=0.9)
    ax.grid(True, which="both", alpha=0.3)
    return save(fig, path)


def torque_limits(run: dict[str, np.ndarray]) -> np.ndarray:
    """(nv,) torque limits [N m] seen in a run: ``|tau_applied|`` where it was clipped
    (``saturated``), NaN for joints never clipped."""
    tau = run["tau_applied"]
    flags: Any = run.get("saturated", False)
    per_tick = np.ndim(flags) > 0
    out = np.full(tau.shape[1], np.nan)
    for rows in row_blocks(len(tau), tau, flags):  # a long run's log a block at a time
        block = np.abs(np.asarray(tau[rows]))
        sat = np.asarray(flags[rows] if per_tick else flags, dtype=bool)
        sat = np.broadcast_to(sat, block.shape)
        for j in range(block.shape[1]):
            if sat[:, j].any():
                out[j] = np.fmax(out[j], block[sat[:, j], j].max())
    return out


def torque_plot(
    path: Path,
    runs: dict[str, dict[str, np.ndarray]],
    limits: np.ndarray | None = None,
    windows: Sequence[tuple[float, float, str]] = (),
    joint_names: Sequence[str] | None = None,
) -> Path:
    """Applied joint torques ``tau_applied`` (T, nv) [N m] against ``t`` (T,) [s], one panel
    per run (a run longer than `PLOT_POINTS` ticks as its `envelope`), with each joint's
    torque limit as a dashed line of its colour.

    Args:
        path: PNG to write.
        runs: label -> arrays with ``t``, ``tau_applied`` (and ``saturated``, ``q_ref``).
        limits: (nv,) torque limits [N m]; None: the limits the runs were clipped at
            (`torque_limits`; joints never clipped get no line).
        windows: (start, stop, label) time windows to shade [s].
        joint_names: legend names of the joints; default ``joint 1..nv``.
    """
    fig, axes = figure((9, 2.4 * len(runs) + 0.6), len(runs), 1, sharex=True, squeeze=False)
    for ax, (label, r) in zip(axes[:, 0], runs.items(), strict=True):
        t, tau = envelope(r["t"], r["tau_applied"])
        lim = torque_limits(r) if limits is None else np.asarray(limits, dtype=np.float64)
        colors = []
        for j in range(tau.shape[1]):
            name = joint_names[j] if joint_names is not None else f"joint {j + 1}"
            (line,) = ax.plot(t, tau[:, j], lw=0.9, label=name)
            colors.append(line.get_color())
        for value in np.unique(lim[np.isfinite(lim)]):  # one line per distinct limit
            joints = [j for j in range(len(lim)) if lim[j] == value]
            color = colors[joints[0]] if len(joints) == 1 else "0.4"
            for sign in (-1.0, 1.0):
                ax.axhline(sign * value, color=color, ls="--", lw=0.8, alpha=0.9)
            which = ", ".join(str(j + 1) for j in joints)
            ax.annotate(
                f"limit {value:g} N m (joint{'s' if len(joints) > 1 else ''} {which})",
                (1.0, value),
                xycoords=("axes fraction", "data"),
                xytext=(-3, 2),
                textcoords="offset points",
                ha="right",
                fontsize=7,
                color=color,
            )
        lo, hi = ax.get_ylim()  # room for the limit labels
        ax.set_ylim(lo - 0.06 * (hi - lo), hi + 0.1 * (hi - lo))
        shade_windows(ax, windows)
        mark_reference_end(ax, reference_end(r))
        ax.set_ylabel(r"$\tau$ [N m]")
        what = "torque limits" if limits is not None else "limits of the clipped joints"
        ax.set_title(f"{label}  (dashed: {what})", fontsize=9)
        ax.grid(True, alpha=0.3)
    axes[0, 0].legend(fontsize=7, ncol=1, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    axes[-1, 0].set_xlabel("t [s]")
    return save(fig, path)


def use_log_axis(values: Sequence[float] | np.ndarray, ratio: float = 30.0) -> bool:
    """Whether bars of these values belong on a log axis: all positive and spanning more
    than a factor ``ratio`` (the point is then a ratio, and small bars must stay visible)."""
    vals = np.asarray(values, dtype=np.float64)
    return bool(vals.size > 1 and np.all(vals > 0) and vals.max() / vals.min() > ratio)


def bar_plot(
    path: Path,
    labels: Sequence[str],
    values: Sequence[float],
    ylabel: str,
    title: str,
    log: bool | None = None,
) -> Path:
    """One bar per label, its value written on it.

    Args:
        path: PNG to write.
        labels: bar names.
        values: bar heights (in the unit of ``ylabel``).
        ylabel: axis label, with its unit.
        title: figure title.
        log: log axis; None: when the positive values span more than a factor 30 (a
            ratio is the point, and small bars stay visible).
    """
    vals = np.asarray(values, dtype=np.float64)
    pos = vals[vals > 0]
    if log is None:
        log = use_log_axis(vals)
    fig, ax = figure((5, 3.5))
    bottom = 10.0 ** np.floor(np.log10(pos.min())) / 2 if log and pos.size else 0.0
    ax.bar(list(labels), vals - bottom, bottom=bottom, color=COLORS[: len(labels)])
    for i, v in enumerate(vals):
        ax.annotate(
            f"{v:.3g}", (i, v), xytext=(0, 2), textcoords="offset points", ha="center", fontsize=8
        )
    if log:
        ax.set_yscale("log")
        ax.set_ylim(bottom=bottom)
    ax.set_ylabel(ylabel + (" (log)" if log else ""))
    ax.set_title(title)
    ax.set_axisbelow(True)
    ax.grid(True, axis="y", which="both", alpha=0.3)
    return save(fig, path)


__all__ = [
    "COLORS",
    "LOG_FLOOR",
    "PLOT_POINTS",
    "RESIDUAL_LABEL",
    "bar_plot",
    "envelope",
    "figure",
    "log_floor",
    "mark_reference_end",
    "reference_end",
    "save",
    "shade_windows",
    "torque_limits",
    "torque_plot",
    "tracking_error_plot",
    "use_log_axis",
]
