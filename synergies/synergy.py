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

from geosyn.core.types import Matrix, Vector
from geosyn.metrics.base import Metric
from geosyn.metrics.errors import GeodesicNotFound
from geosyn.metrics.geodesic import Geodesic, exp, log, parallel_transport
from geosyn.synergies.errors import (
    DimensionMismatch,
    InvalidSynergyInput,
    LogMapFailed,
    WeightCountMismatch,
)

COMMON_BASE_TOL = 1e-12
"""Bases closer than this (max-norm) [rad] count as equal: no transport is done."""


def as_vector(x: object, n: int, name: str) -> np.ndarray:
    """Validate a finite float64 vector of shape (n,) (copy).

    Raises:
        DimensionMismatch: wrong shape.
        InvalidSynergyInput: not numeric or not finite.
    """
    try:
        arr = np.array(x, dtype=np.float64)
    except (TypeError, ValueError) as err:
        raise InvalidSynergyInput(
            f"{name} must be a float array of shape ({n},), got {x!r}"
        ) from err
    if arr.shape != (n,):
        raise DimensionMismatch(f"{name} must have shape ({n},), got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise InvalidSynergyInput(f"{name} must be finite, got {arr.tolist()}")
    return arr


def checked_log(metric: Metric, q_from: Vector, q_to: Vector, **options: object) -> Vector:
    """``log(metric, q_from, q_to)``, with a failure reported as `LogMapFailed`.

    Args:
        metric: the metric.
        q_from: (n,) start configuration [rad].
        q_to: (n,) end configuration [rad].
        **options: forwarded to `geosyn.metrics.geodesic.log` (v_init, steps, tol, ...).

    Returns:
        (n,) initial velocity [rad/s] of the geodesic reaching ``q_to`` at t = 1 s.

    Raises:
        LogMapFailed: the shooting did not converge (carries its residual).
    """
    try:
        return np.asarray(log(metric, q_from, q_to, **options), dtype=np.float64)
    except GeodesicNotFound as err:
        raise LogMapFailed(
            f"no geodesic found from q={np.round(q_from, 6).tolist()} to "
            f"q={np.round(q_to, 6).tolist()} (endpoint residual {err.residual:.3g} rad): {err}",
            err.residual,
            err.v0,
            np.array(q_from),
            np.array(q_to),
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
        if not isinstance(self.metric, Metric):
            raise InvalidSynergyInput(
                f"metric must be a geosyn Metric, got {type(self.metric).__name__}"
            )
        n = self.metric.n
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
        raise InvalidSynergyInput("synergies must hold at least one GeodesicSynergy, got none")
    for i, s in enumerate(syns):
        if not isinstance(s, GeodesicSynergy):
            raise InvalidSynergyInput(
                f"synergies[{i}] must be a GeodesicSynergy, got {type(s).__name__}"
            )
        if s.metric is not syns[0].metric:
            raise DimensionMismatch(
                f"synergies[{i}] uses metric {s.metric!r}, synergies[0] uses "
                f"{syns[0].metric!r}; all synergies must share one metric object"
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
        InvalidSynergyInput, DimensionMismatch: bad synergies or q_start.
        LogMapFailed: a base could not be joined to ``q_start``.
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


def check_weights(weights: object, m: int) -> np.ndarray:
    """Validate (m,) finite weights.

    Raises:
        WeightCountMismatch: not m of them.
        InvalidSynergyInput: not numeric / not finite.
    """
    try:
        w = np.array(weights, dtype=np.float64)
    except (TypeError, ValueError) as err:
        raise InvalidSynergyInput(f"weights must be {m} numbers, got {weights!r}") from err
    w = np.atleast_1d(w)
    if w.ndim != 1 or w.size != m:
        raise WeightCountMismatch(
            f"weights must hold one weight per synergy ({m}), got shape {w.shape}"
        )
    if not np.all(np.isfinite(w)):
        raise InvalidSynergyInput(f"weights must be finite, got {w.tolist()}")
    return w


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
        WeightCountMismatch: ``len(weights) != len(synergies)``.
        DimensionMismatch: ``q_start`` of the wrong size, or synergies on different metrics.
        LogMapFailed: a base could not be joined to ``q_start``.
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
