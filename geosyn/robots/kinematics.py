"""Forward kinematics of a `Robot` with Pinocchio: the one helper every layer calls.

Frame positions at one configuration or along a trajectory, and the position Jacobian.
Each call allocates a Pinocchio ``Data`` unless one is passed (O(njoints) per call).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from geosyn.core.types import Matrix, Vector
from geosyn.robots.robot import Robot


def _frame(robot: Robot, frame: str | int) -> int:
    return frame if isinstance(frame, int) else robot.frame_id(frame)


def frame_position(
    robot: Robot, q: Vector, frame: str | int, data: pin.Data | None = None
) -> Vector:
    """World position of a frame.

    Args:
        robot: the robot.
        q: (nq,) configuration [rad].
        frame: frame name (or Pinocchio frame index).
        data: optional Pinocchio data to reuse (avoids an allocation).

    Returns:
        (3,) position [m] (a fresh array).
    """
    data = robot.model.createData() if data is None else data
    pin.forwardKinematics(robot.model, data, q)
    return pin.updateFramePlacement(robot.model, data, _frame(robot, frame)).translation.copy()


def frame_positions(robot: Robot, q: np.ndarray, frame: str | int) -> np.ndarray:
    """World positions of a frame along configurations; rows with non-finite q stay NaN.

    Args:
        robot: the robot.
        q: (T, nq) configurations [rad].
        frame: frame name (or Pinocchio frame index).

    Returns:
        (T, 3) positions [m].
    """
    fid = _frame(robot, frame)
    data = robot.model.createData()
    out = np.full((len(q), 3), np.nan)
    for i, qi in enumerate(q):
        if np.all(np.isfinite(qi)):
            pin.forwardKinematics(robot.model, data, qi)
            out[i] = pin.updateFramePlacement(robot.model, data, fid).translation
    return out


def joint_positions(robot: Robot, q: Vector, frame: str | int | None = None) -> np.ndarray:
    """World positions of every joint origin, base to tip, optionally with a frame last.

    Args:
        robot: the robot.
        q: (nq,) configuration [rad].
        frame: frame appended as the last point (e.g. the end effector), or None.

    Returns:
        (njoints - 1 [+ 1], 3) positions [m].
    """
    data = robot.model.createData()
    pin.forwardKinematics(robot.model, data, q)
    pts = [data.oMi[j].translation.copy() for j in range(1, robot.model.njoints)]
    if frame is not None:
        pts.append(pin.updateFramePlacement(robot.model, data, _frame(robot, frame)).translation)
    return np.array(pts)


def frame_position_jacobian(robot: Robot, q: Vector, frame: str | int) -> Matrix:
    """Linear part of the world-aligned frame Jacobian.

    Args:
        robot: the robot.
        q: (nq,) configuration [rad].
        frame: frame name (or Pinocchio frame index).

    Returns:
        (3, nv) Jacobian of the frame origin's world position [m/rad].
    """
    data = robot.model.createData()
    J = pin.computeFrameJacobian(
        robot.model, data, q, _frame(robot, frame), pin.LOCAL_WORLD_ALIGNED
    )
    return np.array(J[:3])
