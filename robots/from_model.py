"""A `Robot` from a Pinocchio model: joint normalisation, limits and link capsules."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import pinocchio as pin

from geosyn.core.errors import InvalidArgument
from geosyn.core.validation import check_float, check_vector
from geosyn.robots.errors import RobotFileError, UnknownFrame
from geosyn.robots.robot import CollisionCapsule, Robot

#: Joint types geosyn accepts after loading (one coordinate each, nq == nv).
_SCALAR_JOINTS = {
    "JointModelRX",
    "JointModelRY",
    "JointModelRZ",
    "JointModelRevoluteUnaligned",
    "JointModelPX",
    "JointModelPY",
    "JointModelPZ",
    "JointModelPrismaticUnaligned",
}
_UNBOUNDED = {
    "JointModelRUBX": pin.JointModelRX,
    "JointModelRUBY": pin.JointModelRY,
    "JointModelRUBZ": pin.JointModelRZ,
}

NO_LIMIT = 1e10
"""The large position limit [rad or m] Pinocchio writes for a joint without limits."""


def _joint_axis_from_motion(model: pin.Model, jid: int) -> np.ndarray:
    """(3,) rotation axis of a one-DoF revolute joint, read from its motion subspace.

    Pinocchio does not expose the axis of ``JointModelRevoluteUnboundedUnaligned`` in
    Python; the joint's spatial velocity for a unit joint rate (all others zero) is it.
    """
    data = model.createData()
    v = np.zeros(model.nv)
    v[model.joints[jid].idx_v] = 1.0
    pin.forwardKinematics(model, data, pin.neutral(model), v)
    return np.array(data.v[jid].angular, dtype=np.float64)


def _as_scalar_joints(model: pin.Model) -> pin.Model:
    """Rebuild a model with continuous (unbounded) joints turned into plain revolute joints.

    Pinocchio loads URDF continuous joints as ``JointModelRUB*`` with a (cos, sin) pair, so
    nq != nv. geosyn's configuration space uses one angle per joint (no position limit).
    """
    names = [j.shortname() for j in model.joints[1:]]
    if all(n in _SCALAR_JOINTS for n in names):
        return model
    new = pin.Model()
    new.name = model.name
    new.gravity = model.gravity
    for jid in range(1, model.njoints):
        jm = model.joints[jid]
        kind = jm.shortname()
        iq, iv = jm.idx_q, jm.idx_v
        if kind in _UNBOUNDED:
            new_jm = _UNBOUNDED[kind]()
            lo, hi = np.array([-NO_LIMIT]), np.array([NO_LIMIT])
        elif kind == "JointModelRevoluteUnboundedUnaligned":
            new_jm = pin.JointModelRevoluteUnaligned(_joint_axis_from_motion(model, jid))
            lo, hi = np.array([-NO_LIMIT]), np.array([NO_LIMIT])
        elif kind in _SCALAR_JOINTS:
            new_jm = jm
            lo = model.lowerPositionLimit[iq : iq + 1].copy()
            hi = model.upperPositionLimit[iq : iq + 1].copy()
        else:
            raise RobotFileError(
                f"joint {model.names[jid]!r} has type {kind}; geosyn supports revolute,"
                " continuous and prismatic joints of a fixed-base robot"
            )
        new_id = new.addJoint(
            model.parents[jid],
            new_jm,
            model.jointPlacements[jid],
            model.names[jid],
            model.effortLimit[iv : iv + 1].copy(),
            model.velocityLimit[iv : iv + 1].copy(),
            lo,
            hi,
        )
        new.appendBodyToJoint(new_id, model.inertias[jid], pin.SE3.Identity())
        new.armature[new.joints[new_id].idx_v] = model.armature[iv]
    for frame in list(model.frames)[1:]:
        new.addFrame(pin.Frame(frame), False)
    return new


def _capsules_from_model(model: pin.Model, radius: float) -> tuple[CollisionCapsule, ...]:
    """One capsule per link, from the joint origin to the child joint (or the com).

    A simple, geometry-free approximation used for obstacle terms and drawing: the segment
    joins a joint's origin to each child joint's origin; a leaf body gets a segment to twice
    its centre of mass.
    """
    caps: list[CollisionCapsule] = []
    children: dict[int, list[int]] = {j: [] for j in range(model.njoints)}
    for j in range(1, model.njoints):
        children[model.parents[j]].append(j)
    for j in range(1, model.njoints):
        name = model.names[j]
        ends = [np.asarray(model.jointPlacements[c].translation) for c in children[j]]
        if not ends:
            ends = [2.0 * np.asarray(model.inertias[j].lever)]
        for end in ends:
            if float(np.linalg.norm(end)) < 1e-6:
                continue
            tip = (float(end[0]), float(end[1]), float(end[2]))
            caps.append(CollisionCapsule(name, (0.0, 0.0, 0.0), tip, radius))
    return tuple(caps)


def _limits(model: pin.Model) -> tuple[np.ndarray, ...]:
    q_min = np.array(model.lowerPositionLimit, dtype=np.float64)
    q_max = np.array(model.upperPositionLimit, dtype=np.float64)
    q_min[q_min <= -NO_LIMIT / 10] = -np.inf
    q_max[q_max >= NO_LIMIT / 10] = np.inf
    # Pinocchio writes 0 when a file states no limit; treat an empty interval as unlimited.
    empty = q_max <= q_min
    q_min[empty], q_max[empty] = -np.inf, np.inf
    v_max = np.array(model.velocityLimit, dtype=np.float64)
    tau_max = np.array(model.effortLimit, dtype=np.float64)
    return q_min, q_max, v_max, tau_max


def robot_from_model(
    model: pin.Model,
    *,
    name: str | None = None,
    keep_joints: Sequence[str] | None = None,
    lock_q: dict[str, float] | None = None,
    ee_frame: str | None = None,
    armature: float | Sequence[float] = 0.0,
    gravity: Sequence[float] = (0.0, 0.0, -9.81),
    capsule_radius: float = 0.04,
    capsules: Sequence[CollisionCapsule] | None = None,
    default_tau_max: float = 100.0,
    default_v_max: float = 3.0,
) -> Robot:
    """Turn a Pinocchio model into a `Robot`.

    Args:
        model: a fixed-base Pinocchio model (copied, not modified).
        name: robot name; defaults to ``model.name``.
        keep_joints: names of the joints to keep; every other joint is locked at the
            value in ``lock_q`` (default 0, clipped into its limits). ``None`` keeps all.
        lock_q: positions [rad or m] at which locked joints are held.
        ee_frame: end-effector frame; defaults to the last frame of the model.
        armature: (nv,) or scalar reflected rotor inertia [kg m^2], applied on both the
            Pinocchio and the MuJoCo side.
        gravity: (3,) gravity in the world frame [m/s^2].
        capsule_radius: radius of the automatically derived link capsules [m].
        capsules: explicit collision capsules; derived from the kinematic tree when ``None``.
        default_tau_max: torque limit used where the file gives none (0) [N m].
        default_v_max: velocity limit used where the file gives none (0) [rad/s].

    Returns:
        The robot.

    Raises:
        RobotFileError: unsupported joint types.
        UnknownFrame: an unknown joint or frame name (the message lists the available ones).
        InvalidArgument: wrong sizes or non-finite values.
    """
    model = pin.Model(model)
    if keep_joints is not None:
        unknown = [j for j in keep_joints if not model.existJointName(j)]
        if unknown:
            available = list(model.names[1:])
            raise UnknownFrame(
                f"keep_joints names unknown joints {unknown}; available: {', '.join(available)}",
                unknown[0],
                available,
            )
        lock_q = dict(lock_q or {})
        to_lock = [model.getJointId(n) for n in model.names[1:] if n not in set(keep_joints)]
        q_ref = pin.neutral(model)
        for jid in to_lock:
            jm = model.joints[jid]
            n_q = jm.nq
            if model.names[jid] in lock_q:
                val = check_float(lock_q[model.names[jid]], f"lock_q[{model.names[jid]!r}]")
                if n_q == 2:  # continuous joint stored as (cos, sin)
                    q_ref[jm.idx_q : jm.idx_q + 2] = (math.cos(val), math.sin(val))
                else:
                    q_ref[jm.idx_q] = val
            elif n_q == 1:
                lo, hi = model.lowerPositionLimit[jm.idx_q], model.upperPositionLimit[jm.idx_q]
                q_ref[jm.idx_q] = float(np.clip(0.0, lo, hi)) if lo <= hi else 0.0
        model = pin.buildReducedModel(model, to_lock, q_ref)
    model = _as_scalar_joints(model)
    if model.nq != model.nv:
        raise RobotFileError(f"model {model.name!r} has nq={model.nq} != nv={model.nv}")
    g = check_vector(gravity, 3, "gravity")
    model.gravity = pin.Motion(g, np.zeros(3))
    arm = np.broadcast_to(np.asarray(armature, dtype=np.float64), (model.nv,)).copy()
    if np.any(arm < 0) or not np.all(np.isfinite(arm)):
        raise InvalidArgument(f"armature must be finite and >= 0, got {armature!r}")
    model.armature = arm
    q_min, q_max, v_max, tau_max = _limits(model)
    tau_max[tau_max <= 0] = default_tau_max
    v_max[v_max <= 0] = default_v_max
    model.effortLimit = tau_max.copy()
    model.velocityLimit = v_max.copy()
    if ee_frame is None:
        ee_frame = model.frames[len(model.frames) - 1].name
    robot = Robot(
        name=name or model.name,
        model=model,
        joint_names=tuple(model.names[1:]),
        q_min=q_min,
        q_max=q_max,
        v_max=v_max,
        tau_max=tau_max,
        ee_frame=ee_frame,
        capsules=tuple(capsules)
        if capsules is not None
        else _capsules_from_model(model, capsule_radius),
        gravity=(float(g[0]), float(g[1]), float(g[2])),
    )
    robot.frame_id(ee_frame)  # validates the name
    return robot
