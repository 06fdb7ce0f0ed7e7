"""Where the video camera looks: `CameraView`, and `auto_camera` that frames a motion."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, NamedTuple

import mujoco
import numpy as np

from geosyn.robots.kinematics import frame_positions
from geosyn.robots.robot import Robot
from geosyn.sim.scene import build_scene
from geosyn.world import Payload

#: MuJoCo's default free-camera vertical field of view [deg].
_FOVY = 45.0


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

    def mjv_camera(self) -> mujoco.MjvCamera:
        """This view as a free `mujoco.MjvCamera`."""
        cam = mujoco.MjvCamera()
        cam.type = mujoco.mjtCamera.mjCAMERA_FREE
        cam.lookat[:] = self.lookat
        cam.distance = self.distance
        cam.azimuth = self.azimuth
        cam.elevation = self.elevation
        return cam


def body_points(robot: Robot, q: np.ndarray, payloads: Sequence[Payload] = ()) -> np.ndarray:
    """Body origins and collision-sphere centres over (at most ~20 of) the configurations.

    Args:
        robot: the robot.
        q: (F, nq) configurations [rad].
        payloads: payloads welded to the robot (their bodies are included).

    Returns:
        (N, 3) points in the world [m].
    """
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

    A spatial robot is seen from 25 deg above, 45 deg beside the direction its end effector
    reaches in (135 deg azimuth for an arm reaching along +x); a planar one (all joint axes
    parallel) square to its plane of motion, from above.

    Args:
        robot: the robot.
        q: (F, nq) configurations shown [rad].
        payloads: payloads (their bodies are framed too).
        obstacles: obstacles (their centres are framed too; half-spaces are not).

    Returns:
        A view of the centre of the points' bounding box, far enough to keep the box (at
        least 0.6 m wide) in view.
    """
    pts = [body_points(robot, q, payloads)]
    for ob in obstacles:
        for attr in ("center", "p0", "p1"):
            if hasattr(ob, attr) and not hasattr(ob, "normal"):
                pts.append(np.asarray(getattr(ob, attr), dtype=np.float64).reshape(1, 3))
    allp = np.vstack(pts)
    lo, hi = allp.min(axis=0), allp.max(axis=0)
    center = 0.5 * (lo + hi)
    c = (float(center[0]), float(center[1]), float(center[2]))
    extent = max(float(np.linalg.norm(hi - lo)), 0.6)
    distance = 0.75 * extent / np.tan(0.5 * np.deg2rad(_FOVY))
    normal = _planar_normal(robot, np.asarray(q)[0])
    if normal is not None:
        n = normal if normal[2] >= 0 else -normal  # camera on the upper side
        elevation = float(np.rad2deg(np.arcsin(np.clip(-n[2], -1.0, 1.0))))
        azimuth = 90.0 if abs(n[2]) > 0.999 else float(np.rad2deg(np.arctan2(-n[1], -n[0])))
        return CameraView(c, float(distance), azimuth, max(elevation, -89.9))
    return CameraView(c, float(distance), _reach_azimuth(robot, np.asarray(q)), -25.0)


def _reach_azimuth(robot: Robot, q: np.ndarray) -> float:
    """Azimuth [deg] that sees the end effector from 45 deg beside the direction it reaches
    in (from the first joint to its mean position): 135 deg for an arm reaching along +x,
    and the robot's own body (a humanoid's torso) stays behind the arm, not in front."""
    base = np.asarray(robot.model.jointPlacements[1].translation, dtype=np.float64)
    ee = frame_positions(robot, q[:: max(1, len(q) // 20)], robot.ee_frame).mean(axis=0)
    u = (ee - base)[:2]
    if float(np.linalg.norm(u)) < 1e-3:
        return 135.0
    c, s = np.cos(np.deg2rad(-45.0)), np.sin(np.deg2rad(-45.0))
    cam = np.array([c * u[0] - s * u[1], s * u[0] + c * u[1]])  # camera side of the look-at
    return float(np.rad2deg(np.arctan2(-cam[1], -cam[0])))


__all__ = ["CameraView", "auto_camera", "body_points"]
