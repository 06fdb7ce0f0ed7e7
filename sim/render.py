"""Videos of simulation logs: a `Clip` (what is shown and how) drawn headless, frame by frame.

``Clip(result, robot, fps, width, height, ...)`` describes the video of one run; its
`Clip.frames` yields the RGB frames one by one, `Clip.render` stacks them, `Clip.save`
streams them to a ``.gif`` or ``.mp4`` (`geosyn.sim.video`). `render_video` is the
one-call form. The OpenGL context is made when drawing starts (`geosyn.sim.offscreen`:
EGL on Linux unless ``MUJOCO_GL`` says otherwise); nothing global is set on import.
"""

from __future__ import annotations

import os
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from geosyn.core.errors import InvalidArgument
from geosyn.core.validation import check_int, check_positive
from geosyn.robots.kinematics import frame_positions
from geosyn.robots.robot import Robot
from geosyn.sim.camera import CameraView, auto_camera, body_points
from geosyn.sim.log import SimResult
from geosyn.sim.offscreen import OffscreenRenderer
from geosyn.sim.scene import build_scene
from geosyn.sim.video import check_video_path, write_frames
from geosyn.world import Payload

#: Largest frame size [px] (the offscreen buffer of `Robot.mjcf`).
MAX_WIDTH, MAX_HEIGHT = 1280, 960

#: Marker colours (RGBA): the end effector's reference path and its path so far.
_REF_RGBA = (0.1, 0.75, 0.3, 0.8)
_PATH_RGBA = (0.15, 0.35, 0.9, 1.0)


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


def _add_marker(
    scn: mujoco.MjvScene, pos: np.ndarray, radius: float, rgba: Sequence[float]
) -> None:
    """Append a visual-only sphere to a `mujoco.MjvScene` (ignored when the scene is full)."""
    if scn.ngeom >= scn.maxgeom:
        return
    mujoco.mjv_initGeom(
        scn.geoms[scn.ngeom],
        mujoco.mjtGeom.mjGEOM_SPHERE,
        np.array([radius, 0.0, 0.0]),
        np.asarray(pos, dtype=np.float64),
        np.eye(3).ravel(),
        np.asarray(rgba, dtype=np.float32),
    )
    scn.ngeom += 1


@dataclass(frozen=True, eq=False)
class Clip:
    """The video of one simulation log: what is shown and how (checked when built).

    Args:
        result: the log of a run of ``robot``.
        robot: the robot simulated.
        fps: frames per second [Hz], > 0; frames as in `frame_indices`.
        width: frame width [px], 1..1280.
        height: frame height [px], 1..960.
        payloads: payloads to draw (as in the simulation).
        obstacles: obstacles to draw (as in the simulation).
        camera: the view; by default `geosyn.sim.camera.auto_camera` frames the motion.
        trail: draw the end effector's reference path (green, where the log has a
            reference) and its path so far (blue) as small markers.

    Raises:
        InvalidArgument: bad sizes or fps, or a log of another robot.
    """

    result: SimResult
    robot: Robot
    fps: float = 30.0
    width: int = 640
    height: int = 480
    payloads: Sequence[Payload] = ()
    obstacles: Sequence[Any] = ()
    camera: CameraView | None = None
    trail: bool = True

    def __post_init__(self) -> None:
        result, robot = self.result, self.robot
        if not isinstance(result, SimResult):
            raise InvalidArgument(f"result must be a SimResult, got {type(result).__name__}")
        if not isinstance(robot, Robot):
            raise InvalidArgument(f"robot must be a geosyn Robot, got {type(robot).__name__}")
        if result.robot_name != robot.name or result.q.shape[1:] != (robot.nq,):
            raise InvalidArgument(
                f"result is a log of robot {result.robot_name!r} with nq={result.q.shape[1:]},"
                f" but robot {robot.name!r} has nq={robot.nq}"
            )
        object.__setattr__(self, "fps", check_positive(self.fps, "fps", "Hz"))
        object.__setattr__(
            self, "width", check_int(self.width, "width [px]", low=1, high=MAX_WIDTH)
        )
        object.__setattr__(
            self, "height", check_int(self.height, "height [px]", low=1, high=MAX_HEIGHT)
        )
        object.__setattr__(self, "payloads", tuple(self.payloads))
        object.__setattr__(self, "obstacles", tuple(self.obstacles))

    def _states(self) -> np.ndarray:
        """(T + 1, nq) logged states then the final one; a non-finite state (a diverged
        run) repeats the previous one [rad]."""
        states = np.vstack([self.result.q, self.result.q_final[None, :]])
        for i in range(1, len(states)):
            if not np.all(np.isfinite(states[i])):
                states[i] = states[i - 1]
        return states

    def _trails(self, states: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """State indices of the path markers, the path's and the reference's points [m]."""
        res, robot = self.result, self.robot
        stride = max(1, int(round(1.0 / (self.fps * res.control_dt))) // 2)
        marks = np.arange(0, len(states), stride)
        path = frame_positions(robot, states[marks], robot.ee_frame)
        ref = frame_positions(robot, res.q_ref[marks[marks < res.n_ticks]], robot.ee_frame)
        return marks, path, ref[np.all(np.isfinite(ref), axis=1)][::2]

    def frames(self) -> Iterator[np.ndarray]:
        """Render the frames one by one; the OpenGL context is made at the first ``next()``.

        Yields:
            (height, width, 3) uint8 RGB frames (fresh arrays).

        Raises:
            RenderError: no OpenGL context could be made.
        """
        robot, payloads = self.robot, self.payloads
        states = self._states()
        idx = frame_indices(self.result, self.fps)
        q_frames = states[idx]
        scene = build_scene(robot, payloads=payloads, obstacles=self.obstacles, decor=True)
        model = scene.model
        # Keep the floor below the robot (planar arms move in the z = 0 plane).
        floor = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "floor")
        if floor >= 0:
            low = float(body_points(robot, q_frames, payloads)[:, 2].min())
            radius = max((c.radius for c in robot.capsules), default=0.0)
            model.geom_pos[floor, 2] = min(float(model.geom_pos[floor, 2]), low - radius - 0.02)
        view = self.camera or auto_camera(robot, q_frames, payloads, self.obstacles)
        cam = view.mjv_camera()
        opt = mujoco.MjvOption()
        opt.geomgroup[:] = 1  # robot capsules (1), payloads (1) and obstacles (2) are visible
        trail = self._trails(states) if self.trail else None
        model.vis.quality.shadowsize = 4096  # fewer shadow-acne artifacts on the floor
        data = mujoco.MjData(model)
        with OffscreenRenderer(model, self.width, self.height) as renderer:
            for k, qi in zip(idx, q_frames, strict=True):
                data.qpos[scene.qpos_adr] = qi
                mujoco.mj_forward(model, data)
                renderer.update(data, cam, opt)
                if trail is not None:
                    marks, path, ref = trail
                    for p in ref:
                        _add_marker(renderer.scene, p, 0.006, _REF_RGBA)
                    for p in path[marks <= k]:
                        _add_marker(renderer.scene, p, 0.008, _PATH_RGBA)
                yield renderer.render()

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
            path: output file, ``.gif`` or ``.mp4``; the video has
                ``floor(duration * fps) + 1`` frames.

        Returns:
            The path written.

        Raises:
            InvalidArgument: an unknown suffix.
            RenderError: no OpenGL context, mp4 without imageio/ffmpeg, or writing failed.
        """
        return write_frames(self.frames(), check_video_path(path), self.fps)


def render_video(
    result: SimResult,
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

    Returns:
        The path written.

    Raises:
        InvalidArgument: bad arguments (see `Clip`) or an unknown suffix.
        RenderError: no OpenGL context, mp4 without imageio/ffmpeg, or writing failed.
    """
    clip = Clip(result, robot, fps, width, height, payloads, obstacles, camera, trail)
    return clip.save(path)


__all__ = ["MAX_HEIGHT", "MAX_WIDTH", "Clip", "frame_indices", "render_video"]
