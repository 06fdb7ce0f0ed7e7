"""Videos of a floating-base robot standing in its scene (`geosyn.sim.floating_scene`).

The scene's own MJCF (geosyn's twin under a free joint, the floor, the contact spheres) is
posed at each frame from a logged Pinocchio configuration (`to_mujoco`) and drawn
offscreen (`OffscreenRenderer`, EGL unless ``MUJOCO_GL`` names another backend), the
camera following the base; frames are written as .gif or .mp4 (`write_frames`).
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path

import mujoco
import numpy as np

from geosyn.core.errors import InvalidArgument
from geosyn.core.validation import check_positive
from geosyn.robots.floating import to_mujoco
from geosyn.sim.floating_scene import FloatingScene
from geosyn.sim.offscreen import OffscreenRenderer, Overlay
from geosyn.sim.video import write_frames

__all__ = ["floating_frames", "render_floating_video"]


def floating_frames(
    scene: FloatingScene,
    t: np.ndarray,
    q: np.ndarray,
    fps: float = 30.0,
    width: int = 640,
    height: int = 480,
    label: str = "",
) -> Iterator[np.ndarray]:
    """RGB frames of the logged motion ``(t, q)`` in the scene.

    Args:
        scene: the floating scene that was simulated.
        t: (T,) increasing time stamps [s].
        q: (T, nq) Pinocchio configurations (base pose with a unit quaternion, joints);
            NaN rows (after a fall) end the video.
        fps: frames per second [Hz]; frame ``i`` shows the last sample at or before
            ``t[0] + i / fps``.
        width: image width [px].
        height: image height [px].
        label: text drawn top left with the time.

    Yields:
        (height, width, 3) uint8 images.
    """
    t = np.asarray(t, dtype=np.float64)
    q = np.asarray(q, dtype=np.float64)
    if t.ndim != 1 or q.shape != (len(t), scene.robot.nq) or len(t) == 0:
        raise InvalidArgument(
            f"t (T,) and q (T, {scene.robot.nq}) must match; got {t.shape} and {q.shape}"
        )
    fps = check_positive(fps, "fps", "Hz")
    finite = np.all(np.isfinite(q), axis=1)
    stop = int(np.argmin(finite)) if not finite.all() else len(t)
    if stop == 0:
        raise InvalidArgument("q has no finite configuration to draw")
    model = mujoco.MjModel.from_xml_string(scene.xml)
    model.vis.global_.offwidth = max(int(model.vis.global_.offwidth), width)
    model.vis.global_.offheight = max(int(model.vis.global_.offheight), height)
    data = mujoco.MjData(model)
    cam = mujoco.MjvCamera()
    cam.type = mujoco.mjtCamera.mjCAMERA_FREE
    cam.distance = 2.5 * float(scene.q0[2]) + 0.6  # the robot's height sets the framing
    cam.azimuth, cam.elevation = 135.0, -15.0
    times = np.arange(t[0], t[stop - 1] + 1e-12, 1.0 / fps)
    with OffscreenRenderer(model, width, height) as renderer:
        for tf in times:
            k = min(int(np.searchsorted(t[:stop], tf, side="right")) - 1, stop - 1)
            data.qpos[:] = to_mujoco(q[k], np.zeros(scene.robot.nv))[0]
            mujoco.mj_kinematics(model, data)
            cam.lookat[:] = [q[k, 0], q[k, 1], 0.6 * float(scene.q0[2])]
            renderer.update(data, cam)
            yield renderer.render(Overlay(text=f"{label}  t = {tf:.2f} s".strip()))


def render_floating_video(
    scene: FloatingScene,
    t: np.ndarray,
    q: np.ndarray,
    path: str | os.PathLike[str],
    fps: float = 30.0,
    width: int = 640,
    height: int = 480,
    label: str = "",
) -> Path:
    """Write the video of ``(t, q)`` in the scene to ``path`` (.gif or .mp4); see
    `floating_frames` for the arguments. Returns the path written."""
    return write_frames(floating_frames(scene, t, q, fps, width, height, label), path, fps)
