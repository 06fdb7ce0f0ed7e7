"""Motion planning on a metric: minimum-energy, collision-free paths among obstacles.

`Planner` checks the query, runs collocation of the geodesic energy with clearance
constraints (`geosyn.metrics.geodesic.collocation`; coarse to fine among obstacles),
falls back to an RRT-Connect seed (`rrt`) when no local solve reaches the goal, and
checks the result between nodes.
"""

from geosyn.metrics.planning.errors import (
    InCollision,
    NoPathFound,
    OutsideJointLimits,
    PlanningError,
)
from geosyn.metrics.planning.planner import Plan, Planner
from geosyn.metrics.planning.rrt import rrt_connect, shortcut

__all__ = [
    "InCollision",
    "NoPathFound",
    "OutsideJointLimits",
    "Plan",
    "Planner",
    "PlanningError",
    "rrt_connect",
    "shortcut",
]
