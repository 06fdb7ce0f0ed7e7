"""Videos of simulation logs with `mujoco.Renderer`, headless (EGL) by default.

``MUJOCO_GL`` is set to ``egl`` (unless already set) before mujoco is imported here, which
is why ``geosyn.sim`` imports this module first. When mujoco was imported earlier by
someone else with ``MUJOCO_GL`` unset (it then picks GLFW, which needs a display), the
renderer is created with MuJoCo's EGL context instead, if there is no display.

Formats: ``.gif`` is written with Pillow (always available: matplotlib depends on it);
GIF stores frame durations in 10 ms units, so 30 fps plays at 1000/30 ms rounded.
``.mp4`` needs ``imageio`` with its ffmpeg plugin (``pip install imageio[ffmpeg]``); without
it a `RenderError` says so.
"""

from __future__ import annotations

import os

os.environ.setdefault("MUJOCO_GL", "egl")

import contextlib  # noqa: E402
import platform  # noqa: E402
from collections.abc import Iterable, Iterator, Sequence  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any, NamedTuple  # noqa: E402

import mujoco  # noqa: E402
import numpy as np  # noqa: E402

from geosyn.core.errors import InvalidArgument  # noqa: E402
from geosyn.robots.robot import Robot  # noqa: E402
from geosyn.sim.errors import RenderError  # noqa: E402
from geosyn.sim.log import SimResult  # noqa: E402
from geosyn.sim.scene import Payload, build_scene  # noqa: E402

#: Largest frame size [px] (the offscreen buffer of `Robot.mjcf`).
MAX_WIDTH, MAX_HEIGHT = 1280, 960
_FORMATS = (".gif", ".mp4")


class CameraView(NamedTuple):
    """A free camera looking at a point.

    Attributes:
        lookat: (3,) point looked at, in the world [m].
        distance: distance from the point [m].
        azimuth: azimuth [deg] (rotation about the world z axis).
        elevation: elevation [deg] (negative looks down).
    """

    lookat: tuple[float, float, float]
    distance: float
    azimuth: float = 135.0
    elevation: float = -20.0


@contextlib.contextmanager
def _gl_context() -> Iterator[None]:
    """Use MuJoCo's EGL context while creating a renderer if mujoco fell back to GLFW
    without a display (mujoco imported before this module with MUJOCO_GL unset)."""
    from mujoco.rendering.classic import gl_context

    chosen = str(getattr(gl_context, "_MUJOCO_GL", "egl"))
    headless = platform.system() == "Linux" and not os.environ.get("DISPLAY")
    if chosen not in ("", "glfw", "enable", "enabled", "on", "true", "1") or not headless:
        yield
        return
    try:
        from mujoco.egl import GLContext as EglContext
    except ImportError as err:
        raise RenderError(
            "mujoco was imported with MUJOCO_GL unset and there is no display; EGL is not"
            f" available either ({err}); set MUJOCO_GL=egl or osmesa before starting Python"
        ) from err
    previous = gl_context.GLContext
    gl_context.GLContext = EglContext
    try:
        yield
    finally:
        gl_context.GLContext = previous


def frame_indices(result: SimResult, fps: float) -> np.ndarray:
    """Indices of the states shown in each frame (index ``n_ticks`` is the final state).

    Frames are taken every ``1/fps`` seconds from the first tick up to the end of the last
    tick (``n_ticks * control_dt``), nearest state, so a run of duration D gives
    ``floor(D * fps) + 1`` frames.

    Args:
        result: the log.
        fps: frames per second, > 0.

    Returns:
        (F,) indices into the states ``[q[0], ..., q[T-1], q_final]``.
    """
    if not (np.isfinite(fps) and fps > 0):
        raise InvalidArgument(f"fps must be > 0, got {fps!r}")
    span = result.n_ticks * result.control_dt
    n_frames = int(np.floor(span * fps + 1e-9)) + 1
    idx = np.rint(np.arange(n_frames) / fps / result.control_dt).astype(np.int64)
    return np.clip(idx, 0, result.n_ticks)


def _body_points(robot: Robot, q: np.ndarray, payloads: Sequence[Payload] = ()) -> np.ndarray:
    """(N, 3) body origins and collision-sphere centres over the configurations [m]."""
    scene = build_scene(robot, payloads=payloads)
    data = mujoco.MjData(scene.model)
    stride = max(1, len(q) // 20)
    pts = []
    for qi in np.asarray(q)[::stride]:
        data.qpos[scene.qpos_adr] = qi
        mujoco.mj_kinematics(scene.model, data)
        pts.append(np.array(data.xpos[1:]))
        pts.append(scene.clearance.sphere_centers(data.xpos, data.xmat))
    return np.vstack(pts)


def _point(x: np.ndarray) -> tuple[float, float, float]:
    return (float(x[0]), float(x[1]), float(x[2]))


def _planar_normal(robot: Robot, q: np.ndarray) -> np.ndarray | None:
    """(3,) common world axis of all joints if the robot is planar (parallel revolute
    axes, no prismatic joint), else None."""
    scene = build_scene(robot)
    data = mujoco.MjData(scene.model)
    data.qpos[scene.qpos_adr] = q
    mujoco.mj_kinematics(scene.model, data)
    if np.any(scene.model.jnt_type != mujoco.mjtJoint.mjJNT_HINGE):
        return None
    axes = np.array(data.xaxis)
    if np.all(np.linalg.norm(np.cross(axes, axes[0]), axis=1) < 1e-6):
        return axes[0] / np.linalg.norm(axes[0])
    return None


def auto_camera(
    robot: Robot,
    q: np.ndarray,
    payloads: Sequence[Payload] = (),
    obstacles: Sequence[Any] = (),
) -> CameraView:
    """A camera that frames the robot's bodies and the obstacles over the configurations.

    A spatial robot is seen from 135 deg azimuth, 25 deg above; a planar one (all joint
    axes parallel) square to its plane of motion, from above.

    Args:
        robot: the robot.
        q: (F, nq) configurations shown [rad].
        payloads: payloads (their bodies are framed too).
        obstacles: obstacles (their centres are framed too; half-spaces are not).

    Returns:
        A view of the centre of the points' bounding box, far enough to keep the box (at
        least 0.6 m wide) in view.
    """
    pts = [_body_points(robot, q, payloads)]
    for ob in obstacles:
        for attr in ("center", "p0", "p1"):
            if hasattr(ob, attr) and not hasattr(ob, "normal"):
                pts.append(np.asarray(getattr(ob, attr), dtype=np.float64).reshape(1, 3))
    allp = np.vstack(pts)
    lo, hi = allp.min(axis=0), allp.max(axis=0)
    center = 0.5 * (lo + hi)
    extent = max(float(np.linalg.norm(hi - lo)), 0.6)
    fovy = np.deg2rad(45.0)  # MuJoCo's default free-camera field of view
    distance = 0.75 * extent / np.tan(0.5 * fovy)
    normal = _planar_normal(robot, np.asarray(q)[0])
    if normal is not None:
        n = normal if normal[2] >= 0 else -normal  # camera on the upper side
        elevation = float(np.rad2deg(np.arcsin(np.clip(-n[2], -1.0, 1.0))))
        azimuth = 90.0 if abs(n[2]) > 0.999 else float(np.rad2deg(np.arctan2(-n[1], -n[0])))
        return CameraView(_point(center), float(distance), azimuth, max(elevation, -89.9))
    return CameraView(_point(center), float(distance), 135.0, -25.0)


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


def _frame_positions(robot: Robot, q: np.ndarray, frame: str) -> np.ndarray:
    """(T, 3) world positions of a Pinocchio frame along configurations [m] (NaN rows kept)."""
    import pinocchio as pin

    fid = robot.frame_id(frame)
    data = robot.model.createData()
    out = np.full((len(q), 3), np.nan)
    for i, qi in enumerate(q):
        if np.all(np.isfinite(qi)):
            pin.forwardKinematics(robot.model, data, qi)
            pin.updateFramePlacement(robot.model, data, fid)
            out[i] = data.oMf[fid].translation
    return out


def _check_render_args(result: SimResult, robot: Robot, width: int, height: int) -> None:
    if not isinstance(result, SimResult):
        raise InvalidArgument(f"result must be a SimResult, got {type(result).__name__}")
    if result.robot_name != robot.name or result.q.shape[1:] != (robot.nq,):
        raise InvalidArgument(
            f"result is a log of robot {result.robot_name!r} with nq={result.q.shape[1:]},"
            f" but robot {robot.name!r} has nq={robot.nq}"
        )
    for name, val, top in (("width", width, MAX_WIDTH), ("height", height, MAX_HEIGHT)):
        if isinstance(val, bool) or not isinstance(val, (int, np.integer)) or not 1 <= val <= top:
            raise InvalidArgument(f"{name} must be an int in [1, {top}] [px], got {val!r}")


def iter_frames(
    result: SimResult,
    robot: Robot,
    fps: float = 30.0,
    width: int = 640,
    height: int = 480,
    *,
    payloads: Sequence[Payload] = (),
    obstacles: Sequence[Any] = (),
    camera: CameraView | None = None,
    trail: bool = True,
) -> Iterator[np.ndarray]:
    """Render the frames of a log one by one (see `frame_indices` for which states).

    Arguments are checked and the OpenGL context is created at the first ``next()``; each
    frame is a fresh (height, width, 3) uint8 RGB array. See `render_frames` for the
    arguments.

    Raises:
        InvalidArgument: bad sizes, or a log of another robot.
        RenderError: no OpenGL context could be made.
    """
    _check_render_args(result, robot, width, height)
    states = np.vstack([result.q, result.q_final[None, :]])
    for i in range(1, len(states)):  # a diverged run may end on a non-finite state
        if not np.all(np.isfinite(states[i])):
            states[i] = states[i - 1]
    idx = frame_indices(result, fps)
    q_frames = states[idx]
    scene = build_scene(robot, payloads=payloads, obstacles=obstacles, decor=True)
    model = scene.model
    # Keep the floor below the robot (planar arms move in the z = 0 plane).
    floor = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "floor")
    if floor >= 0:
        low = float(_body_points(robot, q_frames, payloads)[:, 2].min())
        radius = max((c.radius for c in robot.capsules), default=0.0)
        model.geom_pos[floor, 2] = min(float(model.geom_pos[floor, 2]), low - radius - 0.02)
    if camera is None:
        camera = auto_camera(robot, q_frames, payloads, obstacles)
    cam = mujoco.MjvCamera()
    cam.type = mujoco.mjtCamera.mjCAMERA_FREE
    cam.lookat[:] = camera.lookat
    cam.distance = camera.distance
    cam.azimuth = camera.azimuth
    cam.elevation = camera.elevation
    opt = mujoco.MjvOption()
    opt.geomgroup[:] = 1  # robot capsules (1), payloads (1) and obstacles (2) are visible
    ee_path = ee_ref = None
    if trail:
        stride = max(1, int(round(1.0 / (fps * result.control_dt))) // 2)
        marks = np.arange(0, len(states), stride)
        ee_path = (marks, _frame_positions(robot, states[marks], robot.ee_frame))
        q_ref = result.q_ref[marks[marks < result.n_ticks]]
        ee_ref = _frame_positions(robot, q_ref, robot.ee_frame)
        ee_ref = ee_ref[np.all(np.isfinite(ee_ref), axis=1)][::2]
    model.vis.quality.shadowsize = 4096  # fewer shadow-acne artifacts on the floor
    data = mujoco.MjData(model)
    try:
        with _gl_context():
            renderer = mujoco.Renderer(model, height, width, max_geom=4000)
    except Exception as err:  # mujoco raises FatalError/ImportError/RuntimeError here
        raise RenderError(
            f"could not create an OpenGL context (MUJOCO_GL={os.environ.get('MUJOCO_GL')!r}):"
            f" {err}; on a headless machine use MUJOCO_GL=egl or osmesa"
        ) from err
    with renderer:
        for k, qi in zip(idx, q_frames, strict=True):
            data.qpos[scene.qpos_adr] = qi
            mujoco.mj_forward(model, data)
            renderer.update_scene(data, camera=cam, scene_option=opt)
            if ee_ref is not None:
                for p in ee_ref:
                    _add_marker(renderer.scene, p, 0.006, (0.1, 0.75, 0.3, 0.8))
            if ee_path is not None:
                marks, pos = ee_path
                for p in pos[marks <= k]:
                    _add_marker(renderer.scene, p, 0.008, (0.15, 0.35, 0.9, 1.0))
            yield renderer.render().copy()


def render_frames(
    result: SimResult,
    robot: Robot,
    fps: float = 30.0,
    width: int = 640,
    height: int = 480,
    *,
    payloads: Sequence[Payload] = (),
    obstacles: Sequence[Any] = (),
    camera: CameraView | None = None,
    trail: bool = True,
) -> np.ndarray:
    """Render all frames of a log into one array (see `frame_indices` for which states).

    Allocates the (F, height, width, 3) frame array and an OpenGL context; for long runs
    prefer `render_video`, which streams the frames.

    Args:
        result: the log of a run of ``robot``.
        robot: the robot simulated.
        fps: frames per second, > 0.
        width: frame width [px], 1..1280.
        height: frame height [px], 1..960.
        payloads: payloads to draw (as in the simulation).
        obstacles: obstacles to draw (as in the simulation).
        camera: the view; by default `auto_camera` frames the motion.
        trail: draw the end effector's reference path (green, where the log has a
            reference) and its path so far (blue) as small markers.

    Returns:
        (F, height, width, 3) uint8 RGB frames.

    Raises:
        InvalidArgument: bad sizes, or a log of another robot.
        RenderError: no OpenGL context could be made.
    """
    frames = iter_frames(
        result,
        robot,
        fps,
        width,
        height,
        payloads=payloads,
        obstacles=obstacles,
        camera=camera,
        trail=trail,
    )
    return np.stack(list(frames))


def write_frames(
    frames: Iterable[np.ndarray], path: str | os.PathLike[str], fps: float = 30.0
) -> Path:
    """Write RGB frames to a ``.gif`` (Pillow) or ``.mp4`` (imageio + ffmpeg), streaming.

    GIF frames are palette-quantized one by one as they arrive (adaptive 256 colours), so
    only the quantized images are held in memory; mp4 frames go straight to the encoder.

    Args:
        frames: (H, W, 3) uint8 RGB frames, all of one size (an array (F, H, W, 3) works).
        path: output file; its suffix picks the format.
        fps: frames per second, > 0.

    Returns:
        The path written.

    Raises:
        InvalidArgument: an unknown suffix, no frames, or a frame of the wrong type or size.
        RenderError: mp4 requested but imageio/ffmpeg are not installed, or writing failed.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in _FORMATS:
        raise InvalidArgument(f"path {str(path)!r} must end in one of {', '.join(_FORMATS)}")
    if not (np.isfinite(fps) and fps > 0):
        raise InvalidArgument(f"fps must be > 0, got {fps!r}")
    shape: tuple[int, ...] | None = None

    def checked(f: np.ndarray, i: int) -> np.ndarray:
        nonlocal shape
        f = np.asarray(f)
        if f.ndim != 3 or f.shape[-1] != 3 or f.dtype != np.uint8 or (shape and f.shape != shape):
            raise InvalidArgument(
                f"frame {i} must be a (H, W, 3) uint8 array like frame 0 {shape},"
                f" got {f.shape} {f.dtype}"
            )
        shape = f.shape
        return f

    path.parent.mkdir(parents=True, exist_ok=True)
    if suffix == ".gif":
        from PIL import Image

        images = [
            Image.fromarray(checked(f, i)).convert("P", palette=Image.Palette.ADAPTIVE, colors=256)
            for i, f in enumerate(frames)
        ]
        if not images:
            raise InvalidArgument("frames is empty; nothing to write")
        images[0].save(
            path,
            save_all=True,
            append_images=images[1:],
            duration=max(int(round(1000.0 / fps)), 10),
            loop=0,
            optimize=False,
        )
        return path
    imageio = _mp4_writer()
    count = 0
    try:
        with imageio.get_writer(path, fps=fps, macro_block_size=1) as writer:
            for i, f in enumerate(frames):
                writer.append_data(checked(f, i))
                count += 1
    except (InvalidArgument, RenderError):
        raise
    except Exception as err:  # the plugins raise their own types
        raise RenderError(f"could not write {str(path)!r}: {err}") from err
    if count == 0:
        raise InvalidArgument("frames is empty; nothing to write")
    return path


def _mp4_writer() -> Any:
    """The ``imageio.v2`` module (with ffmpeg), or a `RenderError` saying how to get it."""
    try:
        import imageio.v2 as iio
        import imageio_ffmpeg  # noqa: F401
    except ImportError as err:
        raise RenderError(
            "writing .mp4 needs imageio with ffmpeg (pip install 'imageio[ffmpeg]');"
            " use a .gif path instead"
        ) from err
    return iio


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
    """Render a log to a ``.gif`` or ``.mp4`` video, streaming (`iter_frames`, `write_frames`).

    Args:
        result: the log of a run of ``robot``.
        path: output file, ``.gif`` or ``.mp4``.
        robot: the robot simulated.
        fps: frames per second, > 0; the video has ``floor(duration * fps) + 1`` frames.
        width: frame width [px].
        height: frame height [px].
        payloads: payloads to draw.
        obstacles: obstacles to draw.
        camera: the view; framed automatically by default.
        trail: draw the end effector's reference and actual paths.

    Returns:
        The path written.
    """
    suffix = Path(path).suffix.lower()
    if suffix not in _FORMATS:
        raise InvalidArgument(f"path {str(path)!r} must end in one of {', '.join(_FORMATS)}")
    if suffix == ".mp4":
        _mp4_writer()  # fail before rendering
    frames = iter_frames(
        result,
        robot,
        fps,
        width,
        height,
        payloads=payloads,
        obstacles=obstacles,
        camera=camera,
        trail=trail,
    )
    return write_frames(frames, path, fps)


__all__ = [
    "CameraView",
    "auto_camera",
    "iter_frames",
    "frame_indices",
    "render_frames",
    "render_video",
    "write_frames",
]
