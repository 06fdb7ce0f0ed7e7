"""MJCF files through MuJoCo's own compiler: a Pinocchio model from a compiled `MjModel`.

MuJoCo resolves defaults, classes, ``<include>``, angle units, ``fromto``, inertias from
geoms, ``fusestatic`` and the rest; geosyn reads the compiled numbers (body poses including
a fixed root's, inertias, joint anchors, axes, references and ranges, armature), so its
M(q), gravity and bias torques are MuJoCo's ``qM`` / ``qfrc_bias`` on the same file.

Each MuJoCo hinge or slide joint becomes one Pinocchio joint whose frame sits at the
joint's anchor, with the body frame of MuJoCo's model (and its sites) as Pinocchio frames.
A hinge with ``ref`` != 0 is folded into its placement, so q means MuJoCo's ``qpos``.
"""

from __future__ import annotations

import warnings
from pathlib import Path
from typing import NamedTuple

import mujoco
import numpy as np
import pinocchio as pin

from geosyn.robots.couplings import LinearConstraint
from geosyn.robots.errors import RobotFileError, RobotWarning
from geosyn.robots.limits import ActuatorInfo, mjcf_actuation
from geosyn.robots.validity import check_includes

NO_LIMIT = 1e10
"""The large position limit [rad or m] written for a joint without limits (Pinocchio's)."""

_FREE, _BALL, _SLIDE, _HINGE = 0, 1, 2, 3
_AXIS_JOINTS = {
    (_HINGE, 0): pin.JointModelRX,
    (_HINGE, 1): pin.JointModelRY,
    (_HINGE, 2): pin.JointModelRZ,
    (_SLIDE, 0): pin.JointModelPX,
    (_SLIDE, 1): pin.JointModelPY,
    (_SLIDE, 2): pin.JointModelPZ,
}
_EQ_KINDS = {0: "connect", 1: "weld", 2: "joint", 3: "tendon", 4: "flex"}


class MjcfModel(NamedTuple):
    """What geosyn reads from a compiled MJCF model."""

    model: pin.Model  # Pinocchio model, joints in MuJoCo's dof order, named as in the file
    armature: dict[str, float]  # joint -> armature [kg m^2 or kg]
    damping: dict[str, float]  # joint -> viscous damping [N m s/rad or N s/m]
    frictionloss: dict[str, float]  # joint -> dry friction [N m or N]
    tau_max: dict[str, tuple[float, str]]  # joint -> (torque limit, where it came from)
    actuators: tuple[ActuatorInfo, ...]
    base: str  # "fixed", or how a free joint was welded
    gravity: np.ndarray  # (3,) [m/s^2]
    couplings: list[LinearConstraint]  # linear joint couplings (equality constraints)


def _name(m: mujoco.MjModel, kind: mujoco.mjtObj, i: int, fallback: str) -> str:
    return mujoco.mj_id2name(m, kind, i) or f"{fallback}{i}"


def _rotation(quat: np.ndarray) -> np.ndarray:
    mat = np.zeros(9)
    mujoco.mju_quat2Mat(mat, np.asarray(quat, dtype=np.float64))
    return mat.reshape(3, 3)


def compile_mjcf(path: str | Path) -> mujoco.MjModel:
    """Compile an MJCF file with MuJoCo, its includes confined to its folder first.

    Raises:
        RobotFileError: MuJoCo refuses the file (its message names the element), or an
            ``<include>`` reaches outside the file's folder (`check_includes`).
    """
    check_includes(path)
    try:
        return mujoco.MjModel.from_xml_path(str(path))
    except ValueError as err:
        raise RobotFileError(f"MuJoCo could not compile {str(path)!r}: {err}", path) from err


def _check_supported(
    m: mujoco.MjModel, joint_names: list[str], fixed_base: bool, path: object
) -> str:
    """Refuse what geosyn cannot represent; returns the base description."""
    base = "fixed"
    for j in range(m.njnt):
        body = _name(m, mujoco.mjtObj.mjOBJ_BODY, int(m.jnt_bodyid[j]), "body")
        if m.jnt_type[j] == _FREE:
            if not fixed_base:
                if j != 0 or m.body_parentid[m.jnt_bodyid[j]] != 0:
                    raise RobotFileError(
                        f"joint {joint_names[j]!r} of body {body!r} is a free joint that is"
                        " not the robot's root (the first joint, on a child of the world);"
                        " geosyn models one kinematic tree with at most one floating base:"
                        " pass fixed_base=True to weld every free joint at its initial pose",
                        path,
                    )
                base = f"MJCF free joint {joint_names[j]!r} of body {body!r}"
                continue
            base = f"free joint {joint_names[j]!r} welded at its initial pose (fixed_base=True)"
            warnings.warn(f"{path}: {base}", RobotWarning, stacklevel=4)
        elif m.jnt_type[j] == _BALL:
            raise RobotFileError(
                f"joint {joint_names[j]!r} of body {body!r} is a ball joint; geosyn supports"
                " hinge and slide joints",
                path,
            )
    if all(m.jnt_type[j] == _FREE for j in range(m.njnt)):
        raise RobotFileError(f"{path}: the model has no hinge or slide joints", path)
    return base


def _fixed_tendon(
    m: mujoco.MjModel, t: int, joint_names: list[str], where: str, path: object
) -> tuple[dict[str, float], float]:
    """``({joint: coef}, length at qpos0)`` of a fixed tendon, or refuse a spatial one."""
    coefs: dict[str, float] = {}
    for w in range(int(m.tendon_adr[t]), int(m.tendon_adr[t] + m.tendon_num[t])):
        if m.wrap_type[w] != int(mujoco.mjtWrap.mjWRAP_JOINT):
            raise RobotFileError(
                f"{where} constrains a spatial tendon (not a linear joint coupling): it"
                " closes a kinematic loop, which geosyn does not model",
                path,
            )
        joint = joint_names[int(m.wrap_objid[w])]
        coefs[joint] = coefs.get(joint, 0.0) + float(m.wrap_prm[w])
    return coefs, float(m.tendon_length0[t])


def _equalities(m: mujoco.MjModel, joint_names: list[str], path: object) -> list[LinearConstraint]:
    """The file's equality constraints as linear joint couplings, or refuse them.

    Raises:
        RobotFileError: a connect, weld, flex or distance constraint (a closed loop), a
            polynomial coupling that is not linear, or a spatial tendon; names it.
    """
    rows: list[LinearConstraint] = []
    for e in range(m.neq):
        name = _name(m, mujoco.mjtObj.mjOBJ_EQUALITY, e, "equality")
        kind = _EQ_KINDS.get(int(m.eq_type[e]), str(m.eq_type[e]))
        where = f"equality constraint {name!r} ({kind})"
        if kind not in ("joint", "tendon"):
            raise RobotFileError(
                f"{where} closes a kinematic loop; geosyn loads kinematic trees whose joints"
                " may be coupled linearly (joint or fixed-tendon equalities) only",
                path,
            )
        a = np.array(m.eq_data[e, :5], dtype=np.float64)
        if np.any(a[2:] != 0.0):
            raise RobotFileError(
                f"{where} has polycoef {a.tolist()}: a nonlinear coupling; geosyn supports"
                " linear couplings (polycoef a0 a1 0 0 0)",
                path,
            )
        if not m.eq_active0[e]:
            warnings.warn(f"{path}: {where} is inactive and ignored", RobotWarning, stacklevel=4)
            continue
        i1, i2 = int(m.eq_obj1id[e]), int(m.eq_obj2id[e])
        coefs: dict[str, float]
        if kind == "joint":
            j1 = joint_names[i1]
            q1_0 = float(m.qpos0[m.jnt_qposadr[i1]])
            coefs, rhs, pivot = {j1: 1.0}, a[0] + q1_0, j1
            if i2 >= 0:
                j2 = joint_names[i2]
                q2_0 = float(m.qpos0[m.jnt_qposadr[i2]])
                coefs[j2] = coefs.get(j2, 0.0) - a[1]
                rhs -= a[1] * q2_0
        else:
            coefs, l1_0 = _fixed_tendon(m, i1, joint_names, where, path)
            pivot = max(coefs, key=lambda j: (abs(coefs[j]), list(coefs).index(j)))
            rhs = a[0] + l1_0
            if i2 >= 0:
                coefs2, l2_0 = _fixed_tendon(m, i2, joint_names, where, path)
                for j, cf in coefs2.items():
                    coefs[j] = coefs.get(j, 0.0) - a[1] * cf
                rhs -= a[1] * l2_0
        rows.append(LinearConstraint(where, coefs, float(rhs), pivot))
    return rows


def _warn_ignored(m: mujoco.MjModel, joint_names: list[str], path: object) -> None:
    """Report what the file states that geosyn's dynamics leave out."""
    springs = [joint_names[j] for j in range(m.njnt) if m.jnt_stiffness[j] != 0]
    if springs:
        warnings.warn(
            f"{path}: joint stiffness (springs) on {springs} is not part of geosyn's model",
            RobotWarning,
            stacklevel=4,
        )
    gravcomp = [
        _name(m, mujoco.mjtObj.mjOBJ_BODY, b, "body") for b in range(m.nbody) if m.body_gravcomp[b]
    ]
    if gravcomp:
        warnings.warn(
            f"{path}: gravcomp of bodies {gravcomp} is not part of geosyn's gravity torques",
            RobotWarning,
            stacklevel=4,
        )
    limited = [
        _name(m, mujoco.mjtObj.mjOBJ_TENDON, t, "tendon")
        for t in range(m.ntendon)
        if m.tendon_limited[t] or m.tendon_stiffness[t] or m.tendon_damping[t]
    ]
    if limited:
        warnings.warn(
            f"{path}: limits, stiffness and damping of tendons {limited} are not part of"
            " geosyn's model",
            RobotWarning,
            stacklevel=4,
        )


def pinocchio_from_mjmodel(
    m: mujoco.MjModel, *, fixed_base: bool = False, path: object = None
) -> MjcfModel:
    """The Pinocchio model of a compiled MuJoCo model (kinematic tree, inertias, limits).

    Args:
        m: compiled MuJoCo model.
        fixed_base: weld free joints at their initial pose. Without it a free joint on
            the root body (the first joint) is left out of the model, welded at its
            initial pose with the root body's inertia on the world, for
            `geosyn.robots.free_flyer.floating_robot` to free; ``base`` names it.
        path: the file, for messages.

    Returns:
        The model and the per-joint properties read from the file.

    Raises:
        RobotFileError: a free joint other than the root's (without ``fixed_base``), a
            ball joint, an equality
            constraint that is not a linear joint coupling, or no joints; the message
            names the joint or constraint.
    """
    joint_names = [_name(m, mujoco.mjtObj.mjOBJ_JOINT, j, "joint") for j in range(m.njnt)]
    base = _check_supported(m, joint_names, fixed_base, path)
    couplings = _equalities(m, joint_names, path)
    _warn_ignored(m, joint_names, path)
    model = pin.Model()
    model.name = m.names[: m.names.find(b"\0")].decode() if m.names else "mjcf"
    disabled = m.opt.disableflags & int(mujoco.mjtDisableBit.mjDSBL_GRAVITY)
    gravity = np.zeros(3) if disabled else np.array(m.opt.gravity, dtype=np.float64)
    model.gravity = pin.Motion(gravity, np.zeros(3))
    floating_body = int(m.jnt_bodyid[0]) if m.njnt and m.jnt_type[0] == _FREE else -1
    owner = [0] * m.nbody  # Pinocchio joint carrying each body
    X_owner = [pin.SE3.Identity()] * m.nbody  # owner joint frame -> body frame
    joint_frame = {0: 0}
    armature: dict[str, float] = {}
    damping: dict[str, float] = {}
    friction: dict[str, float] = {}
    for b in range(1, m.nbody):
        p = int(m.body_parentid[b])
        X = X_owner[p] * pin.SE3(_rotation(m.body_quat[b]), np.array(m.body_pos[b]))
        parent = owner[p]
        for j in range(int(m.body_jntadr[b]), int(m.body_jntadr[b] + m.body_jntnum[b])):
            kind = int(m.jnt_type[j])
            if kind == _FREE:
                continue
            anchor = np.array(m.jnt_pos[j], dtype=np.float64)
            axis = np.array(m.jnt_axis[j], dtype=np.float64)
            ref = float(m.qpos0[m.jnt_qposadr[j]])
            if kind == _HINGE:
                offset = pin.SE3(pin.AngleAxis(-ref, axis).matrix(), anchor)
            else:
                offset = pin.SE3(np.eye(3), anchor - ref * axis)
            unit = [i for i in range(3) if axis[i] == 1.0]
            if unit and np.count_nonzero(axis) == 1:
                jm = _AXIS_JOINTS[(kind, unit[0])]()
            elif kind == _HINGE:
                jm = pin.JointModelRevoluteUnaligned(axis)
            else:
                jm = pin.JointModelPrismaticUnaligned(axis)
            lo, hi = m.jnt_range[j] if m.jnt_limited[j] else (-NO_LIMIT, NO_LIMIT)
            name = joint_names[j]
            parent = model.addJoint(
                parent,
                jm,
                X * offset,
                name,
                np.zeros(1),
                np.zeros(1),
                np.array([float(lo)]),
                np.array([float(hi)]),
            )
            joint_frame[parent] = model.addJointFrame(parent, joint_frame[owner[p]])
            dof = int(m.jnt_dofadr[j])
            armature[name] = float(m.dof_armature[dof])
            damping[name] = float(m.dof_damping[dof])
            friction[name] = float(m.dof_frictionloss[dof])
            X = pin.SE3(np.eye(3), -anchor)
        owner[b], X_owner[b] = parent, X
        # A floating root body's inertia is kept on the world (the free flyer takes it,
        # `geosyn.robots.free_flyer`); a welded one's is dropped (it never moves).
        if (parent != 0 or (b == floating_body and not fixed_base)) and m.body_mass[b] > 0:
            R = _rotation(m.body_iquat[b])
            inertia = pin.Inertia(
                float(m.body_mass[b]),
                np.array(m.body_ipos[b], dtype=np.float64),
                R @ np.diag(m.body_inertia[b]) @ R.T,
            )
            model.appendBodyToJoint(parent, inertia, X)
        body = _name(m, mujoco.mjtObj.mjOBJ_BODY, b, "body")
        model.addFrame(pin.Frame(body, parent, joint_frame[parent], X, pin.FrameType.BODY), False)
    for s in range(m.nsite):
        b = int(m.site_bodyid[s])
        X = X_owner[b] * pin.SE3(_rotation(m.site_quat[s]), np.array(m.site_pos[s]))
        name = _name(m, mujoco.mjtObj.mjOBJ_SITE, s, "site")
        if not model.existFrame(name):
            frame = pin.Frame(name, owner[b], joint_frame[owner[b]], X, pin.FrameType.OP_FRAME)
            model.addFrame(frame, False)
    for jid in range(1, model.njoints):
        model.armature[model.joints[jid].idx_v] = armature[model.names[jid]]
    tau, actuators = mjcf_actuation(m, joint_names)
    return MjcfModel(model, armature, damping, friction, tau, actuators, base, gravity, couplings)
