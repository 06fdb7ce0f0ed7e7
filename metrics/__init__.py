"""Riemannian metrics on configuration space: kinetic energy, shaping terms, geodesics."""

if not __name__.startswith("geosyn."):  # the folder imported as a top-level package
    raise ImportError(f"import geosyn.metrics, not {__name__}: one module, one name")


from geosyn.metrics import geodesic
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
    "sx_cholesky_solve",
]
