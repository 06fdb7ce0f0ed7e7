"""Geodesic-tracking model predictive control: a CasADi OCP solved by fatrop or IPOPT.

`GeodesicMPC` solves, every ``dt`` seconds, a multiple-shooting optimal control problem
over ``horizon`` stages with states ``x = (q, v)`` and torque or acceleration controls,
and follows the plan between solves. The problem is built once; each solve only sets
parameters (the measured state and the reference samples) and the shifted previous
solution. The package reads in the order the problem is composed:

============================  =========================================================
module                        holds
============================  =========================================================
`.settings`                   argument choices, defaults, validated settings
`.dynamics`                   one shooting stage: RK4 on the ABA, or a double integrator
`.gauss_newton`               stage dynamics compiled without curvature (codegen cache)
`.costs`                      cost terms with their weights, stage and terminal costs
`.problem`                    shooting problem -> NLP graph -> indexed NLP, one solve
`.solvers`                    fatrop and IPOPT option builders, warm and cold solvers
`.ocp`                        `OCPBuilder`: the tracking and open-loop OCPs from parts
`.plan`                       `MPCPlan`, reference samples, following a plan
`.controller`                 `GeodesicMPC`: re-solves, warm starts, fallbacks
`.open_loop`                  the minimum-effort Riemannian OCP, `OpenLoopSolution`
============================  =========================================================

Speed. The per-stage dynamics dominate an interior-point iteration when their exact
second derivatives are used; with ``hessian="gauss-newton"`` (default) they are compiled
to C with a structurally zero second derivative and the NLP is an MX graph with one
mapped call per stage function, so the Lagrangian Hessian keeps only the costs' own
curvature. Only these small functions are compiled, never the whole NLP. Measured
figures are in ``benchmarks/RESULTS.md`` (``benchmarks/controllers.py``).
"""

from geosyn.controllers.mpc.controller import GeodesicMPC
from geosyn.controllers.mpc.open_loop import OpenLoopSolution
from geosyn.controllers.mpc.plan import MPCPlan
from geosyn.controllers.mpc.settings import CONTROLS, EFFORTS, HESSIANS, SOLVERS

__all__ = [
    "CONTROLS",
    "EFFORTS",
    "GeodesicMPC",
    "HESSIANS",
    "MPCPlan",
    "OpenLoopSolution",
    "SOLVERS",
]
