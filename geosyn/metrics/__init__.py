"""Riemannian metrics on configuration space: kinetic energy, shaping terms, geodesics."""

if not __name__.startswith("geosyn."):  # the folder imported as a top-level package
    raise ImportError(f"import geosyn.metrics, not {__name__}: one module, one name")


from geosyn.metrics import geodesic
from geosyn.metrics.base import Metric
from geosyn.metrics.coupled import CoupledMetric
from geosyn.metrics.errors import (
    FloatingBaseUnsupported,
    GeodesicNotFound,
    MetricError,
    NoSymbolicForm,
    StanceError,
)
from geosyn.metrics.floating import FloatingKineticEnergyMetric
from geosyn.metrics.geodesic import *  # noqa: F403  (its __all__, listed below)
from geosyn.metrics.kinetic import KineticEnergyMetric
from geosyn.metrics.stance import Stance

__all__ = [
    *geodesic.__all__,
    "CoupledMetric",
    "FloatingBaseUnsupported",
    "FloatingKineticEnergyMetric",
    "GeodesicNotFound",
    "KineticEnergyMetric",
    "Metric",
    "MetricError",
    "NoSymbolicForm",
    "Stance",
    "StanceError",
]
