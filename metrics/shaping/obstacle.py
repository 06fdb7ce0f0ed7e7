"""`ObstacleTerm`: barrier metrics pulled back along the clearance of robot spheres.

Every obstacle shape is stored as one primitive, a *rounded box*: the Minkowski sum of an
oriented box (centre ``c``, rotation ``R``, half-extents ``h``) and a ball of radius
``r``. Its signed distance at a point ``x`` is

.. math::
    p = R^T (x - c), \\qquad
    \\mathrm{sd}(x) = \\lVert p - \\mathrm{clamp}(p, -h, h) \\rVert
                    + \\min(\\max_i (|p_i| - h_i), 0) - r

which is the exact Euclidean signed distance. The four shapes map onto it exactly:

- `Sphere`: ``h = 0``, ``r`` the radius (smooth everywhere outside the centre);
- `Capsule`: ``h = (L/2, 0, 0)`` along the segment, ``r`` the radius (C1 outside,
  curvature jumps where the closest point moves from the segment's body to an end cap);
- `Box`: ``h`` the half-extents, ``r = 0`` (exact signed distance, not a smooth
  approximation: C1 outside the box, with jumps of the curvature, and so of the
  Christoffel symbols, across the face / edge / corner regions);
- `HalfSpace`: a cube of half-extent `HALFSPACE_EXTENT` (100 m) with one face on the
  plane, so the distance is exactly ``n . x - offset`` for points within 100 m of the
  plane's point closest to the origin (rounding error ~1e-14 m).

Because all shapes share one parameter layout, the compiled functions have a fixed number
of obstacle *slots* (``capacity``); moving, adding or removing obstacles up to the
capacity only writes the parameter array.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import casadi as ca
import numpy as np

from geosyn.core.validation import check_vector
from geosyn.metrics.shaping.base import MetricTerm, _numpy_call
from geosyn.metrics.shaping.errors import (
    CapacityExceeded,
    InvalidObstacle,
    InvalidTermArgument,
    UnknownObstacleType,
)
from geosyn.robots.robot import CollisionSphere, Robot

__all__ = [
    "Box",
    "Capsule",
    "GATES",
    "HALFSPACE_EXTENT",
    "HalfSpace",
    "Obstacle",
    "ObstacleTerm",
    "PARAMS_PER_OBSTACLE",
    "PROFILES",
    "Sphere",
]

HALFSPACE_EXTENT = 100.0
"""Half-extent [m] of the cube that represents a `HalfSpace`."""

HOMOTOPY_RADIUS = 1e-3
"""Radius [m] of the ball each obstacle shrinks to at the start of a log-map homotopy."""

PARAMS_PER_OBSTACLE = 17
"""Parameters per obstacle slot: centre (3), rotation (9, row-major), half-extents (3),
rounding radius (1), active flag (1)."""

_ORTHO_TOL = 1e-9


def _vec3(x: object, name: str, shape: str) -> tuple[float, float, float]:
    try:
        a = np.asarray(x, dtype=np.float64)
    except (TypeError, ValueError) as err:
        raise InvalidObstacle(f"{shape}.{name} must be a finite (3,) vector, got {x!r}") from err
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        raise InvalidObstacle(f"{shape}.{name} must be a finite (3,) vector, got {x!r}")
    return (float(a[0]), float(a[1]), float(a[2]))


def _nonneg(x: object, name: str, shape: str, strict: bool = False) -> float:
    try:
        f = float(x)  # type: ignore[arg-type]
    except (TypeError, ValueError) as err:
        raise InvalidObstacle(f"{shape}.{name} must be a number [m], got {x!r}") from err
    if not math.isfinite(f) or f < 0.0 or (strict and f == 0.0):
        allowed = "> 0" if strict else ">= 0"
        raise InvalidObstacle(f"{shape}.{name} must be finite and {allowed} [m], got {x!r}")
    return f


def _frame_with_axis(axis: np.ndarray, column: int) -> np.ndarray:
    """A rotation matrix whose column ``column`` is the unit vector ``axis``."""
    helper = np.eye(3)[int(np.argmin(np.abs(axis)))]
    e1 = np.cross(axis, helper)
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(axis, e1)
    cols = [e1, e2]
    cols.insert(column, axis)
    R = np.column_stack(cols)
    if np.linalg.det(R) < 0:
        R[:, (column + 1) % 3] *= -1.0
    return R


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
        object.__setattr__(self, "center", _vec3(self.center, "center", "Sphere"))
        object.__setattr__(self, "radius", _nonneg(self.radius, "radius", "Sphere", True))

    def rounded_box(self) -> np.ndarray:
        """(16,) rounded-box parameters: centre, rotation (row-major), half-extents, r."""
        return np.concatenate([self.center, np.eye(3).ravel(), np.zeros(3), [self.radius]])

    def moved_to(self, center: np.ndarray) -> Sphere:
        """The same sphere centred at ``center`` (3,) [m]."""
        return Sphere(center, self.radius)  # type: ignore[arg-type]


@dataclass(frozen=True)
class Box:
    """An oriented box (exact signed distance; see the module docstring on smoothness).

    Attributes:
        center: (3,) centre in the world [m].
        half_extents: (3,) half side lengths along the box axes [m], >= 0.
        rotation: (3, 3) box axes in the world (columns), a rotation matrix.
    """

    center: tuple[float, float, float]
    half_extents: tuple[float, float, float]
    rotation: tuple[tuple[float, ...], ...] = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))

    def __post_init__(self) -> None:
        object.__setattr__(self, "center", _vec3(self.center, "center", "Box"))
        h = _vec3(self.half_extents, "half_extents", "Box")
        if min(h) < 0.0:
            raise InvalidObstacle(f"Box.half_extents must be >= 0 [m], got {h}")
        object.__setattr__(self, "half_extents", h)
        try:
            R = np.asarray(self.rotation, dtype=np.float64)
        except (TypeError, ValueError) as err:
            raise InvalidObstacle(
                f"Box.rotation must be a (3, 3) rotation matrix, got {self.rotation!r}"
            ) from err
        if (
            R.shape != (3, 3)
            or not np.all(np.isfinite(R))
            or np.max(np.abs(R.T @ R - np.eye(3))) > _ORTHO_TOL
            or np.linalg.det(R) < 0.0
        ):
            raise InvalidObstacle(
                f"Box.rotation must be a (3, 3) rotation matrix (R^T R = I within "
                f"{_ORTHO_TOL}, det +1), got {self.rotation!r}"
            )
        object.__setattr__(self, "rotation", tuple(tuple(map(float, r)) for r in R))

    def rounded_box(self) -> np.ndarray:
        """(16,) rounded-box parameters: centre, rotation (row-major), half-extents, r."""
        R = np.asarray(self.rotation)
        return np.concatenate([self.center, R.ravel(), self.half_extents, [0.0]])

    def moved_to(self, center: np.ndarray) -> Box:
        """The same box centred at ``center`` (3,) [m]."""
        return Box(center, self.half_extents, self.rotation)  # type: ignore[arg-type]


@dataclass(frozen=True)
class Capsule:
    """The set of points within ``radius`` of the segment ``p0 p1``.

    Attributes:
        p0: (3,) first end point in the world [m].
        p1: (3,) second end point in the world [m].
        radius: radius [m], > 0.
    """

    p0: tuple[float, float, float]
    p1: tuple[float, float, float]
    radius: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "p0", _vec3(self.p0, "p0", "Capsule"))
        object.__setattr__(self, "p1", _vec3(self.p1, "p1", "Capsule"))
        object.__setattr__(self, "radius", _nonneg(self.radius, "radius", "Capsule", True))

    def rounded_box(self) -> np.ndarray:
        """(16,) rounded-box parameters: centre, rotation (row-major), half-extents, r."""
        p0, p1 = np.asarray(self.p0), np.asarray(self.p1)
        seg = p1 - p0
        length = float(np.linalg.norm(seg))
        R = np.eye(3) if length == 0.0 else _frame_with_axis(seg / length, 0)
        c = 0.5 * (p0 + p1)
        return np.concatenate([c, R.ravel(), [0.5 * length, 0.0, 0.0], [self.radius]])

    def moved_to(self, center: np.ndarray) -> Capsule:
        """The same capsule translated so that its midpoint is ``center`` (3,) [m]."""
        d = np.asarray(center, dtype=np.float64) - 0.5 * (np.asarray(self.p0) + self.p1)
        return Capsule(np.asarray(self.p0) + d, np.asarray(self.p1) + d, self.radius)  # type: ignore[arg-type]


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
        n = _vec3(self.normal, "normal", "HalfSpace")
        if abs(math.sqrt(sum(x * x for x in n)) - 1.0) > _ORTHO_TOL:
            raise InvalidObstacle(f"HalfSpace.normal must be a unit vector, got {n}")
        object.__setattr__(self, "normal", n)
        try:
            off = float(self.offset)
        except (TypeError, ValueError) as err:
            raise InvalidObstacle(
                f"HalfSpace.offset must be a number [m], got {self.offset!r}"
            ) from err
        if not math.isfinite(off):
            raise InvalidObstacle(f"HalfSpace.offset must be finite [m], got {self.offset!r}")
        object.__setattr__(self, "offset", off)

    def rounded_box(self) -> np.ndarray:
        """(16,) rounded-box parameters: a 100 m cube with one face on the plane."""
        n = np.asarray(self.normal)
        R = _frame_with_axis(n, 2)
        c = (self.offset - HALFSPACE_EXTENT) * n
        return np.concatenate([c, R.ravel(), [HALFSPACE_EXTENT] * 3, [0.0]])

    def moved_to(self, center: np.ndarray) -> HalfSpace:
        """The same half-space with its plane through the point ``center`` (3,) [m]."""
        return HalfSpace(self.normal, float(np.dot(self.normal, center)))


Obstacle = Sphere | Box | Capsule | HalfSpace
_OBSTACLE_TYPES = (Sphere, Box, Capsule, HalfSpace)


# -- weight profiles w(d) and velocity gates ---------------------------------------------


def _inverse_square(d: ca.SX, term: ObstacleTerm) -> ca.SX:
    # w = gain (1/d - 1/d_cut)^2 for d < d_cut, 0 beyond: ~gain/d^2 near contact, C1 at the
    # cutoff; d clamped at d_min so the weight stays finite at and inside the boundary.
    dd = ca.fmax(d, term.d_min)
    u = ca.fmax(1.0 / dd - 1.0 / term.cutoff, 0.0)
    return term.gain * u * u


def _rmp(d: ca.SX, term: ObstacleTerm) -> ca.SX:
    # RMPflow-like bounded weight gain exp(-d/l) / (d/l + eps), times a C1 cutoff factor.
    dd = ca.fmax(d, 0.0)
    s = ca.fmax(1.0 - dd / term.cutoff, 0.0)
    return term.gain * s * s * ca.exp(-dd / term.length) / (dd / term.length + term.epsilon)


PROFILES: dict[str, Callable[[ca.SX, ObstacleTerm], ca.SX]] = {
    "inverse_square": _inverse_square,
    "rmp": _rmp,
}
"""Registry of weight profiles ``w(d)`` by name (see `ObstacleTerm`)."""


def _gate_none(ddot: ca.SX, term: ObstacleTerm) -> ca.SX | float:
    return 1.0


def _gate_approach(ddot: ca.SX, term: ObstacleTerm) -> ca.SX:
    # Smoothstep from 0 (d not decreasing) to 1 (approaching at gate_speed or faster).
    s = ca.fmin(ca.fmax(-ddot / term.gate_speed, 0.0), 1.0)
    return s * s * (3.0 - 2.0 * s)


GATES: dict[str, Callable[[ca.SX, ObstacleTerm], ca.SX | float]] = {
    "none": _gate_none,
    "approach": _gate_approach,
}
"""Registry of velocity gates by name (see `ObstacleTerm`)."""


def _rounded_box_distance() -> ca.Function:
    """``(x (3), prm (16)) -> (sd, d sd / dx)`` for the rounded-box primitive."""
    x = ca.SX.sym("x", 3)
    prm = ca.SX.sym("prm", PARAMS_PER_OBSTACLE - 1)
    c = prm[0:3]
    R = ca.reshape(prm[3:12], 3, 3).T  # row-major storage
    h = prm[12:15]
    r = prm[15]
    p = ca.mtimes(R.T, x - c)
    # Closest point of the box, by branches rather than fabs/fmax: at a tie (h_i = 0 and
    # p_i = 0, e.g. a planar scene) the outer branch is taken, so the derivatives of a
    # sphere's or capsule's distance are exact there too (AD through fabs at 0 is not).
    b = ca.vertcat(
        *[ca.if_else(p[i] >= h[i], h[i], ca.if_else(p[i] <= -h[i], -h[i], p[i])) for i in range(3)]
    )
    # The 1e-24 m^2 keeps the gradient finite (zero) at and inside the surface; it is below
    # round-off of any clearance above 1e-8 m.
    outside = ca.sqrt(ca.sumsqr(p - b) + 1e-24)
    inside = ca.fmin(ca.mmax(ca.fabs(p) - h), 0.0)
    sd = outside + inside - r
    return ca.Function("rounded_box_distance", [x, prm], [sd, ca.gradient(sd, x)])


class ObstacleTerm(MetricTerm):
    """Barrier metric keeping the robot's collision spheres away from obstacles.

    For every robot sphere ``s`` (centre ``x_s(q)`` from symbolic forward kinematics,
    radius ``r_s``) and every active obstacle ``o``, the clearance is
    ``d = sd_o(x_s(q)) - r_s`` and the term adds the pull-back of a 1-D metric ``w(d)``
    along its gradient ``grad d = J_s^T n`` (``n = d sd_o / dx``, ``J_s = dx_s/dq``):

    .. math:: G_{obs}(q) = \\sum_{s,o} w(d_{so})\\, \\gamma_{so}\\, J_s^T n_{so} n_{so}^T J_s
                         = \\sum_s J_s^T \\Big(\\sum_o w\\, \\gamma\\, n n^T\\Big) J_s

    which is symmetric PSD. Weight profiles ``w(d)`` (registry `PROFILES`):

    - ``"inverse_square"`` (default): ``w = gain (1/d - 1/cutoff)^2`` for ``d < cutoff``,
      0 beyond. Near contact ``w ~ gain / d^2``, so the Riemannian distance to the boundary
      ``int sqrt(w) dd`` diverges (logarithmically) and geodesics cannot reach it. ``d`` is
      clamped at ``d_min`` (default 1e-4 m): at and inside the boundary the weight is the
      large constant ``gain (1/d_min - 1/cutoff)^2``.
    - ``"rmp"``: RMPflow-like bounded ``w = gain exp(-d/l) / (d/l + epsilon)``, times
      ``(1 - d/cutoff)^2`` for ``d < cutoff``; at most ``gain / epsilon``.

    Both vanish with their first derivative at ``d = cutoff``: obstacles farther than the
    cutoff contribute exactly nothing (to G and its derivatives).

    Gates ``gamma`` (registry `GATES`): ``"none"`` (1) or ``"approach"`` (velocity-gated:
    active only while the sphere approaches the obstacle, ``ddot = grad d . qdot < 0``,
    with a C1 smoothstep from 0 at ``ddot = 0`` to 1 at ``ddot = -gate_speed``). A gated
    term is velocity dependent; see `ShapedMetric` for the geodesic equation used then.

    How geodesics behave. The barrier only weighs the *normal* velocity ``ddot``: close to
    an obstacle the normal direction becomes very heavy, so a geodesic's approach speed is
    driven to zero and it cannot reach the surface, but it is not pushed away either; a
    shaped geodesic bends around an obstacle in its way at a clearance that grows with
    ``gain`` (a few cm for gain 1e-2 kg m^2 on planar2 and panda). Boundary-value
    problems (log) near the barrier become ill-conditioned for single shooting as the
    clearance shrinks; a continuation on the obstacle's size or position (parameter
    writes only, see `set_obstacle`) warm-starts them well.

    Obstacle poses and sizes are parameters: the term owns a CasADi symbol of
    ``capacity * PARAMS_PER_OBSTACLE`` values (rounded-box parameters and an active flag
    per slot). `set_obstacles` and `move` only write that numpy array, so any compiled
    function of a `ShapedMetric` using the term stays valid.

    Args:
        obstacles: initial obstacles (`Sphere`, `Box`, `Capsule`, `HalfSpace`).
        capacity: number of obstacle slots, >= 1.
        spheres: robot collision spheres; None uses ``robot.collision_spheres()``.
        profile: name of the weight profile in `PROFILES`.
        gain: profile gain [kg m^2 for "inverse_square", kg for "rmp"], > 0.
        cutoff: distance beyond which an obstacle contributes nothing [m], > 0.
        d_min: clearance clamp of "inverse_square" [m], 0 < d_min < cutoff.
        length: length scale l of "rmp" [m], > 0.
        epsilon: "rmp" bound parameter (max weight gain / epsilon), > 0.
        gate: name of the gate in `GATES`.
        gate_speed: approach speed at which the "approach" gate is fully on [m/s], > 0.

    Raises:
        InvalidTermArgument: a setting is out of range or names an unknown profile/gate.
        UnknownObstacleType: an obstacle is not a supported shape.
        CapacityExceeded: more obstacles than ``capacity``.
    """

    def __init__(
        self,
        obstacles: Sequence[Obstacle] = (),
        capacity: int = 16,
        spheres: Sequence[CollisionSphere] | None = None,
        *,
        profile: str = "inverse_square",
        gain: float = 1e-3,
        cutoff: float = 0.2,
        d_min: float = 1e-4,
        length: float = 0.05,
        epsilon: float = 0.05,
        gate: str = "none",
        gate_speed: float = 0.05,
    ) -> None:
        super().__init__()
        if (
            isinstance(capacity, bool)
            or not isinstance(capacity, (int, np.integer))
            or capacity < 1
        ):
            raise InvalidTermArgument(f"capacity must be an int >= 1, got {capacity!r}")
        if profile not in PROFILES:
            raise InvalidTermArgument(
                f"profile {profile!r} is unknown; allowed: {', '.join(PROFILES)}"
            )
        if gate not in GATES:
            raise InvalidTermArgument(f"gate {gate!r} is unknown; allowed: {', '.join(GATES)}")
        for name, val in (
            ("gain", gain),
            ("cutoff", cutoff),
            ("d_min", d_min),
            ("length", length),
            ("epsilon", epsilon),
            ("gate_speed", gate_speed),
        ):
            if not isinstance(val, (int, float, np.floating)) or not (
                math.isfinite(val) and val > 0
            ):
                raise InvalidTermArgument(f"{name} must be finite and > 0, got {val!r}")
        if d_min >= cutoff:
            raise InvalidTermArgument(
                f"d_min must be < cutoff [m], got d_min={d_min!r}, cutoff={cutoff!r}"
            )
        self.capacity = int(capacity)
        self.profile = profile
        self.gain = float(gain)
        self.cutoff = float(cutoff)
        self.d_min = float(d_min)
        self.length = float(length)
        self.epsilon = float(epsilon)
        self.gate = gate
        self.gate_speed = float(gate_speed)
        self.velocity_dependent = gate != "none"
        self._spheres_arg = None if spheres is None else tuple(spheres)
        if self._spheres_arg is not None:
            for i, s in enumerate(self._spheres_arg):
                if not isinstance(s, CollisionSphere):
                    raise InvalidTermArgument(
                        f"spheres[{i}] must be a CollisionSphere, got {type(s).__name__}"
                    )
        self.spheres: tuple[CollisionSphere, ...] = ()
        self._sphere_joints: list[int] = []
        self._p = ca.SX.sym("obstacle_params", self.capacity * PARAMS_PER_OBSTACLE)
        self._values = np.zeros(self.capacity * PARAMS_PER_OBSTACLE)
        self._slots = self._values.reshape(self.capacity, PARAMS_PER_OBSTACLE)
        self._obstacles: list[Obstacle] = []
        self._clearance_call: Callable[..., tuple[np.ndarray, ...]] | None = None
        self.set_obstacles(obstacles)

    def __repr__(self) -> str:
        return (
            f"ObstacleTerm({len(self._obstacles)}/{self.capacity} obstacles, "
            f"profile={self.profile!r}, gate={self.gate!r})"
        )

    # -- obstacles (parameter writes only) -------------------------------------------
    @property
    def obstacles(self) -> tuple[Obstacle, ...]:
        """The active obstacles, in slot order."""
        return tuple(self._obstacles)

    @staticmethod
    def _check_obstacle(ob: object, where: str) -> None:
        if not isinstance(ob, _OBSTACLE_TYPES):
            raise UnknownObstacleType(
                f"{where} is a {type(ob).__name__}, not a supported obstacle; allowed: "
                "Sphere, Box, Capsule, HalfSpace (geosyn.metrics.shaping)"
            )

    def set_obstacles(self, obstacles: Sequence[Obstacle]) -> None:
        """Replace all obstacles (a parameter write; rebuilds nothing).

        Args:
            obstacles: at most ``capacity`` obstacles.

        Raises:
            UnknownObstacleType: an element is not a supported shape.
            CapacityExceeded: more than ``capacity`` obstacles.
        """
        obstacles = list(obstacles)
        if len(obstacles) > self.capacity:
            raise CapacityExceeded(
                f"obstacles has {len(obstacles)} elements but the term's capacity is "
                f"{self.capacity}; create the ObstacleTerm with capacity >= {len(obstacles)}"
            )
        for i, ob in enumerate(obstacles):
            self._check_obstacle(ob, f"obstacles[{i}]")
        slots = self._slots
        slots[:] = 0.0
        slots[:, 3:12] = np.eye(3).ravel()  # harmless identity rotation in empty slots
        for i, ob in enumerate(obstacles):
            slots[i, :16] = ob.rounded_box()
            slots[i, 16] = 1.0
        self._obstacles = obstacles

    def set_obstacle(self, index: int, obstacle: Obstacle) -> None:
        """Replace obstacle ``index``, or append it when ``index == len(obstacles)``.

        Raises:
            UnknownObstacleType: not a supported shape.
            InvalidTermArgument: ``index`` out of range.
            CapacityExceeded: appending beyond the capacity.
        """
        self._check_obstacle(obstacle, "obstacle")
        k = len(self._obstacles)
        if index == k and k == self.capacity:
            raise CapacityExceeded(
                f"cannot add obstacle {index}: the term's capacity is {self.capacity}"
            )
        if not (isinstance(index, (int, np.integer)) and 0 <= index <= k):
            raise InvalidTermArgument(f"index must be in [0, {k}], got {index!r}")
        self._slots[index, :16] = obstacle.rounded_box()
        self._slots[index, 16] = 1.0
        if index == k:
            self._obstacles.append(obstacle)
        else:
            self._obstacles[index] = obstacle

    def move(self, index: int, center: Sequence[float] | np.ndarray) -> None:
        """Translate obstacle ``index`` (a parameter write; rebuilds nothing).

        `Sphere` and `Box` get the new centre, a `Capsule` its midpoint, and a `HalfSpace`
        its plane through ``center``.

        Args:
            index: obstacle index in [0, len(obstacles)).
            center: (3,) new reference point in the world [m].

        Raises:
            InvalidTermArgument: ``index`` out of range.
            InvalidObstacle: ``center`` is not a finite (3,) vector.
        """
        if not (isinstance(index, (int, np.integer)) and 0 <= index < len(self._obstacles)):
            raise InvalidTermArgument(
                f"index must be in [0, {len(self._obstacles)}), got {index!r}"
            )
        ob = self._obstacles[index].moved_to(center)  # type: ignore[arg-type]
        self._slots[index, :16] = ob.rounded_box()
        self._obstacles[index] = ob

    def symbolic_parameters(self) -> ca.SX:
        """(capacity * 17, 1) SX parameter symbol (see `PARAMS_PER_OBSTACLE`)."""
        return self._p

    def parameter_homotopy(self, s: float) -> np.ndarray:
        """Obstacles shrunk about their centres: sizes scaled by ``s`` in [0, 1].

        Half-extents become ``s h`` and the rounding radius ``s r + (1 - s) HOMOTOPY_RADIUS``,
        so at ``s = 0`` every obstacle is a 1 mm ball at its centre and at ``s = 1`` it is
        itself. A half-space's far-away cube grows until its face reaches the plane. Used by
        `log_solve` to follow a geodesic from around points to around the real obstacles.

        Args:
            s: homotopy parameter in [0, 1].

        Returns:
            (capacity * 17,) parameters (a new array).
        """
        s = float(np.clip(s, 0.0, 1.0))
        values = self._values.copy()
        slots = values.reshape(self.capacity, PARAMS_PER_OBSTACLE)
        slots[:, 12:15] *= s
        slots[:, 15] = s * slots[:, 15] + (1.0 - s) * HOMOTOPY_RADIUS
        return values

    def parameter_values(self) -> np.ndarray:
        """(capacity * 17,) current parameters (the live array: do not modify)."""
        return self._values

    # -- binding and symbolic form ---------------------------------------------------
    def _on_bind(self, robot: Robot) -> None:
        spheres = robot.collision_spheres() if self._spheres_arg is None else self._spheres_arg
        if not spheres:
            raise InvalidTermArgument(
                f"robot {robot.name!r} has no collision spheres; pass spheres= explicitly"
            )
        self._sphere_joints = [robot.joint_id(s.joint) for s in spheres]
        self.spheres = tuple(spheres)

    def _sphere_centers(self, q: ca.SX) -> list[ca.SX]:
        from geosyn.robots import symbolic

        oMi = symbolic.joint_placements(self.robot.model, q)
        out = []
        for s, jid in zip(self.spheres, self._sphere_joints, strict=True):
            R, p = oMi[jid]
            out.append(ca.mtimes(R, ca.DM(s.center)) + p)
        return out

    def _pairs(self, q: ca.SX) -> list[tuple[ca.SX, list[tuple[ca.SX, ca.SX, ca.SX]]]]:
        """Per sphere: (centre, [(clearance, normal, active) per slot])."""
        dist = _rounded_box_distance()
        P = PARAMS_PER_OBSTACLE
        out = []
        for s, x in zip(self.spheres, self._sphere_centers(q), strict=True):
            pairs = []
            for o in range(self.capacity):
                prm = self._p[o * P : o * P + P - 1]
                sd, n = dist(x, prm)
                pairs.append((sd - s.radius, n, self._p[o * P + P - 1]))
            out.append((x, pairs))
        return out

    def symbolic_G(self, q: ca.SX, v: ca.SX | None = None) -> ca.SX:
        """SX ``sum_s J_s^T (sum_o w gamma n n^T) J_s`` (see the class docstring)."""
        n = self.n
        profile = PROFILES[self.profile]
        gate = GATES[self.gate]
        G = ca.SX.zeros(n, n)
        for x, pairs in self._pairs(q):
            J = ca.jacobian(x, q)  # (3, n)
            if J.nnz() == 0:  # a sphere fixed to the base cannot move: no contribution
                continue
            xdot = None
            if self.velocity_dependent:
                xdot = ca.mtimes(J, v) if v is not None else ca.SX.zeros(3)
            A = ca.SX.zeros(3, 3)
            for d, nrm, active in pairs:
                w = active * profile(d, self)
                if xdot is not None:
                    w = w * gate(ca.dot(nrm, xdot), self)
                A = A + w * ca.mtimes(nrm, nrm.T)
            G = G + ca.mtimes(J.T, ca.mtimes(A, J))
        return G

    # -- diagnostics -----------------------------------------------------------------
    def clearances(self, q: np.ndarray) -> np.ndarray:
        """Clearance of every robot sphere to every active obstacle.

        Builds a CasADi function on first call (allocates), then only evaluates.

        Args:
            q: (n,) joint positions [rad].

        Returns:
            (n_spheres, n_obstacles) signed clearances [m] (negative: penetration).
        """
        q = check_vector(q, self.n, "q")
        if self._clearance_call is None:
            qs = ca.SX.sym("q", self.n)
            rows = [ca.horzcat(*[d for d, _, _ in pairs]) for _, pairs in self._pairs(qs)]
            f = ca.Function("obstacle_clearances", [qs, self._p], [ca.densify(ca.vertcat(*rows))])
            self._clearance_call = _numpy_call(f)
        out = np.asarray(self._clearance_call(q, self._values)[0])
        out = out.reshape(len(self.spheres), self.capacity)
        return np.array(out[:, : len(self._obstacles)])

    def min_clearance(self, q: np.ndarray) -> float:
        """Smallest clearance over all robot spheres and active obstacles [m] (inf if none)."""
        c = self.clearances(q)
        return float(c.min()) if c.size else math.inf
