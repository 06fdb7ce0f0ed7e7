"""`JointLimitTerm`: a diagonal barrier metric that grows without bound at position limits."""

from __future__ import annotations

import casadi as ca
import numpy as np

from geosyn.core.validation import check_positive
from geosyn.metrics.shaping.base import MetricTerm
from geosyn.metrics.shaping.errors import InvalidTermArgument, term_arguments
from geosyn.robots.robot import Robot

__all__ = ["JointLimitTerm"]


class JointLimitTerm(MetricTerm):
    """Barrier metric near the joint position limits.

    Diagonal, with for each joint ``i`` that has finite limits

    .. math::
        w_i(q) = \\mathrm{gain}\\,\\big[\\phi(q_i - q_{\\min,i}) + \\phi(q_{\\max,i} - q_i)\\big],
        \\qquad \\phi(d) = \\big(\\max(1/d - 1/\\mathrm{margin}, 0)\\big)^2

    ``phi`` is zero farther than ``margin`` from a limit (the interior is not shaped), C1 at
    ``d = margin``, and behaves like ``1/d^2`` near the limit, so the Riemannian length to
    the limit, ``int sqrt(w) dq``, diverges: geodesics approach a limit but never cross it.
    ``d`` is clamped at ``d_min`` so the weight stays finite at and beyond the limit.
    Joints with an infinite limit get no barrier on that side.

    Args:
        margin: width of the shaped band next to each limit [rad or m], > 0.
        gain: barrier gain [kg m^2 rad^2 over the kinetic-energy metric], > 0.
        d_min: clamp of the distance to the limit [rad or m], 0 < d_min < margin.

    Raises:
        InvalidTermArgument: a setting out of range; at `bind`, a margin wider than half
            the range of some joint (the two bands would overlap).
    """

    def __init__(self, margin: float = 0.2, gain: float = 1e-3, *, d_min: float = 1e-12) -> None:
        super().__init__()
        with term_arguments():
            self.margin = check_positive(margin, "margin")
            self.gain = check_positive(gain, "gain")
            self.d_min = check_positive(d_min, "d_min")
        if self.d_min >= self.margin:
            raise InvalidTermArgument(
                f"d_min must be < margin, got d_min={d_min!r}, margin={margin!r}"
            )

    def __repr__(self) -> str:
        return f"JointLimitTerm(margin={self.margin}, gain={self.gain})"

    def _on_bind(self, robot: Robot) -> None:
        rng = np.asarray(robot.q_max) - np.asarray(robot.q_min)
        bad = [
            robot.joint_names[i]
            for i in range(robot.nq)
            if np.isfinite(rng[i]) and rng[i] < 2.0 * self.margin
        ]
        if bad:
            raise InvalidTermArgument(
                f"margin {self.margin} is more than half the position range of joints {bad} "
                f"of robot {robot.name!r}; use a smaller margin"
            )

    def _phi(self, d: ca.SX) -> ca.SX:
        u = ca.fmax(1.0 / ca.fmax(d, self.d_min) - 1.0 / self.margin, 0.0)
        return u * u

    def symbolic_G(self, q: ca.SX, v: ca.SX | None = None) -> ca.SX:
        """SX diagonal barrier matrix (see the class docstring)."""
        robot = self.robot
        diag = []
        for i in range(robot.nq):
            w: ca.SX | float = 0.0
            if np.isfinite(robot.q_min[i]):
                w = w + self._phi(q[i] - float(robot.q_min[i]))
            if np.isfinite(robot.q_max[i]):
                w = w + self._phi(float(robot.q_max[i]) - q[i])
            diag.append(self.gain * w)
        return ca.diag(ca.vertcat(*[ca.SX(x) if isinstance(x, float) else x for x in diag]))
