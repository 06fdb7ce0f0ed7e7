"""A stance synergy played in time: the reference of a whole-body controller.

`StanceSynergyReference` plays a `geosyn.metrics.stance_synergy.StanceSynergy` with a
minimum-jerk timing ``s(t)`` (``s = 10 u^3 - 15 u^4 + 6 u^5``, ``u = (t - t0) /
duration``), so the motion starts and stops at rest and every sample keeps the stance's
frames at their poses (velocities and accelerations consistent with them).
"""

from __future__ import annotations

import numpy as np

from geosyn.controllers.reference import Reference, ReferenceSample
from geosyn.core.types import Vector
from geosyn.core.validation import check_float, check_positive
from geosyn.metrics.stance_synergy import StanceSynergy

__all__ = ["StanceSynergyReference"]


class StanceSynergyReference(Reference):
    """A stance synergy with a minimum-jerk timing.

    Args:
        synergy: the stance synergy.
        duration: time from its start to its end [s], > 0.
        t0: start time [s].

    Attributes:
        n: velocity dimension nv (configurations have nq = nv + 1 entries).
    """

    def __init__(self, synergy: StanceSynergy, duration: float, t0: float = 0.0) -> None:
        self.synergy = synergy
        self.n = synergy.stance.robot.nv
        self.duration = check_positive(duration, "duration", "s")
        self.t0 = check_float(t0, "t0", unit="s")

    def timing(self, t: float) -> tuple[float, float, float]:
        """``(s, ds/dt, d2s/dt2)`` of the minimum-jerk timing at time ``t`` [s]."""
        T = self.duration
        u = min(max((t - self.t0) / T, 0.0), 1.0)
        s = u**3 * (10.0 - 15.0 * u + 6.0 * u * u)
        ds = 30.0 * u * u * (1.0 - u) ** 2 / T
        dds = 60.0 * u * (1.0 - u) * (1.0 - 2.0 * u) / (T * T)
        return s, ds, dds

    def sample(self, t: float) -> ReferenceSample:
        """``(q (nq,), v (nv,), a (nv,))`` at time ``t`` [s]: the synergy point at
        ``s(t)`` with ``v = q' ds`` and ``a = q'' ds^2 + q' dds``."""
        s, ds, dds = self.timing(check_float(t, "t", unit="s"))
        p = self.synergy.at(s)
        return ReferenceSample(p.q, p.dq * ds, p.ddq * ds * ds + p.dq * dds)

    def goal(self) -> Vector:
        """(nq,) the synergy's end configuration."""
        return np.array(self.synergy.at(1.0).q)
