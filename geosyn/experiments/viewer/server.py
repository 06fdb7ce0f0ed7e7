"""The viser server of a viewer: bound to 127.0.0.1, a robot drawn from its MuJoCo scene
(robot geoms, payloads, obstacles) and posed per configuration, playback of a time axis."""

from __future__ import annotations

import socket
import threading
import time
from collections.abc import Callable, Sequence
from typing import Any

import mujoco
import numpy as np

from geosyn.experiments.errors import ExperimentError
from geosyn.robots import Robot
from geosyn.sim.camera import auto_camera
from geosyn.sim.render_scene import FrameScene, force_now, point_in_body
from geosyn.world import Payload


class ViewerUnavailable(ExperimentError):
    """The viewer cannot start: viser is not installed, or the port is taken."""


def start_server(host: str, port: int, fast: bool = False) -> Any:
    """A `viser.ViserServer` on ``host:port`` (0: a free port).

    Args:
        host: address to bind.
        port: TCP port; 0 picks a free one.
        fast: no environment map and no shadows: a browser without a GPU (software
            WebGL) draws the first frame in ~0.1 s instead of ~10 s.

    Raises:
        ViewerUnavailable: viser is missing (install the ``viewer`` extra) or the port is in use.
    """
    try:  # deferred: viser is the optional 'viewer' extra
        import viser
    except ImportError as err:
        raise ViewerUnavailable(
            "the browser viewer needs viser: pip install 'geosyn[viewer]'"
        ) from err
    if port == 0:
        with socket.socket() as s:
            s.bind((host, 0))
            port = int(s.getsockname()[1])
    try:
        server = viser.ViserServer(host=host, port=port, verbose=False)
    except OSError as err:
        raise ViewerUnavailable(f"port {port} on {host} cannot be used: {err}") from err
    if server.get_port() != port:  # viser moves to the next free port: not silently here
        taken = server.get_port()
        server.stop()
        raise ViewerUnavailable(
            f"port {port} on {host} is in use (the next free one is {taken}); pass another"
            " --port, or --port 0 for any free one"
        )
    if fast:
        server.scene.configure_environment_map(None)
        server.scene.configure_default_lights(enabled=True, cast_shadow=False)
    return server


def _geom_mesh(model: mujoco.MjModel, g: int) -> tuple[np.ndarray, np.ndarray] | None:
    """(vertices (V, 3) [m], faces (F, 3)) of geom ``g`` in its own frame; None for planes."""
    import trimesh  # deferred: trimesh comes with the optional 'viewer' extra

    kind, size = int(model.geom_type[g]), model.geom_size[g]
    T = mujoco.mjtGeom
    if kind == T.mjGEOM_SPHERE:
        m = trimesh.creation.icosphere(2, radius=size[0])
    elif kind == T.mjGEOM_CAPSULE:
        m = trimesh.creation.capsule(height=2 * size[1], radius=size[0], count=[16, 16])
    elif kind == T.mjGEOM_CYLINDER:
        m = trimesh.creation.cylinder(radius=size[0], height=2 * size[1], sections=24)
    elif kind == T.mjGEOM_BOX:
        m = trimesh.creation.box(extents=2 * size[:3])
    elif kind == T.mjGEOM_ELLIPSOID:
        m = trimesh.creation.icosphere(2, radius=1.0)
        m.apply_scale(size[:3])
    elif kind == T.mjGEOM_MESH:
        mid = int(model.geom_dataid[g])
        v0, nv = model.mesh_vertadr[mid], model.mesh_vertnum[mid]
        f0, nf = model.mesh_faceadr[mid], model.mesh_facenum[mid]
        return np.array(model.mesh_vert[v0 : v0 + nv]), np.array(model.mesh_face[f0 : f0 + nf])
    else:
        return None
    return np.asarray(m.vertices), np.asarray(m.faces)


class RobotGhost:
    """One copy of the robot (and its payloads, obstacles) in the viser scene: the robot's
    own meshes where its model file has them, else its collision capsules
    (`geosyn.sim.render_scene.FrameScene`, as the videos).

    Args:
        server: the viser server.
        name: scene-node prefix.
        robot: the robot.
        color: RGB 0..255 of the robot's geoms.
        payloads: payloads drawn with it.
        obstacles: obstacles drawn (once, by the first ghost: ``with_world``).
        with_world: draw the obstacles too.
    """

    def __init__(
        self,
        server: Any,
        name: str,
        robot: Robot,
        color: tuple[int, int, int],
        payloads: Sequence[Payload] = (),
        obstacles: Sequence[Any] = (),
        with_world: bool = True,
    ) -> None:
        self.frames = FrameScene(robot, payloads, obstacles if with_world else ())
        self.robot, self.server, self.name = robot, server, name
        self.extras: list[Any] = []
        self.forces: list[tuple[Any, int, np.ndarray | None]] = []  # see bind_forces
        self._arrows: Any = None
        self.geoms: list[tuple[Any, int]] = []  # (MjData, geom id) of each handle
        self.handles: list[Any] = []
        scene = self.frames.scene
        own = {int(b) for b in scene.payload_body_ids} | {0}  # drawn in their own colours
        for model, data in self.frames.posed_models():
            for g in range(model.ngeom):
                if int(model.geom_group[g]) > 2 or model.geom_rgba[g, 3] == 0.0:
                    continue
                mesh = _geom_mesh(model, g)
                if mesh is None:
                    continue
                keep = model is scene.model and int(model.geom_bodyid[g]) in own
                rgb = tuple(int(255 * c) for c in model.geom_rgba[g, :3]) if keep else color
                handle = server.scene.add_mesh_simple(
                    f"/{name}/geom{len(self.handles)}", mesh[0], mesh[1], color=rgb
                )
                self.geoms.append((data, g))
                self.handles.append(handle)

    def add_path(
        self, name: str, points: np.ndarray, color: tuple[int, int, int], thickness: float = 0.004
    ) -> None:
        """A line through ``points`` (N, 3) [m], shown and hidden with this copy."""
        handle = self.server.scene.add_line_segments(
            f"/{self.name}/{name}", polyline_segments(points), color, thickness=thickness
        )
        self.extras.append(handle)

    def pose(self, q: np.ndarray) -> None:
        """Move the geoms to configuration ``q`` (nq,) [rad]."""
        self.frames.pose(q)
        quat = np.empty(4)
        for (data, g), h in zip(self.geoms, self.handles, strict=True):
            mujoco.mju_mat2Quat(quat, data.geom_xmat[g])
            h.position = np.array(data.geom_xpos[g])
            h.wxyz = quat.copy()

    def bind_forces(self, disturbances: Sequence[Any]) -> None:
        """Draw the pushes and wrenches among ``disturbances`` as red arrows while they act
        (as the videos do); `show_forces` updates them."""
        scene = self.frames.scene
        self.forces = [
            (d, scene.resolve_body(d.body), point_in_body(scene, d))
            for d in disturbances
            if hasattr(d, "force") and hasattr(d, "body")
        ]

    def show_forces(self, t: float, length: float = 0.25) -> list[str]:
        """Arrows of the forces acting at ``t`` [s] (pose first); returns their descriptions."""
        data, arrows, text = self.frames.data, [], []
        for d, bid, point in self.forces:
            f = force_now(d, t)
            if f is None:
                continue
            R = data.xmat[bid].reshape(3, 3)
            tip = data.xipos[bid] if point is None else data.xpos[bid] + R @ point
            unit = f / np.linalg.norm(f)
            arrows.append([tip - length * unit, tip])
            text.append(f"{type(d).__name__.lower()} {np.linalg.norm(f):.0f} N on {d.body}")
        if arrows:
            self._arrows = self.server.scene.add_arrows(
                f"/{self.name}/forces",
                np.array(arrows),
                (220, 30, 30),
                shaft_radius=0.008,
                head_radius=0.02,
                head_length=0.05,
            )
        elif self._arrows is not None:
            self._arrows.remove()
            self._arrows = None
        return text

    def set_visible(self, visible: bool) -> None:
        """Show or hide this copy (and its paths)."""
        for h in [*self.handles, *self.extras]:
            h.visible = visible


class Player:
    """A time slider with play/pause: calls ``show(t)`` when the time changes.

    Args:
        server: the viser server.
        t_end: last time [s].
        show: called with the time [s] to display.
        step: slider step [s].
        initial: time shown first [s].
    """

    def __init__(
        self,
        server: Any,
        t_end: float,
        show: Callable[[float], None],
        step: float = 0.01,
        initial: float = 0.0,
    ) -> None:
        self.show = show
        t_max = max(float(t_end), step)
        self.slider = server.gui.add_slider(
            "time [s]", min=0.0, max=t_max, step=step, initial_value=min(float(initial), t_max)
        )
        self.playing = server.gui.add_checkbox("play", initial_value=False)
        self.speed = server.gui.add_slider(
            "speed [x real time]", min=0.1, max=2.0, step=0.1, initial_value=1.0
        )
        self.slider.on_update(lambda _: self.show(float(self.slider.value)))
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._loop, daemon=True, name="geosyn-viewer-play")
        self._thread.start()

    def set_end(self, t_end: float) -> None:
        """Change the last time [s] (the slider's range)."""
        self.slider.max = max(float(t_end), self.slider.step)
        self.slider.value = min(float(self.slider.value), self.slider.max)

    def _loop(self) -> None:
        period = 1.0 / 30.0
        while not self._stop.wait(period):
            if self.playing.value:
                t = float(self.slider.value) + period * float(self.speed.value)
                self.slider.value = t if t <= self.slider.max else 0.0

    def close(self) -> None:
        """Stop the playback thread (within one frame period)."""
        self._stop.set()
        self._thread.join(timeout=1.0)


class Viewer:
    """A running viewer: its server, URL and the things to stop.

    Attributes:
        server: the `viser.ViserServer`.
        url: ``http://127.0.0.1:<port>``.
    """

    def __init__(self, server: Any, player: Player | None = None) -> None:
        self.server = server
        self.player = player
        self.url = f"http://{server.get_host()}:{server.get_port()}"

    def close(self) -> None:
        """Stop playback and the server."""
        if self.player is not None:
            self.player.close()
        self.server.stop()

    def serve_forever(self) -> None:
        """Block until interrupted, then close: Ctrl-C returns, SIGTERM (under the CLI's
        `geosyn.experiments.run.termination.sigterm_exits`) exits after closing."""
        try:
            while True:
                time.sleep(0.5)
        except KeyboardInterrupt:
            pass
        finally:
            self.close()

    def __enter__(self) -> Viewer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def frame_camera(
    server: Any,
    robot: Robot,
    q: np.ndarray,
    payloads: Sequence[Payload] = (),
    obstacles: Sequence[Any] = (),
) -> None:
    """Point the browser's initial camera at the motion, as the videos do
    (`geosyn.sim.camera.auto_camera`), a little closer (viser has a wider field of view).

    Args:
        server: the viser server.
        robot: the robot.
        q: (F, nq) configurations shown [rad].
        payloads: payloads framed too.
        obstacles: obstacles framed too.
    """
    view = auto_camera(robot, np.atleast_2d(q), payloads, obstacles)
    az, el = np.deg2rad(view.azimuth), np.deg2rad(view.elevation)
    forward = np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])
    distance = 0.8 * view.distance
    server.initial_camera.look_at = tuple(view.lookat)
    server.initial_camera.position = tuple(np.asarray(view.lookat) - distance * forward)


#: Colours (RGB 0..255) of the compared runs, in order; reference path colour.
RUN_COLORS = ((31, 95, 191), (217, 84, 30), (42, 157, 58), (142, 68, 173), (192, 57, 43))
REF_COLOR = (26, 191, 77)


def polyline_segments(points: np.ndarray) -> np.ndarray:
    """(N-1, 2, 3) segments of a polyline through (N, 3) points [m]."""
    return np.stack([points[:-1], points[1:]], axis=1)


__all__ = [
    "REF_COLOR",
    "RUN_COLORS",
    "Player",
    "RobotGhost",
    "Viewer",
    "ViewerUnavailable",
    "frame_camera",
    "polyline_segments",
    "start_server",
]
