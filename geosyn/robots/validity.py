"""Physical validity of a robot file's inertias: finite, mass > 0 where a body has inertia,
inertia tensors positive semi-definite and satisfying the triangle inequality.

A zero principal moment (a thin rod) or a zero tensor (a point mass) is accepted: both are
limits of physical bodies and Pinocchio's algorithms handle them (MuJoCo refuses them).

MuJoCo's compiler checks MJCF files itself (geosyn wraps its message); URDF inertials are
checked here, link by link, before Pinocchio merges them.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import NamedTuple

import numpy as np

from geosyn.robots.errors import RobotFileError

_REL_TOL = 1e-9  # relative slack for rounding in files written with few digits


def check_inertia(body: str, mass: float, inertia: np.ndarray, path: object = None) -> None:
    """Raise `RobotFileError` naming ``body`` unless (mass, inertia) is physical.

    Args:
        body: body or link name, for the message.
        mass: mass [kg].
        inertia: (3, 3) rotational inertia about the centre of mass [kg m^2].
        path: the file, for the message.
    """
    where = f"{path}: " if path is not None else ""
    I = np.asarray(inertia, dtype=np.float64)  # noqa: E741 (the usual symbol)
    if not (math.isfinite(mass) and np.all(np.isfinite(I))):
        raise RobotFileError(f"{where}body {body!r} has a non-finite mass or inertia", path)
    if mass < 0:
        raise RobotFileError(f"{where}body {body!r} has negative mass {mass}", path)
    scale = float(np.abs(I).max())
    if scale == 0.0:
        return
    if mass == 0.0:
        raise RobotFileError(
            f"{where}body {body!r} has rotational inertia but zero mass; allowed: mass > 0",
            path,
        )
    if np.abs(I - I.T).max() > _REL_TOL * scale:
        raise RobotFileError(f"{where}body {body!r} has a non-symmetric inertia tensor", path)
    eig = np.linalg.eigvalsh(0.5 * (I + I.T))
    tol = _REL_TOL * scale
    if eig[0] < -tol:
        raise RobotFileError(
            f"{where}body {body!r} has an inertia tensor that is not positive semi-definite"
            f" (principal moments {eig.tolist()})",
            path,
        )
    if eig[0] + eig[1] < eig[2] - tol:
        raise RobotFileError(
            f"{where}body {body!r} violates the triangle inequality of principal moments"
            f" {eig.tolist()} (A + B >= C)",
            path,
        )


def check_urdf_inertials(path: str | Path) -> None:
    """Check every ``<link><inertial>`` of a URDF file (see `check_inertia`).

    Raises:
        RobotFileError: a link with an unphysical or non-numeric inertial; names the link.
    """
    try:
        root = ET.parse(str(path)).getroot()
    except (ET.ParseError, OSError) as err:
        raise RobotFileError(f"could not parse robot file {str(path)!r}: {err}", path) from err
    for link in root.iter("link"):
        inertial = link.find("inertial")
        if inertial is None:
            continue
        name = link.get("name", "?")
        try:
            mass_el = inertial.find("mass")
            mass = float(mass_el.get("value", "0")) if mass_el is not None else 0.0
            el = inertial.find("inertia")
            attrib = el.attrib if el is not None else {}
            ixx, iyy, izz, ixy, ixz, iyz = (
                float(attrib.get(k, "0")) for k in ("ixx", "iyy", "izz", "ixy", "ixz", "iyz")
            )
        except ValueError as err:
            raise RobotFileError(
                f"{path}: link {name!r} has a non-numeric inertial: {err}", path
            ) from err
        tensor = np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])
        check_inertia(name, mass, tensor, path)


class Mimic(NamedTuple):
    """A URDF ``<mimic>``: ``joint = multiplier * leader + offset``."""

    joint: str
    leader: str
    multiplier: float
    offset: float

    def __str__(self) -> str:
        return f"{self.joint} = {self.multiplier:g} * {self.leader} + {self.offset:g}"


def urdf_mimics(path: str | Path) -> list[Mimic]:
    """Every ``<mimic>`` of a URDF file."""
    root = ET.parse(str(path)).getroot()
    out = []
    for joint in root.iter("joint"):
        mimic = joint.find("mimic")
        if mimic is not None:
            out.append(
                Mimic(
                    joint.get("name", "?"),
                    mimic.get("joint", "?"),
                    float(mimic.get("multiplier", "1")),
                    float(mimic.get("offset", "0")),
                )
            )
    return out
