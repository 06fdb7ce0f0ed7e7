"""Built-in robots: planar arms of uniform rods, curated arms from example-robot-data, and
every other URDF of example-robot-data by its name (`geosyn.robots.catalog`)."""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
import pinocchio as pin

from geosyn.core.errors import InvalidArgument
from geosyn.robots.catalog import catalog_builders
from geosyn.robots.files import example_robot_data_dir, load_file
from geosyn.robots.from_model import NO_LIMIT, robot_from_model
from geosyn.robots.robot import CollisionCapsule, Robot


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
    try:
        m = np.asarray(masses, dtype=np.float64)
        lengths_arr = np.asarray(lengths, dtype=np.float64)
    except (TypeError, ValueError) as err:
        raise InvalidArgument(
            f"masses and lengths must be (n,) arrays of floats > 0, got {masses!r} and {lengths!r}"
        ) from err
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
            np.array([-NO_LIMIT]),
            np.array([NO_LIMIT]),
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
        limit_source=f"built-in: planar arm tau_max={tau_max:g}",
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


def _example_robot(
    relative_path: str,
    name: str,
    ee_frame: str,
    keep_joints: list[str] | None,
    options: dict[str, object],
) -> Robot:
    """A URDF of example-robot-data with the defaults the built-in arms share.

    Args:
        relative_path: URDF path below `example_robot_data_dir`.
        name: default robot name.
        ee_frame: default end-effector frame.
        keep_joints: the joints kept (the others are locked), or None for all.
        options: forwarded to `geosyn.robots.from_model.robot_from_model`; armature
            defaults to 0.1 kg m^2 per joint (a typical reflected rotor inertia) and the
            capsule radius to 0.06 m; joint damping and friction default to none (the
            URDFs' ``<dynamics>`` values are left out, as the experiments and figures built
            on these arms assume; pass ``damping=None, frictionloss=None`` to keep them).
            ``keep_joints`` may not be overridden.
    """
    defaults = {
        "name": name,
        "ee_frame": ee_frame,
        "armature": 0.1,
        "capsule_radius": 0.06,
        "damping": {},
        "frictionloss": {},
    }
    for key, value in defaults.items():
        options.setdefault(key, value)
    keep = {} if keep_joints is None else {"keep_joints": keep_joints}
    return load_file(example_robot_data_dir() / relative_path, **keep, **options)


def panda(**options: object) -> Robot:
    """7-DoF Franka Emika Panda (example-robot-data), fingers locked closed.

    ``options`` as for `_example_robot`.
    """
    keep = [f"panda_joint{i}" for i in range(1, 8)]
    return _example_robot(
        "panda_description/urdf/panda.urdf", "panda", "panda_hand_tcp", keep, options
    )


def talos_arm(**options: object) -> Robot:
    """TALOS left arm (example-robot-data), 7 DoF, gripper locked; ``options`` as for
    `_example_robot`.

    The humanoid arm in example-robot-data closest to ARMAR-6's, used for paper Figure 2.
    """
    path, keep = (
        "talos_data/robots/talos_reduced.urdf",
        [f"arm_left_{i}_joint" for i in range(1, 8)],
    )
    return _example_robot(path, "talos_arm", "gripper_left_base_link", keep, options)


def ur5(**options: object) -> Robot:
    """Universal Robots UR5 (example-robot-data), 6 DoF; ``options`` as for `_example_robot`."""
    return _example_robot("ur_description/urdf/ur5_robot.urdf", "ur5", "tool0", None, options)


CURATED: dict[str, Callable[..., Robot]] = {
    "planar2": planar2,
    "planar3": planar3,
    "panda": panda,
    "talos_arm": talos_arm,
    "ur5": ur5,
}
"""The curated built-ins (fixed end-effector, armature and locked joints chosen by hand)."""

BUILTINS: dict[str, Callable[..., Robot]] = {
    **CURATED,
    **{k: v for k, v in catalog_builders().items() if k not in CURATED},
}
"""Every robot `load_robot` knows by name: the curated ones first, then the catalog."""
