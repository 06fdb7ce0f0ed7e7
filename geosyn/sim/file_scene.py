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

The run's scene goes into the file as into geosyn's model (`geosyn.sim.scene`): obstacles as
world geoms ``obstacle<i>``, payloads as bodies welded in the MuJoCo body of the link they
name, at the same place. With ``contact`` the obstacles collide with the file's collision
geoms (those with a nonzero ``contype`` or ``conaffinity``; the file's own contacts, e.g.
self-collisions or a floor, are kept); without it they are drawn only.
"""

from __future__ import annotations

import re
import warnings
from collections.abc import Sequence
from pathlib import Path

import mujoco
import numpy as np
import pinocchio as pin

from geosyn.core.errors import InvalidArgument
from geosyn.core.validation import check_choice, check_positive, check_vector
from geosyn.robots.mjcf import body_name
from geosyn.robots.robot import Robot
from geosyn.sim.obstacles import ROBOT_BIT, Clearance, ObstacleGeom, obstacle_geom
from geosyn.sim.scene import Scene, _payload_body, link_placement
from geosyn.world import Payload, Shape

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
    payloads: Sequence[Payload] = (),
    obstacles: Sequence[Shape] = (),
    contact: bool = False,
) -> Scene:
    """Compile the robot's own MJCF file as the plant (see the module doc).

    Args:
        robot: a robot loaded from an MJCF file (``robot.source_file``).
        timestep: physics time step [s], > 0.
        integrator: MuJoCo integrator: Euler, RK4, implicit or implicitfast.
        gravity: (3,) gravity [m/s^2]; defaults to ``robot.gravity`` (the file's).
        limits: keep the file's joint position limits (False disables them).
        payloads: `geosyn.world.Payload` bodies welded to the links they name.
        obstacles: `geosyn.world` shapes (world geoms ``obstacle<i>``).
        contact: the obstacles collide with the file's collision geoms.

    Returns:
        The scene.

    Raises:
        InvalidArgument: the robot was not loaded from an MJCF file, a payload on a
            floating robot or fixed to the world, or a bad argument.
        UnknownBody: a payload's frame is not in the robot.
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
    payloads, names = _check_payloads(robot, payloads)
    geoms = tuple(obstacle_geom(o, i, contact) for i, o in enumerate(obstacles))
    xml = spec.to_xml()
    if payloads or geoms:
        xml = _with_scene(robot, model, xml, payloads, names, geoms)
        model = _compile(xml, Path(path).parent, path)
        if contact:
            _collide_with_obstacles(model)
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
        xml=xml,
        payloads=payloads,
        payload_body_ids=np.array([model.body(n).id for n in names], dtype=np.int64),
        obstacles=geoms,
        obstacle_geom_ids=np.array(
            [model.geom(f"obstacle{i}").id for i in range(len(geoms))], dtype=np.int64
        ),
        joint_body_ids=np.array([model.jnt_bodyid[j] for j in joint_ids], dtype=np.int64),
        qpos_adr=np.array([model.jnt_qposadr[j] for j in joint_ids], dtype=np.int64),
        dof_adr=dof_adr,
        clearance=Clearance(robot, model, geoms),
    )


def _check_payloads(
    robot: Robot, payloads: Sequence[Payload]
) -> tuple[tuple[Payload, ...], list[str]]:
    out = tuple(payloads)
    for i, p in enumerate(out):
        if not isinstance(p, Payload):
            raise InvalidArgument(f"payloads[{i}] must be a geosyn.world.Payload, got {p!r}")
    names = [p.name or f"payload{i}" for i, p in enumerate(out)]
    if len(set(names)) != len(names):
        raise InvalidArgument(f"payload names must be unique, got {names}")
    if out and robot.floating:
        raise InvalidArgument(
            f"payloads on the file plant of the floating robot {robot.name!r} are not"
            " supported; use plant='model' or fixed_base=True"
        )
    return out, names


def _body_from_joint(robot: Robot, model: mujoco.MjModel, jid: int) -> tuple[str, pin.SE3]:
    """(the file's MuJoCo body of Pinocchio joint ``jid``, the joint frame in that body):
    both poses at the file's ``qpos0``, so any offset of the joint in its body is kept."""
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    q = np.array(
        [data.qpos[model.joint(n).qposadr[0]] for n in robot.joint_names], dtype=np.float64
    )
    pdata = robot.model.createData()
    pin.forwardKinematics(robot.model, pdata, q)
    name = body_name(robot.model, jid)
    b = model.body(name).id
    T_world_body = pin.SE3(data.xmat[b].reshape(3, 3).copy(), data.xpos[b].copy())
    return name, T_world_body.actInv(pdata.oMi[jid])


def _with_scene(
    robot: Robot,
    model: mujoco.MjModel,
    xml: str,
    payloads: tuple[Payload, ...],
    names: list[str],
    geoms: tuple[ObstacleGeom, ...],
) -> str:
    """``xml`` with the obstacle geoms in the world body and each payload body in the body
    of the link it names."""
    for p, name in zip(payloads, names, strict=True):
        jid, placement = link_placement(robot, p.frame)
        if jid == 0:
            raise InvalidArgument(
                f"payload {name!r} frame {p.frame!r} is fixed to the world; attach it to a moving link"
            )
        body, T_body_joint = _body_from_joint(robot, model, jid)
        tag = re.search(rf'<body\b[^>]*\bname="{re.escape(body)}"[^>]*?(?<!/)>', xml)
        if tag is None:
            raise InvalidArgument(f"payload {name!r}: body {body!r} is not in the file's XML")
        xml = xml[: tag.end()] + _payload_body(p, name, T_body_joint * placement) + xml[tag.end() :]
    if geoms:
        world = re.search(r"<worldbody>", xml)
        if world is None:
            raise InvalidArgument("the file plant's XML has no <worldbody>")
        extra = "".join(g.xml for g in geoms)
        xml = xml[: world.end()] + extra + xml[world.end() :]
    return xml


def _compile(xml: str, folder: Path, path: object) -> mujoco.MjModel:
    spec = mujoco.MjSpec.from_string(xml)
    spec.modelfiledir = str(folder)
    try:
        return spec.compile()
    except ValueError as err:
        raise InvalidArgument(
            f"the file plant {path!r} with the scene does not compile: {err}"
        ) from err


def _collide_with_obstacles(model: mujoco.MjModel) -> None:
    """The file's collision geoms of moving bodies also collide with the obstacles
    (``contype |= ROBOT_BIT``; their ``conaffinity`` and so their own contacts unchanged)."""
    for g in range(model.ngeom):
        if model.geom_bodyid[g] != 0 and (model.geom_contype[g] or model.geom_conaffinity[g]):
            model.geom_contype[g] |= ROBOT_BIT
    for b in range(model.nbody):
        mine = model.geom_bodyid == b
        model.body_contype[b] = np.bitwise_or.reduce(model.geom_contype[mine], initial=0)
        model.body_conaffinity[b] = np.bitwise_or.reduce(model.geom_conaffinity[mine], initial=0)


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
