"""A floating-base `Robot`: a free-flyer root joint added above a fixed-base robot.

Every loader builds the fixed-base robot first (joint normalisation, limits, torque
limits, damping, capsules; `geosyn.robots.from_model`), whose root body (the URDF's root
link, the MJCF body of the free joint) is welded to the world at a pose ``T_world_base``.
`floating_robot` then puts a free flyer between the world and that body: the root body's
inertia and frames move to the free flyer, so at ``q = [T_world_base, joints]`` the robot
is where the welded one was. For a URDF this is the model of
``pinocchio.buildModelFromUrdf(path, pinocchio.JointModelFreeFlyer())``; for an MJCF the
base frame is the free joint's body frame, as in MuJoCo. Conventions:
`geosyn.robots.floating`.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pinocchio as pin

from geosyn.robots.errors import FloatingBaseError
from geosyn.robots.robot import Robot

__all__ = ["BASE_TAU_SOURCE", "ROOT_JOINT", "add_free_flyer", "floating_robot", "free_joint_pose"]

ROOT_JOINT = "root_joint"
"""Name of the free-flyer joint (Pinocchio's own name for a URDF's root joint)."""

BASE_TAU_SOURCE = "unactuated floating base"
"""`Robot.tau_max_source` of the six base coordinates (their torque limit is 0)."""

_BIG = np.finfo(np.float64).max


def add_free_flyer(model: pin.Model, T_world_base: pin.SE3 | None = None) -> pin.Model:
    """A copy of a fixed-base model with a free flyer between the world and its root body.

    Args:
        model: fixed-base Pinocchio model; its root body's inertia is ``model.inertias[0]``
            (where Pinocchio's URDF parser puts it), expressed in the world frame.
        T_world_base: pose of the root body (the new base frame) in ``model``'s world
            frame; identity (the default) for a URDF's root link.

    Returns:
        The floating-base model: joint 1 is the free flyer `ROOT_JOINT`, joints 2.. are
        ``model``'s joints in order, every frame kept (a frame on the world moves to the
        base), armature kept.
    """
    T_base_world = (pin.SE3.Identity() if T_world_base is None else T_world_base).inverse()
    new = pin.Model()
    new.name = model.name
    new.gravity = model.gravity
    root = new.addJoint(
        0,
        pin.JointModelFreeFlyer(),
        pin.SE3.Identity(),
        ROOT_JOINT,
        np.full(6, _BIG),
        np.full(6, _BIG),
        np.full(7, -_BIG),
        np.full(7, _BIG),
    )
    new.appendBodyToJoint(root, T_base_world.act(model.inertias[0]), pin.SE3.Identity())
    new.addJointFrame(root, 0)
    for jid in range(1, model.njoints):
        jm = model.joints[jid]
        parent = int(model.parents[jid])
        placement = model.jointPlacements[jid]
        new_id = new.addJoint(
            parent + 1,
            jm,
            T_base_world * placement if parent == 0 else placement,
            model.names[jid],
            model.effortLimit[jm.idx_v : jm.idx_v + jm.nv].copy(),
            model.velocityLimit[jm.idx_v : jm.idx_v + jm.nv].copy(),
            model.lowerPositionLimit[jm.idx_q : jm.idx_q + jm.nq].copy(),
            model.upperPositionLimit[jm.idx_q : jm.idx_q + jm.nq].copy(),
        )
        new.appendBodyToJoint(new_id, model.inertias[jid], pin.SE3.Identity())
        new.armature[new.joints[new_id].idx_v : new.joints[new_id].idx_v + jm.nv] = model.armature[
            jm.idx_v : jm.idx_v + jm.nv
        ]
    # Frames keep their order after the universe and the new root joint frame, so frame i
    # of `model` (i >= 1) is frame i + 1 here.
    for frame in list(model.frames)[1:]:
        f = pin.Frame(frame)
        f.parentJoint = frame.parentJoint + 1 if frame.parentJoint > 0 else root
        f.parentFrame = frame.parentFrame + 1 if frame.parentFrame > 0 else 1
        if frame.parentJoint == 0:
            f.placement = T_base_world * frame.placement
        new.addFrame(f, False)
    return new


def floating_robot(fixed: Robot, T_world_base: pin.SE3 | None = None, *, how: str) -> Robot:
    """The floating-base robot of a fixed-base `Robot` (see the module docstring).

    Args:
        fixed: the robot with its root body welded to the world at ``T_world_base``.
        T_world_base: that pose; identity when None.
        how: what the file says about the base, recorded in ``Robot.base``.

    Returns:
        The robot with ``nq = fixed.nq + 7``, ``nv = fixed.nv + 6``: base position
        limits infinite, base velocity limits infinite, base torque limits 0
        (`BASE_TAU_SOURCE`), no damping or friction on the base; ``joint_names`` stay
        the n joints (the free flyer is `ROOT_JOINT`).

    Raises:
        FloatingBaseError: the robot has joint couplings (not supported on a floating
            base yet).
    """
    if fixed.coupling is not None:
        raise FloatingBaseError(
            f"robot {fixed.name!r} has joint couplings {list(fixed.coupling.constraints)} and"
            " a floating base; geosyn couples joints of fixed-base robots only: load it with"
            " fixed_base=True"
        )
    model = add_free_flyer(fixed.model, T_world_base)
    inf = np.full(7, np.inf)
    q_min = np.concatenate([-inf, fixed.q_min])
    q_max = np.concatenate([inf, fixed.q_max])
    v_max = np.concatenate([np.full(6, np.inf), fixed.v_max])
    tau_max = np.concatenate([np.zeros(6), fixed.tau_max])
    model.velocityLimit = np.concatenate([np.full(6, _BIG), fixed.v_max])
    model.effortLimit = tau_max.copy()
    return replace(
        fixed,
        model=model,
        q_min=q_min,
        q_max=q_max,
        v_max=v_max,
        tau_max=tau_max,
        damping=np.concatenate([np.zeros(6), fixed.damping]),
        frictionloss=np.concatenate([np.zeros(6), fixed.frictionloss]),
        tau_max_source=(BASE_TAU_SOURCE,) * 6 + fixed.tau_max_source,
        base=f"floating: free flyer {ROOT_JOINT!r} ({how}); q on SE(3) x R^{fixed.nv}",
    )


def free_joint_pose(
    jnt_type: np.ndarray, jnt_bodyid: np.ndarray, body: tuple[np.ndarray, np.ndarray]
) -> tuple[int, pin.SE3] | None:
    """The free joint of a compiled MJCF model and its body's initial pose, if any.

    Args:
        jnt_type: (njnt,) MuJoCo joint types (``mjJNT_FREE`` is 0).
        jnt_bodyid: (njnt,) body of each joint.
        body: ``(body_pos (nbody, 3) [m], body_quat (nbody, 4) (w, x, y, z))``.

    Returns:
        ``(joint index, T_world_body)``, or None when the model has no free joint.
    """
    free = np.flatnonzero(np.asarray(jnt_type) == 0)
    if free.size == 0:
        return None
    j = int(free[0])
    b = int(jnt_bodyid[j])
    pos, quat = np.asarray(body[0][b], dtype=np.float64), np.asarray(body[1][b], dtype=np.float64)
    rotation = pin.Quaternion(quat[0], quat[1], quat[2], quat[3]).normalized().matrix()
    return j, pin.SE3(rotation, pos)
