"""The MuJoCo scene of a simulation: a `Robot`, payload bodies welded to its links, obstacles.

The robot part comes from `Robot.mjcf` (same inertias, armature and torque limits as the
Pinocchio model), so the MuJoCo plant and every Pinocchio-based controller share their
parameters. Payloads (`geosyn.world.Payload`) are extra bodies without joints, welded to
a link; their mass can be changed during a run (`geosyn.sim.disturbances.PayloadChange`).
Obstacles are the shapes of `geosyn.world`, as geoms in the world body
(`geosyn.sim.obstacles`): visual only by default (clearance is measured, contact is not
simulated), or, with ``contact=True``, colliding with the robot file's own collision
geometry (`geosyn.sim.collision_geoms`; the capsules for a robot built in code).
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from xml.sax.saxutils import quoteattr

import mujoco
import numpy as np
import pinocchio as pin

from geosyn.core.errors import InvalidArgument
from geosyn.core.types import Vector
from geosyn.core.validation import check_vector
from geosyn.robots.mjcf import body_name
from geosyn.robots.mjcf import mjcf_number as _f
from geosyn.robots.mjcf import mjcf_vector as _vec
from geosyn.robots.robot import Robot
from geosyn.sim.collision_geoms import CollisionGeoms, collision_geoms
from geosyn.sim.errors import UnknownBody
from geosyn.sim.obstacles import ROBOT_BIT, Clearance, ObstacleGeom, obstacle_geom
from geosyn.world import Payload, Shape
from geosyn.world.pose import quaternion_wxyz

#: Radius [m] a payload of radius 0 is drawn with (drawing only: the geom has no mass).
PAYLOAD_MARKER_RADIUS = 0.02


# -- payloads -------------------------------------------------------------------------
def link_placement(robot: Robot, name: str) -> tuple[int, pin.SE3]:
    """The joint carrying a frame and the frame's placement in that joint's frame.

    Args:
        robot: the robot.
        name: a Pinocchio frame name (link, joint or operational frame) or joint name.

    Returns:
        (joint id, placement joint-from-frame). Joint id 0 is the fixed world.

    Raises:
        UnknownBody: the name is neither a frame nor a joint; the message lists them.
    """
    model = robot.model
    if isinstance(name, str) and model.existFrame(name):
        frame = model.frames[robot.frame_id(name)]  # a joint's frame of the same name too
        return int(frame.parentJoint), pin.SE3(frame.placement)
    if isinstance(name, str) and model.existJointName(name):
        return int(model.getJointId(name)), pin.SE3.Identity()
    names = ", ".join(f.name for f in model.frames)
    raise UnknownBody(
        f"link {name!r} is not a frame or joint of robot {robot.name!r}; available: {names}"
    )


# -- the scene ------------------------------------------------------------------------
@dataclass(frozen=True)
class Scene:
    """A compiled MuJoCo model of a robot with its payloads and obstacles.

    Attributes:
        robot: the robot.
        model: the compiled MuJoCo model (owned by whoever built the scene).
        xml: its MJCF text.
        payloads: the payloads, in order.
        payload_body_ids: (P,) MuJoCo body ids of the payloads.
        obstacles: the resolved obstacles, in order.
        obstacle_geom_ids: (O,) MuJoCo geom ids of the obstacles.
        joint_body_ids: (nv,) MuJoCo body id moved by each actuated joint.
        qpos_adr: (nv,) ``qpos`` address of each joint of ``robot.joint_names``.
        dof_adr: (nv,) ``qvel`` address of each joint.
        clearance: the clearance evaluator.
    """

    robot: Robot
    model: mujoco.MjModel
    xml: str
    payloads: tuple[Payload, ...]
    payload_body_ids: np.ndarray
    obstacles: tuple[ObstacleGeom, ...]
    obstacle_geom_ids: np.ndarray
    joint_body_ids: np.ndarray
    qpos_adr: np.ndarray
    dof_adr: np.ndarray
    clearance: Clearance

    def body_names(self) -> list[str]:
        """Names of all MuJoCo bodies of the scene."""
        return [
            mujoco.mj_id2name(self.model, mujoco.mjtObj.mjOBJ_BODY, i) or ""
            for i in range(self.model.nbody)
        ]

    def resolve_body(self, name: str) -> int:
        """MuJoCo body id of a MuJoCo body, Pinocchio frame or joint name, or payload name.

        Raises:
            UnknownBody: no such name; the message lists the MuJoCo bodies and frames.
        """
        if isinstance(name, str):
            bid = mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_BODY, name)
            if bid >= 0:
                return int(bid)
            rmodel = self.robot.model
            if rmodel.existFrame(name) or rmodel.existJointName(name):
                jid, _ = link_placement(self.robot, name)
                return int(self.joint_body_ids_by_jid()[jid])
        frames = [f.name for f in self.robot.model.frames]
        raise UnknownBody(
            f"body {name!r} is not in the scene of {self.robot.name!r}; available MuJoCo bodies:"
            f" {', '.join(self.body_names())}; Pinocchio frames: {', '.join(frames)}"
        )

    def joint_body_ids_by_jid(self) -> np.ndarray:
        """(njoints,) MuJoCo body id of each Pinocchio joint (index 0: the world, body 0)."""
        rmodel = self.robot.model
        ids = [0] + [
            mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_BODY, body_name(rmodel, j))
            for j in range(1, rmodel.njoints)
        ]
        return np.array(ids, dtype=np.int64)

    def frame_point_in_body(self, name: str, point: Sequence[float] | None) -> Vector:
        """(3,) a point given in a named frame, expressed in its MuJoCo body frame [m].

        MuJoCo bodies and payload names take the point as is; a Pinocchio frame's point is
        moved by the frame's placement in its joint (= body) frame. ``None`` is the frame
        origin.
        """
        p = np.zeros(3) if point is None else check_vector(point, 3, "point")
        rmodel = self.robot.model
        if mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_BODY, name) < 0 and (
            rmodel.existFrame(name) or rmodel.existJointName(name)
        ):
            _, placement = link_placement(self.robot, name)
            return np.asarray(placement.act(p), dtype=np.float64)
        return p


def torque_range(
    scene: Scene, robot: Robot, plant: str, limits: bool
) -> tuple[np.ndarray, np.ndarray]:
    """(nv,), (nv,) torque bounds [N m] a simulation of ``scene`` clips to.

    ``plant`` ``"model"``: MuJoCo's actuator ctrlrange (with ``limits`` False, the
    actuators are made unlimited in ``scene.model`` and the range is MuJoCo's unused one);
    ``"file"``: the joint forces are clipped to ``robot.tau_max`` (+-inf without
    ``limits``). `InvalidArgument` when the model's actuators are not in joint order.
    """
    model = scene.model
    if plant == "file":  # joint forces, clipped to the robot's limits
        tau_max = np.asarray(robot.tau_max, dtype=np.float64).copy()
        return (-tau_max, tau_max) if limits else (-np.inf * tau_max, np.inf * tau_max)
    if not limits:
        model.actuator_ctrllimited[:] = 0
    act_joints = [int(model.actuator_trnid[a, 0]) for a in range(model.nu)]
    act_dof = np.array([model.jnt_dofadr[j] for j in act_joints], dtype=np.int64)
    if not np.array_equal(act_dof, scene.dof_adr):
        raise InvalidArgument(
            "the scene's actuators are not in joint order; check robot.joint_names"
        )
    return np.array(model.actuator_ctrlrange[:, 0]), np.array(model.actuator_ctrlrange[:, 1])


def _payload_body(payload: Payload, name: str, placement: pin.SE3) -> str:
    """The ``<body>`` of a payload in its carrying joint's body; ``placement`` is the
    payload frame in that body [m]."""
    pos = placement.act(np.asarray(payload.com))
    moments, axes = payload.principal_inertia()
    orientation = ""
    if payload.inertia is not None:  # a ball's inertia needs no orientation
        orientation = f' quat="{_vec(quaternion_wxyz(placement.rotation @ axes))}"'
    size = payload.radius if payload.radius > 0.0 else PAYLOAD_MARKER_RADIUS
    return (
        f'<body name={quoteattr(name)} pos="{_vec(pos)}">'
        f'<inertial pos="0 0 0"{orientation} mass="{_f(payload.mass)}"'
        f' diaginertia="{_vec(moments)}"/>'
        f'<geom name={quoteattr(name + "_geom")} type="sphere" size="{_f(size)}"'
        ' contype="0" conaffinity="0" group="1" rgba="0.95 0.6 0.1 1" mass="0"/></body>'
    )


_SKY = (
    '  <asset><texture name="sky" type="skybox" builtin="gradient" rgb1="0.93 0.95 0.98"'
    ' rgb2="0.62 0.7 0.8" width="64" height="64"/></asset>'
)


def _pedestals(robot: Robot) -> list[str]:
    """Visual cylinders from the floor up to each root joint standing above the origin."""
    model = robot.model
    out = []
    for j in range(1, model.njoints):
        if model.parents[j] != 0:
            continue
        p = np.asarray(model.jointPlacements[j].translation, dtype=np.float64)
        if p[2] > 0.02 and float(np.hypot(p[0], p[1])) < 0.05:  # a base, not a shoulder
            out.append(
                f'<geom name="pedestal{j}" type="cylinder" size="0.07"'
                f' fromto="{_vec([p[0], p[1], 0.0])} {_vec(p)}" contype="0" conaffinity="0"'
                ' group="1" rgba="0.35 0.37 0.42 1"/>'
            )
    return out


def build_scene(
    robot: Robot,
    *,
    payloads: Sequence[Payload] = (),
    obstacles: Sequence[Shape] = (),
    timestep: float = 1e-3,
    integrator: str = "implicitfast",
    gravity: Sequence[float] | None = None,
    contact: bool = False,
    limits: bool = True,
    decor: bool = False,
) -> Scene:
    """Compile the MuJoCo model of a robot with payload bodies and obstacle geoms.

    Allocates: builds MJCF text and compiles it; call once per simulation.

    Args:
        robot: the robot.
        payloads: `geosyn.world.Payload` bodies welded to links; a payload of radius 0
            is drawn as a ball of `PAYLOAD_MARKER_RADIUS`.
        obstacles: `geosyn.world` shapes, see the module doc.
        timestep: physics time step [s], > 0.
        integrator: MuJoCo integrator: Euler, RK4, implicit or implicitfast.
        gravity: (3,) gravity [m/s^2]; defaults to ``robot.gravity``.
        contact: obstacles collide with the robot and its payloads (default: visual
            only): with the robot file's own collision geometry (`geosyn.sim.collision_geoms`),
            or, for a robot without one, its capsules (warned).
        limits: finite joint position limits are enforced by MuJoCo.
        decor: add visual-only decoration for rendering: a sky, and a pedestal under the
            robot's base when its first joint is above the floor.

    Returns:
        The scene.

    Raises:
        InvalidArgument: a bad payload list, timestep, integrator or gravity.
        geosyn.world.InvalidGeometry: an obstacle is not a shape.
        UnknownBody: a payload's frame is not in the robot.
    """
    payloads = tuple(payloads)
    for i, p in enumerate(payloads):
        if not isinstance(p, Payload):
            raise InvalidArgument(f"payloads[{i}] must be a geosyn.world.Payload, got {p!r}")
    names = [p.name or f"payload{i}" for i, p in enumerate(payloads)]
    if len(set(names)) != len(names):
        raise InvalidArgument(f"payload names must be unique, got {names}")
    body_extra: dict[str, list[str]] = {}
    for p, name in zip(payloads, names, strict=True):
        jid, placement = link_placement(robot, p.frame)
        if jid == 0:
            raise InvalidArgument(
                f"payload {name!r} frame {p.frame!r} is fixed to the world; attach it to a moving link"
            )
        body_extra.setdefault(str(robot.model.names[jid]), []).append(
            _payload_body(p, name, placement)
        )
    file_geoms = collision_geoms(robot) if contact else CollisionGeoms()
    if contact and not file_geoms.from_file:
        warnings.warn(f"robot {robot.name!r}: {file_geoms.note}", RuntimeWarning, stacklevel=2)
    for joint, xml in file_geoms.bodies.items():
        body_extra[joint] = [*body_extra.get(joint, []), xml]
    obstacle_geoms = tuple(obstacle_geom(o, i, contact) for i, o in enumerate(obstacles))
    world_extra = [o.xml for o in obstacle_geoms]
    if decor:
        world_extra += _pedestals(robot)
    xml = robot.mjcf(
        gravity=gravity,
        timestep=timestep,
        integrator=integrator,
        limits=limits,
        worldbody_extra="\n    ".join(world_extra),
        body_extra={k: "".join(v) for k, v in body_extra.items()},
    )
    head = (_SKY + "\n" if decor else "") + (file_geoms.asset + "\n" if file_geoms.asset else "")
    if head:
        xml = xml.replace("  <worldbody>", head + "  <worldbody>", 1)
    try:
        model = mujoco.MjModel.from_xml_string(xml)
    except ValueError as err:
        raise InvalidArgument(f"the scene of robot {robot.name!r} does not compile: {err}") from err
    if contact:
        # Robot and payload geoms collide with obstacles only (not with each other); the
        # capsules only when the file has no geometry. body_contype/body_conaffinity (OR
        # of the body's geoms) filter the broad phase.
        for g in range(model.ngeom):
            name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g) or ""
            off = file_geoms.from_file and name.startswith("capsule")
            if model.geom_bodyid[g] != 0:
                model.geom_contype[g] = 0 if off else ROBOT_BIT
                model.geom_conaffinity[g] = 0
        for b in range(model.nbody):
            geoms = model.geom_bodyid == b
            model.body_contype[b] = np.bitwise_or.reduce(model.geom_contype[geoms], initial=0)
            model.body_conaffinity[b] = np.bitwise_or.reduce(
                model.geom_conaffinity[geoms], initial=0
            )

    def bid(name: str) -> int:
        return int(mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name))

    def jnt(name: str) -> int:
        return int(mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name))

    rmodel = robot.model
    joint_ids = [jnt(n) for n in robot.joint_names]
    return Scene(
        robot=robot,
        model=model,
        xml=xml,
        payloads=payloads,
        payload_body_ids=np.array([bid(n) for n in names], dtype=np.int64),
        obstacles=obstacle_geoms,
        obstacle_geom_ids=np.array(
            [
                mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, f"obstacle{i}")
                for i in range(len(obstacle_geoms))
            ],
            dtype=np.int64,
        ),
        joint_body_ids=np.array(
            [bid(body_name(rmodel, robot.joint_id(n))) for n in robot.joint_names], dtype=np.int64
        ),
        qpos_adr=np.array([model.jnt_qposadr[j] for j in joint_ids], dtype=np.int64),
        dof_adr=np.array([model.jnt_dofadr[j] for j in joint_ids], dtype=np.int64),
        clearance=Clearance(robot, model, obstacle_geoms),
    )


__all__ = ["PAYLOAD_MARKER_RADIUS", "Scene", "build_scene", "link_placement", "torque_range"]
