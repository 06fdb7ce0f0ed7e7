"""Obstacle clearance in the DDP tracking OCP, from the obstacle terms of a shaped metric.

``GeodesicMPC(solver="ddp", clearance_margin=m)`` with a `ShapedMetric` that has
`ObstacleTerm` s adds to every stage (and the terminal state) the stiff penalty

.. math:: w_c \\sum_{s,o} \\max(0,\\ m - c_{so}(q))^2

over the robot's collision spheres ``s`` and the terms' obstacle slots ``o`` (clearance
``c_so = sd_o(x_s(q)) - r_s`` [m], `ObstacleTerm.symbolic_clearances`; empty slots never
count). Its Gauss-Newton derivatives use the exact clearance Jacobian. The obstacles'
poses and sizes are read from the terms at every solve (moving obstacles need no
rebuild); the weight ``w_c`` is ``solver_options["clearance_weight"]`` [1/m^2].

A penalty, not a constraint: the margin holds to within a few millimetres when the
reference passes near an obstacle (the intended use: a reference from the shaped metric,
the clearance guarding against disturbances). A reference running *through* an obstacle
makes the OCP trade tracking against clearance at full torque, and with stiff weights
the closed loop can become violent: keep the reference collision-free.
"""

from __future__ import annotations

import hashlib

import casadi as ca
import numpy as np

from geosyn.core.errors import InvalidArgument
from geosyn.metrics.base import Metric
from geosyn.metrics.shaping import ObstacleTerm, ShapedMetric

__all__ = [
    "clearance_digest",
    "clearance_function",
    "clearance_values",
    "find_obstacle_terms",
    "obstacle_terms",
]


def find_obstacle_terms(metric: Metric) -> tuple[ObstacleTerm, ...]:
    """The `ObstacleTerm` s of a `ShapedMetric`, in term order (empty for other metrics)."""
    terms = metric.terms if isinstance(metric, ShapedMetric) else ()
    return tuple(t for t in terms if isinstance(t, ObstacleTerm))


def obstacle_terms(metric: Metric) -> tuple[ObstacleTerm, ...]:
    """`find_obstacle_terms`, refusing a metric without any.

    Raises:
        InvalidArgument: ``metric`` is not a `ShapedMetric` with an `ObstacleTerm`.
    """
    found = find_obstacle_terms(metric)
    if not found:
        raise InvalidArgument(
            "clearance_margin needs a ShapedMetric with an ObstacleTerm (its obstacles are "
            f"the OCP's), got {metric!r}"
        )
    return found


def clearance_function(terms: tuple[ObstacleTerm, ...]) -> ca.Function:
    """``ddp_clearance: (q (n,), p (m_p,)) -> (c (m,), dc/dq (m, n))`` for the terms'
    spheres and slots, ``p`` their stacked parameters (`clearance_values`)."""
    n = terms[0].n
    q = ca.SX.sym("q", n)
    c = ca.vertcat(*(t.symbolic_clearances(q) for t in terms))
    p = ca.vertcat(*(t.symbolic_parameters() for t in terms))
    return ca.Function(
        "ddp_clearance", [q, p], [c, ca.jacobian(c, q)], ["q", "p"], ["c", "dc_dq"], {"cse": True}
    )


def clearance_values(terms: tuple[ObstacleTerm, ...]) -> np.ndarray:
    """(m_p,) the terms' current parameters (obstacle poses, sizes, active flags)."""
    return np.concatenate([t.parameter_values() for t in terms])


def clearance_digest(fun: ca.Function) -> str:
    """sha256 of the serialised clearance function (part of the compiled library's key)."""
    return hashlib.sha256(fun.serialize().encode()).hexdigest()
