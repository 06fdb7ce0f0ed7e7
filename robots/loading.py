"""Loading robots: built-in descriptions and any URDF or MJCF file."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np
import pinocchio as pin

from geosyn.core.errors import InvalidArgument
from geosyn.robots.errors import RobotFileError, UnknownRobot
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

#: Large limits that Pinocchio writes for joints without limits.
_NO_LIMIT = 1e10


def example_robot_data_dir() -> Path:
    """Folder of the URDFs shipped by the `example-robot-data` PyPI package.

    Raises:
        RobotFileError: the package is not installed.
    """
    site = Path(pin.__file__).resolve().parents[1]
    for base in (site, *Path(pin.__file__).resolve().parents):
        cand = base / "cmeel.prefix" / "share" / "example-robot-data" / "robots"
        if cand.is_dir():
            return cand
    raise RobotFileError(
        "example-robot-data is not installed (looked for cmeel.prefix/share/example-robot-data"
        f" under {site}); install it with `pip install example-robot-data`"
    )


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
            lo, hi = np.array([-_NO_LIMIT]), np.array([_NO_LIMIT])
        elif kind == "JointModelRevoluteUnboundedUnaligned":
            new_jm = pin.JointModelRevoluteUnaligned(_joint_axis_from_motion(model, jid))
            lo, hi = np.array([-_NO_LIMIT]), np.array([_NO_LIMIT])
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
            caps.append(CollisionCapsule(name, (0.0, 0.0, 0.0), tuple(map(float, end)), radius))
    return tuple(caps)


def _limits(model: pin.Model) -> tuple[np.ndarray, ...]:
    q_min = np.array(model.lowerPositionLimit, dtype=np.float64)
    q_max = np.array(model.upperPositionLimit, dtype=np.float64)
    q_min[q_min <= -_NO_LIMIT / 10] = -np.inf
    q_max[q_max >= _NO_LIMIT / 10] = np.inf
    # Pinocchio writes 0 when a file states no limit; treat an empty interval as unlimited.
    empty = q_max <= q_min
    q_min[empty], q_max[empty] = -np.inf, np.inf
    v_max = np.array(model.velocityLimit, dtype=np.float64)
    tau_max = np.array(model.effortLimit, dtype=np.float64)
    return q_min, q_max, v_max, tau_max


def _read_model(path: Path) -> pin.Model:
    if not path.is_file():
        raise RobotFileError(f"robot file {str(path)!r} does not exist")
    suffix = path.suffix.lower()
    try:
        if suffix == ".urdf":
            return pin.buildModelFromUrdf(str(path))
        if suffix in (".xml", ".mjcf"):
            return pin.buildModelFromMJCF(str(path))
    except (RuntimeError, ValueError) as err:
        raise RobotFileError(f"could not parse robot file {str(path)!r}: {err}") from err
    raise RobotFileError(
        f"robot file {str(path)!r} has suffix {suffix!r}; allowed: .urdf, .xml, .mjcf"
    )


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
    from geosyn.robots.errors import UnknownFrame

    model = pin.Model(model)
    if keep_joints is not None:
        unknown = [j for j in keep_joints if not model.existJointName(j)]
        if unknown:
            raise UnknownFrame(
                f"keep_joints names unknown joints {unknown}; available: {', '.join(model.names[1:])}"
            )
        lock_q = dict(lock_q or {})
        to_lock = [model.getJointId(n) for n in model.names[1:] if n not in set(keep_joints)]
        q_ref = pin.neutral(model)
        for jid in to_lock:
            jm = model.joints[jid]
            n_q = jm.nq
            if model.names[jid] in lock_q:
                val = float(lock_q[model.names[jid]])
                if not math.isfinite(val):
                    raise InvalidArgument(f"lock_q[{model.names[jid]!r}] must be finite, got {val}")
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
    g = np.asarray(gravity, dtype=np.float64)
    if g.shape != (3,) or not np.all(np.isfinite(g)):
        raise InvalidArgument(f"gravity must be a finite (3,) vector [m/s^2], got {gravity!r}")
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


def load_file(path: str | Path, **options: object) -> Robot:
    """Load a robot from a URDF (``.urdf``) or MJCF (``.xml``/``.mjcf``) file.

    Args:
        path: file path.
        **options: forwarded to `robot_from_model` (``keep_joints``, ``lock_q``,
            ``ee_frame``, ``armature``, ``gravity``, ...).

    Raises:
        RobotFileError: missing, unreadable or malformed file.
    """
    p = Path(path)
    model = _read_model(p)
    options.setdefault("name", p.stem)
    return robot_from_model(model, **options)  # type: ignore[arg-type]


# -- built-ins ------------------------------------------------------------------------


def planar_arm(
    masses: Sequence[float],
    lengths: Sequence[float],
    *,
    name: str = "planar",
    radius: float = 0.02,
    armature: float | Sequence[float] = 0.0,
    gravity: Sequence[float] = (0.0, 0.0, -9.81),
    tau_max: float = 50.0,
    v_max: float = 10.0,
) -> Robot:
    """An n-link planar arm of uniform rods, rotating about z in the horizontal plane.

    Each link is a uniform rod of mass ``m_i`` and length ``l_i`` along its x axis, with
    centre of mass at ``l_i / 2`` and inertia about its centre ``m_i l_i^2 / 12`` about y
    and z (the thin-rod value) and ``m_i r^2 / 2`` about the rod axis. Gravity points
    along -z, perpendicular to the plane of motion, so it does no work.

    Args:
        masses: (n,) link masses [kg], > 0.
        lengths: (n,) link lengths [m], > 0.
        name: robot name.
        radius: rod radius for collision capsules and axial inertia [m].
        armature: reflected rotor inertia, scalar or (n,) [kg m^2].
        gravity: (3,) gravity [m/s^2].
        tau_max: torque limit of every joint [N m].
        v_max: velocity limit of every joint [rad/s].
    """
    m = np.asarray(masses, dtype=np.float64)
    lengths_arr = np.asarray(lengths, dtype=np.float64)
    if m.ndim != 1 or m.shape != lengths_arr.shape or m.size == 0:
        raise InvalidArgument(
            f"masses and lengths must be (n,) of equal length, got {m.shape} and {lengths_arr.shape}"
        )
    for label, arr in (("masses", m), ("lengths", lengths_arr)):
        if not np.all(np.isfinite(arr)) or np.any(arr <= 0):
            raise InvalidArgument(f"{label} must be finite and > 0, got {arr.tolist()}")
    model = pin.Model()
    model.name = name
    parent = 0
    placement = pin.SE3.Identity()
    caps = []
    n = m.size
    for i in range(n):
        jname = f"joint{i + 1}"
        parent = model.addJoint(
            parent,
            pin.JointModelRZ(),
            placement,
            jname,
            np.array([tau_max]),
            np.array([v_max]),
            np.array([-_NO_LIMIT]),
            np.array([_NO_LIMIT]),
        )
        li, mi = lengths_arr[i], m[i]
        inertia = np.diag([0.5 * mi * radius**2, mi * li**2 / 12.0, mi * li**2 / 12.0])
        model.appendBodyToJoint(
            parent, pin.Inertia(mi, np.array([li / 2.0, 0.0, 0.0]), inertia), pin.SE3.Identity()
        )
        model.addFrame(
            pin.Frame(f"link{i + 1}", parent, 0, pin.SE3.Identity(), pin.FrameType.BODY), False
        )
        caps.append(CollisionCapsule(jname, (0.0, 0.0, 0.0), (float(li), 0.0, 0.0), radius))
        placement = pin.SE3(np.eye(3), np.array([li, 0.0, 0.0]))
    model.addFrame(pin.Frame("tip", parent, 0, placement, pin.FrameType.OP_FRAME), False)
    return robot_from_model(
        model,
        name=name,
        ee_frame="tip",
        armature=armature,
        gravity=gravity,
        capsules=caps,
    )


def planar2(
    m1: float = 1.0,
    m2: float = 1.0,
    l1: float = 1.0,
    l2: float = 1.0,
    **options: object,
) -> Robot:
    """The paper's 2-DoF planar arm: two uniform rods in the horizontal plane.

    Args:
        m1, m2: link masses [kg].
        l1, l2: link lengths [m].
        **options: forwarded to `planar_arm`.
    """
    options.setdefault("name", "planar2")
    return planar_arm([m1, m2], [l1, l2], **options)  # type: ignore[arg-type]


def planar3(
    masses: Sequence[float] = (1.0, 1.0, 0.5),
    lengths: Sequence[float] = (1.0, 0.8, 0.5),
    **options: object,
) -> Robot:
    """A 3-DoF planar arm of uniform rods in the horizontal plane; see `planar_arm`."""
    options.setdefault("name", "planar3")
    return planar_arm(masses, lengths, **options)  # type: ignore[arg-type]


def panda(**options: object) -> Robot:
    """7-DoF Franka Emika Panda (example-robot-data), fingers locked closed.

    Armature defaults to 0.1 kg m^2 per joint (a typical reflected rotor inertia).
    """
    options.setdefault("name", "panda")
    options.setdefault("ee_frame", "panda_hand_tcp")
    options.setdefault("armature", 0.1)
    options.setdefault("capsule_radius", 0.06)
    keep = [f"panda_joint{i}" for i in range(1, 8)]
    path = example_robot_data_dir() / "panda_description" / "urdf" / "panda.urdf"
    return load_file(path, keep_joints=keep, **options)


def talos_arm(**options: object) -> Robot:
    """TALOS left arm (example-robot-data), 7 DoF, gripper locked.

    The humanoid arm in example-robot-data closest to ARMAR-6's, used for paper Figure 2.
    """
    options.setdefault("name", "talos_arm")
    options.setdefault("ee_frame", "gripper_left_base_link")
    options.setdefault("armature", 0.1)
    options.setdefault("capsule_radius", 0.06)
    keep = [f"arm_left_{i}_joint" for i in range(1, 8)]
    path = example_robot_data_dir() / "talos_data" / "robots" / "talos_reduced.urdf"
    return load_file(path, keep_joints=keep, **options)


def ur5(**options: object) -> Robot:
    """Universal Robots UR5 (example-robot-data), 6 DoF."""
    options.setdefault("name", "ur5")
    options.setdefault("ee_frame", "tool0")
    options.setdefault("armature", 0.1)
    options.setdefault("capsule_radius", 0.06)
    path = example_robot_data_dir() / "ur_description" / "urdf" / "ur5_robot.urdf"
    return load_file(path, **options)


BUILTINS: dict[str, Callable[..., Robot]] = {
    "planar2": planar2,
    "planar3": planar3,
    "panda": panda,
    "talos_arm": talos_arm,
    "ur5": ur5,
}


def load_robot(name_or_path: str | Path, **options: object) -> Robot:
    """Load a built-in robot by name, or any URDF/MJCF file by path.

    Args:
        name_or_path: one of ``BUILTINS`` (planar2, planar3, panda, talos_arm, ur5) or a
            path to a ``.urdf`` / ``.xml`` / ``.mjcf`` file.
        **options: forwarded to the builder (e.g. ``m1=2.0`` for planar2, ``armature``,
            ``gravity``, ``keep_joints`` for files).

    Raises:
        UnknownRobot: neither a built-in name nor a path with a robot-file suffix.
        RobotFileError: the file is missing or malformed.
    """
    key = str(name_or_path)
    if key in BUILTINS:
        try:
            return BUILTINS[key](**options)
        except TypeError as err:
            raise InvalidArgument(f"bad option for robot {key!r}: {err}") from err
    if Path(key).suffix.lower() in (".urdf", ".xml", ".mjcf"):
        return load_file(key, **options)
    raise UnknownRobot(
        f"{key!r} is not a built-in robot; available: {', '.join(sorted(BUILTINS))}"
        " (or give a path to a .urdf/.xml/.mjcf file)"
    )
