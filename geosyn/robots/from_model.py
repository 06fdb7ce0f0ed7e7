"""A `Robot` from a Pinocchio model: joint normalisation, limits and link capsules."""

from __future__ import annotations

import math
import re
import warnings
from collections.abc import Mapping, Sequence

import numpy as np
import pinocchio as pin

from geosyn.core.errors import InvalidArgument
from geosyn.core.validation import check_float, check_vector
from geosyn.robots.couplings import Coupling, LinearConstraint, linear_coupling
from geosyn.robots.errors import RobotFileError, RobotWarning, UnknownFrame
from geosyn.robots.limits import DEFAULT_TAU_MAX, ActuatorInfo, resolve_tau_max
from geosyn.robots.robot import CollisionCapsule, Robot
from geosyn.robots.validity import check_model, check_moving_mass

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
    its centre of mass; a massless link gets none.
    """
    caps: list[CollisionCapsule] = []
    children: dict[int, list[int]] = {j: [] for j in range(model.njoints)}
    for j in range(1, model.njoints):
        children[model.parents[j]].append(j)
    for j in range(1, model.njoints):
        if model.inertias[j].mass == 0.0:  # a massless link (e.g. between two joints of
            continue  # one MJCF body) has no extent of its own
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


_SENSOR = re.compile(
    r"sonar|laser|lidar|radar|camera|imu|rgbd|ultra_?sound|kinect|realsense|d435|depth"
    r"|optical|gyro|accel|livox|mid360|sensor",
    re.IGNORECASE,
)
"""Frame names never chosen as the default end-effector."""

_DIGIT = re.compile(r"finger|thumb|knuckle|jaw", re.IGNORECASE)
"""Frame names skipped by the default end-effector (one finger is not the hand)."""


def _subtree_heights(children: dict[int, list[int]], order: range) -> dict[int, int]:
    height: dict[int, int] = {}
    for node in reversed(order):
        height[node] = 1 + max((height[c] for c in children[node]), default=0)
    return height


def default_ee_frame(model: pin.Model) -> str:
    """The tip of the longest kinematic chain, never a sensor frame.

    From the root, follow the child joint with the deepest subtree; stop where two or
    more tie (a gripper's fingers, a hand's digits, legs), so a symmetric branch never
    picks one finger. On the joint reached, descend its frame tree the same way, skipping
    sensor and finger frames; ties between frames go to the one furthest from the joint.

    Args:
        model: Pinocchio model.

    Returns:
        The frame name.
    """
    children: dict[int, list[int]] = {j: [] for j in range(model.njoints)}
    for j in range(1, model.njoints):
        children[model.parents[j]].append(j)
    height = _subtree_heights(children, range(model.njoints))
    j = 0
    while children[j]:
        best = max(height[c] for c in children[j])
        top = [c for c in children[j] if height[c] == best]
        if len(top) > 1:
            break
        j = top[0]
    nf = len(model.frames)
    digit = _DIGIT if not _DIGIT.search(model.names[j]) else None  # a finger robot keeps them
    on_joint = [
        f
        for f in range(nf)
        if model.frames[f].parentJoint == j
        and not _SENSOR.search(model.frames[f].name)
        and not (digit and digit.search(model.frames[f].name))
    ]
    if not on_joint:
        return (
            str(model.names[j]) if model.existFrame(model.names[j]) else str(model.frames[0].name)
        )
    kept = set(on_joint)
    frame_children: dict[int, list[int]] = {f: [] for f in range(nf)}
    roots = []
    for f in on_joint:
        parent = model.frames[f].parentFrame
        if parent in kept and parent != f:
            frame_children[parent].append(f)
        else:
            roots.append(f)
    fheight = _subtree_heights(frame_children, range(nf))

    def pick(frames: list[int]) -> int:
        best = max(fheight[f] for f in frames)
        top = [f for f in frames if fheight[f] == best]
        return max(top, key=lambda f: (np.linalg.norm(model.frames[f].placement.translation), f))

    f = pick(roots)
    while frame_children[f]:
        f = pick(frame_children[f])
    return str(model.frames[f].name)


def _by_name(model: pin.Model, values: Mapping[str, float] | None) -> np.ndarray:
    """(nv,) per-joint values looked up by joint name (0 where absent)."""
    out = np.zeros(model.nv)
    for jid in range(1, model.njoints):
        out[model.joints[jid].idx_v] = float((values or {}).get(model.names[jid], 0.0))
    return out


def robot_from_model(
    model: pin.Model,
    *,
    name: str | None = None,
    keep_joints: Sequence[str] | None = None,
    lock_q: dict[str, float] | None = None,
    ee_frame: str | None = None,
    armature: float | Sequence[float] | None = None,
    gravity: Sequence[float] | None = None,
    capsule_radius: float = 0.04,
    capsules: Sequence[CollisionCapsule] | None = None,
    tau_max: float | Sequence[float] | Mapping[str, float] | None = None,
    file_tau_max: Mapping[str, tuple[float, str]] | None = None,
    limit_source: str = "file: URDF effort",
    default_tau_max: float = DEFAULT_TAU_MAX,
    default_v_max: float = 3.0,
    damping: Mapping[str, float] | None = None,
    frictionloss: Mapping[str, float] | None = None,
    actuators: Sequence[ActuatorInfo] = (),
    base: str = "fixed",
    source_file: str | None = None,
    couplings: Sequence[LinearConstraint] = (),
) -> Robot:
    """Turn a Pinocchio model into a `Robot`.

    Args:
        model: a fixed-base Pinocchio model (copied, not modified).
        name: robot name; defaults to ``model.name``.
        keep_joints: names of the joints to keep; every other joint is locked at the
            value in ``lock_q`` (default 0, clipped into its limits). ``None`` keeps all.
        lock_q: positions [rad or m] at which locked joints are held.
        ee_frame: end-effector frame; defaults to `default_ee_frame` (tip of the longest
            chain, never a sensor frame).
        armature: (nv,) or scalar reflected rotor inertia [kg m^2], applied on both the
            Pinocchio and the MuJoCo side; ``None`` keeps the model's (the file's).
        gravity: (3,) gravity in the world frame [m/s^2]; ``None`` keeps the model's.
        capsule_radius: radius of the automatically derived link capsules [m].
        capsules: explicit collision capsules; derived from the kinematic tree when ``None``.
        tau_max: user torque limits overriding the file: scalar, (nv,) or ``{joint: value}``
            [N m or N].
        file_tau_max: ``{joint: (limit, source)}`` stated by the file; ``None`` reads the
            model's ``effortLimit`` (> 0 and finite), labelled ``limit_source``.
        limit_source: label of limits read from ``effortLimit``.
        default_tau_max: torque limit where neither the user nor the file gives one
            [N m]; each use is reported (`RobotWarning`, ``Robot.tau_max_source``).
        default_v_max: velocity limit used where the file gives none (0) [rad/s];
            reported (`RobotWarning`).
        damping: ``{joint: viscous damping}`` [N m s/rad]; ``None`` reads the model's
            ``damping`` (a URDF's ``<dynamics damping>``), ``{}`` means none.
        frictionloss: ``{joint: dry friction}`` [N m]; ``None`` reads the model's
            ``friction`` (a URDF's ``<dynamics friction>``), ``{}`` means none.
        actuators: the actuators the file declares.
        base: how the base is fixed (see `Robot.base`).
        source_file: the file loaded.
        couplings: linear equality constraints between joints (`Robot.coupling`); a
            constraint on a locked joint is dropped (warned about when it also involves a
            kept joint).

    Returns:
        The robot.

    Raises:
        RobotFileError: unsupported joint types.
        UnknownFrame: an unknown joint or frame name (the message lists the available ones).
        InvalidArgument: wrong sizes or non-finite values.
    """
    model = pin.Model(model)
    check_model(model, source_file)  # meaningless values (any loader): refused
    if file_tau_max is None:
        file_tau_max = {}
        for jid in range(1, model.njoints):
            effort = float(model.effortLimit[model.joints[jid].idx_v])
            if math.isfinite(effort) and effort > 0:
                file_tau_max[model.names[jid]] = (effort, limit_source)

    def per_joint(values: np.ndarray) -> dict[str, float]:
        return {
            model.names[j]: float(values[model.joints[j].idx_v]) for j in range(1, model.njoints)
        }

    file_armature = per_joint(model.armature)
    if damping is None:  # the model's (a URDF's <dynamics damping>)
        damping = per_joint(model.damping)
    if frictionloss is None:  # the model's (a URDF's <dynamics friction>)
        frictionloss = per_joint(model.friction)
    if keep_joints is not None:
        model = _reduce(model, keep_joints, lock_q)
    model = _as_scalar_joints(model)
    if model.nv == 0:
        raise RobotFileError(f"robot {name or model.name!r} has no movable joints", source_file)
    if model.nq != model.nv:
        raise RobotFileError(f"model {model.name!r} has nq={model.nq} != nv={model.nv}")
    g = np.array(model.gravity.linear) if gravity is None else check_vector(gravity, 3, "gravity")
    model.gravity = pin.Motion(g, np.zeros(3))
    if armature is None:
        arm = _by_name(model, file_armature)
    else:
        try:
            arm = np.broadcast_to(np.asarray(armature, dtype=np.float64), (model.nv,)).copy()
        except (TypeError, ValueError) as err:
            raise InvalidArgument(
                f"armature must be a scalar or ({model.nv},) array of floats >= 0 [kg m^2],"
                f" got {armature!r}"
            ) from err
    if np.any(arm < 0) or not np.all(np.isfinite(arm)):
        raise InvalidArgument(f"armature must be finite and >= 0, got {armature!r}")
    model.armature = arm
    check_moving_mass(model, source_file)  # every kept joint moves some inertia
    q_min, q_max, v_max, _ = _limits(model)
    joint_names = tuple(model.names[1:])
    robot_name = name or model.name
    tau, tau_source = resolve_tau_max(
        joint_names, file_tau_max, tau_max, default_tau_max, robot_name
    )
    no_v = ~(v_max > 0) | ~np.isfinite(v_max)
    if np.any(no_v):
        warnings.warn(
            f"robot {robot_name!r}: no velocity limit in the file for joints"
            f" {[n for n, m in zip(joint_names, no_v, strict=True) if m]}; using the default"
            f" {default_v_max:g} (set default_v_max=... to change it)",
            RobotWarning,
            stacklevel=3,
        )
    v_max[no_v] = default_v_max
    model.effortLimit = tau.copy()
    model.velocityLimit = v_max.copy()
    if ee_frame is None:
        ee_frame = default_ee_frame(model)
    coupling = _coupling(joint_names, couplings, robot_name)
    robot = Robot(
        name=robot_name,
        model=model,
        joint_names=joint_names,
        q_min=q_min,
        q_max=q_max,
        v_max=v_max,
        tau_max=tau,
        ee_frame=ee_frame,
        capsules=tuple(capsules)
        if capsules is not None
        else _capsules_from_model(model, capsule_radius),
        gravity=(float(g[0]), float(g[1]), float(g[2])),
        damping=_by_name(model, damping),
        frictionloss=_by_name(model, frictionloss),
        tau_max_source=tau_source,
        actuators=tuple(actuators),
        base=base,
        source_file=source_file,
        coupling=coupling,
    )
    robot.frame_id(ee_frame)  # validates the name
    return robot


def _coupling(
    joint_names: tuple[str, ...], couplings: Sequence[LinearConstraint], robot_name: str
) -> Coupling | None:
    """The coupling of the constraints on kept joints (see `robot_from_model`)."""
    kept = set(joint_names)
    rows = [c for c in couplings if set(c.coefficients) <= kept]
    dropped = [c.name for c in couplings if set(c.coefficients) & kept and c not in rows]
    if dropped:
        warnings.warn(
            f"robot {robot_name!r}: couplings {dropped} involve locked joints and are dropped",
            RobotWarning,
            stacklevel=4,
        )
    if not rows:
        return None
    coupling = linear_coupling(joint_names, rows)
    warnings.warn(
        f"robot {robot_name!r} has joint couplings {list(coupling.constraints)}: its"
        f" {coupling.nz} independent coordinates are {list(coupling.independent)}"
        " (robot.coupling, q = S z + c); M(q) is the uncoupled tree's, use"
        " geosyn.metrics.CoupledMetric for the coupled robot's metric",
        RobotWarning,
        stacklevel=4,
    )
    return coupling


def _reduce(
    model: pin.Model, keep_joints: Sequence[str], lock_q: dict[str, float] | None
) -> pin.Model:
    """``model`` with every joint not in ``keep_joints`` locked (see `robot_from_model`)."""
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
    return pin.buildReducedModel(model, to_lock, q_ref)
