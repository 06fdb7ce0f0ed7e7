"""MJCF export: a MuJoCo model with exactly the dynamics of a `Robot`'s Pinocchio model.

One MuJoCo body per Pinocchio joint, placed by ``model.jointPlacements``, with the joint
at the body origin, the explicit inertial of ``model.inertias`` (never inferred from
geoms), the same armature, and a ``motor`` actuator whose ctrlrange is the torque limit.
Collision capsules are drawn as geoms that do not collide with each other.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING
from xml.sax.saxutils import quoteattr

import numpy as np
import pinocchio as pin

from geosyn.core.errors import InvalidArgument
from geosyn.core.validation import check_choice, check_positive, check_vector

if TYPE_CHECKING:
    from geosyn.robots.robot import Robot

_AXES = {"X": (1.0, 0.0, 0.0), "Y": (0.0, 1.0, 0.0), "Z": (0.0, 0.0, 1.0)}
_INTEGRATORS = ("Euler", "RK4", "implicit", "implicitfast")


def mjcf_number(x: float) -> str:
    """A float in MJCF text at full precision (round-trips exactly)."""
    return repr(float(x))


def mjcf_vector(v: Sequence[float] | np.ndarray) -> str:
    """A vector in MJCF text: space-separated full-precision floats."""
    return " ".join(mjcf_number(x) for x in np.asarray(v, dtype=np.float64).ravel())


def joint_axis(model: pin.Model, jid: int) -> tuple[str, np.ndarray]:
    """MuJoCo joint type (``hinge`` or ``slide``) and (3,) unit axis in the joint frame."""
    jm = model.joints[jid]
    kind = jm.shortname()
    if kind in ("JointModelRevoluteUnaligned", "JointModelPrismaticUnaligned"):
        axis = np.asarray(jm.extract().axis, dtype=np.float64)
    elif kind[-1] in _AXES and kind[:-1] in ("JointModelR", "JointModelP"):
        axis = np.array(_AXES[kind[-1]])
    else:
        raise InvalidArgument(f"joint {model.names[jid]!r} of type {kind} has no MJCF export")
    return ("slide" if "Prismatic" in kind or kind.startswith("JointModelP") else "hinge"), axis


def body_name(model: pin.Model, jid: int) -> str:
    """Name of the MuJoCo body of joint ``jid``: its first Pinocchio BODY frame, else the joint's."""
    for frame in model.frames:
        if frame.parentJoint == jid and frame.type == pin.FrameType.BODY:
            return str(frame.name)
    return f"{model.names[jid]}_body"


def robot_to_mjcf(
    robot: Robot,
    *,
    gravity: Sequence[float] | None = None,
    timestep: float = 0.001,
    integrator: str = "implicitfast",
    limits: bool = True,
    worldbody_extra: str = "",
    body_extra: dict[str, str] | None = None,
) -> str:
    """MJCF text of a MuJoCo model with the same dynamics as ``robot.model``.

    Args:
        robot: the robot.
        gravity: (3,) gravity [m/s^2]; defaults to ``robot.gravity``.
        timestep: physics time step [s], > 0.
        integrator: one of Euler, RK4, implicit, implicitfast.
        limits: whether finite joint position limits are enforced by MuJoCo.
        worldbody_extra: MJCF elements appended inside ``<worldbody>`` (obstacles, ...).
        body_extra: MJCF elements appended inside the body of a joint, keyed by the
            Pinocchio joint name (payloads, ...).

    Returns:
        The MJCF document.

    Raises:
        InvalidArgument: bad ``gravity``, ``timestep`` or ``integrator``, or
            ``body_extra`` naming an unknown joint.
    """
    model = robot.model
    g = check_vector(robot.gravity if gravity is None else gravity, 3, "gravity")
    timestep = check_positive(timestep, "timestep", unit="s")
    check_choice(integrator, _INTEGRATORS, "integrator")
    body_extra = dict(body_extra or {})
    unknown = [k for k in body_extra if not model.existJointName(k)]
    if unknown:
        raise InvalidArgument(
            f"body_extra names unknown joints {unknown}; available: {', '.join(model.names[1:])}"
        )

    children: dict[int, list[int]] = {j: [] for j in range(model.njoints)}
    for j in range(1, model.njoints):
        children[model.parents[j]].append(j)
    caps_by_joint: dict[str, list[str]] = {}
    for i, c in enumerate(robot.capsules):
        geom = (
            f'<geom name="capsule{i}" type="capsule" fromto="{mjcf_vector(c.p0)} {mjcf_vector(c.p1)}"'
            f' size="{mjcf_number(c.radius)}" contype="0" conaffinity="0" group="1"'
            ' rgba="0.55 0.6 0.7 1"/>'
        )
        caps_by_joint.setdefault(c.joint, []).append(geom)
    ee = model.frames[robot.frame_id(robot.ee_frame)]

    def body(jid: int, indent: str) -> list[str]:
        placement = model.jointPlacements[jid]
        quat = pin.Quaternion(placement.rotation)
        wxyz = (quat.w, quat.x, quat.y, quat.z)
        inertia = model.inertias[jid]
        Ic = np.asarray(inertia.inertia)
        name = model.names[jid]
        jtype, axis = joint_axis(model, jid)
        iq, iv = model.joints[jid].idx_q, model.joints[jid].idx_v
        lo, hi = robot.q_min[iq], robot.q_max[iq]
        limited = limits and np.isfinite(lo) and np.isfinite(hi)
        rng = (
            f' limited="true" range="{mjcf_number(lo)} {mjcf_number(hi)}"'
            if limited
            else ' limited="false"'
        )
        lines = [
            f'{indent}<body name={quoteattr(body_name(model, jid))} pos="{mjcf_vector(placement.translation)}"'
            f' quat="{mjcf_vector(wxyz)}">',
            f'{indent}  <joint name={quoteattr(name)} type="{jtype}" axis="{mjcf_vector(axis)}"'
            f' armature="{mjcf_number(model.armature[iv])}" damping="0" frictionloss="0"{rng}/>',
            f'{indent}  <inertial pos="{mjcf_vector(inertia.lever)}" mass="{mjcf_number(inertia.mass)}"'
            f' fullinertia="{mjcf_vector([Ic[0, 0], Ic[1, 1], Ic[2, 2], Ic[0, 1], Ic[0, 2], Ic[1, 2]])}"/>',
        ]
        lines += [f"{indent}  {g_}" for g_ in caps_by_joint.get(name, [])]
        if ee.parentJoint == jid:
            q_ee = pin.Quaternion(ee.placement.rotation)
            lines.append(
                f'{indent}  <site name={quoteattr(robot.ee_frame)} pos="{mjcf_vector(ee.placement.translation)}"'
                f' quat="{mjcf_vector((q_ee.w, q_ee.x, q_ee.y, q_ee.z))}" size="0.01"/>'
            )
        if name in body_extra:
            lines.append(f"{indent}  {body_extra[name]}")
        for c in children[jid]:
            lines += body(c, indent + "  ")
        lines.append(f"{indent}</body>")
        return lines

    tree: list[str] = []
    for child in children[0]:
        tree += body(child, "    ")
    actuators = [
        f'    <motor name={quoteattr(n + "_motor")} joint={quoteattr(n)} gear="1"'
        f' ctrllimited="true" ctrlrange="{mjcf_number(-t)} {mjcf_number(t)}"/>'
        for n, t in zip(robot.joint_names, robot.tau_max, strict=True)
    ]
    return "\n".join(
        [
            f"<mujoco model={quoteattr(robot.name)}>",
            '  <compiler angle="radian" inertiafromgeom="false" autolimits="false"/>',
            f'  <option timestep="{mjcf_number(timestep)}" gravity="{mjcf_vector(g)}" integrator="{integrator}"/>',
            '  <visual><global offwidth="1280" offheight="960"/></visual>',
            "  <worldbody>",
            '    <light pos="0 0 4" dir="0 0 -1" directional="true"/>',
            '    <geom name="floor" type="plane" size="3 3 0.1" pos="0 0 -0.01" rgba="0.9 0.9 0.9 1"'
            ' contype="0" conaffinity="0"/>',
            *tree,
            *(["    " + worldbody_extra] if worldbody_extra else []),
            "  </worldbody>",
            "  <actuator>",
            *actuators,
            "  </actuator>",
            "</mujoco>",
        ]
    )
