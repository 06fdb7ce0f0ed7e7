"""Geodesic-tracking model predictive control: a CasADi OCP solved by fatrop, IPOPT or
box-DDP.

`GeodesicMPC` solves, every ``dt`` seconds, an optimal control problem over ``horizon``
stages with states ``x = (q, v)`` and torque or acceleration controls, and follows the
plan between solves. The package reads "describe, then solve": one description of the
problem (`.ocp`), shared by every solver family (`.nlp`, `.ddp`), each family behind the
contract of `.backend`. The problem is built once; each solve only sets parameters (the
measured state, the reference samples, the obstacles) and the shifted previous solution.

==============================  =======================================================
module                          holds
==============================  =======================================================
`.ocp.settings`                 argument choices, defaults, validated `OCPSettings`
`.ocp.dynamics`                 one shooting stage: RK4 on the ABA, or a double integrator
`.ocp.rk4`                      the RK4 step's Jacobians by the chain rule
`.ocp.linalg`                   small symbolic SPD solves (Cholesky, LDL^T)
`.ocp.compiled`                 stage dynamics compiled without curvature (codegen cache)
`.ocp.costs`                    cost terms: expression and Gauss-Newton derivatives
`.ocp.penalties`                soft joint-limit and clearance penalties (cost terms)
`.ocp.obstacles`                obstacle slots of `geosyn.world` shapes, clearances
`.ocp.plan`                     `MPCPlan` (what every backend returns), reference samples
`.backend`                      `TrackingProblem`, the `TrackingBackend` protocol
`.nlp.options`                  `NLPOptions` (fatrop, IPOPT)
`.nlp.problem`                  shooting problem -> NLP graph -> indexed NLP, one solve
`.nlp.solvers`                  fatrop and IPOPT option builders, warm and cold solvers
`.nlp.bounded`                  `BoundedSolver`: a solve within its time budget, signals heard
`.nlp.builder`                  `OCPBuilder`: the tracking and open-loop NLPs from parts
`.nlp.tracking`                 the fatrop/IPOPT backend (`NLPTracking`)
`.nlp.open_loop`                the minimum-effort Riemannian OCP, `OpenLoopSolution`
`.ddp.options`                  `DDPOptions` (box-DDP)
`.ddp.parameters`               the DDP's parameter vector and its cost terms
`.ddp.box_qp`                   the box-constrained QP of a stage (projected Newton)
`.ddp.parts`                    compiled stage functions: linearisation, Riccati step, ...
`.ddp.riccati`                  `RiccatiSolver`: backward and forward passes, line search
`.ddp.tracking`                 the box-DDP backend (`DDPTracking`)
`.ddp.native.functions`         the small generated functions of the native backward pass
`.ddp.native.library`           the hand-written C backward pass (default), compiled, cached
`.families`                     ``solver=`` names and the backend builder of each options class
`.follow`                       `PlanFollower`: a plan between solves, the fallback torque
`.controller`                   `GeodesicMPC`: re-solves, warm starts, fallbacks
==============================  =======================================================

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
                        zero curvature, found on disk by a recipe (`.ocp.compiled`), one
                        MX graph; ``"exact"``: an SX graph with exact Hessians on
                        CasADi's virtual machine (no compiler needed).
``solver``              None (default): ``"ddp"`` with torque control where the DDP
                        solves the problem, else ``"fatrop"`` (`.families`);
                        ``"fatrop"``: interior point on the stage structure
                        (Riccati); ``"ipopt"``: general sparse interior point;
                        ``"ddp"``: box-DDP (torque control); or the options objects
                        `NLPOptions`, `DDPOptions` (YAML: ``solver: {type: ddp, ...}``).
``joint_limit_guard``   True (default): every torque passes
                        `geosyn.controllers.limit_guard` (joint position and velocity
                        limits hard in closed loop, torque inside its limits);
                        False: the torque is only clamped to its limits.
``max_solve_time``      the wall-time budget of one solve (IPOPT stops at it; a longer
                        fatrop or DDP solve is discarded); over it, the controller
                        falls back.
``obstacles``           `geosyn.world` shapes kept ``clearance_margin`` [m] away (DDP;
                        YAML: the scene's obstacles, passed by the experiment builder).
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

from geosyn.controllers.mpc.backend import TrackingBackend, TrackingProblem
from geosyn.controllers.mpc.controller import GeodesicMPC
from geosyn.controllers.mpc.ddp.options import DDPOptions
from geosyn.controllers.mpc.families import SOLVERS
from geosyn.controllers.mpc.nlp.open_loop import OpenLoopSolution
from geosyn.controllers.mpc.nlp.options import NLPOptions
from geosyn.controllers.mpc.ocp.plan import MPCPlan
from geosyn.controllers.mpc.ocp.settings import (
    CONTROLS,
    EFFORTS,
    HESSIANS,
    MAX_HORIZON,
    MAX_SOLVER_ITER,
    MAX_STAGE_DT,
    MIN_SOLVER_TOL,
    MIN_STAGE_DT,
)

__all__ = [
    "CONTROLS",
    "DDPOptions",
    "EFFORTS",
    "GeodesicMPC",
    "HESSIANS",
    "MAX_HORIZON",
    "MAX_SOLVER_ITER",
    "MAX_STAGE_DT",
    "MIN_SOLVER_TOL",
    "MIN_STAGE_DT",
    "MPCPlan",
    "NLPOptions",
    "OpenLoopSolution",
    "SOLVERS",
    "TrackingBackend",
    "TrackingProblem",
]
