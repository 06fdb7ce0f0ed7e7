"""MJCF export: a MuJoCo model with exactly the dynamics of a `Robot`'s Pinocchio model.

One MuJoCo body per Pinocchio joint, placed by ``model.jointPlacements``, with the joint
at the body origin, the explicit inertial of ``model.inertias`` (never inferred from
geoms), the same armature, damping and frictionloss, and a ``motor`` actuator whose ctrlrange is the torque limit.
Collision capsules are drawn as geoms that do not collide with each other. Joint couplings
(``robot.coupling``) become fixed tendons held by tendon equality constraints.
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
    robot.require_fixed_base("robot_to_mjcf (the MuJoCo twin)")
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
    damping, friction = robot.damping, robot.frictionloss

    def massless(jid: int) -> bool:
        inertia = model.inertias[jid]
        return inertia.mass == 0.0 and not np.any(np.asarray(inertia.inertia))

    def joint_line(jid: int, pos: np.ndarray, axis: np.ndarray, indent: str) -> str:
        jtype = joint_axis(model, jid)[0]
        iq, iv = model.joints[jid].idx_q, model.joints[jid].idx_v
        lo, hi = robot.q_min[iq], robot.q_max[iq]
        limited = limits and np.isfinite(lo) and np.isfinite(hi)
        rng = (
            f' limited="true" range="{mjcf_number(lo)} {mjcf_number(hi)}"'
            if limited
            else ' limited="false"'
        )
        return (
            f'{indent}  <joint name={quoteattr(model.names[jid])} type="{jtype}"'
            f' pos="{mjcf_vector(pos)}" axis="{mjcf_vector(axis)}"'
            f' armature="{mjcf_number(model.armature[iv])}" damping="{mjcf_number(damping[iv])}"'
            f' frictionloss="{mjcf_number(friction[iv])}"{rng}/>'
        )

    def body(jid: int, indent: str) -> list[str]:
        # A massless joint with one child joint and nothing attached (a MuJoCo body with
        # several joints, loaded as a chain) shares its child's MuJoCo body: MuJoCo refuses
        # moving bodies without mass. Each joint's anchor and axis are then expressed in
        # the body frame at q = 0, which MuJoCo composes in order, as Pinocchio does.
        chain = [jid]
        while (
            massless(chain[-1])
            and len(children[chain[-1]]) == 1
            and model.names[chain[-1]] not in caps_by_joint
            and model.names[chain[-1]] not in body_extra
            and ee.parentJoint != chain[-1]
        ):
            chain.append(children[chain[-1]][0])
        placement = model.jointPlacements[jid]
        quat = pin.Quaternion(placement.rotation)
        lines = [
            f'{indent}<body name={quoteattr(body_name(model, jid))} pos="{mjcf_vector(placement.translation)}"'
            f' quat="{mjcf_vector((quat.w, quat.x, quat.y, quat.z))}">'
        ]
        A = pin.SE3.Identity()
        for k, j in enumerate(chain):
            if k:
                A = A * model.jointPlacements[j]
            lines.append(joint_line(j, A.translation, A.rotation @ joint_axis(model, j)[1], indent))
        last = chain[-1]
        inner = indent
        if len(chain) > 1:  # the last joint's frame, welded inside the shared body
            inner = indent + "  "
            q_a = pin.Quaternion(A.rotation)
            lines.append(
                f'{inner}<body name={quoteattr(body_name(model, last))} pos="{mjcf_vector(A.translation)}"'
                f' quat="{mjcf_vector((q_a.w, q_a.x, q_a.y, q_a.z))}">'
            )
        inertia = model.inertias[last]
        Ic = np.asarray(inertia.inertia)
        name = model.names[last]
        if not massless(last):
            lines.append(
                f'{inner}  <inertial pos="{mjcf_vector(inertia.lever)}" mass="{mjcf_number(inertia.mass)}"'
                f' fullinertia="{mjcf_vector([Ic[0, 0], Ic[1, 1], Ic[2, 2], Ic[0, 1], Ic[0, 2], Ic[1, 2]])}"/>'
            )
        lines += [f"{inner}  {g_}" for g_ in caps_by_joint.get(name, [])]
        if ee.parentJoint == last:
            q_ee = pin.Quaternion(ee.placement.rotation)
            lines.append(
                f'{inner}  <site name={quoteattr(robot.ee_frame)} pos="{mjcf_vector(ee.placement.translation)}"'
                f' quat="{mjcf_vector((q_ee.w, q_ee.x, q_ee.y, q_ee.z))}" size="0.01"/>'
            )
        if name in body_extra:
            lines.append(f"{inner}  {body_extra[name]}")
        for c in children[last]:
            lines += body(c, inner + "  ")
        if len(chain) > 1:
            lines.append(f"{inner}</body>")
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
            *_coupling_constraints(robot, timestep),
            "  <actuator>",
            *actuators,
            "  </actuator>",
            "</mujoco>",
        ]
    )


def _coupling_constraints(robot: Robot, timestep: float) -> list[str]:
    """The robot's joint couplings as fixed tendons held by tendon equalities.

    Each dependent joint d gives ``q_d - sum_i S[d, i] z_i = c_d`` (a fixed tendon of
    length 0 at q = 0 and an equality ``length = c_d``), with the stiffest time constant
    MuJoCo accepts at this time step (``solref = 2 timestep``).
    """
    coupling = robot.coupling
    if coupling is None:
        return []
    names = coupling.joint_names
    tendons, equalities = ["  <tendon>"], ["  <equality>"]
    for d, name in enumerate(names):
        if name in coupling.independent:
            continue
        joints = [f'<joint joint={quoteattr(name)} coef="1.0"/>']
        for i, ind in enumerate(coupling.independent):
            if coupling.S[d, i] != 0.0:
                joints.append(
                    f"<joint joint={quoteattr(ind)} coef={quoteattr(mjcf_number(-coupling.S[d, i]))}/>"
                )
        tendon = f"coupling_{name}"
        tendons.append(f"    <fixed name={quoteattr(tendon)}>{''.join(joints)}</fixed>")
        equalities.append(
            f"    <tendon tendon1={quoteattr(tendon)}"
            f' polycoef="{mjcf_number(coupling.c[d])} 0 0 0 0"'
            f' solref="{mjcf_number(2.0 * timestep)} 1"/>'
        )
    return [*tendons, "  </tendon>", *equalities, "  </equality>"]
