"""`ObstacleTerm`: barrier metrics pulled back along the clearance of robot spheres.

Obstacles are the shapes of `geosyn.world` (`Sphere`, `Box`, `Capsule`, `Cylinder` as
its enclosing capsule, `HalfSpace`), each stored in one parameter *slot* as its rounded
box (`geosyn.world.shapes`) plus an active flag, and measured with the rounded box's exact
signed distance (`geosyn.world.distance.rounded_box_distance`, the default) or its smooth
conservative approximation (``distance="smooth"``, `geosyn.world.smooth`). Because all
shapes share one parameter layout, the compiled functions have a fixed number of slots
(``capacity``); moving, adding or removing obstacles up to the capacity only writes the
parameter array.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import casadi as ca
import numpy as np

from geosyn.core.calls import numpy_function as _numpy_call
from geosyn.core.errors import InvalidArgument
from geosyn.core.validation import check_int, check_positive, check_vector
from geosyn.metrics.shaping.base import MetricTerm
from geosyn.metrics.shaping.errors import CapacityExceeded, InvalidTermArgument, term_arguments
from geosyn.metrics.shaping.profiles import GATES, PROFILES
from geosyn.robots.robot import CollisionSphere, Robot
from geosyn.robots.sphere_cover import check_spheres, report_sphere_miss, resolve_spheres
from geosyn.world.distance import rounded_box_distance
from geosyn.world.shapes import ROUNDED_BOX_SIZE, Shape, check_shape
from geosyn.world.smooth import smooth_rounded_box_distance

__all__ = [
    "DISTANCES",
    "GATES",
    "HOMOTOPY_RADIUS",
    "INACTIVE_CLEARANCE",
    "ObstacleTerm",
    "PARAMS_PER_OBSTACLE",
    "PROFILE_PARAMS",
    "PROFILES",
]

HOMOTOPY_RADIUS = 1e-3
"""Radius [m] of the ball each obstacle shrinks to at the start of a log-map homotopy."""

INACTIVE_CLEARANCE = 10.0
"""Clearance [m] that `ObstacleTerm.symbolic_clearances` reports for an empty slot."""

PARAMS_PER_OBSTACLE = ROUNDED_BOX_SIZE + 1
"""Parameters per obstacle slot (17): centre (3), rotation (9, row-major), half-extents (3),
rounding radius (1), active flag (1)."""

PROFILE_PARAMS = 2
"""Parameters after the slots: the profile's ``gain`` and ``cutoff`` [m]."""


DISTANCES: dict[str, Callable[[], ca.Function]] = {
    "exact": rounded_box_distance,
    "smooth": smooth_rounded_box_distance,
}
"""Registry of the signed distances by name: ``"exact"`` (C1,
`geosyn.world.distance.rounded_box_distance`) or ``"smooth"`` (C-infinity, at most
`geosyn.world.smooth.error_bound` below the exact one, `smooth_rounded_box_distance`)."""


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

    Obstacle poses and sizes, and the profile's ``gain`` and ``cutoff``, are parameters:
    the term owns a CasADi symbol of ``capacity * PARAMS_PER_OBSTACLE + PROFILE_PARAMS``
    values (rounded-box parameters and an active flag per slot, then gain and cutoff).
    `set_obstacles` and `move` only write that numpy array, so any compiled function of a
    `ShapedMetric` using the term stays valid; and terms that differ only in gain or cutoff
    share their compiled code (no compile when a sweep varies them).

    Args:
        obstacles: initial obstacles, shapes of `geosyn.world` (`Sphere`, `Box`,
            `Capsule`, `HalfSpace`).
        capacity: number of obstacle slots, >= 1.
        spheres: robot collision spheres; None: ``robot.collision_spheres()``; ``"file"``:
            spheres covering the file's collision geometry (`geosyn.robots.sphere_cover.resolve_spheres`).
        profile: name of the weight profile in `PROFILES`.
        gain: profile gain [kg m^2 for "inverse_square", kg for "rmp"], > 0.
        cutoff: distance beyond which an obstacle contributes nothing [m], > 0.
        d_min: clearance clamp of "inverse_square" [m], 0 < d_min < cutoff.
        length: length scale l of "rmp" [m], > 0.
        epsilon: "rmp" bound parameter (max weight gain / epsilon), > 0.
        gate: name of the gate in `GATES`.
        gate_speed: approach speed at which the "approach" gate is fully on [m/s], > 0.
        distance: name of the signed distance in `DISTANCES` (``"exact"``, the default,
            or ``"smooth"``).

    Raises:
        InvalidTermArgument: a setting is out of range or names an unknown profile/gate.
        geosyn.world.InvalidGeometry: an obstacle is not a shape of `geosyn.world`.
        CapacityExceeded: more obstacles than ``capacity``.
    """

    def __init__(
        self,
        obstacles: Sequence[Shape] = (),
        capacity: int = 16,
        spheres: Sequence[CollisionSphere] | str | None = None,
        *,
        profile: str = "inverse_square",
        gain: float = 1e-3,
        cutoff: float = 0.2,
        d_min: float = 1e-4,
        length: float = 0.05,
        epsilon: float = 0.05,
        gate: str = "none",
        gate_speed: float = 0.05,
        distance: str = "exact",
    ) -> None:
        super().__init__()
        if distance not in DISTANCES:
            raise InvalidTermArgument(
                f"distance {distance!r} is unknown; allowed: {', '.join(DISTANCES)}"
            )
        self.distance = distance
        if profile not in PROFILES:
            raise InvalidTermArgument(
                f"profile {profile!r} is unknown; allowed: {', '.join(PROFILES)}"
            )
        if gate not in GATES:
            raise InvalidTermArgument(f"gate {gate!r} is unknown; allowed: {', '.join(GATES)}")
        with term_arguments():
            self.capacity = check_int(capacity, "capacity", low=1)
            self.d_min = check_positive(d_min, "d_min", "m")
            self.length = check_positive(length, "length", "m")
            self.epsilon = check_positive(epsilon, "epsilon")
            self.gate_speed = check_positive(gate_speed, "gate_speed", "m/s")
        self.profile = profile
        self.gate = gate
        self.velocity_dependent = gate != "none"
        try:
            self._spheres_arg = check_spheres(spheres, "spheres")
        except InvalidArgument as err:
            raise InvalidTermArgument(str(err)) from None
        self.spheres: tuple[CollisionSphere, ...] = ()
        self._sphere_joints: list[int] = []
        n_slots = self._n_slots = self.capacity * PARAMS_PER_OBSTACLE
        self._p = ca.SX.sym("obstacle_params", n_slots + PROFILE_PARAMS)
        self._values = np.zeros(n_slots + PROFILE_PARAMS)
        self._slots = self._values[:n_slots].reshape(self.capacity, PARAMS_PER_OBSTACLE)
        self._gain, self._cutoff = self._p[n_slots], self._p[n_slots + 1]
        with term_arguments():
            self._write_profile(check_positive(gain, "gain"), check_positive(cutoff, "cutoff", "m"))
        self._obstacles: list[Shape] = []
        self._clearance_call: Callable[..., tuple[np.ndarray, ...]] | None = None
        self.set_obstacles(obstacles)

    def __repr__(self) -> str:
        return (
            f"ObstacleTerm({len(self._obstacles)}/{self.capacity} obstacles, "
            f"profile={self.profile!r}, gate={self.gate!r})"
        )

    # -- obstacles (parameter writes only) -------------------------------------------
    @property
    def obstacles(self) -> tuple[Shape, ...]:
        """The active obstacles, in slot order."""
        return tuple(self._obstacles)

    def _write_slot(self, index: int, obstacle: Shape) -> None:
        self._slots[index, :ROUNDED_BOX_SIZE] = obstacle.rounded_box()
        self._slots[index, ROUNDED_BOX_SIZE] = 1.0

    def set_obstacles(self, obstacles: Sequence[Shape]) -> None:
        """Replace all obstacles (a parameter write; rebuilds nothing).

        Args:
            obstacles: at most ``capacity`` obstacles.

        Raises:
            geosyn.world.InvalidGeometry: an element is not a shape.
            CapacityExceeded: more than ``capacity`` obstacles.
        """
        obstacles = list(obstacles)
        if len(obstacles) > self.capacity:
            raise CapacityExceeded(
                f"obstacles has {len(obstacles)} elements but the term's capacity is "
                f"{self.capacity}; create the ObstacleTerm with capacity >= {len(obstacles)}",
                self.capacity,
                len(obstacles),
            )
        obstacles = [check_shape(ob, f"obstacles[{i}]") for i, ob in enumerate(obstacles)]
        slots = self._slots
        slots[:] = 0.0
        slots[:, 3:12] = np.eye(3).ravel()  # harmless identity rotation in empty slots
        for i, ob in enumerate(obstacles):
            self._write_slot(i, ob)
        self._obstacles = obstacles

    def set_obstacle(self, index: int, obstacle: Shape) -> None:
        """Replace obstacle ``index``, or append it when ``index == len(obstacles)``.

        Raises:
            geosyn.world.InvalidGeometry: ``obstacle`` is not a shape.
            InvalidTermArgument: ``index`` out of range.
            CapacityExceeded: appending beyond the capacity.
        """
        obstacle = check_shape(obstacle, "obstacle")
        k = len(self._obstacles)
        if index == k and k == self.capacity:
            raise CapacityExceeded(
                f"cannot add obstacle {index}: the term's capacity is {self.capacity}",
                self.capacity,
                k + 1,
            )
        with term_arguments():
            index = check_int(index, "index", low=0, high=k)
        self._write_slot(index, obstacle)
        if index == k:
            self._obstacles.append(obstacle)
        else:
            self._obstacles[index] = obstacle

    def set_profile(self, gain: float | None = None, cutoff: float | None = None) -> None:
        """Change the profile's gain and/or cutoff (a parameter write; rebuilds nothing:
        the compiled functions of a `ShapedMetric` read them at their next call).

        Args:
            gain: new gain (units as the constructor's), > 0; None keeps it.
            cutoff: new cutoff [m], > 0 and > ``d_min``; None keeps it.

        Raises:
            InvalidTermArgument: a value out of range (nothing is changed then).
        """
        with term_arguments():
            g = self.gain if gain is None else check_positive(gain, "gain")
            c = self.cutoff if cutoff is None else check_positive(cutoff, "cutoff", "m")
        self._write_profile(g, c)

    def _write_profile(self, gain: float, cutoff: float) -> None:
        if self.d_min >= cutoff:
            raise InvalidTermArgument(
                f"d_min must be < cutoff [m], got d_min={self.d_min!r}, cutoff={cutoff!r}"
            )
        self._values[self._n_slots :] = (gain, cutoff)

    @property
    def gain(self) -> float:
        """The profile's gain (a parameter: `set_profile` changes it)."""
        return float(self._values[self._n_slots])

    @property
    def cutoff(self) -> float:
        """The profile's cutoff [m] (a parameter: `set_profile` changes it)."""
        return float(self._values[self._n_slots + 1])

    def move(self, index: int, center: Sequence[float] | np.ndarray) -> None:
        """Translate obstacle ``index`` (a parameter write; rebuilds nothing).

        `Sphere` and `Box` get the new centre, a `Capsule` its midpoint, and a `HalfSpace`
        its plane through ``center``.

        Args:
            index: obstacle index in [0, len(obstacles)).
            center: (3,) new reference point in the world [m].

        Raises:
            InvalidTermArgument: ``index`` out of range.
            geosyn.world.InvalidGeometry: ``center`` is not a finite (3,) vector.
        """
        with term_arguments():
            index = check_int(index, "index", low=0, high=len(self._obstacles) - 1)
        ob = self._obstacles[index].moved_to(center)  # type: ignore[arg-type]
        self._write_slot(index, ob)
        self._obstacles[index] = ob

    def symbolic_parameters(self) -> ca.SX:
        """(capacity * 17 + 2, 1) SX parameter symbol: the slots (`PARAMS_PER_OBSTACLE`
        each), then gain and cutoff (`PROFILE_PARAMS`)."""
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
            (capacity * 17 + 2,) parameters (a new array; gain and cutoff unchanged).
        """
        s = float(np.clip(s, 0.0, 1.0))
        values = self._values.copy()
        slots = values[: self._n_slots].reshape(self.capacity, PARAMS_PER_OBSTACLE)
        slots[:, 12:15] *= s
        slots[:, 15] = s * slots[:, 15] + (1.0 - s) * HOMOTOPY_RADIUS
        return values

    def parameter_values(self) -> np.ndarray:
        """(capacity * 17 + 2,) current parameters (the live array: do not modify)."""
        return self._values

    # -- binding and symbolic form ---------------------------------------------------
    def _on_bind(self, robot: Robot) -> None:
        spheres = resolve_spheres(robot, self._spheres_arg, "spheres")
        if not spheres:
            raise InvalidTermArgument(
                f"robot {robot.name!r} has no collision spheres; pass spheres= explicitly"
            )
        self._sphere_joints = [robot.joint_id(s.joint) for s in spheres]
        self.spheres = tuple(spheres)
        fix = "spheres='file' (YAML: the obstacle term's spheres: file)"
        report_sphere_miss(robot, self.spheres, "ObstacleTerm", fix)  # warned once

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
        dist = DISTANCES[self.distance]()
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
                w = active * profile(d, self._gain, self._cutoff, self)
                if xdot is not None:
                    w = w * gate(ca.dot(nrm, xdot), self)
                A = A + w * ca.mtimes(nrm, nrm.T)
            G = G + ca.mtimes(J.T, ca.mtimes(A, J))
        return G

    def symbolic_clearances(self, q: ca.SX, softmin: float | None = None) -> ca.SX:
        """SX clearances of the robot spheres to every obstacle slot, for constraints.

        Without ``softmin``: row ``s * capacity + o`` is ``sd_o(x_s(q)) - r_s`` [m] for an
        active slot ``o`` and `INACTIVE_CLEARANCE` for an empty one, so a constraint
        ``clearance >= margin`` holds trivially on empty slots and one function serves any
        obstacle count. With ``softmin = k`` [1/m]: one row per slot, the smooth minimum
        over the spheres ``-log(sum_s exp(-k d_so)) / k``, which lies between
        ``min_s d_so - log(n_spheres) / k`` and ``min_s d_so`` (conservative).

        Args:
            q: (n, 1) SX joint positions [rad].
            softmin: sharpness of the smooth minimum over spheres [1/m], > 0, or None.

        Returns:
            (n_spheres * capacity, 1) or (capacity, 1) SX expression, containing
            `symbolic_parameters`.
        """
        pairs = [p for _, p in self._pairs(q)]
        if softmin is None:
            rows = [
                active * d + (1.0 - active) * INACTIVE_CLEARANCE
                for sphere in pairs
                for d, _, active in sphere
            ]
            return ca.vertcat(*rows)
        k = check_positive(softmin, "softmin", "1/m")
        rows = []
        for o in range(self.capacity):
            d = ca.vertcat(*[sphere[o][0] for sphere in pairs])
            low = ca.mmin(d)  # the shift cancels analytically (exact derivatives)
            smooth = low - ca.log(ca.sum1(ca.exp(-k * (d - low)))) / k
            active = pairs[0][o][2]
            rows.append(active * smooth + (1.0 - active) * INACTIVE_CLEARANCE)
        return ca.vertcat(*rows)

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
