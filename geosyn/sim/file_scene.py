"""The robot's ORIGINAL MJCF file as the simulated plant (``Simulation(plant="file")``).

The file is compiled as it is (its meshes, geoms, contacts, joint damping and friction,
armature, keyframes) with three changes, all stated here: the physics time step and
integrator are the simulation's, gravity is the simulation's when one is given, and the
file's actuators are disabled (MuJoCo's ``mjDSBL_ACTUATION``) because geosyn's torques are
applied as generalized joint forces (``qfrc_applied``) whatever actuators the file declares
(motors, position or velocity servos, tendon actuators). Joints of the file that the robot
does not control (e.g. locked with ``keep_joints``) stay passive; this is warned about.

A robot loaded with ``fixed_base=True`` from a file with free joints (geosyn's model welds
them at their initial pose) has them removed from the plant too, which welds their bodies at
the same pose (the file's body ``pos``/``quat``); the file's keyframes lose those joints'
coordinates. This is warned about.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from pathlib import Path

import mujoco
import numpy as np

from geosyn.core.errors import InvalidArgument
from geosyn.core.validation import check_choice, check_positive, check_vector
from geosyn.robots.robot import Robot
from geosyn.sim.obstacles import Clearance
from geosyn.sim.scene import Scene

_INTEGRATORS = {
    "Euler": mujoco.mjtIntegrator.mjINT_EULER,
    "RK4": mujoco.mjtIntegrator.mjINT_RK4,
    "implicit": mujoco.mjtIntegrator.mjINT_IMPLICIT,
    "implicitfast": mujoco.mjtIntegrator.mjINT_IMPLICITFAST,
}


def build_file_scene(
    robot: Robot,
    *,
    timestep: float = 1e-3,
    integrator: str = "implicitfast",
    gravity: Sequence[float] | None = None,
    limits: bool = True,
) -> Scene:
    """Compile the robot's own MJCF file as the plant (see the module doc).

    Args:
        robot: a robot loaded from an MJCF file (``robot.source_file``).
        timestep: physics time step [s], > 0.
        integrator: MuJoCo integrator: Euler, RK4, implicit or implicitfast.
        gravity: (3,) gravity [m/s^2]; defaults to ``robot.gravity`` (the file's).
        limits: keep the file's joint position limits (False disables them).

    Returns:
        The scene (no payloads or obstacles).

    Raises:
        InvalidArgument: the robot was not loaded from an MJCF file, or a bad argument.
    """
    path = robot.source_file
    if path is None or Path(path).suffix.lower() not in (".xml", ".mjcf"):
        raise InvalidArgument(
            f"plant='file' needs a robot loaded from an MJCF file; robot {robot.name!r} comes"
            f" from {path or 'code (a built-in)'}: use plant='model'"
        )
    timestep = check_positive(timestep, "timestep", "s")
    check_choice(integrator, tuple(_INTEGRATORS), "integrator")
    g = check_vector(robot.gravity if gravity is None else gravity, 3, "gravity")
    spec = mujoco.MjSpec.from_file(str(path))
    spec.option.timestep = timestep
    spec.option.integrator = int(_INTEGRATORS[integrator])
    spec.option.gravity = g
    spec.option.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_ACTUATION)
    if not robot.floating:
        _weld_free_joints(spec, path)
    if not limits:
        for joint in spec.joints:
            joint.limited = int(mujoco.mjtLimited.mjLIMITED_FALSE)
    try:
        model = spec.compile()
    except ValueError as err:
        raise InvalidArgument(f"the file plant {path!r} does not compile: {err}") from err
    joint_ids = [
        int(mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, n)) for n in robot.joint_names
    ]
    if min(joint_ids, default=0) < 0:
        missing = [n for n, j in zip(robot.joint_names, joint_ids, strict=True) if j < 0]
        raise InvalidArgument(f"joints {missing} of robot {robot.name!r} are not in {path!r}")
    dof_adr = np.array([model.jnt_dofadr[j] for j in joint_ids], dtype=np.int64)
    if model.nv != robot.nv:
        passive = sorted(set(range(model.nv)) - set(dof_adr.tolist()))
        warnings.warn(
            f"plant {path!r}: dofs {passive} are not controlled by geosyn and move passively",
            RuntimeWarning,
            stacklevel=3,
        )
    return Scene(
        robot=robot,
        model=model,
        xml=spec.to_xml(),
        payloads=(),
        payload_body_ids=np.zeros(0, dtype=np.int64),
        obstacles=(),
        obstacle_geom_ids=np.zeros(0, dtype=np.int64),
        joint_body_ids=np.array([model.jnt_bodyid[j] for j in joint_ids], dtype=np.int64),
        qpos_adr=np.array([model.jnt_qposadr[j] for j in joint_ids], dtype=np.int64),
        dof_adr=dof_adr,
        clearance=Clearance(robot, model, ()),
    )


def _weld_free_joints(spec: mujoco.MjSpec, path: object) -> None:
    """Remove the free joints of ``spec`` (welding their bodies at the file's pose), and
    their coordinates from the keyframes, as geosyn's model of a fixed-base robot does."""
    free = [j for j in spec.joints if j.type == mujoco.mjtJoint.mjJNT_FREE]
    if not free:
        return
    try:
        original = spec.compile()
    except ValueError as err:
        raise InvalidArgument(f"the file plant {path!r} does not compile: {err}") from err
    names = [j.name for j in free]
    qpos_drop: list[int] = []
    qvel_drop: list[int] = []
    for j in range(original.njnt):
        if original.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE:
            qpos_drop += range(int(original.jnt_qposadr[j]), int(original.jnt_qposadr[j]) + 7)
            qvel_drop += range(int(original.jnt_dofadr[j]), int(original.jnt_dofadr[j]) + 6)
    keys = [(key, np.array(key.qpos), np.array(key.qvel)) for key in spec.keys]
    for key, _, _ in keys:  # emptied first: deleting a joint checks the keyframes' sizes
        key.qpos, key.qvel = np.zeros(0), np.zeros(0)
    for joint in free:
        spec.delete(joint)
    for key, qpos, qvel in keys:
        key.qpos = np.delete(qpos, qpos_drop) if len(qpos) == original.nq else qpos
        key.qvel = np.delete(qvel, qvel_drop) if len(qvel) == original.nv else qvel
    warnings.warn(
        f"plant {path!r}: free joints {names} welded at the file's pose (fixed_base=True),"
        " as in geosyn's model",
        RuntimeWarning,
        stacklevel=4,
    )


__all__ = ["build_file_scene"]
