"""``geosyn explore ROBOT``: a robot's geodesic synergies in the browser.

The synergies are the metric-orthonormal basis at a configuration
(`geosyn.synergies.orthonormal_synergies` of the kinetic-energy metric); one slider per
weight; the combination (`geosyn.synergies.combine`: the geodesic from ``q0`` along the
weighted sum of the synergies' initial velocities) is recomputed when a weight changes,
drawn as the robot plus its end-effector path, and animated by the time slider / play.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence

import numpy as np

from geosyn.core.errors import GeosynError
from geosyn.core.validation import check_int, check_vector
from geosyn.experiments.config.chatter import quiet
from geosyn.experiments.viewer.server import (
    RUN_COLORS,
    Player,
    RobotGhost,
    Viewer,
    frame_camera,
    polyline_segments,
    start_server,
)
from geosyn.experiments.viewer.text import markdown_text
from geosyn.metrics import KineticEnergyMetric
from geosyn.robots import load_robot
from geosyn.robots.kinematics import frame_positions
from geosyn.synergies import combine, orthonormal_synergies

#: Range of each weight slider.
WEIGHT_RANGE = (-2.0, 2.0)


def explore_robot(
    name: str,
    k: int = 3,
    q0: Sequence[float] | None = None,
    duration: float = 1.0,
    steps: int = 60,
    host: str = "127.0.0.1",
    port: int = 8080,
    fast: bool = False,
) -> Viewer:
    """Serve the synergy explorer of a robot; returns the running `Viewer` (close it).

    Args:
        name: a built-in robot name or a robot file (as ``load_robot``).
        k: number of synergies (at most the robot's DoF).
        q0: (nq,) configuration the synergies start from [rad]; default the robot's neutral.
        duration: duration of the combined geodesic [s].
        steps: integration steps of the combined geodesic.
        host: address to bind; 127.0.0.1 by default.
        port: TCP port; 0 picks a free one.
        fast: plain lighting without shadows, for browsers without a GPU (see
            `geosyn.experiments.viewer.server.start_server`).

    Raises:
        GeosynError: unknown robot, bad ``q0`` or ``k``.
        ViewerUnavailable: viser is not installed, or the port is taken.
    """
    with quiet() as loading:  # the robot file's parser and MuJoCo's compiler print
        try:
            robot = load_robot(name)
            k = check_int(k, "k", low=1, high=robot.nv)
            start = robot.neutral() if q0 is None else check_vector(q0, robot.nq, "q0 [rad]")
        except GeosynError as err:
            failure: GeosynError | None = err
        else:
            failure = None
    if failure is not None:
        if loading.reason():  # their words in geosyn's one line, not before it
            failure.args = (f"{failure}{loading.reason()}",)
        raise failure
    loading.show_own_warnings()
    for line in loading.log_lines():  # no run log here: one line each, after loading
        print(f"geosyn explore: note: {line}", file=sys.stderr)
    metric = KineticEnergyMetric(robot)
    synergies = list(orthonormal_synergies(metric, start, k, robot=robot).synergies)
    server = start_server(host, port, fast)
    server.gui.add_markdown(
        f"**{markdown_text(robot.name)}**: {k} geodesic synergies at q0; the robot follows their combination"
    )
    server.scene.add_grid("/floor", width=3.0, height=3.0, cell_size=0.1)
    ghost = RobotGhost(server, "robot", robot, RUN_COLORS[0])
    state: dict[str, np.ndarray] = {}
    path_handle: list[object] = [None]

    def show(t: float) -> None:
        q = state["q"]
        i = int(np.clip(round(t / duration * (len(q) - 1)), 0, len(q) - 1))
        ghost.pose(q[i])

    def recompute() -> None:
        w = np.array([float(s.value) for s in sliders])
        geo = combine(synergies, w).trajectory(duration, steps)
        state["q"] = np.asarray(geo.q)
        ee = frame_positions(robot, state["q"], robot.ee_frame)
        path_handle[0] = server.scene.add_line_segments(
            "/robot_ee_path", polyline_segments(ee), RUN_COLORS[1], thickness=0.004
        )
        show(float(player.slider.value) if player is not None else 0.0)

    player: Player | None = None
    lo, hi = WEIGHT_RANGE
    sliders = [
        server.gui.add_slider(
            f"weight {j + 1}", min=lo, max=hi, step=0.05, initial_value=1.0 if j == 0 else 0.0
        )
        for j in range(k)
    ]
    for s in sliders:
        s.on_update(lambda _: recompute())
    # Shown first at the end of the combination: a weight then visibly moves the robot.
    player = Player(server, duration, show, step=duration / 100, initial=duration)
    recompute()
    frame_camera(server, robot, state["q"])
    return Viewer(server, player)


__all__ = ["WEIGHT_RANGE", "explore_robot"]
