"""geosyn: the Riemannian geometry of a robot's configuration space, turned into motion
and torque control (geodesic synergies, shaped metrics, controllers, MuJoCo experiments).

The handful of names a user starts from are here; everything else lives in the layers
`geosyn.core`, `geosyn.robots`, `geosyn.world`, `geosyn.metrics`, `geosyn.synergies`,
`geosyn.controllers`, `geosyn.sim` and `geosyn.experiments`. Names load on first use, so
``import geosyn`` is cheap and imports neither MuJoCo nor CasADi.

Example:
    >>> import geosyn
    >>> metric = geosyn.KineticEnergyMetric(geosyn.load_robot("planar2"))
"""

from __future__ import annotations

import importlib
from importlib.metadata import PackageNotFoundError, version
from typing import TYPE_CHECKING, Any

try:
    __version__ = version("geosyn")
except PackageNotFoundError:  # running from a source tree that was never installed
    __version__ = "0+unknown"

_NAMES = {
    "GeosynError": "geosyn.core.errors",
    "Robot": "geosyn.robots.robot",
    "load_robot": "geosyn.robots.loading",
    "KineticEnergyMetric": "geosyn.metrics.kinetic",
    "ShapedMetric": "geosyn.metrics.shaping",
    "exp": "geosyn.metrics.geodesic",
    "log": "geosyn.metrics.geodesic",
    "parallel_transport": "geosyn.metrics.geodesic",
    "GeodesicSynergy": "geosyn.synergies.synergy",
    "combine": "geosyn.synergies.synergy",
    "ComputedTorque": "geosyn.controllers.computed_torque",
    "QPController": "geosyn.controllers.qp",
    "GeodesicMPC": "geosyn.controllers.mpc",
    "Simulation": "geosyn.sim.simulation",
}

__all__ = [
    "ComputedTorque",
    "GeodesicMPC",
    "GeodesicSynergy",
    "GeosynError",
    "KineticEnergyMetric",
    "QPController",
    "Robot",
    "ShapedMetric",
    "Simulation",
    "__version__",
    "combine",
    "exp",
    "load_robot",
    "log",
    "parallel_transport",
]

if TYPE_CHECKING:
    from geosyn.controllers.computed_torque import ComputedTorque
    from geosyn.controllers.mpc import GeodesicMPC
    from geosyn.controllers.qp import QPController
    from geosyn.core.errors import GeosynError
    from geosyn.metrics.geodesic import exp, log, parallel_transport
    from geosyn.metrics.kinetic import KineticEnergyMetric
    from geosyn.metrics.shaping import ShapedMetric
    from geosyn.robots.loading import load_robot
    from geosyn.robots.robot import Robot
    from geosyn.sim.simulation import Simulation
    from geosyn.synergies.synergy import GeodesicSynergy, combine


def __getattr__(name: str) -> Any:
    """Load a curated name from its layer on first use (PEP 562)."""
    module = _NAMES.get(name)
    if module is None:
        raise AttributeError(f"module 'geosyn' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_NAMES))
