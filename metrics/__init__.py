"""Riemannian metrics on configuration space: kinetic energy, shaping terms, geodesics."""

from geosyn.metrics import codegen, symbolic
from geosyn.metrics.base import Metric, MetricFunctions, christoffel_from_dG, sx_cholesky_solve
from geosyn.metrics.errors import GeodesicNotFound, MetricError, NoSymbolicForm
from geosyn.metrics.kinetic import KineticEnergyMetric

__all__ = [
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
