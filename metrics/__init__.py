"""Riemannian metrics on configuration space: kinetic energy, shaping terms, geodesics."""

from geosyn.metrics import codegen, geodesic, symbolic
from geosyn.metrics.base import Metric, MetricFunctions, christoffel_from_dG, sx_cholesky_solve
from geosyn.metrics.errors import GeodesicNotFound, MetricError, NoSymbolicForm
from geosyn.metrics.geodesic import (
    Geodesic,
    LogResult,
    clear_geodesic_cache,
    distance,
    exp,
    log,
    log_solve,
    parallel_transport,
    path_energy,
    straight_line,
)
from geosyn.metrics.kinetic import KineticEnergyMetric

__all__ = [
    "Geodesic",
    "LogResult",
    "clear_geodesic_cache",
    "distance",
    "exp",
    "geodesic",
    "log",
    "log_solve",
    "parallel_transport",
    "path_energy",
    "straight_line",
    "GeodesicNotFound",
    "KineticEnergyMetric",
    "Metric",
    "MetricError",
    "MetricFunctions",
    "NoSymbolicForm",
    "christoffel_from_dG",
    "codegen",
    "symbolic",
    "sx_cholesky_solve",
]
