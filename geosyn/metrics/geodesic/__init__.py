"""Geodesics of any `Metric`: exponential map, log map, transport, energy and distance.

One module per subject:

- `exp_map`: `exp` and `Geodesic` (compiled fixed-step RK4, or SciPy's DOP853);
- `log_map`: `log`, `log_solve`, `LogResult` (damped Newton shooting, `shooting`, then
  the strategies of `continuation` and a seeded multistart);
- `transport`: `parallel_transport` along a sampled curve;
- `energy`: `path_energy`, `straight_line` and `distance`;
- `collocation`: `Collocation`, `CollocationResult` (minimum-energy paths by direct
  collocation with IPOPT, optionally with clearance constraints; refined to geodesics by
  shooting when no constraint is active).

Compiled functions (RK4 step, shooting maps, transport operator) are built once per
metric and kept in ``metric.functions``; ``metric.functions.clear()`` forgets them.
"""

from geosyn.metrics.geodesic.collocation import Collocation, CollocationResult
from geosyn.metrics.geodesic.energy import distance, path_energy, straight_line
from geosyn.metrics.geodesic.exp_map import Geodesic, exp
from geosyn.metrics.geodesic.log_map import LogOptions, LogResult, log, log_solve
from geosyn.metrics.geodesic.transport import parallel_transport

__all__ = [
    "Collocation",
    "CollocationResult",
    "Geodesic",
    "LogOptions",
    "LogResult",
    "distance",
    "exp",
    "log",
    "log_solve",
    "parallel_transport",
    "path_energy",
    "straight_line",
]
