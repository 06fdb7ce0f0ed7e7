"""References a controller tracks: ``sample(t) -> (q_ref, v_ref, a_ref)``.

- `GeodesicReference`: a geodesic (or a geodesic synergy's trajectory) of a metric,
  optionally slowed down or sped up by a time scale, with the exact geodesic acceleration.
- `JointTrajectoryReference`: a joint-space trajectory given by samples, interpolated by
  piecewise cubic (or quintic, when accelerations are given) polynomials.
- (`geosyn.controllers.coupled_reference.CoupledReference`: a reference in the
  independent coordinates z of coupled joints, lifted; `geosyn.controllers.
  sequence_reference.SequenceReference`: references played one after the other.)

On a robot with coupled joints, a `GeodesicReference` on the joints' metric whose samples
satisfy the coupling is computed in the independent coordinates on the pull-back metric and
lifted (its velocities and accelerations then keep the coupling too); samples off the
coupling are tracked as given, with a `RobotWarning` stating by how much they leave it.
`JointTrajectoryReference` interpolates linearly in its samples, so samples on a coupling
give positions on it.

All hold the final configuration with zero velocity and acceleration after their
duration, and the initial configuration with zero velocity and acceleration before their
start time ``t0``.
"""

from __future__ import annotations

import bisect
import warnings
from abc import ABC, abstractmethod
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np

from geosyn.core.errors import InvalidArgument
from geosyn.core.interpolation import hermite_cubic_coefficients, hermite_quintic_coefficients
from geosyn.core.types import Vector
from geosyn.core.validation import check_float, check_int, check_positive
from geosyn.metrics.coupled import CoupledMetric
from geosyn.robots.couplings import Coupling
from geosyn.robots.errors import RobotWarning

if TYPE_CHECKING:
    from geosyn.metrics.base import Metric


class ReferenceSample(NamedTuple):
    """A reference state; unpacks as ``q_ref, v_ref, a_ref = ref.sample(t)``.

    Attributes:
        q: (n,) joint positions [rad].
        v: (n,) joint velocities [rad/s].
        a: (n,) joint accelerations [rad/s^2].
    """

    q: Vector
    v: Vector
    a: Vector


class Reference(ABC):
    """A time-parametrised joint-space reference.

    Attributes:
        n: dimension (number of joints).
        duration: length of the moving part [s]; after ``t0 + duration`` the reference
            holds `goal` with zero velocity and acceleration.
        t0: start time [s] in the controller's clock.
    """

    n: int
    duration: float
    t0: float = 0.0

    @abstractmethod
    def sample(self, t: float) -> ReferenceSample:
        """Reference state at time ``t`` [s] (arrays are fresh copies).

        Before ``t0`` the start configuration is held, after ``t0 + duration`` the goal,
        both with zero velocity and acceleration.
        """

    @abstractmethod
    def goal(self) -> Vector:
        """(n,) final configuration [rad] (a copy)."""


class _Piecewise:
    """Piecewise polynomial in local time, evaluated as one small matrix product.

    ``x(t) = sum_p coef[k, p] (t - knots[k])**p`` on ``[knots[k], knots[k+1]]``.
    """

    def __init__(self, knots: np.ndarray, coef: np.ndarray) -> None:
        self.knots = [float(x) for x in knots]  # a list: bisect is cheaper than numpy
        self.coef = np.ascontiguousarray(coef, dtype=np.float64)  # (K, deg+1, n)
        p = np.arange(self.coef.shape[1], dtype=np.float64)
        # Rows: value, first and second derivative of the monomials s**p.
        self._exp = np.stack([p, np.maximum(p - 1, 0), np.maximum(p - 2, 0)])
        self._fac = np.stack([np.ones_like(p), p, p * (p - 1)])
        self.last = len(self.knots) - 2

    def __call__(self, t: float) -> tuple[Vector, Vector, Vector]:
        k = min(max(bisect.bisect_right(self.knots, t) - 1, 0), self.last)
        basis = self._fac * (t - self.knots[k]) ** self._exp
        out = basis @ self.coef[k]  # (3, n), a fresh array
        return out[0], out[1], out[2]


def _check_samples(t: object, q: object, name_q: str = "q") -> tuple[np.ndarray, np.ndarray]:
    try:
        t_arr = np.asarray(t, dtype=np.float64)
        q_arr = np.asarray(q, dtype=np.float64)
    except (TypeError, ValueError) as err:
        raise InvalidArgument(f"t and {name_q} must be float arrays: {err}") from err
    if t_arr.ndim != 1 or t_arr.size < 2:
        raise InvalidArgument(f"t must have shape (T,) with T >= 2, got shape {t_arr.shape}")
    if not np.all(np.isfinite(t_arr)) or np.any(np.diff(t_arr) <= 0.0):
        raise InvalidArgument("t must be finite and strictly increasing [s]")
    if q_arr.ndim != 2 or q_arr.shape[0] != t_arr.size or q_arr.shape[1] < 1:
        raise InvalidArgument(
            f"{name_q} must have shape (T, n) = ({t_arr.size}, n), got shape {q_arr.shape}"
        )
    if not np.all(np.isfinite(q_arr)):
        raise InvalidArgument(f"{name_q} must be finite")
    return t_arr, q_arr


def _check_like(x: object, shape: tuple[int, ...], name: str) -> np.ndarray:
    try:
        arr = np.asarray(x, dtype=np.float64)
    except (TypeError, ValueError) as err:
        raise InvalidArgument(f"{name} must be a float array of shape {shape}") from err
    if arr.shape != shape:
        raise InvalidArgument(f"{name} must have shape {shape}, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise InvalidArgument(f"{name} must be finite")
    return arr


class _SampledReference(Reference):
    """Shared sampling logic: clamp in time, hold start and goal, evaluate the spline."""

    _spline: _Piecewise
    _t_knots0: float
    _q_start: np.ndarray
    _q_goal: np.ndarray

    def _local(self, t: float) -> float | None:
        """Time since the first knot, or None when outside the moving part."""
        tau = t - self.t0
        if tau < 0.0 or tau > self.duration:
            return None
        return tau

    def _hold(self, t: float) -> ReferenceSample:
        q = self._q_start if t < self.t0 else self._q_goal
        return ReferenceSample(q.copy(), np.zeros(self.n), np.zeros(self.n))

    def goal(self) -> Vector:
        """(n,) final configuration [rad] (a copy)."""
        return self._q_goal.copy()


class GeodesicReference(_SampledReference):
    """A geodesic of a metric as a joint reference, with an optional time scale.

    The geodesic samples ``(t_k, q_k, v_k)`` are interpolated by a C1 cubic Hermite
    spline (position error O(h^4) in the sample spacing h). The velocity is the spline's
    derivative. The acceleration, when the metric is known, is the exact geodesic
    acceleration at the interpolated state, ``a = -G(q)^-1 C(q, v) v`` (one metric call
    per `sample`); without a metric it is the spline's second derivative (piecewise
    linear). For metrics whose geodesic acceleration is too slow for a control tick (e.g.
    a shaped metric evaluated by CasADi's virtual machine), ``exact_acceleration=False``
    evaluates it once per sample at construction and interpolates ``(q_k, v_k, a_k)`` by
    a C2 quintic Hermite spline instead (no metric call per `sample`).

    A time scale ``s`` traverses the same path in ``s`` times the time: the reference at
    controller time ``t0 + s * tau`` is the geodesic at ``tau``, with velocity divided by
    ``s`` and acceleration by ``s**2`` (a reparametrised geodesic is still a geodesic).

    A geodesic has constant speed, so it starts and ends moving; after ``duration`` the
    reference then steps to rest. With ``rest_to_rest=True`` the same path is traversed
    (in the same ``duration``) with the quintic time law
    ``sigma(u) = T_g (10 u^3 - 15 u^4 + 6 u^5)``, ``u = (t - t0) / duration``, so that
    velocity and acceleration are zero at both ends:

    .. math::
        q = \\gamma(\\sigma), \\quad \\dot q = \\gamma'(\\sigma)\\dot\\sigma, \\quad
        \\ddot q = \\Gamma(q, \\dot q) + \\gamma'(\\sigma)\\ddot\\sigma,

    where ``Gamma(q, qdot) = -G^-1 C(q, qdot) qdot`` is the geodesic acceleration
    (quadratic in the velocity). The path is still the geodesic; the timing is not.

    Args:
        source: a ``Geodesic`` (anything with arrays ``t`` (T,), ``q`` (T, n),
            ``v`` (T, n)) or a geodesic synergy (anything with ``metric``, ``q0``, ``v0``
            and ``trajectory(duration, steps)`` returning such a geodesic).
        metric: the metric whose geodesic this is (for the exact acceleration); taken
            from the synergy when ``source`` is one.
        t0: controller time [s] at which the reference starts.
        time_scale: time scale ``s > 0`` (``s > 1`` is slower).
        rest_to_rest: traverse the path with the quintic rest-to-rest time law.
        exact_acceleration: with a metric, evaluate the geodesic acceleration at each
            `sample` (True) or only at the knots, interpolated (False).
        duration: geodesic time [s] to sample when ``source`` is a synergy (ignored for
            a ``Geodesic``, which carries its own time stamps).
        steps: number of integration steps when ``source`` is a synergy.

    On a coupled robot (``metric.robot.coupling``, ``metric`` on the joints) samples on the
    coupling (to `COUPLING_TOLERANCE`) are tracked in the independent coordinates z on
    `geosyn.metrics.CoupledMetric` and lifted exactly (``coupling`` attribute set); samples
    off it are tracked as given, with a `RobotWarning` (``coupling`` None).

    `sample` allocates its three result arrays and calls the metric once.
    """

    coupling: Coupling | None = None

    def __init__(
        self,
        source: Any,
        metric: Metric | None = None,
        *,
        t0: float = 0.0,
        time_scale: float = 1.0,
        rest_to_rest: bool = False,
        exact_acceleration: bool = True,
        duration: float = 1.0,
        steps: int = 100,
    ) -> None:
        if hasattr(source, "trajectory") and hasattr(source, "metric"):
            if metric is None:
                metric = source.metric
            duration = check_positive(duration, "duration", "s")
            geo = source.trajectory(duration, check_int(steps, "steps", low=1))
        elif all(hasattr(source, name) for name in ("t", "q", "v")):
            geo = source
        else:
            raise InvalidArgument(
                "source must be a Geodesic (with t, q, v) or a geodesic synergy "
                f"(with metric and trajectory(duration, steps)), got {type(source).__name__}"
            )
        t, q = _check_samples(geo.t, geo.q)
        v = _check_like(geo.v, q.shape, "source.v")
        scale = check_positive(time_scale, "time_scale")
        if metric is not None and getattr(metric, "n", q.shape[1]) != q.shape[1]:
            raise InvalidArgument(
                f"metric has dimension {metric.n}, but the geodesic has n={q.shape[1]}"
            )
        self.n = int(q.shape[1])
        self.coupling = _coupling_to_keep(metric, q)
        if self.coupling is not None:
            idx = _independent(self.coupling)
            q, v = q[:, idx], v[:, idx]
            metric = CoupledMetric(metric, self.coupling)  # type: ignore[arg-type]
            self._S = np.asarray(self.coupling.S, dtype=np.float64)
            self._c = np.asarray(self.coupling.c, dtype=np.float64)
        self.metric = metric
        self.time_scale = scale
        self.t0 = check_float(t0, "t0", unit="s")
        self.geodesic_duration = float(t[-1] - t[0])
        self.duration = self.geodesic_duration * scale
        self._exact = metric is not None and bool(exact_acceleration)
        if metric is not None and not self._exact:
            a = np.array(
                [metric.geodesic_acceleration(qk, vk) for qk, vk in zip(q, v, strict=True)]
            )
            coef = hermite_quintic_coefficients(t, q, v, a)
        else:
            coef = hermite_cubic_coefficients(t, q, v)
        self._spline = _Piecewise(t - t[0], coef)
        self._q_start = self._lifted(q[0])
        self._q_goal = self._lifted(q[-1])
        self.rest_to_rest = bool(rest_to_rest)

    def _lifted(self, z: np.ndarray) -> np.ndarray:
        return z.copy() if self.coupling is None else self._S @ z + self._c

    def sample(self, t: float) -> ReferenceSample:
        """Reference ``(q, v, a)`` at controller time ``t`` [s].

        Returns:
            (n,) position [rad], (n,) velocity [rad/s], (n,) acceleration [rad/s^2];
            the goal with zero velocity and acceleration after ``t0 + duration``.
        """
        tau = self._local(float(t))
        if tau is None:
            return self._hold(float(t))
        q, v, a = self._sample_rest_to_rest(tau) if self.rest_to_rest else self._sample_at(tau)
        if self.coupling is not None:  # exact lift: S is constant
            return ReferenceSample(self._S @ q + self._c, self._S @ v, self._S @ a)
        return ReferenceSample(q, v, a)

    def _sample_at(self, tau: float) -> ReferenceSample:
        s = self.time_scale
        q, v, a = self._spline(tau / s)
        if self._exact:
            a = self.metric.geodesic_acceleration(q, v)  # type: ignore[union-attr]
        if s != 1.0:
            v /= s
            a = a / (s * s)
        return ReferenceSample(q, v, a)

    def _sample_rest_to_rest(self, tau: float) -> ReferenceSample:
        T, Tg = self.duration, self.geodesic_duration
        u = tau / T
        u2 = u * u
        sigma = Tg * u2 * u * (10.0 - 15.0 * u + 6.0 * u2)
        sigma_d = Tg * 30.0 * u2 * (1.0 - u) ** 2 / T
        sigma_dd = Tg * 60.0 * u * (1.0 - u) * (1.0 - 2.0 * u) / (T * T)
        q, dq, ddq = self._spline(sigma)  # dq = gamma'(sigma)
        v = dq * sigma_d
        if self._exact:
            a = self.metric.geodesic_acceleration(q, v)  # type: ignore[union-attr]
        else:
            a = ddq * (sigma_d * sigma_d)
        a += dq * sigma_dd
        return ReferenceSample(q, v, a)


COUPLING_TOLERANCE = 1e-6
"""Largest constraint residual [rad or m] of samples that a `GeodesicReference` on a coupled
robot treats as on the coupling."""


def _coupling_to_keep(metric: Metric | None, q: np.ndarray) -> Coupling | None:
    """The robot's coupling when ``metric`` is on a coupled robot's joints and the samples
    ``q`` (T, nq) satisfy it; None otherwise (warned when the samples leave it)."""
    coupling = getattr(getattr(metric, "robot", None), "coupling", None)
    if not isinstance(coupling, Coupling) or coupling.S.shape[0] != q.shape[1]:
        return None
    residual = float(np.abs(q - (q[:, _independent(coupling)] @ coupling.S.T + coupling.c)).max())
    if residual <= COUPLING_TOLERANCE:
        return coupling
    warnings.warn(
        f"the geodesic to track leaves the robot's joint coupling by {residual:.3g} (constraints:"
        f" {'; '.join(coupling.constraints)}); it is tracked as given: compute it in the"
        " independent coordinates on CoupledMetric(metric, robot.coupling) to keep the coupling",
        RobotWarning,
        stacklevel=4,
    )
    return None


def _independent(coupling: Coupling) -> list[int]:
    return [coupling.joint_names.index(j) for j in coupling.independent]


class JointTrajectoryReference(_SampledReference):
    """A joint trajectory from samples, interpolated piecewise-polynomially.

    - only ``q``: a C2 cubic spline (not-a-knot), velocity and acceleration from it;
    - ``q`` and ``v``: a C1 cubic Hermite spline, acceleration its second derivative;
    - ``q``, ``v`` and ``a``: a C2 quintic Hermite spline matching all three.

    Args:
        t: (T,) strictly increasing time stamps [s], T >= 2; the reference starts at
            ``t[0]`` (its ``t0``).
        q: (T, n) joint positions [rad].
        v: optional (T, n) joint velocities [rad/s].
        a: optional (T, n) joint accelerations [rad/s^2] (needs ``v``).

    `sample` allocates its three result arrays.
    """

    def __init__(
        self,
        t: np.ndarray,
        q: np.ndarray,
        v: np.ndarray | None = None,
        a: np.ndarray | None = None,
    ) -> None:
        t_arr, q_arr = _check_samples(t, q)
        if a is not None and v is None:
            raise InvalidArgument("a (accelerations) given without v (velocities); pass both")
        if v is None:
            from scipy.interpolate import CubicSpline  # heavy: imported where used

            spline = CubicSpline(t_arr, q_arr, axis=0)
            coef = spline.c[::-1].transpose(1, 0, 2)  # (K, 4, n), lowest power first
        else:
            v_arr = _check_like(v, q_arr.shape, "v")
            if a is None:
                coef = hermite_cubic_coefficients(t_arr, q_arr, v_arr)
            else:
                a_arr = _check_like(a, q_arr.shape, "a")
                coef = hermite_quintic_coefficients(t_arr, q_arr, v_arr, a_arr)
        self.n = int(q_arr.shape[1])
        self.t0 = float(t_arr[0])
        self.duration = float(t_arr[-1] - t_arr[0])
        self._spline = _Piecewise(t_arr - t_arr[0], coef)
        self._q_start = q_arr[0].copy()
        self._q_goal = q_arr[-1].copy()

    def sample(self, t: float) -> ReferenceSample:
        """Reference ``(q, v, a)`` at time ``t`` [s]; holds start/goal outside [t0, t0+T]."""
        tau = self._local(float(t))
        if tau is None:
            return self._hold(float(t))
        return ReferenceSample(*self._spline(tau))
