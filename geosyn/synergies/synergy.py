"""Geodesic synergies and their combination (paper section 2.2).

A geodesic synergy is a geodesic of a metric, fixed by its initial configuration ``q0`` and
initial velocity ``v0``. Synergies are combined by summing weighted initial velocities in
one tangent space; synergies based elsewhere are first parallel-transported there along
the geodesic joining their base to the start configuration, so the result is again a
geodesic (a minimum-energy passive motion).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from typing_extensions import Unpack

from geosyn.core.types import Matrix, Vector
from geosyn.core.validation import check_int, check_vector
from geosyn.metrics.base import Metric
from geosyn.metrics.errors import GeodesicNotFound
from geosyn.metrics.geodesic import Geodesic, LogOptions, exp, log, parallel_transport
from geosyn.robots.robot import Robot
from geosyn.synergies.errors import InvalidSynergyInput, SynergyNotConverged, synergy_input

COMMON_BASE_TOL = 1e-12
"""Bases closer than this (max-norm) [rad] count as equal: no transport is done."""


def as_vector(x: object, n: int, name: str) -> Vector:
    """Return ``x`` as a new finite float64 (n,) array (always a copy).

    Args:
        x: candidate vector.
        n: expected length.
        name: argument name for the error message.

    Raises:
        InvalidSynergyInput: wrong shape, not numeric or not finite.
    """
    with synergy_input(name):
        return check_vector(x, n, name).copy()


def check_count(k: object, n: int) -> int:
    """Return ``k``, a number of synergies or directions, as an int in ``[1, n]``.

    Raises:
        InvalidSynergyInput: not an integer, or out of range.
    """
    with synergy_input("k"):
        return check_int(k, "k", low=1, high=n)


def check_metric(metric: object) -> Metric:
    """Return ``metric`` if it is a geosyn `Metric`.

    Raises:
        InvalidSynergyInput: anything else.
    """
    if not isinstance(metric, Metric):
        raise InvalidSynergyInput(
            f"metric must be a geosyn Metric, got {type(metric).__name__}", "metric"
        )
    if getattr(metric, "nq", metric.n) != metric.n:  # configurations on SE(3) x R^n
        raise InvalidSynergyInput(
            f"{metric!r} is a floating base's metric: synergies and PGA need log and"
            " parallel transport, which geosyn has on fixed-base robots only yet; load the"
            " robot with fixed_base=True",
            "metric",
        )
    return metric


def check_robot(robot: object, n: int) -> Robot:
    """Return ``robot`` if it is a geosyn `Robot` with ``nv == n``.

    Args:
        robot: candidate robot.
        n: dimension of the metric's configuration space.

    Raises:
        InvalidSynergyInput: not a `Robot`, or its nv differs from n.
    """
    if not isinstance(robot, Robot):
        raise InvalidSynergyInput(
            f"robot must be a geosyn Robot, got {type(robot).__name__}", "robot"
        )
    if robot.nv != n:
        raise InvalidSynergyInput(
            f"robot {robot.name!r} has nv={robot.nv}, the metric has n={n}", "robot"
        )
    return robot


def checked_log(
    metric: Metric, q_from: Vector, q_to: Vector, **options: Unpack[LogOptions]
) -> Vector:
    """``log(metric, q_from, q_to)``, with a failure reported as `SynergyNotConverged`.

    Args:
        metric: the metric.
        q_from: (n,) start configuration [rad].
        q_to: (n,) end configuration [rad].
        **options: forwarded to `geosyn.metrics.geodesic.log` (v_init, steps, tol, ...).

    Returns:
        (n,) initial velocity [rad/s] of the geodesic reaching ``q_to`` at t = 1 s.

    Raises:
        SynergyNotConverged: the shooting did not converge (carries its residual, the
            configurations and the best initial velocity found).
    """
    try:
        return np.asarray(log(metric, q_from, q_to, **options), dtype=np.float64)
    except GeodesicNotFound as err:
        raise SynergyNotConverged(
            f"no geodesic found from q={np.round(q_from, 6).tolist()} to "
            f"q={np.round(q_to, 6).tolist()} (endpoint residual {err.residual:.3g} rad): {err}",
            err.residual,
            q_from=np.array(q_from),
            q_to=np.array(q_to),
            v0=err.v0,
        ) from err


@dataclass(frozen=True, eq=False)
class GeodesicSynergy:
    """A geodesic synergy: the geodesic of ``metric`` through ``(q0, v0)``.

    Arrays are copied and made read-only on construction.

    Attributes:
        metric: the metric whose geodesic this is.
        q0: (n,) initial configuration [rad].
        v0: (n,) initial velocity [rad/s] (at unit duration, the geodesic reaches
            ``exp_q0(v0)``).
    """

    metric: Metric
    q0: np.ndarray
    v0: np.ndarray

    def __post_init__(self) -> None:
        n = check_metric(self.metric).n
        for name in ("q0", "v0"):
            arr = as_vector(getattr(self, name), n, name)
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)

    @property
    def n(self) -> int:
        """Dimension of the configuration space."""
        return self.metric.n

    def trajectory(self, duration: float = 1.0, steps: int = 100) -> Geodesic:
        """Integrate the synergy (allocates the trajectory).

        Args:
            duration: final time [s], > 0.
            steps: integration steps (RK4), >= 1.

        Returns:
            The geodesic sampled at ``steps + 1`` times.
        """
        return exp(self.metric, self.q0, self.v0, duration=duration, steps=steps)

    def __repr__(self) -> str:
        return (
            f"GeodesicSynergy({self.metric!r}, q0={np.round(self.q0, 4).tolist()}, "
            f"v0={np.round(self.v0, 4).tolist()})"
        )


def _check_synergies(synergies: Sequence[GeodesicSynergy]) -> list[GeodesicSynergy]:
    if isinstance(synergies, GeodesicSynergy):
        syns: list[GeodesicSynergy] = [synergies]
    else:
        syns = list(synergies)
    if not syns:
        raise InvalidSynergyInput(
            "synergies must hold at least one GeodesicSynergy, got none", "synergies"
        )
    for i, s in enumerate(syns):
        if not isinstance(s, GeodesicSynergy):
            raise InvalidSynergyInput(
                f"synergies[{i}] must be a GeodesicSynergy, got {type(s).__name__}", "synergies"
            )
        if s.metric is not syns[0].metric:
            raise InvalidSynergyInput(
                f"synergies[{i}] uses metric {s.metric!r}, synergies[0] uses "
                f"{syns[0].metric!r}; all synergies must share one metric object",
                "synergies",
            )
    return syns


def transported_velocities(
    synergies: Sequence[GeodesicSynergy], q_start: Vector | None = None, steps: int = 100
) -> Matrix:
    """Initial velocities of the synergies, parallel-transported to ``q_start``.

    A synergy based at ``q0_i`` has its ``v0_i`` transported along the geodesic from
    ``q0_i`` to ``q_start`` (``log`` then ``exp``); a synergy based at ``q_start``
    (within `COMMON_BASE_TOL`) is used as is. Transport preserves G-inner products, so
    a G-orthonormal set stays G-orthonormal.

    Args:
        synergies: m synergies sharing one metric.
        q_start: (n,) configuration [rad]; defaults to the first synergy's base.
        steps: integration steps of the connecting geodesic and of the transport.

    Returns:
        (n, m) transported velocities [rad/s], one per column.

    Raises:
        InvalidSynergyInput: bad synergies or q_start.
        SynergyNotConverged: a base could not be joined to ``q_start``.
    """
    syns = _check_synergies(synergies)
    metric = syns[0].metric
    q_s = syns[0].q0.copy() if q_start is None else as_vector(q_start, metric.n, "q_start")
    out = np.empty((metric.n, len(syns)))
    for i, s in enumerate(syns):
        if np.max(np.abs(s.q0 - q_s)) <= COMMON_BASE_TOL:
            out[:, i] = s.v0
            continue
        u = checked_log(metric, s.q0, q_s, steps=steps)
        path = exp(metric, s.q0, u, duration=1.0, steps=steps)
        out[:, i] = np.asarray(
            parallel_transport(metric, path.t, path.q, s.v0, qdot=path.v), dtype=np.float64
        ).reshape(metric.n)
    return out


def check_weights(weights: object, m: int) -> Vector:
    """Return ``weights`` as (m,) finite floats [-] (a scalar counts as one weight).

    Raises:
        InvalidSynergyInput: not m of them, not numeric or not finite.
    """
    try:
        w = np.atleast_1d(np.array(weights, dtype=np.float64))
    except (TypeError, ValueError) as err:
        raise InvalidSynergyInput(
            f"weights must be {m} numbers, got {weights!r}", "weights"
        ) from err
    if w.ndim != 1 or w.size != m:
        raise InvalidSynergyInput(
            f"weights must hold one weight per synergy ({m}), got shape {w.shape}", "weights"
        )
    with synergy_input("weights"):
        return check_vector(w, m, "weights")


def combine(
    synergies: Sequence[GeodesicSynergy],
    weights: Sequence[float] | Vector,
    q_start: Vector | None = None,
    *,
    steps: int = 100,
) -> GeodesicSynergy:
    """Combine synergies into one: ``v0 = sum_i w_i P_i v0_i`` at ``q_start``.

    .. math:: v_0 = \\sum_i w_i \\, \\Pi_{q_0^{(i)} \\to q_\\mathrm{start}} v_0^{(i)}

    where :math:`\\Pi` is parallel transport along the geodesic from the synergy's base
    to ``q_start`` (skipped for a common base). The result is a geodesic synergy.

    Args:
        synergies: m synergies sharing one metric.
        weights: (m,) weights [-].
        q_start: (n,) start configuration [rad]; defaults to the first synergy's base.
        steps: integration steps for the transport (when bases differ).

    Returns:
        The combined synergy based at ``q_start``.

    Raises:
        InvalidSynergyInput: ``len(weights) != len(synergies)``, ``q_start`` of the wrong
            size, or synergies on different metrics.
        SynergyNotConverged: a base could not be joined to ``q_start``.
    """
    syns = _check_synergies(synergies)
    w = check_weights(weights, len(syns))
    metric = syns[0].metric
    q_s = syns[0].q0.copy() if q_start is None else as_vector(q_start, metric.n, "q_start")
    V = transported_velocities(syns, q_s, steps=steps)
    v0 = np.zeros(metric.n)
    for i in range(len(syns)):
        v0 = v0 + w[i] * V[:, i]
    return GeodesicSynergy(metric, q_s, v0)
