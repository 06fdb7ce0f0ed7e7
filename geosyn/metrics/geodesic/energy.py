"""Energy and distance: path energy of sampled paths, the straight-line baseline, and the
Riemannian distance along the geodesic found by the log map."""

from __future__ import annotations

import math

import numpy as np
from typing_extensions import Unpack

from geosyn.core.errors import InvalidArgument
from geosyn.core.types import Vector
from geosyn.core.validation import check_int, check_positive, check_vector
from geosyn.metrics.base import Metric, check_metric
from geosyn.metrics.geodesic.exp_map import MAX_STEPS, Geodesic
from geosyn.metrics.geodesic.log_map import LogOptions, log

__all__ = ["check_path", "distance", "path_energy", "path_velocity", "real_array", "straight_line"]


def real_array(x: object, name: str) -> np.ndarray:
    """``x`` as a float64 array; complex values, text and objects raise `InvalidArgument`."""
    if isinstance(x, (str, bytes, complex)) or np.iscomplexobj(x):  # type: ignore[arg-type]
        raise InvalidArgument(f"{name} must be a real (float) array, got {str(x)[:80]!r}")
    try:
        return np.asarray(x, dtype=np.float64)
    except (TypeError, ValueError) as err:
        raise InvalidArgument(f"{name} must be a real (float) array, got {str(x)[:80]!r}") from err


def check_path(
    t: object, q: object, n: int, name_t: str = "t", name_q: str = "q"
) -> tuple[np.ndarray, np.ndarray]:
    """Return a sampled path as float arrays, or raise `InvalidArgument`.

    Args:
        t: (T,) strictly monotonic time stamps [s], T >= 2.
        q: (T, n) joint positions [rad].
        n: dimension of the configuration space.
        name_t, name_q: argument names for the messages.

    Returns:
        ``(t, q)`` as finite float64 arrays.
    """
    tt = real_array(t, name_t)
    qq = real_array(q, name_q)
    if tt.ndim != 1 or tt.shape[0] < 2:
        raise InvalidArgument(f"{name_t} must have shape (T,) with T >= 2, got shape {tt.shape}")
    if qq.ndim != 2 or qq.shape != (tt.shape[0], n):
        raise InvalidArgument(
            f"{name_q} must have shape ({tt.shape[0]}, {n}), got shape {qq.shape}"
        )
    if not (np.all(np.isfinite(tt)) and np.all(np.isfinite(qq))):
        raise InvalidArgument(f"{name_t} and {name_q} must be finite")
    dt = np.diff(tt)
    if not (np.all(dt > 0) or np.all(dt < 0)):
        raise InvalidArgument(f"{name_t} must be strictly monotonic, got {tt}")
    return tt, qq


def path_velocity(t: np.ndarray, q: np.ndarray) -> np.ndarray:
    """(T, n) velocities [rad/s] of a sampled path by finite differences.

    Second order (``np.gradient`` with the time stamps, second order at the ends too)
    when T >= 3; the constant slope when T = 2.

    Args:
        t: (T,) strictly monotonic time stamps [s].
        q: (T, n) joint positions [rad].
    """
    if t.shape[0] >= 3:
        return np.gradient(q, t, axis=0, edge_order=2)
    return np.repeat((q[1:] - q[:1]) / (t[1] - t[0]), 2, axis=0)


def path_energy(metric: Metric, t: np.ndarray, q: np.ndarray) -> float:
    """Energy of a sampled path, ``E = 1/2 integral qdot^T G(q) qdot dt``.

    ``qdot`` is the second-order finite difference of the samples (`path_velocity`) and
    the integral is Simpson's rule on the (possibly non-uniform) samples, so E converges
    to the energy of the underlying smooth path with error O(h^2) in the sample spacing h.
    For a geodesic of unit duration, ``E = 1/2 v0^T G(q0) v0``. Calls ``metric.G`` once
    per sample.

    Args:
        metric: the metric.
        t: (T,) strictly monotonic time stamps [s], T >= 2 (T >= 3 for second order).
        q: (T, n) joint positions [rad].

    Returns:
        The energy [J s for the kinetic-energy metric, i.e. (kg m^2)(rad/s)^2 s].
    """
    from scipy.integrate import simpson

    metric = check_metric(metric)
    t, q = check_path(t, q, metric.n)
    qd = path_velocity(t, q)
    integrand = np.array([qd[k] @ metric.G(q[k]) @ qd[k] for k in range(t.shape[0])])
    return float(0.5 * abs(simpson(integrand, x=t)))


def straight_line(q0: Vector, q1: Vector, duration: float = 1.0, steps: int = 100) -> Geodesic:
    """The Euclidean baseline: constant joint velocity from q0 to q1.

    Args:
        q0, q1: (n,) joint positions [rad].
        duration: time to go from q0 to q1 [s], > 0.
        steps: number of intervals, >= 1 (``steps + 1`` samples).

    Returns:
        t (T,), q (T, n) and the constant velocity v (T, n) = (q1 - q0) / duration.
    """
    q0 = check_vector(q0, np.shape(q0)[0] if np.ndim(q0) == 1 else 1, "q0")
    q1 = check_vector(q1, q0.shape[0], "q1")
    duration = check_positive(duration, "duration")
    steps = check_int(steps, "steps", low=1, high=MAX_STEPS)
    t = np.linspace(0.0, duration, steps + 1)
    s = (t / duration)[:, None]
    vel = (q1 - q0) / duration
    return Geodesic(t, q0 + s * (q1 - q0), np.repeat(vel[None, :], steps + 1, axis=0))


def distance(metric: Metric, q0: Vector, q1: Vector, **options: Unpack[LogOptions]) -> float:
    """Riemannian distance along the geodesic found by `log` (unit duration).

    .. math:: d(q_0, q_1) = \\sqrt{v_0^T G(q_0) v_0}, \\quad v_0 = \\log_{q_0} q_1

    (the speed is constant along a geodesic). For the kinetic-energy metric the unit is
    sqrt(kg) m (sqrt(2 J s^2)). This is the length of the geodesic found, which is the
    minimal distance when that geodesic is minimizing.

    Args:
        metric: the metric.
        q0, q1: (n,) joint positions [rad].
        **options: keyword options of `log_solve` (v_init, steps, tol, ...).
    """
    metric = check_metric(metric)
    q0 = check_vector(q0, metric.n, "q0")
    v0 = log(metric, q0, q1, **options)
    return float(math.sqrt(max(float(v0 @ metric.G(q0) @ v0), 0.0)))
