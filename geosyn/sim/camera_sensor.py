"""An RGB-D camera in the simulation loop, looking at a moving coloured ball.

`RGBDRenderer` adds depth to `OffscreenRenderer` (MuJoCo's reversed-Z buffer converted to
the distance along the optical axis [m]); `pinhole_camera` gives the `PinholeCamera` of a
free `mujoco.MjvCamera` as MuJoCo draws it. `CameraSensor` is a `Disturbance` (the
simulation's hook into the model): before each tick it moves the target ball along its
path (a sphere obstacle of the scene, drawn in the target colour) and, at ``rate`` [Hz],
renders an RGB-D image of the current state into its `Frames` mailbox, which the
controller reads. Rendering time is recorded apart (``render_times``), so the controller's
perception-to-torque latency excludes it.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from typing import Any

import mujoco
import numpy as np

from geosyn.core.errors import InvalidArgument
from geosyn.core.types import Vector
from geosyn.core.validation import check_int, check_positive
from geosyn.sim.camera import CameraView
from geosyn.sim.disturbances import Disturbance
from geosyn.sim.errors import UnknownBody
from geosyn.sim.offscreen import OffscreenRenderer
from geosyn.sim.perception import PinholeCamera
from geosyn.sim.scene import Scene


class RGBDRenderer(OffscreenRenderer):
    """`OffscreenRenderer` that also reads the depth buffer (same arguments)."""

    def render_rgbd(self) -> tuple[np.ndarray, np.ndarray]:
        """Draw `scene`.

        Returns:
            ((H, W, 3) uint8 RGB, (H, W) float64 depth along the optical axis [m]),
            top row first (fresh arrays).
        """
        rgb = self.render()
        depth = np.empty((self._rect.height, self._rect.width), dtype=np.float32)
        mujoco.mjr_readPixels(None, depth, self._rect, self._ctx)
        extent = self.model.stat.extent
        near = np.float32(self.model.vis.map.znear * extent)
        far = np.float32(self.model.vis.map.zfar * extent)
        buf = np.flipud(depth).astype(np.float64)
        if int(self._ctx.readDepthMap) == int(mujoco.mjtDepthMap.mjDEPTH_ZEROFAR):
            # reversed Z (0 at the far plane): undo the projection as mujoco.Renderer does
            c = np.float32(-0.5) * (-(far + near) / (far - near)) - np.float32(0.5)
            d = np.float32(-0.5) * (-(np.float32(2) * far * near) / (far - near))
            z = float(d) / (buf + float(c))
        else:  # 0 at the near plane, 1 at the far plane
            z = float(near) / (1.0 - buf * (1.0 - float(near) / float(far)))
        return rgb, z


def pinhole_camera(renderer: OffscreenRenderer, width: int, height: int) -> PinholeCamera:
    """The camera of the renderer's last `update` (the average of MuJoCo's two eyes)."""
    cam = mujoco.mjv_averageCamera(renderer.scene.camera[0], renderer.scene.camera[1])
    forward = np.array(cam.forward, dtype=np.float64)
    up = np.array(cam.up, dtype=np.float64)
    focal = 0.5 * height * cam.frustum_near / cam.frustum_top
    return PinholeCamera(np.array(cam.pos, dtype=np.float64), forward, up, focal, width, height)


class Frames:
    """Mailbox of the camera's images (shared by every copy of the sensor: the channel
    from the simulation to the controller; the simulation deep-copies its disturbances).

    Attributes:
        path: target position [m] as a function of time [s], (3,); set before each run.
        latest: (time [s], rgb, depth, camera) of the newest image, or None.
        count: images rendered in the current run.
        render_times: wall-clock duration of each rendering [s].
        true_positions: (time [s], (3,) target position [m]) at each rendering.
    """

    def __init__(self) -> None:
        self.path: Callable[[float], Vector] = lambda t: np.zeros(3)
        self.latest: tuple[float, np.ndarray, np.ndarray, PinholeCamera] | None = None
        self.count = 0
        self.render_times: list[float] = []
        self.true_positions: list[tuple[float, Vector]] = []

    def clear(self) -> None:
        """Forget the images of the last run."""
        self.latest = None
        self.count = 0
        self.render_times = []
        self.true_positions = []

    def __deepcopy__(self, memo: dict[int, Any]) -> Frames:
        return self


class CameraSensor(Disturbance):
    """Fixed RGB-D cameras rendering the scene at ``rate``, and a ball moved along a path.

    With several views the cameras take turns (view ``k mod len(views)`` takes image k),
    so what one camera cannot see (the arm in the way) the next one may.

    Args:
        frames: the mailbox (its ``path`` moves the ball).
        target: index of the scene's sphere obstacle that is the ball.
        colour: (4,) rgba the ball is drawn with.
        views: where the cameras look from (one or more).
        rate: images per second [Hz], > 0, all cameras together (an image on the first
            tick and every ``1 / rate`` s after).
        width: image width [px].
        height: image height [px].

    Call `close` when done (frees the OpenGL context).
    """

    def __init__(
        self,
        frames: Frames,
        target: int,
        colour: tuple[float, float, float, float],
        views: Sequence[CameraView],
        rate: float,
        width: int = 320,
        height: int = 240,
    ) -> None:
        self.frames = frames
        self.target = check_int(target, "target", low=0)
        self.colour = np.asarray(colour, dtype=np.float64)
        self.views = tuple(views)
        if not self.views or not all(isinstance(v, CameraView) for v in self.views):
            raise InvalidArgument(f"views must be one or more CameraView, got {views!r}")
        self.period = 1.0 / check_positive(rate, "rate", "Hz")
        self.width = check_int(width, "width", low=8)
        self.height = check_int(height, "height", low=8)
        self._renderer: RGBDRenderer | None = None

    def bind(self, scene: Scene, control_dt: float) -> None:
        if self.target >= len(scene.obstacle_geom_ids):
            raise UnknownBody(
                f"target {self.target} is not an obstacle of the scene (it has "
                f"{len(scene.obstacle_geom_ids)}); add the ball as a sphere obstacle"
            )
        self._gid = int(scene.obstacle_geom_ids[self.target])
        scene.model.geom_rgba[self._gid] = self.colour
        self._scratch = mujoco.MjData(scene.model)
        self._renderer = RGBDRenderer(scene.model, self.width, self.height)
        self._cameras = [v.mjv_camera() for v in self.views]
        self._next = 0.0

    def reset(self, rng: np.random.Generator) -> None:
        self._next = 0.0
        self.frames.clear()

    def before_tick(self, t: float, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        p = self.frames.path(t)
        model.geom_pos[self._gid] = p
        if t + 1e-9 < self._next or self._renderer is None:
            return
        self._next += self.period
        r0 = time.perf_counter()
        s = self._scratch
        s.qpos[:] = data.qpos
        mujoco.mj_kinematics(model, s)
        self._renderer.update(s, self._cameras[self.frames.count % len(self._cameras)])
        rgb, depth = self._renderer.render_rgbd()
        cam = pinhole_camera(self._renderer, self.width, self.height)
        f = self.frames
        f.render_times.append(time.perf_counter() - r0)
        f.true_positions.append((t, np.array(p, dtype=np.float64)))
        f.latest = (t, rgb, depth, cam)
        f.count += 1

    def close(self) -> None:
        """Free the renderer (idempotent)."""
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None


def render_rgbd(
    scene: Scene, q: Vector, view: CameraView, width: int = 320, height: int = 240
) -> tuple[np.ndarray, np.ndarray, PinholeCamera]:
    """One RGB-D image of the scene at configuration ``q`` (allocates and frees a context).

    Returns:
        ((H, W, 3) uint8 RGB, (H, W) depth [m], the camera).
    """
    data = mujoco.MjData(scene.model)
    data.qpos[scene.qpos_adr] = q
    mujoco.mj_kinematics(scene.model, data)
    r = RGBDRenderer(scene.model, width, height)
    try:
        r.update(data, view.mjv_camera())
        rgb, depth = r.render_rgbd()
        cam = pinhole_camera(r, width, height)
    finally:
        r.close()
    return rgb, depth, cam


__all__ = ["CameraSensor", "Frames", "RGBDRenderer", "pinhole_camera", "render_rgbd"]
