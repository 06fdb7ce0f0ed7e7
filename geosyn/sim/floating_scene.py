"""MuJoCo scenes of floating-base robots standing on a floor (base free, not welded).

geosyn's MuJoCo twin (`geosyn.robots.mjcf.robot_to_mjcf`) is fixed-base; the scene takes
the twin of the robot welded at its root link and hangs that tree under a body with a
free joint and the root link's inertia (the floating model's joint 1), so MuJoCo and
Pinocchio's free-flyer model share their dynamics. Contacts are small spheres at the
foot-sole corners (humanoid) or at the foot points (quadruped), on a plane with friction,
with elliptic cones and ``impratio`` 10 (MuJoCo's advice against the creep of its soft
friction). The standing start is the robot's SRDF pose (``half_sitting`` / ``standing``)
lowered or lifted so that the lowest contact point touches the floor.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from geosyn.robots import Robot, load_robot
from geosyn.robots.files import example_robot_data_dir
from geosyn.robots.mjcf import mjcf_number, mjcf_vector
from geosyn.sim.errors import SimError

__all__ = ["SPHERE", "STANDING", "FloatingScene", "StandingSpec", "build_floating_scene"]

SPHERE = 0.005
"""Radius of the contact spheres [m]."""


@dataclass(frozen=True)
class StandingSpec:
    """How a built-in floating robot stands: its SRDF pose, feet and contact points.

    Attributes:
        srdf: the SRDF file, relative to example-robot-data's robots folder.
        pose: the SRDF reference configuration to start from.
        feet: contact frames.
        points: (P, 3) contact points in each foot frame [m] (one point: a point foot).
    """

    srdf: str
    pose: str
    feet: tuple[str, ...]
    points: tuple[tuple[float, float, float], ...]


_SOLE = tuple((x, y, 0.0) for x in (0.09, -0.09) for y in (0.06, -0.06))

STANDING: dict[str, StandingSpec] = {
    "talos_reduced": StandingSpec(
        "talos_data/srdf/talos.srdf", "half_sitting", ("left_sole_link", "right_sole_link"), _SOLE
    ),
    "go2": StandingSpec(
        "go2_description/srdf/go2.srdf",
        "standing",
        ("FL_foot", "FR_foot", "RL_foot", "RR_foot"),
        ((0.0, 0.0, 0.0),),
    ),
    "solo12": StandingSpec(
        "solo_description/srdf/solo.srdf",
        "standing",
        ("FL_FOOT", "FR_FOOT", "HL_FOOT", "HR_FOOT"),
        ((0.0, 0.0, 0.0),),
    ),
}
"""Standing specifications of the built-in floating robots that have one."""


@dataclass(frozen=True)
class FloatingScene:
    """A floating robot, its MJCF on a floor and a standing start.

    Attributes:
        robot: the floating-base robot (Pinocchio free flyer).
        xml: the MJCF: floor, free-joint base, geosyn's twin, contact spheres.
        q0: (nq,) Pinocchio configuration standing, the lowest contact point on the floor.
        feet: contact frames.
        corners: (P, 3) contact points in each foot frame [m].
    """

    robot: Robot
    xml: str
    q0: np.ndarray
    feet: tuple[str, ...]
    corners: np.ndarray


def standing_pose(robot: Robot, spec: StandingSpec) -> np.ndarray:
    """(nq,) the SRDF reference configuration ``spec.pose`` of ``robot`` (not lifted)."""
    model = pin.Model(robot.model)
    pin.loadReferenceConfigurations(model, str(example_robot_data_dir() / spec.srdf), False)
    if spec.pose not in model.referenceConfigurations:
        raise SimError(
            f"pose {spec.pose!r} is not in {spec.srdf}; it has"
            f" {sorted(model.referenceConfigurations.keys())}"
        )
    return np.array(model.referenceConfigurations[spec.pose])


def build_floating_scene(
    name: str,
    timestep: float = 5e-4,
    friction: float = 1.0,
    solref: float = 0.005,
    solimp: str = "0.9 0.95 0.001",
    noslip: int = 0,
    impratio: float = 10.0,
    cone: str = "elliptic",
    *,
    feet: Sequence[str] | None = None,
    points: np.ndarray | None = None,
) -> FloatingScene:
    """The standing scene of a built-in floating robot (a key of `STANDING`).

    Args:
        name: ``"talos_reduced"`` (both soles, 4 corners each), ``"go2"`` or ``"solo12"``
            (4 point feet).
        timestep: MuJoCo time step [s].
        friction: sliding friction coefficient of the contacts.
        solref: contact time constant [s].
        solimp: MuJoCo's contact impedance (its default).
        noslip: MuJoCo's noslip iterations (0: none, MuJoCo's default).
        impratio: MuJoCo's friction-to-normal impedance ratio (its default is 1).
        cone: MuJoCo's friction cone, ``"elliptic"`` or ``"pyramidal"`` (its default).
            With the defaults (pyramidal, impratio 1), go2's feet creep 6.5 mm under a
            50 N push while their forces stay at 0.7 of the friction limit
            (benchmarks/RESULTS.md).
        feet: contact frames (None: the robot's `STANDING` feet).
        points: (P, 3) contact points in each foot frame [m] (None: `STANDING`'s).

    Raises:
        SimError: ``name`` has no standing specification, or ``points`` is not (P, 3).
        UnknownFrame: a foot is not a frame of the robot.
    """
    if name not in STANDING:
        raise SimError(
            f"robot {name!r} has no standing scene; robots that stand: {', '.join(STANDING)}"
        )
    spec = STANDING[name]
    with warnings.catch_warnings():  # the loading notes are the loader's to report
        warnings.simplefilter("ignore")
        robot = load_robot(name)
        welded = load_robot(name, fixed_base=True)
    q0 = standing_pose(robot, spec)
    feet = spec.feet if feet is None else tuple(feet)
    corners = np.array(spec.points if points is None else points, dtype=np.float64)
    if corners.ndim != 2 or corners.shape[1] != 3 or len(corners) == 0:
        raise SimError(f"points must have shape (P, 3), P >= 1; got {corners.shape}")
    model = robot.model
    extra: dict[str, str] = {}
    for foot in feet:
        frame = model.frames[robot.frame_id(foot)]
        spheres = []
        for c in corners:
            p = frame.placement.act(c + np.array([0.0, 0.0, SPHERE]))
            spheres.append(
                f'<geom type="sphere" size="{SPHERE}" pos="{mjcf_vector(p)}" contype="1"'
                f' conaffinity="0" friction="{friction} 0.005 0.0001" solref="{solref} 1"'
                f' solimp="{solimp}" condim="3" mass="0"/>'
            )
        joint = str(model.names[frame.parentJoint])
        extra[joint] = extra.get(joint, "") + "".join(spheres)
    xml = welded.mjcf(timestep=timestep, body_extra=extra, worldbody_extra="<!--tree-->")
    inertia = model.inertias[1]
    Ic = np.asarray(inertia.inertia)
    full = [Ic[0, 0], Ic[1, 1], Ic[2, 2], Ic[0, 1], Ic[0, 2], Ic[1, 2]]
    base = (
        '<geom name="ground" type="plane" size="5 5 0.1" contype="0" conaffinity="1"'
        f' friction="{friction} 0.005 0.0001"/>\n    <body name="base"><freejoint name="root"/>'
        f'<inertial pos="{mjcf_vector(inertia.lever)}" mass="{mjcf_number(inertia.mass)}"'
        f' fullinertia="{mjcf_vector(full)}"/>'
    )
    start = xml.index('    <geom name="floor"')
    stop = xml.index("\n", start)
    xml = xml[:start] + "    " + base + xml[stop:]
    xml = xml.replace("    <!--tree-->", "    </body>")
    xml = xml.replace(
        "<option ", f'<option noslip_iterations="{noslip}" impratio="{impratio}" cone="{cone}" ', 1
    )
    data = model.createData()
    pin.framesForwardKinematics(model, data, q0)
    lowest = min(data.oMf[robot.frame_id(f)].act(c)[2] for f in feet for c in corners)
    q0 = q0.copy()
    q0[2] -= lowest  # the lowest contact point on the floor
    return FloatingScene(robot, xml, q0, feet, corners)
