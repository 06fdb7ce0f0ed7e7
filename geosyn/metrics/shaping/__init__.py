"""Metric shaping: payload, obstacle and joint-limit terms added to a base metric.

`ShapedMetric(base, terms)` is a `Metric`, so geodesics, synergies and controllers use it
unchanged. Terms: `LoadTerm` (exact payload inertia), `ObstacleTerm` (barrier metrics for
the `geosyn.world` shapes `Sphere`, `Box`, `Capsule` and `HalfSpace`, parameterized so
obstacles move without rebuilding), `JointLimitTerm` (barrier at position limits). The
shapes are re-exported here for convenience.
"""

from geosyn.metrics.shaping.base import MetricTerm, ShapedMetric
from geosyn.metrics.shaping.errors import (
    CapacityExceeded,
    InvalidTermArgument,
    ShapingError,
    TermAlreadyBound,
    TermNotBound,
)
from geosyn.metrics.shaping.joint_limit import JointLimitTerm
from geosyn.metrics.shaping.load import LoadTerm
from geosyn.metrics.shaping.obstacle import ObstacleTerm

__all__ = [
    "CapacityExceeded",
    "InvalidTermArgument",
    "JointLimitTerm",
    "LoadTerm",
    "MetricTerm",
    "ObstacleTerm",
    "ShapedMetric",
    "ShapingError",
    "TermAlreadyBound",
    "TermNotBound",
]
