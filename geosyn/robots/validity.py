"""Physical validity of a robot: inertias, joint axes, limits, and mass on every joint.

Two levels:

- meaningless values are always refused, for every loader (`check_model` on the
  Pinocchio model, `check_urdf_values` on a URDF before Pinocchio reads it, whose parser
  would silently drop a non-finite inertial): non-finite or absurd masses and inertias
  (beyond `MAX_MASS`, `MAX_INERTIA`), NaN or zero joint axes, non-finite placements,
  inverted position limits (lower > upper, which once became "no limit"), and a joint
  that moves no mass (its subtree has zero mass and inertia, so M(q) is singular);
- physical consistency of an inertial (mass > 0 where a body has inertia, inertia tensors
  positive semi-definite and satisfying the triangle inequality) is checked link by link
  on a URDF (`check_urdf_inertials`; ``inertia_check="warn"`` downgrades it, as some
  published files are slightly off). MuJoCo's compiler checks an MJCF file's itself.

A zero principal moment (a thin rod) or a zero tensor (a point mass) is accepted: both are
limits of physical bodies and Pinocchio's algorithms handle them (MuJoCo refuses them).
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from collections.abc import Iterator
from pathlib import Path
from typing import NamedTuple

import numpy as np
import pinocchio as pin

from geosyn.robots.errors import RobotFileError

_REL_TOL = 1e-9  # relative slack for rounding in files written with few digits
MAX_MASS = 1e6
"""Largest body mass geosyn accepts [kg] (a tenth of a large crane; 1e300 overflows M)."""
MAX_INERTIA = 1e6
"""Largest rotational inertia entry geosyn accepts [kg m^2]."""
MAX_DISTANCE = 1e4
"""Largest joint offset or centre-of-mass distance geosyn accepts [m] (MuJoCo's M at a
body placed 1e300 m away is rounding noise)."""


def _parse_urdf(path: str | Path) -> ET.Element:
    """The root element of a URDF file.

    Raises:
        RobotFileError: unreadable or not XML.
    """
    try:
        return ET.parse(str(path)).getroot()
    except (ET.ParseError, OSError) as err:
        raise RobotFileError(f"could not parse robot file {str(path)!r}: {err}", path) from err


def _inertials(root: ET.Element) -> Iterator[tuple[str, ET.Element]]:
    """``(link name, <inertial>)`` of every link that has one."""
    for link in root.iter("link"):
        inertial = link.find("inertial")
        if inertial is not None:
            yield link.get("name", "?"), inertial


def _where(path: object) -> str:
    return f"{path}: " if path is not None else ""


def check_magnitudes(body: str, mass: float, inertia: np.ndarray, path: object = None) -> None:
    """Raise `RobotFileError` naming ``body`` unless mass and inertia are finite and sane.

    Always applied (no ``inertia_check="warn"`` downgrade): such a body means nothing.

    Args:
        body: what the body is, for the message, e.g. ``"link 'upper'"``.
        mass: mass [kg].
        inertia: (3, 3) rotational inertia [kg m^2].
        path: the file, for the message.
    """
    I = np.asarray(inertia, dtype=np.float64)  # noqa: E741 (the usual symbol)
    if not (math.isfinite(mass) and np.all(np.isfinite(I))):
        raise RobotFileError(
            f"{_where(path)}{body} has a non-finite mass or inertia (mass {mass!r},"
            f" inertia diagonal {np.diag(I).tolist()}); allowed: finite numbers",
            path,
        )
    if mass < 0:
        raise RobotFileError(f"{_where(path)}{body} has negative mass {mass:g}", path)
    if mass > MAX_MASS or float(np.abs(I).max()) > MAX_INERTIA:
        raise RobotFileError(
            f"{_where(path)}{body} has an absurd mass {mass:g} kg or inertia"
            f" {float(np.abs(I).max()):g} kg m^2; allowed: |mass| <= {MAX_MASS:g} kg,"
            f" |inertia| <= {MAX_INERTIA:g} kg m^2",
            path,
        )


def check_inertia(body: str, mass: float, inertia: np.ndarray, path: object = None) -> None:
    """Raise `RobotFileError` naming ``body`` unless (mass, inertia) is physical.

    Args:
        body: body or link name, for the message.
        mass: mass [kg].
        inertia: (3, 3) rotational inertia about the centre of mass [kg m^2].
        path: the file, for the message.
    """
    where = _where(path)
    I = np.asarray(inertia, dtype=np.float64)  # noqa: E741 (the usual symbol)
    check_magnitudes(f"body {body!r}", mass, I, path)
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

    Meaningless values are `check_urdf_values`'s (never downgraded to a warning).

    Raises:
        RobotFileError: a link with an unphysical or non-numeric inertial; names the link.
    """
    root = _parse_urdf(path)
    for name, inertial in _inertials(root):
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


def _floats(text: str | None, count: int, what: str, path: object) -> np.ndarray:
    """``count`` numbers of a URDF attribute (space separated); refuse non-numbers."""
    try:
        values = np.array([float(x) for x in (text or "").split()], dtype=np.float64)
    except ValueError as err:
        raise RobotFileError(f"{_where(path)}{what} is non-numeric: {text!r}", path) from err
    if values.shape != (count,) or not np.all(np.isfinite(values)):
        raise RobotFileError(
            f"{_where(path)}{what} is {text!r}, non-finite or not {count} number(s);"
            f" allowed: {count} finite number(s)",
            path,
        )
    return values


def _check_urdf_joint(joint: ET.Element, path: object) -> None:
    name = joint.get("name", "?")
    kind = joint.get("type", "?")
    for origin in joint.iter("origin"):
        for attr in ("xyz", "rpy"):
            if origin.get(attr) is not None:
                _floats(origin.get(attr), 3, f"joint {name!r} <origin {attr}>", path)
    axis_el = joint.find("axis")
    if kind in ("revolute", "continuous", "prismatic") and axis_el is not None:
        axis = _floats(axis_el.get("xyz", "1 0 0"), 3, f"joint {name!r} <axis xyz>", path)
        if float(np.linalg.norm(axis)) < 1e-12:
            raise RobotFileError(
                f"{_where(path)}joint {name!r} has a zero axis {axis.tolist()}; allowed: a"
                " non-zero direction",
                path,
            )
    limit = joint.find("limit")
    if limit is not None:
        values = {}
        for attr in ("lower", "upper", "effort", "velocity"):
            if limit.get(attr) is not None:
                values[attr] = float(
                    _floats(limit.get(attr), 1, f"joint {name!r} <limit {attr}>", path)[0]
                )
        if kind != "continuous" and values.get("lower", 0.0) > values.get("upper", 0.0):
            raise RobotFileError(
                f"{_where(path)}joint {name!r} has lower limit {values.get('lower', 0.0):g} >"
                f" upper limit {values.get('upper', 0.0):g}; allowed: lower <= upper (swapped"
                " limits would silently mean no limit)",
                path,
            )
    mimic = joint.find("mimic")
    if mimic is not None:
        for attr in ("multiplier", "offset"):
            if mimic.get(attr) is not None:
                _floats(mimic.get(attr), 1, f"joint {name!r} <mimic {attr}>", path)


def check_urdf_values(path: str | Path) -> None:
    """Refuse a URDF whose numbers mean nothing, before Pinocchio reads it.

    Always applied (``inertia_check="warn"`` does not downgrade it): non-finite or absurd
    masses and inertias (`check_magnitudes`), non-numeric or non-finite origins, a NaN or
    zero joint axis, non-finite limits, lower > upper, non-finite mimic factors.
    Pinocchio's URDF parser would silently drop a non-finite inertial (and print to stderr).

    Raises:
        RobotFileError: names the link or joint and the value.
    """
    root = _parse_urdf(path)
    for name, inertial in _inertials(root):
        mass_el = inertial.find("mass")
        mass = _floats(
            mass_el.get("value", "0") if mass_el is not None else "0",
            1,
            f"link {name!r} <mass>",
            path,
        )[0]
        el = inertial.find("inertia")
        attrib = el.attrib if el is not None else {}
        ixx, iyy, izz, ixy, ixz, iyz = (
            _floats(attrib.get(k, "0"), 1, f"link {name!r} <inertia {k}>", path)[0]
            for k in ("ixx", "iyy", "izz", "ixy", "ixz", "iyz")
        )
        tensor = np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])
        check_magnitudes(f"link {name!r}", float(mass), tensor, path)
    for joint in root.iter("joint"):
        _check_urdf_joint(joint, path)


def check_model(model: pin.Model, path: object = None) -> None:
    """Refuse a Pinocchio model whose numbers mean nothing (any loader, URDF or MJCF).

    Checks every joint's body (`check_magnitudes`, finite centre of mass), placement
    (finite), axis (finite, non-zero, for joints with an arbitrary axis) and position
    limits (lower <= upper). O(njoints).

    Raises:
        RobotFileError: names the joint and the value.
    """
    for jid in range(1, model.njoints):
        name = model.names[jid]
        body = model.inertias[jid]
        what = f"the body moved by joint {name!r}"
        check_magnitudes(what, float(body.mass), np.asarray(body.inertia), path)
        joint = model.joints[jid]
        axis = getattr(joint.extract(), "axis", None)
        if axis is not None:
            axis = np.asarray(axis, dtype=np.float64)
            if not (np.all(np.isfinite(axis)) and float(np.linalg.norm(axis)) > 1e-12):
                raise RobotFileError(
                    f"{_where(path)}joint {name!r} has axis {axis.tolist()}; allowed: a finite,"
                    " non-zero direction",
                    path,
                )
        placement = model.jointPlacements[jid]
        if not (np.all(np.isfinite(body.lever)) and np.all(np.isfinite(placement.homogeneous))):
            raise RobotFileError(
                f"{_where(path)}joint {name!r} has a non-finite placement or centre of mass",
                path,
            )
        far = max(float(np.abs(body.lever).max()), float(np.abs(placement.translation).max()))
        if far > MAX_DISTANCE:
            raise RobotFileError(
                f"{_where(path)}joint {name!r} is placed {far:g} m from its parent (or its"
                f" centre of mass from it); allowed: at most {MAX_DISTANCE:g} m",
                path,
            )
        lo = np.asarray(model.lowerPositionLimit[joint.idx_q : joint.idx_q + joint.nq])
        hi = np.asarray(model.upperPositionLimit[joint.idx_q : joint.idx_q + joint.nq])
        if np.any(np.isnan(lo)) or np.any(np.isnan(hi)) or np.any(lo > hi):
            raise RobotFileError(
                f"{_where(path)}joint {name!r} has lower limit {lo.tolist()} > upper limit"
                f" {hi.tolist()}; allowed: lower <= upper (swapped limits would silently mean"
                " no limit)",
                path,
            )


def check_moving_mass(model: pin.Model, path: object = None) -> None:
    """Refuse a joint that moves no mass: M(q) would be singular (the metric meaningless).

    A joint whose subtree has zero mass and inertia (a massless moving link), or whose
    subtree's inertia about its axis is zero (a point mass on the axis), gives a zero row
    of M at the neutral configuration; armature does not count (it is the motor's).
    One CRBA, O(nv^2).

    Raises:
        RobotFileError: names the joint and the bodies it moves.
    """
    data = model.createData()
    M = pin.crba(model, data, pin.neutral(model))
    own = np.diag(M) - np.asarray(model.armature, dtype=np.float64)
    tol = 1e-14 * max(float(np.max(np.abs(own), initial=0.0)), 1e-300)
    for jid in range(1, model.njoints):
        joint = model.joints[jid]
        dofs = own[joint.idx_v : joint.idx_v + joint.nv]
        if np.all(dofs > tol):
            continue
        subtree = [model.names[j] for j in model.subtrees[jid]]
        mass = sum(float(model.inertias[j].mass) for j in model.subtrees[jid])
        raise RobotFileError(
            f"{_where(path)}joint {model.names[jid]!r} moves no inertia (its subtree, the"
            f" bodies of joints {subtree}, has mass {mass:g} kg and no inertia about its"
            " axis): M(q) is singular; give the moving link an inertial or fix the joint",
            path,
        )


MAX_INCLUDES = 256
"""Most ``<include>`` elements geosyn follows in one MJCF file (nested ones counted)."""


def check_includes(path: str | Path) -> None:
    """Refuse an MJCF file whose ``<include>`` elements reach outside its folder.

    MuJoCo reads an included file relative to the main file's folder, wherever it points
    (``../../../../etc/...``, ``/dev/zero``); geosyn confines includes (nested ones too,
    symbolic links resolved) to that folder and to regular files. A file that does not
    parse is left to MuJoCo's own message.

    Raises:
        RobotFileError: names the include and what is allowed.
    """
    main = Path(path).resolve()
    folder = main.parent
    pending, seen = [main], 0
    while pending:
        try:
            root = ET.parse(str(pending.pop())).getroot()
        except (ET.ParseError, OSError):
            continue
        for element in root.iter("include"):
            name = element.get("file", "")
            target = (folder / name).resolve()
            if not target.is_relative_to(folder) or not target.is_file():
                raise RobotFileError(
                    f"{path}: <include file={name!r}> is {target}, not a file inside the"
                    f" robot's folder {folder}; allowed: included files in that folder",
                    path,
                )
            seen += 1
            if seen > MAX_INCLUDES:
                raise RobotFileError(
                    f"{path}: more than {MAX_INCLUDES} <include> elements (nested ones"
                    " counted); allowed: at most that many",
                    path,
                )
            pending.append(target)
