"""Config sections of the robot and the scene: robot options, obstacles, payload bodies."""

from __future__ import annotations

import difflib
import math
from typing import Annotated, Literal

from pydantic import Field, field_validator

from geosyn.experiments.schema.section import Section, Strict, python_defaults
from geosyn.experiments.schema.values import FiniteFloat, NonNegFloat, PositiveFloat, Vec3
from geosyn.robots import BUILTINS
from geosyn.sim import Simulation
from geosyn.world import Payload, load_mjcf_obstacles


class RobotOptions(Strict):
    """Options of `geosyn.robots.load_robot` (only these are accepted; None: the robot's own).

    Every user option of the file loader (`geosyn.robots.files.load_file` and
    `geosyn.robots.from_model.robot_from_model`) is here; a built-in robot that does not
    take one refuses it by name when the config is loaded.
    """

    armature: NonNegFloat | None = None
    gravity: Vec3 | None = None
    ee_frame: str | None = None
    fixed_base: bool | None = None  # weld a floating base (recorded in Robot.base)
    floating_base: bool | None = None  # a URDF's root link on a free flyer
    # overrides the file's torque limits [N m]: one for every joint or {joint: limit}
    tau_max: PositiveFloat | dict[str, PositiveFloat] | None = None
    default_tau_max: PositiveFloat | None = None  # where neither file nor tau_max gives one
    default_v_max: PositiveFloat | None = None  # where the file gives none [rad/s]
    keep_joints: Annotated[list[str], Field(min_length=1)] | None = None
    lock_q: dict[str, FiniteFloat] | None = None  # positions of the locked joints
    damping: dict[str, NonNegFloat] | None = None  # replaces the file's; {} none
    frictionloss: dict[str, NonNegFloat] | None = None  # replaces the file's; {} none
    capsule_radius: PositiveFloat | None = None  # derived collision capsules [m]
    inertia_check: Literal["error", "warn"] | None = None  # an unphysical URDF inertial


class RobotConfig(Strict):
    """The robot: a built-in name (see ``geosyn robots``) or a URDF/MJCF path.

    ``plant``: ``model`` simulates geosyn's rebuilt model of the robot; ``file`` simulates
    the robot's original MJCF file (its meshes, contacts, joint properties; its actuators
    disabled, geosyn's torques applied as joint forces; the scene's obstacles, payloads and
    contact added to it as to the model), see `geosyn.sim.file_scene`.
    """

    name: str
    options: RobotOptions = RobotOptions()
    plant: Literal["model", "file"] = "model"

    @field_validator("name")
    @classmethod
    def _known(cls, name: str) -> str:
        if name in BUILTINS or name.lower().endswith((".urdf", ".xml", ".mjcf")):
            return name
        close = difflib.get_close_matches(name, list(BUILTINS), n=3, cutoff=0.6)
        hint = f"; did you mean {' or '.join(repr(c) for c in close)}?" if close else ";"
        raise ValueError(
            f"{name!r} is not a built-in robot{hint} available: {', '.join(sorted(BUILTINS))}"
            " (or a path to a .urdf/.xml/.mjcf file)"
        )


class SphereConfig(Strict):
    type: Literal["sphere"]
    center: Vec3
    radius: PositiveFloat


class BoxConfig(Strict):
    type: Literal["box"]
    center: Vec3
    half_extents: Annotated[list[PositiveFloat], Field(min_length=3, max_length=3)]
    #: orientation as roll, pitch, yaw [rad] about the world's x, y, z (URDF convention:
    #: R = Rz(yaw) Ry(pitch) Rx(roll)).
    rpy: Vec3 = Field(default_factory=lambda: [0.0, 0.0, 0.0])


class CapsuleConfig(Strict):
    type: Literal["capsule"]
    p0: Vec3
    p1: Vec3
    radius: PositiveFloat


class HalfSpaceConfig(Strict):
    """``{x : normal . x <= offset}`` is the obstacle; ``normal`` is normalised."""

    type: Literal["halfspace"]
    normal: Vec3
    offset: FiniteFloat

    @field_validator("normal")
    @classmethod
    def _nonzero(cls, n: list[float]) -> list[float]:
        norm = math.sqrt(sum(x * x for x in n))
        if norm < 1e-12:
            raise ValueError("normal must be a nonzero vector")
        return [x / norm for x in n]


ObstacleConfig = Annotated[
    SphereConfig | BoxConfig | CapsuleConfig | HalfSpaceConfig, Field(discriminator="type")
]

# frame None: the robot's end-effector frame (known once the robot is loaded)
_PAYLOAD = python_defaults(Payload, frame=None)


class PayloadConfig(Section):
    """A rigid payload welded to a link (`geosyn.world.Payload`): ``offset`` is its centre
    of mass in ``frame`` [m]; ``inertia`` its (3, 3) inertia about it [kg m^2], None: a
    solid ball of ``radius`` [m]."""

    builds = (Payload,)
    parameter_names = {"offset": "com"}
    to_python = {
        "offset": tuple,
        "inertia": lambda rows: None if rows is None else tuple(map(tuple, rows)),
    }
    frame: str | None = _PAYLOAD["frame"]
    mass: NonNegFloat
    offset: Vec3 = _PAYLOAD["com"]
    inertia: Annotated[list[Vec3], Field(min_length=3, max_length=3)] | None = _PAYLOAD["inertia"]
    radius: NonNegFloat = _PAYLOAD["radius"]
    name: str | None = _PAYLOAD["name"]


#: ``contact`` of `geosyn.sim.Simulation` (the one place the config sets it: ``scene.contact``)
_CONTACT = python_defaults(Simulation)["contact"]


class MjcfObstaclesConfig(Strict):
    """Obstacles from a MuJoCo scene file (`geosyn.world.load_mjcf_obstacles`): MuJoCo
    compiles it, and every geom welded to its world body becomes a shape, after
    ``scene.obstacles``. A mesh or ellipsoid geom becomes its enclosing box; those and
    the geoms left out (of moving bodies; visual-only ones unless ``visual``) are listed
    in the run log. ``file``: a path, relative to the config file."""

    file: str
    visual: bool = python_defaults(load_mjcf_obstacles)["visual"]


class SceneConfig(Strict):
    """Payload bodies and obstacles of the MuJoCo scene (also seen by shaping terms).

    ``contact``: the obstacles collide with the robot (the collision geometry of its
    file, `geosyn.sim.collision_geoms`; the capsules of a robot built in code) and its
    payloads in MuJoCo (``Simulation(contact=...)``); each run then logs the total obstacle contact force
    (``contact_force`` [N]) next to the clearance. False (the Python default): the
    obstacles are visual only and the robot passes through them (the clearance, negative
    inside, is still logged).
    """

    payloads: list[PayloadConfig] = []
    obstacles: list[ObstacleConfig] = []
    mjcf: MjcfObstaclesConfig | None = None
    contact: bool = _CONTACT

    @property
    def has_obstacles(self) -> bool:
        """Whether the scene lists obstacles or reads them from a MuJoCo scene file."""
        return bool(self.obstacles) or self.mjcf is not None


__all__ = [
    "BoxConfig",
    "CapsuleConfig",
    "HalfSpaceConfig",
    "MjcfObstaclesConfig",
    "ObstacleConfig",
    "PayloadConfig",
    "RobotConfig",
    "RobotOptions",
    "SceneConfig",
    "SphereConfig",
]
