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

Formulation selected by each option (the same names in Python and in YAML ``type: mpc``
sections; the YAML defaults are read from `GeodesicMPC`'s constructor):

======================  ===============================================================
option                  selects
======================  ===============================================================
``control``             ``"acceleration"`` (default): ``u`` = joint accelerations, the
                        exact double integrator, ``|RNEA(q, v, u)| <= tau_max`` as path
                        constraints. ``"torque"``: ``u`` = joint torques, RK4 on the ABA
                        (``rk4_steps`` per stage), ``|u| <= tau_max`` as bounds.
``effort``              None (default): ``"acceleration"`` with acceleration control,
                        ``"torque"`` with torque control. ``"torque"``:
                        ``|tau - tau_ref|^2``; ``"acceleration"``: ``|u - a_ref|^2``;
                        ``"metric"``: the squared Riemannian norm of the covariant
                        acceleration.
``hessian``             ``"gauss-newton"`` (default): the stage dynamics compiled to C with
                        zero curvature, found on disk by a recipe (`.gauss_newton`), one
                        MX graph; ``"exact"``: an SX graph with exact Hessians on
                        CasADi's virtual machine (no compiler needed).
``solver``              ``"fatrop"`` (default): interior point on the stage structure
                        (Riccati); ``"ipopt"``: general sparse interior point.
``max_solve_time``      the wall-time budget of one solve (IPOPT stops at it; a longer
                        fatrop solve is discarded); over it, the controller falls back.
======================  ===============================================================

Build time. The compiled stage functions are looked up by a recipe (the serialised robot
model, the settings and a digest of the code that builds them), so a robot seen before
builds no symbolic graph: a new `GeodesicMPC` is ready in well under a second. The first
build for a robot compiles C for tens of seconds and reports its progress on stderr.

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
