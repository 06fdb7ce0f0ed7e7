"""Videos of simulation logs: a `Clip` (what is shown and how) drawn headless, frame by frame.

``Clip(result, robot, fps, width, height, ...)`` describes the video of one run; its
`Clip.frames` yields the RGB frames one by one, `Clip.render` stacks them, `Clip.save`
streams them to a ``.gif`` or ``.mp4`` (`geosyn.sim.video`). `render_video` is the
one-call form. A `Motion` (time stamps, positions, optional reference) can stand for the
log: a stored run, or a path that was never simulated.

Each frame shows the robot (its own meshes where its model file has them, else its
collision capsules: `geosyn.sim.render_scene`), its payloads and obstacles; the end
effector's reference path
(green line) and its path so far (blue line), labelled in a legend; the time stamp and the
run's label (the controller); an arrow on the body for each push or wrench acting then,
with its force [N]; markers (`geosyn.sim.render_scene.Marker`: a target, fixed or moving) as
balls. A run whose plant was the robot's original MJCF file (``Simulation(plant="file")``)
is drawn from that file (``plant="file"``). The OpenGL context is made when drawing starts (`geosyn.sim.offscreen`:
EGL on Linux unless ``MUJOCO_GL`` says otherwise); nothing global is set on import.
"""

from __future__ import annotations

import os
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, NamedTuple

import mujoco
import numpy as np

from geosyn.core.errors import InvalidArgument
from geosyn.core.validation import check_choice, check_int, check_positive
from geosyn.robots.kinematics import frame_positions
from geosyn.robots.robot import Robot
from geosyn.sim.camera import CameraView, auto_camera, body_points
from geosyn.sim.log import SimResult
from geosyn.sim.offscreen import OffscreenRenderer, Overlay
from geosyn.sim.render_scene import (
    FrameScene,
    Marker,
    add_connector,
    add_polyline,
    add_sphere,
    force_now,
    point_in_body,
)
from geosyn.sim.video import check_video_path, write_frames
from geosyn.world import Payload

#: Largest frame size [px] (the offscreen buffer of `Robot.mjcf`).
MAX_WIDTH, MAX_HEIGHT = 1280, 960

#: Colours (RGBA): the end effector's reference path, its path so far, force arrows.
_REF_RGBA = (0.1, 0.75, 0.3, 1.0)
_PATH_RGBA = (0.15, 0.35, 0.9, 1.0)
_ARROW_RGBA = (0.85, 0.1, 0.1, 1.0)
#: Width of the path lines [px]; length and width of a force arrow, as fractions of the
#: camera distance (the same size on screen whatever the robot's size; the overlay gives
#: the force in newtons).
_LINE_PX = 3.0
_ARROW_LENGTH, _ARROW_WIDTH = 0.15, 0.01
#: Most points drawn per path line (longer paths are subsampled).
_MAX_POINTS = 200


class Motion(NamedTuple):
    """What a video shows of a run: the robot's positions over time, and its reference.

    Attributes:
        t: (T,) time stamps [s], increasing.
        q: (T, nq) joint positions [rad]; a non-finite row repeats the previous one.
        q_ref: (T, nq) reference positions [rad] (NaN rows: no reference), or None.
        end: time the motion ends [s], >= ``t[-1]``; None: ``t[-1]``. A stored run's ticks
            stop one control period before its end: frames up to ``end`` show the last
            sample (nearest state), so the run has as many frames as its log would.
    """

    t: np.ndarray
    q: np.ndarray
    q_ref: np.ndarray | None = None
    end: float | None = None

    @classmethod
    def from_result(cls, result: SimResult) -> Motion:
        """The motion of a log: its ticks, then the final state at ``n_ticks * control_dt``."""
        end = result.t[-1] + result.control_dt if result.n_ticks else 0.0
        nan = np.full((1, result.q_ref.shape[1]), np.nan)
        return cls(
            np.append(result.t, end),
            np.vstack([result.q, result.q_final[None, :]]),
            np.vstack([result.q_ref, nan]),
        )


def frame_indices(result: SimResult, fps: float) -> np.ndarray:
    """Indices of the states shown in each frame (index ``n_ticks`` is the final state).

    Frames are taken every ``1/fps`` seconds from the first tick up to the end of the last
    tick (``n_ticks * control_dt``), nearest state, so a run of duration D gives
    ``floor(D * fps) + 1`` frames.

    Args:
        result: the log.
        fps: frames per second [Hz], > 0.

    Returns:
        (F,) indices into the states ``[q[0], ..., q[T-1], q_final]``.
    """
    fps = check_positive(fps, "fps", "Hz")
    span = result.n_ticks * result.control_dt
    n_frames = int(np.floor(span * fps + 1e-9)) + 1
    idx = np.rint(np.arange(n_frames) / fps / result.control_dt).astype(np.int64)
    return np.clip(idx, 0, result.n_ticks)


def motion_frame_indices(t: np.ndarray, fps: float, end: float | None = None) -> np.ndarray:
    """Indices of the samples shown in each frame of a `Motion` (nearest sample).

    Frames are taken every ``1/fps`` seconds from ``t[0]`` to ``end``.

    Args:
        t: (T,) increasing time stamps [s].
        fps: frames per second [Hz], > 0.
        end: last time [s]; None: ``t[-1]``.

    Returns:
        (F,) indices into ``t``, ``F = floor((end - t[0]) * fps) + 1``.
    """
    fps = check_positive(fps, "fps", "Hz")
    end = float(t[-1]) if end is None else max(float(end), float(t[-1]))
    n_frames = int(np.floor((end - t[0]) * fps + 1e-9)) + 1
    times = t[0] + np.arange(n_frames) / fps
    idx = np.clip(np.searchsorted(t, times), 0, len(t) - 1)
    prev = np.clip(idx - 1, 0, len(t) - 1)
    closer = np.abs(t[prev] - times) <= np.abs(t[idx] - times)
    return np.where(closer, prev, idx)


@dataclass(frozen=True, eq=False)
class Clip:
    """The video of one run: what is shown and how (checked when built).

    Args:
        result: the log of a run of ``robot``, or a `Motion` of it.
        robot: the robot simulated.
        fps: frames per second [Hz], > 0; frames as in `frame_indices`
            (`motion_frame_indices` for a `Motion`).
        width: frame width [px], 1..1280.
        height: frame height [px], 1..960.
        payloads: payloads to draw (as in the simulation).
        obstacles: obstacles to draw (as in the simulation).
        camera: the view; by default `geosyn.sim.camera.auto_camera` frames the motion.
        trail: draw the end effector's reference path (green, where there is a
            reference) and its path so far (blue), with a legend.
        disturbances: the run's disturbances; a push or wrench (`geosyn.sim.Push`,
            `geosyn.sim.Wrench`) is drawn as a red arrow on its body while it acts.
        label: the run's name (the controller), shown top left with the time stamp.
        overlay: draw the texts (label, time, legend, force values).
        meshes: draw the robot's own meshes where its model file has them
            (`geosyn.sim.render_scene.FrameScene`; `mesh_note` says why not), else its
            collision capsules.
        plant: the simulated plant: ``model`` (geosyn's rebuilt model, default) or
            ``file`` (the robot's original MJCF file, ``Simulation(plant="file")``), which
            is then drawn as it is (`FrameScene`).
        markers: balls drawn at fixed or moving points (a target), at each frame's time.

    Raises:
        InvalidArgument: bad sizes, fps, plant or markers, or a log of another robot.
    """

    result: SimResult | Motion
    robot: Robot
    fps: float = 30.0
    width: int = 640
    height: int = 480
    payloads: Sequence[Payload] = ()
    obstacles: Sequence[Any] = ()
    camera: CameraView | None = None
    trail: bool = True
    disturbances: Sequence[Any] = ()
    label: str = ""
    overlay: bool = True
    meshes: bool = True
    plant: str = "model"
    markers: Sequence[Marker] = ()

    def __post_init__(self) -> None:
        result, robot = self.result, self.robot
        if not isinstance(result, (SimResult, Motion)):
            raise InvalidArgument(
                f"result must be a SimResult or a Motion, got {type(result).__name__}"
            )
        if not isinstance(robot, Robot):
            raise InvalidArgument(f"robot must be a geosyn Robot, got {type(robot).__name__}")
        if isinstance(result, SimResult) and (
            result.robot_name != robot.name or result.q.shape[1:] != (robot.nq,)
        ):
            raise InvalidArgument(
                f"result is a log of robot {result.robot_name!r} with nq={result.q.shape[1:]},"
                f" but robot {robot.name!r} has nq={robot.nq}"
            )
        if isinstance(result, Motion):
            t, q = np.asarray(result.t), np.asarray(result.q)
            ok = t.ndim == 1 and len(t) >= 1 and q.shape == (len(t), robot.nq)
            if not ok or (result.q_ref is not None and np.shape(result.q_ref) != q.shape):
                raise InvalidArgument(
                    f"motion must have t (T,), q and q_ref (T, {robot.nq}) for robot"
                    f" {robot.name!r}, got t {t.shape}, q {q.shape},"
                    f" q_ref {None if result.q_ref is None else np.shape(result.q_ref)}"
                )
            if np.any(np.diff(t) <= 0.0):
                raise InvalidArgument("motion.t must be increasing [s]")
        object.__setattr__(self, "fps", check_positive(self.fps, "fps", "Hz"))
        object.__setattr__(
            self, "width", check_int(self.width, "width [px]", low=1, high=MAX_WIDTH)
        )
        object.__setattr__(
            self, "height", check_int(self.height, "height [px]", low=1, high=MAX_HEIGHT)
        )
        object.__setattr__(self, "payloads", tuple(self.payloads))
        object.__setattr__(self, "obstacles", tuple(self.obstacles))
        object.__setattr__(self, "disturbances", tuple(self.disturbances))
        object.__setattr__(self, "plant", check_choice(self.plant, ("model", "file"), "plant"))
        markers = tuple(self.markers)
        if not all(isinstance(m, Marker) for m in markers):
            raise InvalidArgument("markers must be geosyn.sim.render_scene.Marker objects")
        object.__setattr__(self, "markers", tuple(m.checked() for m in markers))

    def mesh_note(self) -> str:
        """Why the robot is drawn as capsules ("" when its own file is drawn)."""
        return FrameScene(self.robot, meshes=self.meshes, plant=self.plant).mesh_note

    def drawn_as(self) -> str:
        """What the robot is drawn with, in words (`FrameScene.drawn_as`)."""
        return FrameScene(self.robot, meshes=self.meshes, plant=self.plant).drawn_as

    def motion(self) -> Motion:
        """The motion shown; a non-finite state (a diverged run) repeats the previous one."""
        m = self.result if isinstance(self.result, Motion) else Motion.from_result(self.result)
        states = np.array(m.q, dtype=np.float64)
        for i in range(1, len(states)):
            if not np.all(np.isfinite(states[i])):
                states[i] = states[i - 1]
        return Motion(np.asarray(m.t, dtype=np.float64), states, m.q_ref, m.end)

    def indices(self, motion: Motion) -> np.ndarray:
        """(F,) indices of the samples of ``motion`` (see `motion`) shown in each frame."""
        if isinstance(self.result, SimResult):
            return frame_indices(self.result, self.fps)
        return motion_frame_indices(motion.t, self.fps, motion.end)

    def _trails(self, motion: Motion) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Sample indices of the path points, the path's points and the reference's [m]."""
        robot, n = self.robot, len(motion.t)
        marks = np.unique(np.linspace(0, n - 1, min(n, _MAX_POINTS)).round().astype(np.int64))
        path = frame_positions(robot, motion.q[marks], robot.ee_frame)
        ref = np.empty((0, 3))
        if motion.q_ref is not None:
            q_ref = np.asarray(motion.q_ref)[marks]
            q_ref = q_ref[np.all(np.isfinite(q_ref), axis=1)]
            if len(q_ref):
                ref = frame_positions(robot, q_ref, robot.ee_frame)
        return marks, path, ref

    def frames(self) -> Iterator[np.ndarray]:
        """Render the frames one by one; the OpenGL context is made at the first ``next()``.

        Yields:
            (height, width, 3) uint8 RGB frames (fresh arrays).

        Raises:
            RenderError: no OpenGL context could be made.
        """
        robot, payloads = self.robot, self.payloads
        motion = self.motion()
        idx = self.indices(motion)
        q_frames = motion.q[idx]
        frame_scene = FrameScene(robot, payloads, self.obstacles, self.meshes, self.plant)
        scene = frame_scene.scene
        # Keep the floor below the robot (planar arms move in the z = 0 plane).
        radius = max((c.radius for c in robot.capsules), default=0.0)
        low = float(body_points(robot, q_frames, payloads)[:, 2].min()) - radius - 0.02
        if frame_scene.has_meshes:  # e.g. the legs of a humanoid whose arm is simulated
            low = min(low, frame_scene.lowest_point(q_frames[0]) - 0.01)
        for m, floor in frame_scene.floors():  # geosyn's floors, not a plane of the file
            m.geom_pos[floor, 2] = min(float(m.geom_pos[floor, 2]), low)
        view = self.camera or auto_camera(robot, q_frames, payloads, self.obstacles)
        cam = view.mjv_camera()
        trail = self._trails(motion) if self.trail else None
        pushes = [
            (d, scene.resolve_body(d.body), point_in_body(scene, d))
            for d in self.disturbances
            if hasattr(d, "force") and hasattr(d, "body")
        ]
        surface = max((c.radius for c in robot.capsules), default=0.0) + 0.01  # [m]
        width = _ARROW_WIDTH * view.distance
        data = frame_scene.data
        with OffscreenRenderer(frame_scene.model, self.width, self.height) as renderer:
            for i, (k, qi) in enumerate(zip(idx, q_frames, strict=True)):
                tk = float(motion.t[0]) + i / self.fps  # the frame's time (nearest state shown)
                frame_scene.pose(qi)
                frame_scene.update(renderer.scene, cam)
                if trail is not None:
                    marks, path, ref = trail
                    add_polyline(renderer.scene, ref, _REF_RGBA, _LINE_PX)
                    add_polyline(renderer.scene, path[marks <= k], _PATH_RGBA, _LINE_PX)
                for mark in self.markers:
                    add_sphere(renderer.scene, mark.at(tk), mark.radius, mark.rgba)
                forces = []
                for d, bid, point in pushes:
                    f = force_now(d, tk)
                    if f is None:
                        continue
                    tip = (
                        data.xipos[bid]
                        if point is None
                        else data.xpos[bid] + (data.xmat[bid].reshape(3, 3) @ point)
                    )
                    norm = float(np.linalg.norm(f))
                    length = _ARROW_LENGTH * view.distance
                    tip = tip - surface * f / norm  # the arrow ends on the link, not inside
                    tail = tip - length * f / norm
                    add_connector(
                        renderer.scene, mujoco.mjtGeom.mjGEOM_ARROW, width, tail, tip, _ARROW_RGBA
                    )
                    forces.append(f"{type(d).__name__.lower()} {norm:.0f} N on {d.body}")
                texts = self._texts(tk, forces, trail) if self.overlay else None
                yield renderer.render(texts)

    def _texts(self, t: float, forces: list[str], trail: Any) -> Overlay:
        """The overlay of one frame: label and time, forces acting, the legend."""
        left = [self.label] if self.label else []
        left += [f"t = {t:.2f} s", *forces]
        legend: list[tuple[str, tuple[float, float, float]]] = []
        if trail is not None:
            if len(trail[2]):
                legend.append(("reference end-effector path", _REF_RGBA[:3]))
            legend.append(("actual end-effector path", _PATH_RGBA[:3]))
        return Overlay("\n".join(left), legend)

    def render(self) -> np.ndarray:
        """All frames in one array; prefer `save` for long runs (it streams).

        Returns:
            (F, height, width, 3) uint8 RGB frames.

        Raises:
            RenderError: no OpenGL context could be made.
        """
        return np.stack(list(self.frames()))

    def save(self, path: str | os.PathLike[str]) -> Path:
        """Stream the frames to a ``.gif`` or ``.mp4`` file (`geosyn.sim.video.write_frames`).

        The format is checked before anything is rendered.

        Args:
            path: output file, ``.gif`` or ``.mp4``; one frame per index of `indices`.

        Returns:
            The path written.

        Raises:
            InvalidArgument: an unknown suffix.
            RenderError: no OpenGL context, mp4 without imageio/ffmpeg, or writing failed.
        """
        return write_frames(self.frames(), check_video_path(path), self.fps)


def render_video(
    result: SimResult | Motion,
    path: str | os.PathLike[str],
    robot: Robot,
    fps: float = 30.0,
    width: int = 640,
    height: int = 480,
    *,
    payloads: Sequence[Payload] = (),
    obstacles: Sequence[Any] = (),
    camera: CameraView | None = None,
    trail: bool = True,
    disturbances: Sequence[Any] = (),
    label: str = "",
    plant: str = "model",
) -> Path:
    """Render a log to a ``.gif`` or ``.mp4`` video, streaming: ``Clip(...).save(path)``.

    Args:
        result: the log of a run of ``robot``.
        path: output file, ``.gif`` or ``.mp4``.
        robot: the robot simulated.
        fps: frames per second [Hz], > 0; the video has ``floor(duration * fps) + 1``
            frames.
        width: frame width [px], 1..1280.
        height: frame height [px], 1..960.
        payloads: payloads to draw.
        obstacles: obstacles to draw.
        camera: the view; framed automatically by default.
        trail: draw the end effector's reference and actual paths.
        disturbances: pushes and wrenches are drawn as arrows while they act.
        label: the run's name, shown with the time stamp.
        plant: ``file`` when the run simulated the robot's original MJCF file (drawn as
            it is), else ``model``.

    Returns:
        The path written.

    Raises:
        InvalidArgument: bad arguments (see `Clip`) or an unknown suffix.
        RenderError: no OpenGL context, mp4 without imageio/ffmpeg, or writing failed.
    """
    clip = Clip(
        result,
        robot,
        fps,
        width,
        height,
        payloads,
        obstacles,
        camera,
        trail,
        disturbances,
        label,
        plant=plant,
    )
    return clip.save(path)


__all__ = [
    "MAX_HEIGHT",
    "MAX_WIDTH",
    "Clip",
    "Motion",
    "frame_indices",
    "motion_frame_indices",
    "render_video",
]
