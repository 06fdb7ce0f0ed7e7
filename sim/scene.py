"""The MuJoCo scene of a simulation: a `Robot`, payload bodies welded to its links, obstacles.

The robot part comes from `Robot.mjcf` (same inertias, armature and torque limits as the
Pinocchio model), so the MuJoCo plant and every Pinocchio-based controller share their
parameters. Payloads are extra bodies without joints, welded to a link; their mass can be
changed during a run (`geosyn.sim.disturbances.PayloadChange`). Obstacles are geoms in the
world body: visual only by default (clearance is measured, contact is not simulated), or
colliding with the robot's capsules when ``contact=True``.

Obstacles are duck-typed on their attributes, so the shapes of `geosyn.metrics.shaping`
(or any object with the same fields) are accepted:

=============  ==========================================  ===================
shape          attributes                                  MuJoCo geom
=============  ==========================================  ===================
Sphere         ``center`` (3,) [m], ``radius`` [m]         ``sphere``
Box            ``center``, ``half_extents`` (3,) [m],      ``box``
               ``rotation`` (3, 3) world-from-box
Capsule        ``p0``, ``p1`` (3,) [m], ``radius`` [m]     ``capsule``
HalfSpace      ``normal`` (3,), ``offset`` [m]             ``plane``
=============  ==========================================  ===================

A HalfSpace is the solid ``{x : normal . x <= offset}`` (unit normal pointing into free
space), so its signed distance is ``normal . x - offset`` after normalising ``normal``.

Minimum clearance: the robot's collision spheres (`Robot.collision_spheres`) are placed
with the MuJoCo body poses (a MuJoCo body frame is its Pinocchio joint frame) and their
analytic signed distances to the obstacles are taken, minus the sphere radius. This is the
geometry the obstacle shaping terms see; negative means penetration.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any
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
from geosyn.sim.errors import UnknownBody, UnsupportedObstacle

#: Collision bit of the robot's and payloads' geoms when ``contact=True``.
_ROBOT_BIT = 2


# -- payloads -------------------------------------------------------------------------
@dataclass(frozen=True)
class Payload:
    """A solid sphere welded to a link of the robot (an object held by the gripper, ...).

    Attributes:
        frame: Pinocchio frame or joint name of the link that carries it.
        mass: initial mass m0 [kg], >= 0.
        offset: (3,) position of the payload's centre in ``frame`` [m].
        radius: sphere radius [m], > 0; sets the inertia (2/5 m r^2) and the drawing.
        name: MuJoCo body name; defaults to ``payload<i>`` (i = index in the scene).
    """

    frame: str
    mass: float
    offset: tuple[float, float, float] = (0.0, 0.0, 0.0)
    radius: float = 0.03
    name: str | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.frame, str):
            raise InvalidArgument(f"Payload frame must be a frame name, got {self.frame!r}")
        if not (np.isfinite(self.mass) and self.mass >= 0.0):
            raise InvalidArgument(f"Payload mass must be finite and >= 0 [kg], got {self.mass!r}")
        if not (np.isfinite(self.radius) and self.radius > 0.0):
            raise InvalidArgument(f"Payload radius must be > 0 [m], got {self.radius!r}")
        off = check_vector(self.offset, 3, "Payload offset")
        object.__setattr__(self, "offset", tuple(map(float, off)))

    def inertia(self, mass: float | None = None) -> Vector:
        """(3,) principal moments of inertia about the centre [kg m^2] for ``mass`` [kg]."""
        m = self.mass if mass is None else float(mass)
        return np.full(3, 0.4 * m * self.radius**2)


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
        frame = model.frames[model.getFrameId(name)]
        return int(frame.parentJoint), pin.SE3(frame.placement)
    if isinstance(name, str) and model.existJointName(name):
        return int(model.getJointId(name)), pin.SE3.Identity()
    names = ", ".join(f.name for f in model.frames)
    raise UnknownBody(
        f"link {name!r} is not a frame or joint of robot {robot.name!r}; available: {names}"
    )


# -- obstacles ------------------------------------------------------------------------
def _rotation_quat(R: np.ndarray) -> np.ndarray:
    q = pin.Quaternion(np.asarray(R, dtype=np.float64))
    q.normalize()
    return np.array([q.w, q.x, q.y, q.z])


def _quat_z_to(n: np.ndarray) -> np.ndarray:
    """(4,) wxyz quaternion rotating the z axis onto the unit vector ``n``."""
    q = pin.Quaternion.FromTwoVectors(np.array([0.0, 0.0, 1.0]), n)
    return np.array([q.w, q.x, q.y, q.z])


@dataclass(frozen=True)
class ObstacleGeom:
    """An obstacle resolved to a MuJoCo geom and an analytic signed distance.

    Attributes:
        kind: ``sphere``, ``box``, ``capsule`` or ``halfspace``.
        params: the shape's numbers (see `signed_distance`).
        xml: the ``<geom>`` element.
    """

    kind: str
    params: tuple[np.ndarray, ...]
    xml: str

    def signed_distance(self, points: np.ndarray) -> np.ndarray:
        """Signed distance of points to the shape [m], negative inside.

        Args:
            points: (S, 3) points in the world frame [m].

        Returns:
            (S,) distances [m].
        """
        p = np.asarray(points, dtype=np.float64)
        if self.kind == "sphere":
            c, r = self.params
            return np.linalg.norm(p - c, axis=1) - r
        if self.kind == "box":
            c, h, R = self.params
            local = np.abs((p - c) @ R) - h  # R is world-from-box: local = R^T (p - c)
            outside = np.linalg.norm(np.maximum(local, 0.0), axis=1)
            inside = np.minimum(local.max(axis=1), 0.0)
            return outside + inside
        if self.kind == "capsule":
            a, b, r = self.params
            ab = b - a
            denom = float(ab @ ab)
            s = np.zeros(len(p)) if denom == 0.0 else np.clip((p - a) @ ab / denom, 0.0, 1.0)
            return np.linalg.norm(p - (a + s[:, None] * ab), axis=1) - r
        n, off = self.params
        return p @ n - off


def obstacle_geom(obstacle: Any, index: int, contact: bool = False) -> ObstacleGeom:
    """Resolve an obstacle object (duck-typed, see the module doc) to an `ObstacleGeom`.

    Args:
        obstacle: a Sphere, Box, Capsule or HalfSpace-like object.
        index: index in the scene, used for the geom name ``obstacle<index>``.
        contact: whether the geom collides with the robot.

    Raises:
        UnsupportedObstacle: the object has none of the known sets of attributes.
        InvalidArgument: a field has the wrong shape or value.
    """
    name = f"obstacle{index}"
    flags = f'contype="0" conaffinity="{_ROBOT_BIT if contact else 0}"'
    style = 'rgba="0.85 0.3 0.25 0.6" group="2"'
    head = f"<geom name={quoteattr(name)} {flags} {style}"
    kind_name = type(obstacle).__name__
    if hasattr(obstacle, "normal") and hasattr(obstacle, "offset"):
        n = check_vector(obstacle.normal, 3, f"{name} ({kind_name}) normal")
        norm = float(np.linalg.norm(n))
        if norm == 0.0:
            raise InvalidArgument(f"{name} ({kind_name}) normal must be non-zero, got {n}")
        off = float(obstacle.offset)
        n = n / norm
        off = off / norm
        pos = n * off
        xml = f'{head} type="plane" size="1.5 1.5 0.02" pos="{_vec(pos)}" quat="{_vec(_quat_z_to(n))}"/>'
        return ObstacleGeom("halfspace", (n, np.float64(off)), xml)
    if hasattr(obstacle, "half_extents"):
        c = check_vector(obstacle.center, 3, f"{name} ({kind_name}) center")
        h = check_vector(obstacle.half_extents, 3, f"{name} ({kind_name}) half_extents")
        if np.any(h < 0):
            raise InvalidArgument(f"{name} ({kind_name}) half_extents must be >= 0 [m], got {h}")
        rot = getattr(obstacle, "rotation", None)
        R = np.eye(3) if rot is None else np.asarray(rot, dtype=np.float64)
        if (
            R.shape != (3, 3)
            or not np.allclose(R.T @ R, np.eye(3), atol=1e-8)
            or np.linalg.det(R) < 0
        ):
            raise InvalidArgument(
                f"{name} ({kind_name}) rotation must be a (3, 3) rotation matrix, got {rot!r}"
            )
        size = np.maximum(h, 1e-4)  # MuJoCo needs positive sizes; the distance uses h
        xml = f'{head} type="box" size="{_vec(size)}" pos="{_vec(c)}" quat="{_vec(_rotation_quat(R))}"/>'
        return ObstacleGeom("box", (c, h, R), xml)
    if hasattr(obstacle, "p0") and hasattr(obstacle, "p1") and hasattr(obstacle, "radius"):
        a = check_vector(obstacle.p0, 3, f"{name} ({kind_name}) p0")
        b = check_vector(obstacle.p1, 3, f"{name} ({kind_name}) p1")
        r = float(obstacle.radius)
        if not (np.isfinite(r) and r > 0):
            raise InvalidArgument(f"{name} ({kind_name}) radius must be > 0 [m], got {r}")
        if np.allclose(a, b):
            xml = f'{head} type="sphere" size="{_f(r)}" pos="{_vec(a)}"/>'
        else:
            xml = f'{head} type="capsule" size="{_f(r)}" fromto="{_vec(a)} {_vec(b)}"/>'
        return ObstacleGeom("capsule", (a, b, np.float64(r)), xml)
    if hasattr(obstacle, "center") and hasattr(obstacle, "radius"):
        c = check_vector(obstacle.center, 3, f"{name} ({kind_name}) center")
        r = float(obstacle.radius)
        if not (np.isfinite(r) and r > 0):
            raise InvalidArgument(f"{name} ({kind_name}) radius must be > 0 [m], got {r}")
        xml = f'{head} type="sphere" size="{_f(r)}" pos="{_vec(c)}"/>'
        return ObstacleGeom("sphere", (c, np.float64(r)), xml)
    raise UnsupportedObstacle(
        f"obstacle {index} of type {kind_name} is not supported; allowed: objects with"
        " (center, radius) Sphere, (center, half_extents, rotation) Box,"
        " (p0, p1, radius) Capsule or (normal, offset) HalfSpace"
    )


# -- clearance ------------------------------------------------------------------------
class Clearance:
    """Minimum signed distance between the robot's collision spheres and the obstacles.

    Built once per scene; each call only evaluates (allocates a few (S, 3) arrays).
    """

    def __init__(
        self, robot: Robot, model: mujoco.MjModel, obstacles: Sequence[ObstacleGeom]
    ) -> None:
        spheres = robot.collision_spheres()
        self.obstacles = tuple(obstacles)
        self.body_ids = np.array(
            [
                mujoco.mj_name2id(
                    model, mujoco.mjtObj.mjOBJ_BODY, body_name(robot.model, robot.joint_id(s.joint))
                )
                for s in spheres
            ],
            dtype=np.int64,
        )
        self.centers = np.array([s.center for s in spheres], dtype=np.float64).reshape(-1, 3)
        self.radii = np.array([s.radius for s in spheres], dtype=np.float64)

    def sphere_centers(self, xpos: np.ndarray, xmat: np.ndarray) -> np.ndarray:
        """(S, 3) world positions of the sphere centres [m] from MuJoCo body poses.

        Args:
            xpos: (nbody, 3) body positions [m] (``MjData.xpos``).
            xmat: (nbody, 9) body orientations, row-major (``MjData.xmat``).
        """
        R = xmat[self.body_ids].reshape(-1, 3, 3)
        return xpos[self.body_ids] + np.einsum("sij,sj->si", R, self.centers)

    def __call__(self, xpos: np.ndarray, xmat: np.ndarray) -> float:
        """Minimum clearance [m] (``inf`` without obstacles or spheres; < 0 penetrating)."""
        if not self.obstacles or len(self.radii) == 0:
            return float("inf")
        pts = self.sphere_centers(xpos, xmat)
        return float(
            min(float(np.min(o.signed_distance(pts) - self.radii)) for o in self.obstacles)
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
    obstacles: Sequence[Any] = (),
    timestep: float = 1e-3,
    integrator: str = "implicitfast",
    gravity: Sequence[float] | None = None,
    contact: bool = False,
    limits: bool = True,
    decor: bool = False,
) -> Scene:
    """Compile the MuJoCo model of a robot with payload bodies and obstacle geoms.

    Allocates: builds MJCF text and compiles it (milliseconds); call once per simulation.

    Args:
        robot: the robot.
        payloads: payloads welded to links, see `Payload`.
        obstacles: Sphere/Box/Capsule/HalfSpace-like objects, see the module doc.
        timestep: physics time step [s], > 0.
        integrator: MuJoCo integrator: Euler, RK4, implicit or implicitfast.
        gravity: (3,) gravity [m/s^2]; defaults to ``robot.gravity``.
        contact: obstacles collide with the robot's capsules and payloads (default:
            visual only).
        limits: finite joint position limits are enforced by MuJoCo.
        decor: add visual-only decoration for rendering: a sky, and a pedestal under the
            robot's base when its first joint is above the floor.

    Returns:
        The scene.

    Raises:
        InvalidArgument: a bad payload, obstacle, timestep, integrator or gravity.
        UnknownBody: a payload's frame is not in the robot.
    """
    payloads = tuple(payloads)
    for i, p in enumerate(payloads):
        if not isinstance(p, Payload):
            raise InvalidArgument(f"payloads[{i}] must be a geosyn.sim.Payload, got {p!r}")
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
        pos = placement.act(np.asarray(p.offset))
        inertia = p.inertia()
        xml = (
            f'<body name={quoteattr(name)} pos="{_vec(pos)}">'
            f'<inertial pos="0 0 0" mass="{_f(p.mass)}" diaginertia="{_vec(inertia)}"/>'
            f'<geom name={quoteattr(name + "_geom")} type="sphere" size="{_f(p.radius)}"'
            ' contype="0" conaffinity="0" group="1" rgba="0.95 0.6 0.1 1" mass="0"/></body>'
        )
        body_extra.setdefault(str(robot.model.names[jid]), []).append(xml)
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
    if decor:
        xml = xml.replace("  <worldbody>", _SKY + "\n  <worldbody>", 1)
    try:
        model = mujoco.MjModel.from_xml_string(xml)
    except ValueError as err:
        raise InvalidArgument(f"the scene of robot {robot.name!r} does not compile: {err}") from err
    if contact:
        # Robot and payload geoms collide with obstacles only (not with each other).
        # body_contype/body_conaffinity (OR of the body's geoms) filter the broad phase.
        for g in range(model.ngeom):
            if model.geom_bodyid[g] != 0:
                model.geom_contype[g] = _ROBOT_BIT
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
