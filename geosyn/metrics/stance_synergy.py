"""A synergy on a stance: a geodesic of the induced metric, read at a path parameter.

A stance-constrained synergy (`StanceSynergy`) is the geodesic of a `Stance`'s induced
metric from a configuration ``q0`` along a tangent direction ``v0`` (``J(q0) v0 = 0``),
for example a whole-body reach or a shift of the body while both feet stay put. It is
parametrised by ``s`` in [0, 1] (unit-time geodesic: ``q(0) = q0``, ``q(1)`` the
synergy's end) so that a controller can play it at any timing ``s(t)``:

.. math:: \\dot q = q'(s)\\,\\dot s, \\qquad
    \\ddot q = q''(s)\\,\\dot s^2 + q'(s)\\,\\ddot s,

where ``q'' = a(q, q')`` is the stance's geodesic acceleration. Every sample is returned
to the stance (`Stance.project`), so the held frames stay put to round-off between the
stored geodesic samples too.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from geosyn.core.types import Vector
from geosyn.core.validation import check_float, check_int, check_vector
from geosyn.metrics.errors import StanceError
from geosyn.metrics.geodesic.exp_map import MAX_STEPS, Geodesic
from geosyn.metrics.geodesic.group_rk4 import group_rk4
from geosyn.metrics.stance import Stance

__all__ = ["StancePoint", "StanceSynergy"]


class StancePoint(NamedTuple):
    """A point of a stance synergy at path parameter ``s``.

    Attributes:
        q: (nq,) configuration on the stance [m, -, rad].
        dq: (nv,) ``dq/ds`` (tangent: ``J dq = 0``) [m, rad per unit s].
        ddq: (nv,) ``d^2q/ds^2``, the stance's geodesic acceleration at ``(q, dq)``.
    """

    q: Vector
    dq: Vector
    ddq: Vector


class StanceSynergy:
    """The geodesic of a stance's induced metric from ``q0`` along ``direction``.

    Args:
        stance: the stance (held frames and their poses).
        q0: (nq,) start configuration on the stance (pose error <= 1e-9 m, rad).
        direction: (nv,) velocity of the unit-time geodesic (base twist in the base frame,
            joint rates); its M-orthogonal projection onto the stance's tangent space is
            used (`Stance.project`), so a whole-body wish such as "move the base down by
            5 cm" becomes the nearest motion that keeps the frames held.
        steps: RKMK4 steps of the stored geodesic, in [1, `MAX_STEPS`]; between samples
            `at` takes one RKMK4 step of the remaining length from the sample before.

    Raises:
        StanceError: ``q0`` off the stance, or a direction with no tangent part (all of
            it would move the held frames).

    Attributes:
        stance: the stance.
        v0: (nv,) the tangent initial velocity used.
        geodesic: the stored samples (``t`` = s in [0, 1]).
    """

    def __init__(self, stance: Stance, q0: Vector, direction: Vector, steps: int = 100) -> None:
        if not isinstance(stance, Stance):
            raise StanceError(f"stance must be a geosyn Stance, got {type(stance).__name__}")
        robot = stance.robot
        q0 = robot.check_q(q0, "q0")
        direction = check_vector(direction, robot.nv, "direction")
        steps = check_int(steps, "steps", low=1, high=MAX_STEPS)
        q_on, v0 = stance.project(q0, direction)
        off = float(np.abs(stance.residual(q0)).max())
        if off > 1e-9:
            raise StanceError(f"q0 must be on {stance!r}: pose error {off:.3g} (<= 1e-9 m, rad)")
        norm = float(np.linalg.norm(direction))
        if norm == 0.0 or np.linalg.norm(v0) <= 1e-9 * norm:
            raise StanceError(
                f"direction {direction.tolist()} has no part tangent to {stance!r}: it only"
                " moves the held frames; choose a motion the stance allows"
            )
        self.stance = stance
        self.v0 = v0
        self.geodesic: Geodesic = stance.geodesic(q_on, v0, duration=1.0, steps=steps)
        self._acc = np.array(
            [
                stance.acceleration(q, v)
                for q, v in zip(self.geodesic.q, self.geodesic.v, strict=True)
            ]
        )
        self._steps = steps

    def __repr__(self) -> str:
        return f"StanceSynergy({self.stance!r}, |v0|={np.linalg.norm(self.v0):.3g})"

    def at(self, s: float) -> StancePoint:
        """The synergy at path parameter ``s`` (clamped to [0, 1]).

        Cost: one RKMK4 step from the stored sample before ``s`` (four constrained
        accelerations) and one `Stance.project`; allocates the returned arrays.

        Args:
            s: path parameter (0: ``q0``, 1: the end) [-].
        """
        s = min(max(check_float(s, "s"), 0.0), 1.0)
        k = min(int(s * self._steps), self._steps - 1)
        h = s - self.geodesic.t[k]
        if h <= 0.0:
            q, dq = self.geodesic.q[k].copy(), self.geodesic.v[k].copy()
            return StancePoint(q, dq, self._acc[k].copy())
        stance = self.stance
        Q, V = group_rk4(
            stance.metric,
            self.geodesic.q[k],
            self.geodesic.v[k],
            h,
            1,
            stance.acceleration,
            stance.project,
        )
        return StancePoint(Q[1], V[1], stance.acceleration(Q[1], V[1]))

    def end(self) -> Vector:
        """(nq,) the synergy's last configuration (a copy)."""
        return np.array(self.geodesic.q[-1])
