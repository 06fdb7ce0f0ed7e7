"""How much of a robot file's collision geometry a set of collision spheres leaves out.

The obstacle terms of a shaped metric and the MPC's clearance keep *spheres* off the
obstacles (by default `Robot.collision_spheres`, spheres along the capsules). Where the
file's collision surfaces (`geosyn.robots.collision_geometry`) stand outside those
spheres, a clearance the spheres keep is not the robot's. `sphere_miss` measures that
(the largest distance of a surface point outside the spheres of its joint), and
`report_sphere_miss` warns once about it, naming the link and how to ask for covering
spheres (`resolve_spheres` with ``"file"``: `geosyn.robots.collision_spheres.file_spheres`).
Objects fixed to the base are left out: no joint moves them, so no sphere on a joint
can keep them clear.

The measurement samples every collision surface (a fraction of a second for an arm, most
of it importing trimesh); it is kept in the process and on disk beside the fitted spheres
(``miss_<hash>.json`` in `geosyn.robots.collision_spheres.sphere_cache_dir`, keyed by a
hash of the geometry, the spheres and the sampling), so a new process that builds an
obstacle term, an MPC or a planner for the same robot and spheres reads it back.
"""

from __future__ import annotations

import hashlib
import math
import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from geosyn.core.cache_folder import read_json, store_json
from geosyn.core.errors import InvalidArgument
from geosyn.robots.collision_geometry import (
    CollisionObject,
    collision_objects,
    geometry_digest,
    surface_points,
)
from geosyn.robots.errors import RobotFileError, RobotWarning
from geosyn.robots.robot import CollisionSphere, Robot

__all__ = [
    "MISS_TOL",
    "SphereMiss",
    "check_spheres",
    "report_sphere_miss",
    "resolve_spheres",
    "sphere_miss",
]

MISS_TOL = 1e-3
"""A miss [m] up to which `report_sphere_miss` stays silent."""

SPACING = 5e-3
"""Largest edge [m] of the surface sampling (a surface point is within
``SPACING / sqrt(3)`` of a sample)."""


class SphereMiss(NamedTuple):
    """What the spheres leave out of the file's moving collision surfaces.

    Attributes:
        distance: largest distance [m] of a sampled surface point outside the union of
            the spheres on its joint, over the links with spheres (<= 0: covered); NaN
            when the robot has no file geometry.
        link: the link of that point ("" if none).
        bare: moving links with collision geometry and no sphere on their joint.
        why: why it was not measured ("" when it was).
    """

    distance: float
    link: str
    bare: tuple[str, ...] = ()
    why: str = ""


_CACHE: dict[tuple[object, ...], SphereMiss] = {}
_REPORTED: set[tuple[object, ...]] = set()


MISS_VERSION = 1
"""Part of the disk cache key: bumped when the measurement changes."""


def sphere_miss(robot: Robot, spheres: Sequence[CollisionSphere]) -> SphereMiss:
    """How far the file's collision surfaces of ``robot`` stand outside ``spheres``.

    Measured once per robot file, joints and spheres (it samples the meshes), then read
    from the process's memory or the disk cache (module docstring).
    """
    key = (robot.name, robot.source_file, tuple(robot.joint_names), tuple(spheres))
    if key not in _CACHE:
        try:
            objects = collision_objects(robot)
        except RobotFileError as err:
            _CACHE[key] = SphereMiss(math.nan, "", (), str(err))
            return _CACHE[key]
        path = _miss_path(objects, spheres)
        found = _read_miss(path)
        _CACHE[key] = found if found is not None else _store(path, _measure(objects, spheres))
    return _CACHE[key]


def _miss_path(objects: tuple[CollisionObject, ...], spheres: Sequence[CollisionSphere]) -> Path:
    """The disk cache file of the miss of ``spheres`` on ``objects``."""
    from geosyn.robots.collision_spheres import sphere_cache_dir

    rows = [(s.joint, tuple(map(float, s.center)), float(s.radius)) for s in spheres]
    key = f"{geometry_digest(objects)}|{rows!r}|{SPACING!r}|{MISS_VERSION}"
    return sphere_cache_dir() / f"miss_{hashlib.sha256(key.encode()).hexdigest()[:24]}.json"


def _read_miss(path: Path) -> SphereMiss | None:
    """The miss cached at ``path``, or None (missing, or damaged: measured again, warned)."""

    def parse(data: Any) -> SphereMiss:
        return SphereMiss(float(data["distance"]), str(data["link"]),
                          tuple(str(b) for b in data["bare"]))  # fmt: skip

    return read_json(path, parse, "sphere cache", "measuring again", 4)


def _store(path: Path, miss: SphereMiss) -> SphereMiss:
    """``miss``, written to ``path`` atomically (an unwritable cache is warned: it only
    costs the measurement next time)."""
    record = {"distance": miss.distance, "link": miss.link, "bare": list(miss.bare)}
    store_json(path, record, "the sphere cache", 4)
    return miss


def _measure(
    objects: tuple[CollisionObject, ...], spheres: Sequence[CollisionSphere]
) -> SphereMiss:
    """`SphereMiss` of ``spheres`` on the file's collision ``objects`` (sampled)."""
    worst, link, bare = -math.inf, "", []
    for obj in objects:
        if obj.joint == "universe":
            continue
        mine = [s for s in spheres if s.joint == obj.joint]
        if not mine:
            bare.append(obj.link)
            continue
        c = np.array([s.center for s in mine], dtype=np.float64)
        r = np.array([s.radius for s in mine], dtype=np.float64)
        P = surface_points(obj, SPACING)  # in the joint frame, as the sphere centres
        d2 = ((P[:, None, :] - c[None, :, :]) ** 2).sum(axis=2)
        miss = float(np.max(np.min(np.sqrt(d2) - r[None, :], axis=1)))
        if miss > worst:
            worst, link = miss, obj.link
    return SphereMiss(worst, link, tuple(dict.fromkeys(bare)))


def check_spheres(
    spheres: Sequence[CollisionSphere] | str | None, name: str
) -> tuple[CollisionSphere, ...] | str | None:
    """``spheres`` as `resolve_spheres` takes it (None, ``"file"`` or a tuple of
    `CollisionSphere`), or `InvalidArgument` naming ``name`` and what is allowed."""
    if spheres is None or spheres == "file":
        return spheres
    if isinstance(spheres, str):
        raise InvalidArgument(f"{name}: None, 'file' or CollisionSphere's, got {spheres!r}")
    out = tuple(spheres)
    for i, s in enumerate(out):
        if not isinstance(s, CollisionSphere):
            raise InvalidArgument(f"{name}[{i}] must be a CollisionSphere, got {type(s).__name__}")
    return out


def resolve_spheres(
    robot: Robot, spheres: Sequence[CollisionSphere] | str | None, name: str
) -> tuple[CollisionSphere, ...]:
    """The spheres an obstacle term or the MPC's clearance keeps clear.

    Args:
        robot: the robot.
        spheres: None: ``robot.collision_spheres()`` (along its capsules); ``"file"``:
            spheres fitted to cover the file's collision geometry
            (`geosyn.robots.collision_spheres.file_spheres`, cached on disk; those on the
            fixed base left out: no joint moves them); or the spheres themselves.
        name: the argument's name, for the error message.

    Raises:
        InvalidArgument: another string or object (`check_spheres`), or ``"file"`` for a
            robot with no file geometry.
    """
    spheres = check_spheres(spheres, name)
    if spheres is None:
        return tuple(robot.collision_spheres())
    if isinstance(spheres, str):  # "file"
        from geosyn.robots.collision_spheres import file_spheres  # reads the meshes

        try:
            fitted = file_spheres(robot)
        except RobotFileError as err:
            raise InvalidArgument(f"{name}='file': {err}") from err
        return fitted.moving
    return tuple(spheres)


def report_sphere_miss(
    robot: Robot, spheres: Sequence[CollisionSphere], who: str, fix: str
) -> SphereMiss:
    """`sphere_miss`, and a `RobotWarning` (once per robot, spheres and ``who``) when the
    surfaces stand more than `MISS_TOL` outside the spheres.

    Args:
        robot: the robot.
        spheres: the spheres ``who`` keeps clear.
        who: what uses them, for the message (e.g. ``"ObstacleTerm"``).
        fix: how the user asks for covering spheres there (for the message).
    """
    miss = sphere_miss(robot, spheres)
    key = (who, robot.name, robot.source_file, tuple(spheres))
    if (miss.distance > MISS_TOL or miss.bare) and key not in _REPORTED:
        _REPORTED.add(key)
        parts = []
        if miss.distance > MISS_TOL:
            parts.append(
                f"it stands up to {miss.distance * 1e3:.1f} mm outside them (link {miss.link!r})"
            )
        if miss.bare:
            parts.append(f"links with no sphere: {list(miss.bare)}")
        warnings.warn(
            f"{who}: the {len(spheres)} collision spheres of robot {robot.name!r} leave out "
            f"part of its collision geometry: {'; '.join(parts)}. The clearance they keep is "
            f"not the robot's; spheres covering it: {fix}",
            RobotWarning,
            stacklevel=3,
        )
    return miss
