"""Solid shapes in the world: `Sphere`, `Box` (oriented), `Capsule`, `Cylinder`, `HalfSpace`.

Shapes are frozen dataclasses validated on construction (`geosyn.world.validation`), in
world coordinates [m]. The same objects are obstacles of the metric shaping term
(`geosyn.metrics.shaping.ObstacleTerm`) and geoms of the simulation scene
(`geosyn.sim.build_scene`); `geosyn.world.distance` gives their signed distances.

Every shape is also one *rounded box* (`rounded_box`): the Minkowski sum of an oriented box
(centre ``c``, rotation ``R``, half-extents ``h``) and a ball of radius ``r``, stored as
16 numbers ``(c (3), R (9, row-major), h (3), r)``. The four shapes map onto it exactly:

- `Sphere`: ``h = 0``, ``r`` the radius;
- `Capsule`: ``h = (L/2, 0, 0)`` along the segment, ``r`` the radius;
- `Box`: ``h`` the half-extents, ``r = 0``;
- `HalfSpace`: a cube of half-extent `HALFSPACE_EXTENT` with one face on the plane, so
  its distance is exactly ``n . x - offset`` for points within 100 m of the plane's point
  closest to the origin (rounding error ~1e-14 m).

A `Cylinder` is not a rounded box: its `rounded_box` is the capsule on its axis with its
radius and length (a superset whose end caps reach ``radius`` beyond the flat ends), which
the obstacle shaping term uses; `geosyn.world.signed_distance` and
`geosyn.world.smooth.smooth_signed_distance` measure the cylinder itself.

One parameter layout for all shapes lets compiled functions take any shape as a
parameter value, without rebuilding.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from geosyn.core.types import Vector
from geosyn.world import validation as check
from geosyn.world.errors import InvalidGeometry
from geosyn.world.pose import rotation_with_axis

HALFSPACE_EXTENT = 100.0
"""Half-extent [m] of the cube that represents a `HalfSpace` as a rounded box."""

ROUNDED_BOX_SIZE = 16
"""Numbers per rounded box: centre (3), rotation (9, row-major), half-extents (3), radius (1)."""

_IDENTITY = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))


@dataclass(frozen=True)
class Sphere:
    """A ball.

    Attributes:
        center: (3,) centre in the world [m].
        radius: radius [m], > 0.
    """

    center: tuple[float, float, float]
    radius: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "center", check.point(self.center, "Sphere.center"))
        object.__setattr__(
            self, "radius", check.nonnegative(self.radius, "Sphere.radius", unit="m", strict=True)
        )

    def rounded_box(self) -> Vector:
        """(16,) rounded-box parameters: centre, rotation (row-major), half-extents, r."""
        return np.concatenate([self.center, np.eye(3).ravel(), np.zeros(3), [self.radius]])

    def moved_to(self, center: Vector) -> Sphere:
        """The same sphere centred at ``center`` (3,) [m]."""
        return Sphere(center, self.radius)  # type: ignore[arg-type]


@dataclass(frozen=True)
class Box:
    """An oriented box.

    Its signed distance is exact (not a smooth approximation): C1 outside the box, with
    jumps of the curvature across the face / edge / corner regions.

    Attributes:
        center: (3,) centre in the world [m].
        half_extents: (3,) half side lengths along the box axes [m], >= 0.
        rotation: (3, 3) world-from-box rotation (columns: the box axes in the world);
            see `geosyn.world.pose.rotation_from_rpy` to build one from angles.
    """

    center: tuple[float, float, float]
    half_extents: tuple[float, float, float]
    rotation: tuple[tuple[float, ...], ...] = _IDENTITY

    def __post_init__(self) -> None:
        object.__setattr__(self, "center", check.point(self.center, "Box.center"))
        h = check.point(self.half_extents, "Box.half_extents")
        if min(h) < 0.0:
            raise InvalidGeometry(
                f"Box.half_extents must be >= 0 [m], got {h}", "Box.half_extents", h
            )
        object.__setattr__(self, "half_extents", h)
        R = check.rotation(self.rotation, "Box.rotation")
        object.__setattr__(self, "rotation", tuple(tuple(map(float, r)) for r in R))

    def rounded_box(self) -> Vector:
        """(16,) rounded-box parameters: centre, rotation (row-major), half-extents, r."""
        R = np.asarray(self.rotation)
        return np.concatenate([self.center, R.ravel(), self.half_extents, [0.0]])

    def moved_to(self, center: Vector) -> Box:
        """The same box centred at ``center`` (3,) [m]."""
        return Box(center, self.half_extents, self.rotation)  # type: ignore[arg-type]


@dataclass(frozen=True)
class Capsule:
    """The set of points within ``radius`` of the segment ``p0 p1`` (``p0 == p1``: a ball).

    Attributes:
        p0: (3,) first end point in the world [m].
        p1: (3,) second end point in the world [m].
        radius: radius [m], > 0.
    """

    p0: tuple[float, float, float]
    p1: tuple[float, float, float]
    radius: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "p0", check.point(self.p0, "Capsule.p0"))
        object.__setattr__(self, "p1", check.point(self.p1, "Capsule.p1"))
        object.__setattr__(
            self, "radius", check.nonnegative(self.radius, "Capsule.radius", unit="m", strict=True)
        )

    def rounded_box(self) -> Vector:
        """(16,) rounded-box parameters: centre, rotation (row-major), half-extents, r."""
        p0, p1 = np.asarray(self.p0), np.asarray(self.p1)
        seg = p1 - p0
        length = float(np.linalg.norm(seg))
        R = np.eye(3) if length == 0.0 else rotation_with_axis(seg / length, 0)
        c = 0.5 * (p0 + p1)
        return np.concatenate([c, R.ravel(), [0.5 * length, 0.0, 0.0], [self.radius]])

    def moved_to(self, center: Vector) -> Capsule:
        """The same capsule translated so that its midpoint is ``center`` (3,) [m]."""
        d = np.asarray(center, dtype=np.float64) - 0.5 * (np.asarray(self.p0) + self.p1)
        return Capsule(np.asarray(self.p0) + d, np.asarray(self.p1) + d, self.radius)  # type: ignore[arg-type]


@dataclass(frozen=True)
class Cylinder:
    """A solid circular cylinder.

    Attributes:
        center: (3,) centre in the world [m].
        radius: radius [m], > 0.
        half_length: half its length along its axis [m], >= 0.
        rotation: (3, 3) world-from-cylinder rotation; its third column is the axis.
    """

    center: tuple[float, float, float]
    radius: float
    half_length: float
    rotation: tuple[tuple[float, ...], ...] = _IDENTITY

    def __post_init__(self) -> None:
        object.__setattr__(self, "center", check.point(self.center, "Cylinder.center"))
        object.__setattr__(
            self,
            "radius",
            check.nonnegative(self.radius, "Cylinder.radius", unit="m", strict=True),
        )
        object.__setattr__(
            self,
            "half_length",
            check.nonnegative(self.half_length, "Cylinder.half_length", unit="m"),
        )
        R = check.rotation(self.rotation, "Cylinder.rotation")
        object.__setattr__(self, "rotation", tuple(tuple(map(float, r)) for r in R))

    @property
    def axis(self) -> np.ndarray:
        """(3,) unit axis in the world."""
        return np.asarray(self.rotation)[:, 2]

    def rounded_box(self) -> Vector:
        """(16,) rounded-box parameters of the enclosing capsule (see the module doc)."""
        R = np.asarray(self.rotation)
        Rc = np.column_stack([R[:, 2], R[:, 0], R[:, 1]])  # capsule segment along its x
        return np.concatenate([self.center, Rc.ravel(), [self.half_length, 0.0, 0.0],
                               [self.radius]])  # fmt: skip

    def moved_to(self, center: Vector) -> Cylinder:
        """The same cylinder centred at ``center`` (3,) [m]."""
        return Cylinder(center, self.radius, self.half_length, self.rotation)  # type: ignore[arg-type]


@dataclass(frozen=True)
class HalfSpace:
    """The half-space ``{x : normal . x <= offset}`` (free space is ``normal . x > offset``).

    Example: a floor at z = 0 is ``HalfSpace((0, 0, 1), 0.0)``.

    Attributes:
        normal: (3,) unit normal pointing out of the obstacle, into free space.
        offset: plane offset along the normal [m].
    """

    normal: tuple[float, float, float]
    offset: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "normal", check.unit_vector(self.normal, "HalfSpace.normal"))
        object.__setattr__(self, "offset", check.offset(self.offset, "HalfSpace.offset"))

    def rounded_box(self) -> Vector:
        """(16,) rounded-box parameters: a 100 m cube with one face on the plane."""
        n = np.asarray(self.normal)
        R = rotation_with_axis(n, 2)
        c = (self.offset - HALFSPACE_EXTENT) * n
        return np.concatenate([c, R.ravel(), [HALFSPACE_EXTENT] * 3, [0.0]])

    def moved_to(self, center: Vector) -> HalfSpace:
        """The same half-space with its plane through the point ``center`` (3,) [m]."""
        return HalfSpace(self.normal, float(np.dot(self.normal, center)))


Shape = Sphere | Box | Capsule | Cylinder | HalfSpace
"""Any solid shape of the world."""

SHAPES: tuple[type, ...] = (Sphere, Box, Capsule, Cylinder, HalfSpace)
"""The shape classes, in documentation order."""


def check_shape(obj: object, name: str) -> Shape:
    """Return ``obj`` if it is a shape, else raise `InvalidGeometry`.

    Args:
        obj: candidate shape.
        name: argument name for the message, e.g. ``"obstacles[2]"``.

    Raises:
        InvalidGeometry: ``obj`` is not a `Sphere`, `Box`, `Capsule`, `Cylinder` or
            `HalfSpace`.
    """
    if not isinstance(obj, SHAPES):
        raise InvalidGeometry(
            f"{name} is a {type(obj).__name__}, not a supported shape; allowed: "
            f"{', '.join(s.__name__ for s in SHAPES)} (geosyn.world)",
            name,
            obj,
        )
    return obj  # type: ignore[return-value]
