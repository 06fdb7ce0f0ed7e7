"""Per-joint acceleration bounds that keep joint positions and velocities inside their
limits over the next control period (`AccelerationBounds`).

Shared by the limit-aware inverse-dynamics QP (`geosyn.controllers.qp.QPController`) and
the MPC's joint-limit guard (`geosyn.controllers.limit_guard.JointLimitGuard`). With the
acceleration ``a`` held over a period ``h``, per joint (and mirrored at the lower limits):

.. math::
    v + a h \\le v_{max}, \\qquad
    q + v T + \\tfrac12 a T^2 \\le q_{max}, \\qquad
    v + a h \\le \\sqrt{2 b (q_{max} - q - v h)}

the velocity limit one period ahead, the position limit ``T`` (``position_horizon``,
default ``h``) ahead, and, with a braking acceleration ``b``, the braking curve: the next
velocity lets the joint stop before the limit decelerating at ``b``.
"""

from __future__ import annotations

import numpy as np

from geosyn.controllers.base import check_gain
from geosyn.core.errors import InvalidArgument
from geosyn.core.types import Vector

__all__ = ["BIG_ACCELERATION", "AccelerationBounds", "check_braking_acceleration"]

BIG_ACCELERATION = 1e6
"""Magnitude standing in for "no bound" on an acceleration [rad/s^2] (infinite limits)."""


def check_braking_acceleration(b: object, n: int) -> Vector | None:
    """The braking acceleration as an (n,) array of positive values, or None.

    Args:
        b: None, a scalar or an (n,) array [rad/s^2].
        n: number of joints.

    Raises:
        InvalidArgument: wrong shape, non-finite, zero or negative entries.
    """
    if b is None:
        return None
    out = check_gain(b, n, "braking_acceleration")
    if np.any(out <= 0.0):
        raise InvalidArgument(f"braking_acceleration must be > 0, got {out}")
    return out


class AccelerationBounds:
    """The acceleration box ``lower <= a <= upper`` [rad/s^2] keeping the joint limits
    over the next period (the module's three bounds, intersected per joint, clipped to
    +-`BIG_ACCELERATION`).

    The box can be empty (``lower > upper`` on a joint) when the state is too close to a
    limit or beyond it: the caller decides what to do then.

    Args:
        q_min: (nv,) lower position limits [rad] (-inf: none).
        q_max: (nv,) upper position limits [rad] (inf: none).
        v_max: (nv,) velocity limits [rad/s] (> 0).
        position_horizon: look-ahead ``T`` of the position bound [s]; None: the period.
        braking_acceleration: (nv,) deceleration ``b`` [rad/s^2] of the braking curve
            (validated by `check_braking_acceleration`), or None (no braking curve).

    Attributes:
        q_max: (nv,) a view of the upper position limits in use (writable).
        lower: (nv,) lower acceleration bounds of the last `update` [rad/s^2].
        upper: (nv,) upper acceleration bounds of the last `update` [rad/s^2].

    The constructor allocates; `update` only writes into preallocated arrays.
    """

    def __init__(
        self,
        q_min: Vector,
        q_max: Vector,
        v_max: Vector,
        position_horizon: float | None = None,
        braking_acceleration: Vector | None = None,
    ) -> None:
        n = int(np.asarray(q_max).shape[0])
        # Both sides at once on stacked (2 nv,) arrays: the upper limit as is, the lower one
        # mirrored (distance q - q_min, velocity -v).
        self._lim = np.concatenate([q_max, -np.asarray(q_min)]).astype(np.float64)
        self.q_max = self._lim[:n]
        self._v_max2 = np.concatenate([v_max, v_max]).astype(np.float64)
        b = braking_acceleration
        self._brake2 = None if b is None else 2.0 * np.concatenate([b, b]).astype(np.float64)
        self.position_horizon = position_horizon
        self._n = n
        self._x2 = np.zeros(2 * n)  # (q, -q)
        self._w2 = np.zeros(2 * n)  # (v, -v)
        self._d2 = np.zeros(2 * n)
        self._bound2 = np.zeros(2 * n)
        self.lower = np.zeros(n)
        self.upper = np.zeros(n)

    def update(self, q: Vector, v: Vector, period: float) -> None:
        """Compute the box at the state ``(q, v)`` for a period ``period`` [s].

        Args:
            q: (nv,) joint positions [rad].
            v: (nv,) joint velocities [rad/s].
            period: how long the acceleration is held [s] (> 0).
        """
        n = self._n
        x, w, d, bound = self._x2, self._w2, self._d2, self._bound2
        x[:n] = q
        np.negative(q, out=x[n:])
        w[:n] = v
        np.negative(v, out=w[n:])
        # Velocity limits one step ahead: w + a h <= v_max.
        np.subtract(self._v_max2, w, out=bound)
        bound *= 1.0 / period
        # Position limits T ahead: x + w T + 1/2 a T^2 <= lim.
        T = period if self.position_horizon is None else self.position_horizon
        np.multiply(w, T, out=d)
        d += x
        np.subtract(self._lim, d, out=d)
        d *= 2.0 / (T * T)
        np.minimum(bound, d, out=bound)
        if self._brake2 is not None:
            # Braking curve: w + a h <= sqrt(2 b (lim - x - w h)).
            np.multiply(w, period, out=d)
            d += x
            np.subtract(self._lim, d, out=d)
            np.maximum(d, 0.0, out=d)
            d *= self._brake2
            np.sqrt(d, out=d)
            d -= w
            d *= 1.0 / period
            np.minimum(bound, d, out=bound)
        np.minimum(bound, BIG_ACCELERATION, out=bound)
        np.maximum(bound, -BIG_ACCELERATION, out=bound)
        self.upper[:] = bound[:n]
        np.negative(bound[n:], out=self.lower)
