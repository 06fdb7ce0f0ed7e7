"""``geosyn view RUN_DIR``: replay a run directory in the browser.

Each stored motion (`geosyn.experiments.results.run_video.run_motions`: one per controller, or the
computed paths of a kind that simulates nothing) is a copy of the robot in its colour,
shown or hidden by a checkbox to compare controllers; its end-effector path is a line of
the same colour, the reference path a green one; pushes and wrenches are red arrows while
they act. The time slider scrubs, ``play`` plays; the time and the forces acting are
written above it.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from geosyn.experiments.config.loader import load_config
from geosyn.experiments.errors import ExperimentError
from geosyn.experiments.results.report import load_results
from geosyn.experiments.results.run_video import run_motions
from geosyn.experiments.run import build as B
from geosyn.experiments.run.scene import build_run_scene
from geosyn.experiments.viewer.server import (
    REF_COLOR,
    RUN_COLORS,
    Player,
    RobotGhost,
    Viewer,
    frame_camera,
    start_server,
)
from geosyn.experiments.viewer.text import markdown_text
from geosyn.robots.kinematics import frame_positions


def view_run(
    run_dir: str | Path, host: str = "127.0.0.1", port: int = 8080, fast: bool = False
) -> Viewer:
    """Serve the replay of a run directory; returns the running `Viewer` (close it).

    Args:
        run_dir: a directory written by ``geosyn run`` (``config.yaml``, ``results.npz``).
        host: address to bind; 127.0.0.1 (this machine only) by default.
        port: TCP port; 0 picks a free one.
        fast: plain lighting without shadows, for browsers without a GPU (see
            `geosyn.experiments.viewer.server.start_server`).

    Raises:
        ExperimentError: not a run directory, or it stores no motion of the robot.
        ViewerUnavailable: viser is not installed, or the port is taken.
    """
    run_dir = Path(run_dir)
    if not (run_dir / "config.yaml").is_file():
        runs = sorted(p.parent.name for p in run_dir.glob("*/config.yaml"))[:5]
        hint = f"; it holds runs (a sweep?): {', '.join(runs)}" if runs else ""
        raise ExperimentError(
            f"run_dir {str(run_dir)!r} has no config.yaml; is it a run directory?{hint}"
        )
    cfg, _ = load_config(run_dir / "config.yaml", allow_unused=True)
    results = load_results(run_dir)
    scene = build_run_scene(cfg)
    robot = scene.robot
    motions = run_motions(results, robot.nq)
    if not motions:
        raise ExperimentError(
            f"run_dir {str(run_dir)!r} (kind {cfg.kind!r}) stores no motion of the robot"
        )
    server = start_server(host, port, fast)
    name, kind, robot_name = (markdown_text(x) for x in (cfg.name, cfg.kind, robot.name))
    server.gui.add_markdown(f"**{name}** ({kind}, robot {robot_name})")
    server.scene.add_grid("/floor", width=3.0, height=3.0, cell_size=0.1)
    payloads, obstacles = scene.payloads, scene.obstacles
    disturbances = B.build_disturbances(cfg)
    ghosts: list[RobotGhost] = []
    for i, m in enumerate(motions):
        color = RUN_COLORS[i % len(RUN_COLORS)]
        ghost = RobotGhost(server, m.name, robot, color, payloads, obstacles, with_world=i == 0)
        ghosts.append(ghost)
        if m.simulated:
            ghost.bind_forces(disturbances)
        stride = max(1, len(m.t) // 300)
        ghost.add_path("ee_path", frame_positions(robot, m.q[::stride], robot.ee_frame), color)
        if m.q_ref is not None:
            q_ref = m.q_ref[::stride]
            q_ref = q_ref[np.all(np.isfinite(q_ref), axis=1)]
            if len(q_ref) > 1:
                ref = frame_positions(robot, q_ref, robot.ee_frame)
                ghost.add_path("ref_path", ref, REF_COLOR, thickness=0.003)
        status = results.get(f"{m.name}__status")
        label = f"show {m.name}" + ("" if status is None else f" ({status})")
        box = server.gui.add_checkbox(label, initial_value=True)
        box.on_update(lambda _, g=ghost, b=box: g.set_visible(bool(b.value)))

    status = server.gui.add_markdown("t = 0.00 s")

    def show(t: float) -> None:
        lines = [f"t = {t:.2f} s"]
        for g, m in zip(ghosts, motions, strict=True):
            k = int(np.clip(np.searchsorted(m.t, t), 0, len(m.t) - 1))
            g.pose(m.q[k])
            forces = g.show_forces(t)
            if forces and g is ghosts[0]:
                lines += forces
        status.content = "; ".join(lines)

    show(0.0)
    frame_camera(server, robot, np.vstack([m.q for m in motions]), payloads, obstacles)
    t_end = max(float(m.t[-1]) for m in motions)
    server.gui.add_markdown("green line: reference end-effector path; coloured lines: actual paths")
    return Viewer(server, Player(server, t_end, show, step=0.01))


__all__ = ["view_run"]
