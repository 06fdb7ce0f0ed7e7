"""Robot files: URDF and MJCF loading, and the example-robot-data folder."""

from __future__ import annotations

import warnings
from pathlib import Path
from typing import Any

import pinocchio as pin

from geosyn.core.validation import check_choice
from geosyn.robots.couplings import LinearConstraint
from geosyn.robots.errors import RobotFileError, RobotWarning
from geosyn.robots.free_flyer import floating_robot, free_joint_pose
from geosyn.robots.from_model import robot_from_model
from geosyn.robots.robot import Robot
from geosyn.robots.validity import check_urdf_inertials, check_urdf_values, urdf_mimics

ROBOT_FILE_SUFFIXES = (".urdf", ".xml", ".mjcf")
"""File suffixes `load_file` reads (case-insensitive)."""


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


def _read_urdf(path: Path, inertia_check: str) -> pin.Model:
    """The Pinocchio model of a URDF file, its values and inertials checked first."""
    check_urdf_values(path)  # meaningless numbers: refused, never downgraded to a warning
    try:
        check_urdf_inertials(path)
    except RobotFileError as err:
        if inertia_check == "error":
            raise
        warnings.warn(f"{err} (loaded anyway: inertia_check='warn')", RobotWarning, stacklevel=3)
    try:
        return pin.buildModelFromUrdf(str(path))
    except (RuntimeError, ValueError) as err:
        raise RobotFileError(f"could not parse robot file {str(path)!r}: {err}", path) from err


def load_file(path: str | Path, **options: Any) -> Robot:
    """Load a robot from a URDF (``.urdf``) or MJCF (``.xml``/``.mjcf``) file.

    An MJCF file is compiled by MuJoCo and the robot built from the compiled model
    (`geosyn.robots.from_mjcf`): armature, damping, frictionloss, actuator torque limits,
    the root body's pose and the file's gravity all carry over. A URDF goes through
    Pinocchio's parser; its ``<limit effort>`` gives the torque limits.

    Args:
        path: file path.
        **options: ``fixed_base`` (bool, default False) welds an MJCF free joint at its
            initial pose (recorded in ``Robot.base`` and warned about); without it an
            MJCF free joint loads as a floating base (`geosyn.robots.floating`).
            ``floating_base`` (bool, default False) gives a URDF's root link a free
            flyer (a URDF does not say whether its root is fixed). ``inertia_check``
            (``error``, the default, refuses a URDF link whose inertial is not physical;
            ``warn`` reports it and loads the file, as some published files have slightly
            invalid inertias). The rest is forwarded to
            `robot_from_model` (``keep_joints``, ``lock_q``, ``ee_frame``, ``armature``,
            ``gravity``, ``tau_max``, ``damping``, ...).

    Raises:
        RobotFileError: missing, unreadable, malformed or unsupported file (a closed
            loop, no joints, unphysical inertia, a free joint that is not the root); the
            message names the part of the file.
        FloatingBaseError: a floating base with joint couplings.
    """
    fixed_base = bool(options.pop("fixed_base", False))
    floating_base = bool(options.pop("floating_base", False))
    inertia_check = options.pop("inertia_check", "error")
    check_choice(inertia_check, ("error", "warn"), "inertia_check")
    p = Path(path)
    if not p.is_file():
        raise RobotFileError(f"robot file {str(p)!r} does not exist", p)
    suffix = p.suffix.lower()
    options.setdefault("name", p.stem)
    options.setdefault("source_file", str(p))
    if suffix == ".urdf":
        model = _read_urdf(p, inertia_check)
        mimics = [
            LinearConstraint(
                f"<mimic> {m}", {m.joint: 1.0, m.leader: -m.multiplier}, m.offset, m.joint
            )
            for m in urdf_mimics(p)
        ]
        options.setdefault("couplings", mimics)
        robot = robot_from_model(model, **options)
        return floating_robot(robot, how="URDF root link") if floating_base else robot
    if suffix in (".xml", ".mjcf"):
        # MuJoCo is imported only for MJCF files (the robot and controller layers stay
        # importable without it)
        from geosyn.robots.from_mjcf import compile_mjcf, pinocchio_from_mjmodel

        m = compile_mjcf(p)
        read = pinocchio_from_mjmodel(m, fixed_base=fixed_base, path=p)
        from_file = {
            "file_tau_max": read.tau_max,
            "damping": read.damping,
            "frictionloss": read.frictionloss,
            "actuators": read.actuators,
            "base": read.base,
            "couplings": read.couplings,
        }
        robot = robot_from_model(read.model, **{**from_file, **options})  # options override
        free = (
            None
            if fixed_base
            else free_joint_pose(m.jnt_type, m.jnt_bodyid, (m.body_pos, m.body_quat))
        )
        if free is None:
            return robot
        return floating_robot(robot, free[1], how=read.base)
    raise RobotFileError(
        f"robot file {str(p)!r} has suffix {suffix!r}; allowed: {', '.join(ROBOT_FILE_SUFFIXES)}",
        p,
    )
