"""Figures of the paper's section 2 (configuration space of planar2, synergy combinations).

Each function draws on its own `matplotlib.figure.Figure` with the Agg canvas (no pyplot,
no global backend switch: importing this module changes nothing), saves a PNG and returns
a NamedTuple whose first field is the saved path, followed by the plotted data (so callers
and tests can check numbers, not only pixels). The functions allocate and are meant for
scripts and the CLI, not control loops.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from geosyn.core.types import Matrix, Vector
from geosyn.metrics.base import Metric
from geosyn.metrics.geodesic import Geodesic, exp, path_energy, straight_line
from geosyn.robots.kinematics import frame_positions, joint_positions
from geosyn.robots.robot import Robot
from geosyn.synergies.errors import InvalidSynergyInput
from geosyn.synergies.synergy import (
    GeodesicSynergy,
    as_vector,
    checked_log,
    combine,
)

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure
    from mpl_toolkits.mplot3d.axes3d import Axes3D

PAPER_WEIGHTS = ((1.2, 0.7), (1.2, -0.5), (-0.5, 1.0), (-0.5, -0.5))
"""Weights of the combinations in the paper's Figure 2 (c)-(f)."""

GEODESIC_COLOR = "#1f5fbf"
STRAIGHT_COLOR = "#d9541e"
SYNERGY_COLORS = ("#2a9d3a", "#8e44ad")
COMBINATION_COLOR = "#c0392b"


class ConfigurationSpaceFigure(NamedTuple):
    """Result of `figure_configuration_space`.

    Attributes:
        path: the saved PNG.
        geodesic: the geodesic from q0 to q1 (log then exp) over 1 s.
        straight: the straight joint-space line from q0 to q1 over 1 s.
        energy_geodesic: path energy 1/2 int qd^T G qd dt of the geodesic [J s].
        energy_straight: path energy of the straight line [J s].
    """

    path: Path
    geodesic: Geodesic
    straight: Geodesic
    energy_geodesic: float
    energy_straight: float


class SynergyCombinationFigure(NamedTuple):
    """Result of `figure_synergy_combinations`.

    Attributes:
        path: the saved PNG.
        hand_paths: (2 + len(weights_list),) list of (T, 3) frame paths [m]: the two
            synergies, then each combination.
        trajectories: the corresponding joint trajectories.
        labels: panel titles.
    """

    path: Path
    hand_paths: list[Matrix]
    trajectories: list[Geodesic]
    labels: list[str]


def agg_figure(figsize: tuple[float, float], dpi: float | None = None) -> Figure:
    """A new figure on its own Agg canvas (no pyplot, nothing global changed).

    matplotlib (~0.5 s to import) is imported by the first figure, not by every process
    that imports the synergies or the experiments' procedures.

    Args:
        figsize: (width, height) [inch].
        dpi: its resolution [dots per inch]; None: matplotlib's default.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=figsize, dpi=dpi)
    FigureCanvasAgg(fig)
    return fig


def _check_path(path: object) -> Path:
    if not isinstance(path, (str, Path)):
        raise InvalidSynergyInput(f"path must be a str or Path, got {type(path).__name__}")
    p = Path(path)
    if p.suffix.lower() != ".png":
        raise InvalidSynergyInput(f"path must end in .png, got {str(p)!r}")
    p.parent.mkdir(parents=True, exist_ok=True)
    return p


def _draw_planar_arm(ax: Axes, robot: Robot, traj: Geodesic, color: str, n_poses: int) -> None:
    """Arm poses along a planar trajectory, from transparent to opaque, numbered."""
    idx = np.linspace(0, len(traj.t) - 1, n_poses).round().astype(int)
    tip = frame_positions(robot, traj.q, robot.ee_frame)
    ax.plot(tip[:, 0], tip[:, 1], color=color, lw=1.2, ls=":", zorder=1)
    for rank, i in enumerate(idx):
        pts = joint_positions(robot, traj.q[i], robot.ee_frame)
        alpha = min(0.25 + 0.75 * rank / max(n_poses - 1, 1), 1.0)
        ax.plot(pts[:, 0], pts[:, 1], "-", color=color, lw=3.0, alpha=alpha, solid_capstyle="round")
        ax.plot(pts[:-1, 0], pts[:-1, 1], "o", ms=5, mfc="white", mec="k", alpha=alpha, zorder=3)
        ax.annotate(
            str(rank + 1),
            (float(pts[-1, 0]), float(pts[-1, 1])),
            xytext=(4, 4),
            textcoords="offset points",
            fontsize=8,
            color=color,
        )
    ax.plot(0, 0, "ks", ms=7)
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(alpha=0.3)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")


def figure_configuration_space(
    metric: Metric,
    q0: Vector,
    q1: Vector,
    path: str | Path,
    robot: Robot | None = None,
    *,
    steps: int = 100,
    grid: int = 13,
    n_poses: int = 5,
    limits: tuple[float, float] = (-np.pi, np.pi),
    dpi: int = 150,
) -> ConfigurationSpaceFigure:
    """Paper Figure 1: the Riemannian configuration space of a 2-DoF arm.

    Left: over a (q1, q2) grid, the metric drawn as ellipses of G(q) itself (semi-axes
    along G's eigenvectors, proportional to the square roots of its eigenvalues, so the
    area grows with sqrt(det G)), on a background shaded by det G(q); the geodesic from
    ``q0`` to ``q1`` (log then exp) and the straight joint-space line. Middle and right:
    the arm at ``n_poses`` configurations along each path.

    Args:
        metric: a metric on a 2-DoF configuration space.
        q0: (2,) start configuration [rad].
        q1: (2,) end configuration [rad].
        path: output PNG.
        robot: the planar robot to draw; defaults to ``metric.robot``.
        steps: integration steps.
        grid: ellipses per axis.
        n_poses: arm poses per side panel.
        limits: joint range shown on both axes [rad].
        dpi: resolution (the figure is 13 x 4.6 inches).

    Returns:
        The `ConfigurationSpaceFigure`.

    Raises:
        InvalidSynergyInput: the metric is not 2-D, or a bad path or robot.
        SynergyNotConverged: no geodesic found between q0 and q1.
    """
    if not isinstance(metric, Metric):
        raise InvalidSynergyInput(f"metric must be a geosyn Metric, got {type(metric).__name__}")
    if metric.n != 2:
        raise InvalidSynergyInput(
            f"figure_configuration_space needs n = 2, metric has {metric.n}", "metric"
        )
    robot = robot if robot is not None else getattr(metric, "robot", None)
    if not isinstance(robot, Robot) or robot.nv != 2:
        raise InvalidSynergyInput("robot must be a 2-DoF geosyn Robot (or metric.robot one)")
    a = as_vector(q0, 2, "q0")
    b = as_vector(q1, 2, "q1")
    out = _check_path(path)

    u = checked_log(metric, a, b, steps=steps)
    geo = exp(metric, a, u, duration=1.0, steps=steps)
    line = straight_line(a, b, duration=1.0, steps=steps)
    e_geo = float(path_energy(metric, geo.t, geo.q))
    e_line = float(path_energy(metric, line.t, line.q))

    from matplotlib.patches import Ellipse

    fig = agg_figure((13.0, 4.6), dpi)
    gs = fig.add_gridspec(1, 3, width_ratios=[1.3, 1, 1], wspace=0.45)
    ax = fig.add_subplot(gs[0])
    lo, hi = limits
    fine = np.linspace(lo, hi, 121)
    det = np.array([[np.linalg.det(metric.G(np.array([x, y]))) for x in fine] for y in fine])
    im = ax.imshow(
        det,
        origin="lower",
        extent=(lo, hi, lo, hi),
        cmap="Greys",
        alpha=0.55,
        aspect="equal",
        vmin=0.0,
        vmax=det.max() * 1.05,
    )
    cb = fig.colorbar(im, ax=ax, fraction=0.046, pad=0.03)
    cb.set_label(r"$\det G(q)$ [kg$^2$m$^4$]")
    centers = np.linspace(lo, hi, grid + 2)[1:-1]
    spacing = centers[1] - centers[0]
    Gs = [[metric.G(np.array([x, y])) for x in centers] for y in centers]
    s_max = max(np.sqrt(np.linalg.eigvalsh(g)).max() for row in Gs for g in row)
    for j, y in enumerate(centers):
        for i, x in enumerate(centers):
            w, Q = np.linalg.eigh(Gs[j][i])
            axes = 0.95 * spacing * np.sqrt(w) / s_max  # full axes lengths
            angle = np.degrees(np.arctan2(Q[1, 1], Q[0, 1]))
            ax.add_patch(Ellipse((x, y), axes[1], axes[0], angle=angle, fc="none", ec="k", lw=0.7))
    ax.plot(
        geo.q[:, 0],
        geo.q[:, 1],
        color=GEODESIC_COLOR,
        lw=2.4,
        label=f"geodesic (E = {e_geo:.3f} J s)",
    )
    ax.plot(
        line.q[:, 0],
        line.q[:, 1],
        color=STRAIGHT_COLOR,
        lw=2.4,
        ls="--",
        label=f"straight line (E = {e_line:.3f} J s)",
    )
    idx = np.linspace(0, steps, n_poses).round().astype(int)
    for traj, c in ((geo, GEODESIC_COLOR), (line, STRAIGHT_COLOR)):
        ax.plot(traj.q[idx, 0], traj.q[idx, 1], "o", ms=5, mfc="white", mec=c, mew=1.5)
        for r_, i in enumerate(idx):
            ax.annotate(
                str(r_ + 1),
                (float(traj.q[i, 0]), float(traj.q[i, 1])),
                xytext=(4, -10),
                textcoords="offset points",
                fontsize=8,
                color=c,
            )
    ax.set_xlim(lo, hi)
    ax.set_ylim(lo, hi)
    ax.set_xlabel(r"$q_1$ [rad]")
    ax.set_ylabel(r"$q_2$ [rad]")
    ax.set_title(
        "(a) Riemannian configuration space\nellipses: G(q); shading: det G(q)", fontsize=10
    )
    ax.legend(loc="lower left", fontsize=8, framealpha=0.9)

    axg = fig.add_subplot(gs[1])
    axs = fig.add_subplot(gs[2])
    _draw_planar_arm(axg, robot, geo, GEODESIC_COLOR, n_poses)
    _draw_planar_arm(axs, robot, line, STRAIGHT_COLOR, n_poses)
    # Same window on both panels (equal aspect, padded box of every drawn point).
    pts = np.vstack(
        [joint_positions(robot, q, robot.ee_frame) for q in np.vstack([geo.q, line.q])]
        + [np.zeros((1, 3))]
    )
    lo_xy, hi_xy = pts[:, :2].min(axis=0) - 0.15, pts[:, :2].max(axis=0) + 0.15
    for a_ in (axg, axs):
        a_.update_datalim([lo_xy, hi_xy])
        a_.autoscale_view()
    axg.set_title("(b) geodesic motion", fontsize=10)
    axs.set_title("(c) straight-line (Euclidean) motion", fontsize=10)
    fig.subplots_adjust(left=0.05, right=0.98, bottom=0.11, top=0.88)
    fig.savefig(out, dpi=dpi, bbox_inches=None)
    return ConfigurationSpaceFigure(out, geo, line, e_geo, e_line)


def _set_equal_3d(ax: Axes3D, pts: Matrix) -> None:
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    c, r = 0.5 * (lo + hi), 0.5 * float(np.max(hi - lo)) * 1.05
    ax.set_xlim(c[0] - r, c[0] + r)
    ax.set_ylim(c[1] - r, c[1] + r)
    ax.set_zlim(c[2] - r, c[2] + r)
    ax.set_box_aspect((1, 1, 1))


def figure_synergy_combinations(
    metric: Metric,
    robot: Robot,
    q0: Vector,
    synergies: Sequence[GeodesicSynergy],
    weights_list: Sequence[Sequence[float]] = PAPER_WEIGHTS,
    path: str | Path = "synergy_combinations.png",
    *,
    duration: float = 1.0,
    steps: int = 100,
    n_poses: int = 4,
    dpi: int = 120,
) -> SynergyCombinationFigure:
    """Paper Figure 2: two synergies and their combinations (hand paths and arm poses).

    One 3-D panel per motion: the two synergies, then ``combine(synergies, w, q0)`` for
    each w in ``weights_list``. Each panel shows the hand (``robot.ee_frame``) path, the
    other motions' hand paths in light grey for reference, and the arm skeleton (joint
    origins) at ``n_poses`` instants from transparent (start) to opaque (end).

    Args:
        metric: the metric of the synergies.
        robot: the robot drawn (its nv equals the metric's n).
        q0: (n,) start configuration of every motion [rad].
        synergies: exactly two synergies.
        weights_list: pairs of weights (w1, w2).
        path: output PNG (3 columns, 4.2 x 4.0 inches per panel).
        duration: motion duration [s].
        steps: integration steps.
        n_poses: skeletons per panel.
        dpi: resolution.

    Returns:
        The `SynergyCombinationFigure`.

    Raises:
        InvalidSynergyInput: bad input (sizes, weights, path).
        SynergyNotConverged: a synergy base could not be joined to q0.
    """
    syns = list(synergies)
    if len(syns) != 2:
        raise InvalidSynergyInput(f"synergies must hold exactly 2 synergies, got {len(syns)}")
    if not isinstance(robot, Robot):
        raise InvalidSynergyInput(f"robot must be a geosyn Robot, got {type(robot).__name__}")
    if robot.nv != metric.n:
        raise InvalidSynergyInput(
            f"robot {robot.name!r} has nv={robot.nv}, metric has n={metric.n}", "robot"
        )
    q_s = as_vector(q0, metric.n, "q0")
    out = _check_path(path)
    weights = [tuple(float(x) for x in w) for w in weights_list]

    motions = [
        combine([syns[0]], [1.0], q_s, steps=steps),
        combine([syns[1]], [1.0], q_s, steps=steps),
    ] + [combine(syns, w, q_s, steps=steps) for w in weights]
    labels = ["(a) 1st geodesic synergy", "(b) 2nd geodesic synergy"] + [
        f"({chr(ord('c') + i)}) $w_1={w[0]:g}$, $w_2={w[1]:g}$" for i, w in enumerate(weights)
    ]
    colors = [SYNERGY_COLORS[0], SYNERGY_COLORS[1]] + [COMBINATION_COLOR] * len(weights)
    trajs = [s.trajectory(duration=duration, steps=steps) for s in motions]
    hand_paths = [frame_positions(robot, tr.q, robot.ee_frame) for tr in trajs]
    skeletons = [
        [
            joint_positions(robot, tr.q[i], robot.ee_frame)
            for i in np.linspace(0, steps, n_poses).round().astype(int)
        ]
        for tr in trajs
    ]
    all_pts = np.vstack(hand_paths + [s for sk in skeletons for s in sk])

    ncols = 3
    nrows = int(np.ceil(len(trajs) / ncols))
    fig = agg_figure((4.2 * ncols, 4.0 * nrows), dpi)
    for k, (hp, sk, lab, col) in enumerate(zip(hand_paths, skeletons, labels, colors, strict=True)):
        ax = fig.add_subplot(nrows, ncols, k + 1, projection="3d")
        for j, other in enumerate(hand_paths):
            if j != k:
                ax.plot(*other.T, color="0.8", lw=0.8)
        if k >= 2:  # the synergies, for reference
            for j in (0, 1):
                ax.plot(*hand_paths[j].T, color=SYNERGY_COLORS[j], lw=1.0, ls="--", alpha=0.7)
        for r_, pts in enumerate(sk):
            alpha = min(0.2 + 0.8 * r_ / max(n_poses - 1, 1), 1.0)
            ax.plot(*pts.T, "-o", color="0.25", ms=2.5, lw=2.0, alpha=alpha)
        ax.plot(*hp.T, color=col, lw=2.5)
        ax.scatter(*hp[0], color="k", s=14, depthshade=False)
        ax.scatter(*hp[-1], color=col, s=30, marker="*", depthshade=False)
        _set_equal_3d(ax, all_pts)
        ax.set_title(lab, fontsize=10)
        ax.set_xlabel("x [m]", fontsize=8, labelpad=-2)
        ax.set_ylabel("y [m]", fontsize=8, labelpad=-2)
        ax.set_zlabel("z [m]", fontsize=8, labelpad=-2)
        ax.tick_params(labelsize=6, pad=0)
        ax.view_init(elev=20, azim=-60)
    fig.suptitle(
        f"Geodesic synergies of {robot.name}: hand paths ({robot.ee_frame}) and arm poses "
        "(transparent = start, opaque = end)",
        fontsize=11,
    )
    fig.subplots_adjust(left=0.02, right=0.98, bottom=0.03, top=0.9, wspace=0.05, hspace=0.12)
    fig.savefig(out, dpi=dpi)
    return SynergyCombinationFigure(out, hand_paths, trajs, labels)
