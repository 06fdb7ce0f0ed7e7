"""MuJoCo scenes of floating-base robots standing on a floor, for the whole-body tests
and benchmarks (tests/test_whole_body*.py, benchmarks/floating_whole_body.py).

geosyn's MuJoCo twin (`geosyn.robots.mjcf.robot_to_mjcf`) is fixed-base; the scene takes
the twin of the robot welded at its root link and hangs that tree under a body with a
free joint and the root link's inertia (the floating model's joint 1), so MuJoCo and
Pinocchio's free-flyer model share their dynamics. Contacts are small spheres at the
foot-sole corners (humanoid) or at the foot points (quadruped), on a plane with friction.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from geosyn.robots import Robot, load_robot
from geosyn.robots.files import example_robot_data_dir
from geosyn.robots.mjcf import mjcf_number, mjcf_vector

SPHERE = 0.005  # contact sphere radius [m]


@dataclass(frozen=True)
class Scene:
    """A floating robot, its MJCF on a floor and a standing start."""

    robot: Robot
    xml: str
    q0: np.ndarray  # (nq,) Pinocchio configuration, feet on the floor
    feet: tuple[str, ...]  # contact frames
    corners: np.ndarray  # (P, 3) contact points in each foot frame [m]


def _standing(robot: Robot, srdf: str, name: str) -> np.ndarray:
    model = pin.Model(robot.model)
    pin.loadReferenceConfigurations(model, str(example_robot_data_dir() / srdf), False)
    return np.array(model.referenceConfigurations[name])


def build_scene(
    name: str,
    timestep: float = 5e-4,
    friction: float = 1.0,
    solref: float = 0.005,
    solimp: str = "0.9 0.95 0.001",
    noslip: int = 0,
    impratio: float = 10.0,
    cone: str = "elliptic",
) -> Scene:
    """The scene of ``talos_reduced`` (both soles, 4 corners each), ``go2`` or ``solo12``
    (4 point feet).

    Args:
        name: ``"talos_reduced"``, ``"go2"`` or ``"solo12"``.
        timestep: MuJoCo time step [s].
        friction: sliding friction coefficient of the contacts.
        solref: contact time constant [s].
        solimp: MuJoCo's contact impedance (its default).
        noslip: MuJoCo's noslip iterations (0: none, MuJoCo's default).
        impratio: MuJoCo's friction-to-normal impedance ratio (its default is 1).
        cone: MuJoCo's friction cone, ``"elliptic"`` or ``"pyramidal"`` (its default).
            Elliptic cones with impratio 10 are MuJoCo's advice against the creep of its
            soft friction: with the defaults, go2's feet creep 6.5 mm under a 50 N push
            while their forces stay at 0.7 of the friction limit (benchmarks/RESULTS.md).
    """
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        robot = load_robot(name)
        welded = load_robot(name, fixed_base=True)
    if name == "talos_reduced":
        q0 = _standing(robot, "talos_data/srdf/talos.srdf", "half_sitting")
        feet = ("left_sole_link", "right_sole_link")
        corners = np.array([[x, y, 0.0] for x in (0.09, -0.09) for y in (0.06, -0.06)])
    elif name == "go2":
        q0 = _standing(robot, "go2_description/srdf/go2.srdf", "standing")
        feet = ("FL_foot", "FR_foot", "RL_foot", "RR_foot")
        corners = np.zeros((1, 3))
    else:
        q0 = _standing(robot, "solo_description/srdf/solo.srdf", "standing")
        feet = ("FL_FOOT", "FR_FOOT", "HL_FOOT", "HR_FOOT")
        corners = np.zeros((1, 3))
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
                f' solimp="{solimp}"'
                ' condim="3" mass="0"/>'
            )
        extra[str(model.names[frame.parentJoint])] = "".join(spheres)
    xml = welded.mjcf(timestep=timestep, body_extra=extra, worldbody_extra="<!--tree-->")
    inertia = model.inertias[1]
    Ic = np.asarray(inertia.inertia)
    base = (
        '<geom name="ground" type="plane" size="5 5 0.1" contype="0" conaffinity="1"'
        f' friction="{friction} 0.005 0.0001"/>\n    <body name="base"><freejoint name="root"/>'
        f'<inertial pos="{mjcf_vector(inertia.lever)}" mass="{mjcf_number(inertia.mass)}"'
        f' fullinertia="{mjcf_vector([Ic[0, 0], Ic[1, 1], Ic[2, 2], Ic[0, 1], Ic[0, 2], Ic[1, 2]])}"/>'
    )
    start = xml.index('    <geom name="floor"')
    stop = xml.index("\n", start)
    xml = xml[:start] + "    " + base + xml[stop:]
    xml = xml.replace("    <!--tree-->", "    </body>")
    xml = xml.replace(
        "<option ", f'<option noslip_iterations="{noslip}" impratio="{impratio}" cone="{cone}" ', 1
    )
    # the base height that puts the feet on the floor
    data = model.createData()
    pin.framesForwardKinematics(model, data, q0)
    lowest = min(data.oMf[robot.frame_id(f)].act(c)[2] for f in feet for c in corners)
    q0 = q0.copy()
    q0[2] -= lowest
    return Scene(robot, xml, q0, feet, corners)


@dataclass(frozen=True)
class StandingRun:
    """What a closed-loop standing run measured."""

    rms: float  # RMS over the run of |q - q_ref| on the group (all coordinates) [m, rad]
    rms_base_legs: float  # the same over the base twist and the first 12 joints
    max_error: float  # largest |q - q_ref| [m, rad]
    slip: float  # largest horizontal displacement of a contact frame [m]
    lift: float  # largest vertical displacement of a contact frame [m]
    min_base_height: float  # lowest base height over the run [m]
    qp_failures: int  # ticks whose QP proxsuite did not solve
    cpu: float  # CPU time of the loop [s]


def run_standing(
    scene: Scene,
    controller: object,
    reference: object,
    duration: float,
    push: tuple[float, float, float] = (0.0, 0.0, 0.0),
    push_window: tuple[float, float] = (0.8, 1.0),
    control_dt: float = 1e-3,
) -> StandingRun:
    """Run ``controller`` on the scene in MuJoCo (base free) and measure it.

    The controller is called at ``control_dt`` with Pinocchio's ``(q, v)``
    (`geosyn.robots.floating.from_mujoco`); its torques (nv,) drive the joint motors
    (entries 6:). ``push`` [N] acts on the base body, world axes, during ``push_window``.
    """
    import time

    import mujoco

    from geosyn.robots.floating import from_mujoco, to_mujoco

    robot = scene.robot
    m = mujoco.MjModel.from_xml_string(scene.xml)
    d = mujoco.MjData(m)
    d.qpos[:], d.qvel[:] = to_mujoco(scene.q0, np.zeros(robot.nv))
    mujoco.mj_forward(m, d)
    data = robot.model.createData()
    ids = [robot.frame_id(f) for f in scene.feet]

    def feet(q: np.ndarray) -> np.ndarray:
        pin.framesForwardKinematics(robot.model, data, q)
        return np.array([data.oMf[i].translation for i in ids])

    p0 = feet(scene.q0)
    controller.reset(scene.q0, np.zeros(robot.nv))  # type: ignore[attr-defined]
    substeps = int(round(control_dt / m.opt.timestep))
    base = m.body("base").id
    errors, legs, slip, lift, low, fails = [], [], 0.0, 0.0, np.inf, 0
    start = time.process_time()
    for k in range(int(round(duration / control_dt))):
        t = k * control_dt
        q, v = from_mujoco(d.qpos, d.qvel)
        tau = controller.compute(t, q, v)  # type: ignore[attr-defined]
        fails += bool(controller.diagnostics.fallback_used)  # type: ignore[attr-defined]
        d.ctrl[:] = tau[6:]
        d.xfrc_applied[base, :3] = push if push_window[0] <= t < push_window[1] else 0.0
        for _ in range(substeps):
            mujoco.mj_step(m, d)
        q, _ = from_mujoco(d.qpos, d.qvel)
        e = pin.difference(robot.model, q, reference.sample(t + control_dt).q)  # type: ignore[attr-defined]
        errors.append(float(np.linalg.norm(e)))
        legs.append(float(np.linalg.norm(e[:18])))
        moved = feet(q) - p0
        slip = max(slip, float(np.abs(moved[:, :2]).max()))
        lift = max(lift, float(np.abs(moved[:, 2]).max()))
        low = min(low, float(q[2]))
    err = np.array(errors)
    return StandingRun(
        rms=float(np.sqrt(np.mean(err**2))),
        rms_base_legs=float(np.sqrt(np.mean(np.square(legs)))),
        max_error=float(err.max()),
        slip=slip,
        lift=lift,
        min_base_height=low,
        qp_failures=fails,
        cpu=time.process_time() - start,
    )


def standing_synergy(scene: Scene, duration: float = 1.5, t0: float = 0.2):  # type: ignore[no-untyped-def]
    """The stance, synergy and reference of the scene's built-in motion.

    TALOS: lower the base by 6 cm and shift it 6 cm sideways while the right arm lifts
    (shoulder and elbow at -0.8 rad), both soles held. Quadruped: lower the base by 4 cm,
    shift it 5 cm sideways and roll it by 0.1 rad, four point feet held. The wish is
    projected onto the stance (`StanceSynergy`).
    """
    from geosyn.controllers.whole_body_reference import StanceSynergyReference
    from geosyn.metrics import FloatingKineticEnergyMetric
    from geosyn.metrics.stance import Stance
    from geosyn.metrics.stance_synergy import StanceSynergy

    robot = scene.robot
    metric = FloatingKineticEnergyMetric(robot)
    direction = np.zeros(robot.nv)
    if scene.corners.shape[0] > 1:  # a humanoid on its soles
        stance = Stance(metric, scene.feet, scene.q0)
        direction[1], direction[2] = 0.06, -0.06
        for joint in ("arm_right_2_joint", "arm_right_4_joint"):
            direction[robot.model.joints[robot.joint_id(joint)].idx_v] = -0.8
    else:
        stance = Stance(metric, scene.feet, scene.q0, points=True)
        direction[1], direction[2], direction[3] = 0.05, -0.04, 0.1
    synergy = StanceSynergy(stance, scene.q0, direction, steps=50)
    return stance, synergy, StanceSynergyReference(synergy, duration=duration, t0=t0)
