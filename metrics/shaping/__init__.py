"""Metric shaping: payload, obstacle and joint-limit terms added to a base metric.

`ShapedMetric(base, terms)` is a `Metric`, so geodesics, synergies and controllers use it
unchanged. Terms: `LoadTerm` (exact payload inertia), `ObstacleTerm` (barrier metrics for
`Sphere`, `Box`, `Capsule` and `HalfSpace` obstacles, parameterized so obstacles move
without rebuilding), `JointLimitTerm` (barrier at position limits).
"""

from geosyn.metrics.shaping.base import MetricTerm, ShapedMetric
from geosyn.metrics.shaping.errors import (
    CapacityExceeded,
    InvalidObstacle,
    InvalidPayload,
    InvalidTermArgument,
    ShapingError,
    TermAlreadyBound,
    TermNotBound,
    UnknownObstacleType,
)
from geosyn.metrics.shaping.joint_limit import JointLimitTerm
from geosyn.metrics.shaping.load import LoadTerm
from geosyn.metrics.shaping.obstacle import (
    GATES,
    HALFSPACE_EXTENT,
    PARAMS_PER_OBSTACLE,
    PROFILES,
    Box,
    Capsule,
    HalfSpace,
    Obstacle,
    ObstacleTerm,
    Sphere,
)

__all__ = [
    "GATES",
    "HALFSPACE_EXTENT",
    "PARAMS_PER_OBSTACLE",
    "PROFILES",
    "Box",
    "CapacityExceeded",
    "Capsule",
    "HalfSpace",
    "InvalidObstacle",
    "InvalidPayload",
    "InvalidTermArgument",
    "JointLimitTerm",
    "LoadTerm",
    "MetricTerm",
    "Obstacle",
    "ObstacleTerm",
    "ShapedMetric",
    "ShapingError",
    "Sphere",
    "TermAlreadyBound",
    "TermNotBound",
    "UnknownObstacleType",
]
