"""Motion planning on a metric: minimum-energy, collision-free paths among obstacles.

`Planner` checks the query, runs collocation of the geodesic energy with clearance
constraints (`geosyn.metrics.geodesic.collocation`; coarse to fine among obstacles),
falls back to an RRT-Connect seed (`rrt`) when no local solve reaches the goal, and
checks the result between nodes. A goal may be a joint vector or an end-effector position
or pose with tolerances (`EndEffectorGoal`, solved by inverse kinematics: `goals`).
"""

from geosyn.metrics.planning.certify import CertifiedClearance, certified_clearance
from geosyn.metrics.planning.errors import (
    GoalUnreachable,
    InCollision,
    NoPathFound,
    OutsideJointLimits,
    PlanningError,
)
from geosyn.metrics.planning.goals import EndEffectorGoal, IKSolution, ik_solutions
from geosyn.metrics.planning.planner import Plan, Planner
from geosyn.metrics.planning.rrt import rrt_connect, shortcut

__all__ = [
    "CertifiedClearance",
    "EndEffectorGoal",
    "GoalUnreachable",
    "IKSolution",
    "InCollision",
    "NoPathFound",
    "OutsideJointLimits",
    "Plan",
    "Planner",
    "PlanningError",
    "certified_clearance",
    "ik_solutions",
    "rrt_connect",
    "shortcut",
]
