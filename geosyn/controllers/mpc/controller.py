"""`GeodesicMPC`: the receding-horizon controller (warm starts, plan following, fallbacks).

The OCP over ``N = horizon`` stages of length ``dt``, solved at time ``t`` from the
measured state ``(q_m, v_m)``, with the reference sampled at ``t_k = t + k dt``:

.. math::
    \\min_{x, u} \\sum_{k=0}^{N-1} \\|q_k - q^r_k\\|^2_{W_q} + \\|v_k - v^r_k\\|^2_{W_v}
        + \\ell(x_k, u_k) + \\|x_N - x^r_N\\|^2_{W_N}

subject to ``x_0 = (q_m, v_m)``, ``x_{k+1} = F(x_k, u_k)`` (RK4, ``rk4_steps`` steps per
stage, on ``qdd = ABA(q, v, tau)`` with gravity when ``control="torque"``; the exact
double integrator with ``tau = RNEA(q, v, u)`` when ``control="acceleration"``),
``|tau_k| <= tau_max``, ``q_min <= q_k <= q_max`` and ``|v_k| <= v_max`` for k >= 1. The
effort ``ell`` is

- ``effort="torque"``: ``w_tau |tau_k - tau^r_k|^2`` with ``tau^r`` the inverse dynamics
  of the reference (so perfect tracking costs nothing);
- ``effort="acceleration"`` (acceleration control only): ``w_tau |u_k - a^r_k|^2``, a
  quadratic regulariser towards the reference acceleration; the torque then enters only
  the limits, which keeps the Hessian cheap;
- ``effort="metric"``: ``w_tau (tau_k - g(q_k))^T G(q_k)^{-1} (tau_k - g(q_k))``, the
  squared Riemannian norm of the covariant acceleration ``D v / dt`` (for the kinetic
  energy metric ``G = M``: ``M qdd + C v``). Without gravity and constraints its
  minimisers between fixed end points are geodesics (zero cost): see
  `GeodesicMPC.solve_open_loop`.

The description (settings, dynamics, costs, obstacle slots, plan) is
`geosyn.controllers.mpc.ocp`; a solver family builds a backend from it
(`geosyn.controllers.mpc.backend`, `geosyn.controllers.mpc.families`). This class only re-solves every ``dt``
seconds (when ``t`` has advanced by at least ``dt`` since the last solve) and follows
the plan in between (`geosyn.controllers.mpc.follow.PlanFollower`). Each solve
warm-starts from the previous plan shifted by the elapsed stages, else cold-starts from
the reference samples: `geosyn.controllers.mpc.nlp.tracking` (fatrop, IPOPT) and
`geosyn.controllers.mpc.ddp.tracking` (box-DDP) say how.

A failed solve (solver status not successful, an exception, non-finite numbers) is
flagged in the diagnostics (``fallback_used``, ``solver_status``, ``iterations``) and
falls back to the previous plan, if it still covers ``t`` and the measured state is
within ``plan_tolerance`` of it (``extra["fallback"] == 1``), else to a computed torque on
the reference (``extra["fallback"] == 2``, clipped to the limits by `Controller.compute`).
A setting changed at build time (no C compiler: ``hessian`` ``"exact"``) is warned and
recorded in ``diagnostics.notes``.

Every torque (plan, previous plan or fallback) then passes the joint-limit guard
(`geosyn.controllers.limit_guard`; ``joint_limit_guard=False``: a clamp to the torque
limits); a law torque over a limit is flagged in ``diagnostics.saturated``, and each tick
the guard changed is counted and described in the diagnostics.
"""

from __future__ import annotations

import math
import sys
import time
from collections.abc import Sequence

import numpy as np

from geosyn.controllers.base import Controller, check_gain
from geosyn.controllers.errors import NoReference
from geosyn.controllers.limit_guard import GuardedCommand
from geosyn.controllers.mpc.backend import TrackingBackend, TrackingProblem
from geosyn.controllers.mpc.ddp.options import DDPOptions
from geosyn.controllers.mpc.families import BACKENDS, default_solver_options, solver_options
from geosyn.controllers.mpc.follow import PlanFollower
from geosyn.controllers.mpc.nlp.builder import OCPBuilder
from geosyn.controllers.mpc.nlp.open_loop import OpenLoopOCP, OpenLoopSolution
from geosyn.controllers.mpc.nlp.options import NLPOptions
from geosyn.controllers.mpc.nlp.tracking import tracking_parameters
from geosyn.controllers.mpc.ocp.dynamics import FRICTION_VELOCITY, joint_damping, joint_friction
from geosyn.controllers.mpc.ocp.obstacles import obstacle_slots
from geosyn.controllers.mpc.ocp.plan import EPS_T, MPCPlan, ReferenceSampler, ReferenceSamples
from geosyn.controllers.mpc.ocp.settings import HESSIANS, ocp_settings, outside_state_margin
from geosyn.controllers.reference import Reference
from geosyn.core.errors import InvalidArgument
from geosyn.core.types import Vector
from geosyn.core.validation import check_choice, check_float, check_positive, check_vector
from geosyn.metrics.base import Metric
from geosyn.robots.robot import CollisionSphere, Robot
from geosyn.world.shapes import Shape

__all__ = ["GeodesicMPC"]


def _report_progress(line: str) -> None:
    """A first build compiles for tens of seconds: say so on stderr (never silent)."""
    print(f"geosyn MPC: {line}", file=sys.stderr, flush=True)


class GeodesicMPC(Controller):
    """Geodesic-tracking MPC: an OCP built in CasADi, solved by fatrop or IPOPT (multiple
    shooting) or by box-DDP (``solver="ddp"``, torque control). The OCP, the efforts and
    the fallbacks: `geosyn.controllers.mpc.controller`.

    Defaults: ``control="acceleration"`` with ``effort="acceleration"`` and fatrop; with
    ``control="torque"``, box-DDP (``solver=None`` picks it wherever it solves the
    problem, `geosyn.controllers.mpc.families.default_solver_options`). Box-DDP is the
    fastest torque-level solver (faster per solve than Crocoddyl's BoxFDDP on the same
    problem, benchmarks/RESULTS.md); fatrop pays for the Jacobian of the RK4 step on
    the ABA over several interior-point iterations. The DDP keeps only the torque box as
    a hard constraint of its OCP (its position and velocity limits are stiff penalties);
    the joint-limit guard (``joint_limit_guard``, on by default) makes them hard in
    closed loop for every solver. fatrop stays the default at the acceleration level
    (the DDP solves torque controls only), and is what ``solver=None`` takes where the
    DDP refuses the problem (an exact Hessian, a metric effort on another metric).

    Args:
        robot: the robot (its model is the OCP's dynamics).
        metric: the metric of the geodesic reference; weighs the ``"metric"`` effort.
        horizon: number of stages N (>= 1).
        dt: stage length and re-solve period [s] (> 0).
        solver: None (default: ``"ddp"`` with torque control where the DDP solves the
            problem, else ``"fatrop"``; the choice is ``solver_options``), ``"fatrop"``,
            ``"ipopt"`` or ``"ddp"`` (each its family's default options), or the options
            themselves: `NLPOptions` (fatrop or IPOPT on the
            multiple-shooting NLP: tolerance, iterations, barrier parameters, plugin
            options) or `DDPOptions` (box-constrained DDP with compiled stage
            derivatives and Riccati feedback between solves, the fastest torque-level
            solver: needs ``control="torque"``, ``effort`` ``"torque"`` or
            ``"metric"``; position and velocity limits become stiff penalties; a warm
            solve is ``warm_iterations`` DDP steps; `solve_open_loop` then uses IPOPT).
        q_weight: scalar or (nv,) weight on the position error [1/rad^2].
        v_weight: scalar or (nv,) weight on the velocity error [s^2/rad^2].
        tau_weight: scalar or (nv,) effort weight: [1/(N m)^2] for the torque and metric
            efforts (the metric effort uses its first entry, a scalar weight on the
            Riemannian norm), [s^4/rad^2] for the acceleration effort. None: 1e-3, 1e-3
            and 1e-2 respectively.
        terminal_weight: scalar or (2 nv,) weight on the terminal state error (q then v).
        effort: ``"torque"``, ``"metric"`` or ``"acceleration"``; None picks
            ``"acceleration"`` with acceleration control and ``"torque"`` with torque control.
        control: ``"torque"`` or ``"acceleration"``.
        rk4_steps: RK4 steps per stage (torque control), 1 or 2.
        hessian: ``"gauss-newton"`` (per-stage dynamics compiled without second
            derivatives, `geosyn.controllers.mpc.ocp.compiled`; the DDP's only one) or
            ``"exact"`` (exact Hessian of an SX graph on CasADi's VM; fatrop and IPOPT).
            Without a C compiler ``"gauss-newton"`` becomes ``"exact"``, with a
            ``RuntimeWarning`` and ``diagnostics.notes["hessian"]``.
        kp: scalar or (nv,) stiffness [1/s^2] of the fallback computed torque and of
            following fatrop and IPOPT plans (a DDP plan is followed by its own Riccati
            gains; ``kp``, ``kd`` stabilise the first rollout of a cold DDP solve).
        kd: scalar or (nv,) damping [1/s], likewise.
        plan_tolerance: max joint deviation [rad] for reusing the previous plan as fallback.
        max_solve_time: wall-time budget of one solve [s] (> 0): IPOPT stops at it, a
            longer fatrop or DDP solve is discarded; either way the controller falls
            back. A state beyond `geosyn.controllers.mpc.ocp.settings.STATE_MARGIN` of
            the limits is not solved (status ``"skipped: ..."``; the OCP is infeasible).
        clearance_margin: clearance [m] kept from ``obstacles`` by a stiff penalty
            (`geosyn.controllers.mpc.ocp.obstacles`; DDP, any effort), or None.
        obstacles: `geosyn.world` shapes (`Sphere`, `Box`, ...; `set_obstacles` moves
            them). None with ``clearance_margin``: a shaped metric's obstacle terms
            (transitional), read at every solve.
        clearance_spheres: the spheres kept clear: None (the robot's), ``"file"`` (covering
            its file's collision geometry) or the spheres (`ObstacleSlots`).
        tracking: ``"euclidean"`` or ``"metric"``: the errors in the kinetic-energy
            metric's norm at the reference (`geosyn.controllers.mpc.ocp.costs.StateTracking`;
            the weights then carry [1/(kg m^2)] more).
        joint_limit_guard: pass every torque through the joint-limit guard
            (`geosyn.controllers.limit_guard.GuardedCommand`: joint position and
            velocity limits hard in closed loop, over the time between the last two
            `compute` calls, and the torque limits). False: the torque is only clamped.
        reference: optional reference.

    Attributes:
        settings: the validated OCP settings (`OCPSettings`: weights, effort, ...).
        solver_options: the solver family's options (`NLPOptions` or `DDPOptions`).
        N: horizon; dt: stage length [s]; control, effort, hessian: the modes in use.
        obstacles: the `ObstacleSlots` (None without ``clearance_margin``).
        ocp: the `OCPBuilder` of the open-loop NLP.
        build_time: wall-clock time of building the tracking backend [s].
        solve_count: number of `solve` calls.
        command: the `GuardedCommand` (``command.guard`` the `JointLimitGuard` or None;
            ``command.count`` the ticks it changed since the last reset).

    Raises:
        InvalidArgument: a bad argument (the message names it and lists what is allowed).

    The constructor builds the solvers (allocates; seconds, up to minutes on first use
    when the compiled dynamics are not cached yet); `compute` allocates only small arrays.
    """

    def __init__(
        self,
        robot: Robot,
        metric: Metric,
        horizon: int = 40,
        dt: float = 0.02,
        *,
        solver: str | NLPOptions | DDPOptions | None = None,
        q_weight: float | np.ndarray = 1e4,
        v_weight: float | np.ndarray = 1e1,
        tau_weight: float | np.ndarray | None = None,
        terminal_weight: float | np.ndarray = 1e5,
        effort: str | None = None,
        control: str = "acceleration",
        rk4_steps: int = 1,
        hessian: str = "gauss-newton",
        kp: float | np.ndarray = 400.0,
        kd: float | np.ndarray = 40.0,
        plan_tolerance: float = 0.05,
        max_solve_time: float = 1.0,
        clearance_margin: float | None = None,
        obstacles: Sequence[Shape] | None = None,
        clearance_spheres: Sequence[CollisionSphere] | str | None = None,
        tracking: str = "euclidean",
        joint_limit_guard: bool = True,
        reference: Reference | None = None,
    ) -> None:
        super().__init__(robot, None)
        n = self.nv
        if not isinstance(metric, Metric) or metric.n != n:
            raise InvalidArgument(
                f"metric must be a geosyn Metric of dimension nv={n}, got {metric!r}"
            )
        self.metric = metric
        weights = (q_weight, v_weight, tau_weight, terminal_weight)
        self.settings = s = ocp_settings(
            n, horizon, dt, control, effort, rk4_steps, *weights, clearance_margin, tracking
        )
        self.max_solve_time = check_positive(max_solve_time, "max_solve_time", "s")
        self.hessian = check_choice(hessian, HESSIANS, "hessian")
        self.kp, self.kd = check_gain(kp, n, "kp"), check_gain(kd, n, "kd")
        self.plan_tolerance = check_float(plan_tolerance, "plan_tolerance", low=0.0, unit="rad")
        self.obstacles = obstacle_slots(robot, s.clearance_margin, obstacles, clearance_spheres)
        self.N, self.dt, self.control, self.effort = s.N, s.dt, s.control, s.effort
        if not isinstance(joint_limit_guard, bool):
            raise InvalidArgument(
                f"joint_limit_guard must be True or False, got {joint_limit_guard!r}"
            )
        damping = joint_damping(robot)
        problem = TrackingProblem(
            robot, metric, s, self.hessian, self.obstacles, self.kp, self.kd,
            self.max_solve_time, _report_progress,
        )  # fmt: skip
        self.solver_options = (
            default_solver_options(problem) if solver is None else solver_options(solver)
        )
        self.command = GuardedCommand(robot, joint_limit_guard, s.dt, damping)
        self._follower = PlanFollower(
            self._model, self._data, s.control, s.dt, self.kp, self.kd, self.plan_tolerance,
            robot.tau_max, damping, joint_friction(robot),
        )  # fmt: skip
        open_loop_options = self.solver_options
        if not isinstance(open_loop_options, NLPOptions):  # a terminal equality: IPOPT
            open_loop_options = NLPOptions(
                "ipopt", open_loop_options.tol, open_loop_options.max_iter
            )
        self.ocp = OCPBuilder(robot, metric, s, open_loop_options, self.max_solve_time)
        self._open_loop = OpenLoopOCP(self.ocp)
        self._sampler = ReferenceSampler(self._model, self._data, damping)
        if damping is not None:
            self.diagnostics.notes["damping"] = f"joint damping {damping.tolist()} modelled"
        if np.any(robot.frictionloss):  # ocp.dynamics: a known torque of each stage
            self.diagnostics.notes["frictionloss"] = (
                f"dry joint friction {robot.frictionloss.tolist()} modelled: fed forward as"
                f" f_c tanh(v_r / {FRICTION_VELOCITY}) on the reference velocity, within the"
                " torque limits"
            )
        start = time.perf_counter()
        self._tracker: TrackingBackend = BACKENDS[type(self.solver_options)](
            problem, self.solver_options
        )
        self.build_time = time.perf_counter() - start
        self.hessian = self._tracker.hessian
        for setting, message in self._tracker.notes.items():
            self._note(setting, message)
        self._plan: MPCPlan | None = None
        self._t_solve = -math.inf
        self._using_fallback = False
        self.solve_count = 0
        if reference is not None:
            self.set_reference(reference)

    def set_obstacles(self, obstacles: Sequence[Shape]) -> None:
        """Move or replace the obstacles (at most as many as given at construction; a
        parameter write, read by the next solve).

        Raises:
            InvalidArgument: no obstacle slots (built without ``obstacles``), or too
                many shapes.
        """
        if self.obstacles is None:
            raise InvalidArgument("set_obstacles needs GeodesicMPC(obstacles=[...]) at build")
        self.obstacles.set_obstacles(obstacles)

    # -- controller hooks ------------------------------------------------------------
    def _on_reset(self, q: Vector, v: Vector, t: float) -> None:
        self._on_reference_changed()
        self._using_fallback = False
        self.command.reset()
        self.diagnostics.notes.pop("joint_limit_guard", None)

    def _on_reference_changed(self) -> None:
        # A new reference invalidates the warm start (a different task).
        self._sampler.clear()
        self._plan = None
        self._tracker.forget()
        self._t_solve = -math.inf

    @property
    def plan(self) -> MPCPlan | None:
        """The plan of the last successful solve (None before)."""
        return self._plan

    @property
    def backend(self) -> TrackingBackend:
        """The solver family's built backend (for ``solver="ddp"`` a
        `geosyn.controllers.mpc.ddp.tracking.DDPTracking`, whose ``graphs()`` and
        ``parameters`` give its solver to code generation)."""
        return self._tracker

    # -- solving ---------------------------------------------------------------------
    def problem_parameters(
        self, t: float, x_init: np.ndarray
    ) -> tuple[np.ndarray, ReferenceSamples]:
        """The tracking NLP's parameters at time ``t`` and the reference samples in them.

        Args:
            t: time of the solve [s].
            x_init: (2 nv,) measured state ``(q, v)`` [rad, rad/s].

        Returns:
            The parameter vector (`pack_parameters`) and the `ReferenceSamples`.

        Raises:
            NoReference: no reference was set.
        """
        ref = self._reference_samples(t)
        return tracking_parameters(self.ocp, x_init, ref), ref

    def _reference_samples(self, t: float) -> ReferenceSamples:
        if self._reference is None:
            raise NoReference(f"{type(self).__name__}.solve called before set_reference")
        return self._sampler.sample(self._reference, t, self.N, self.dt)

    def solve(self, t: float, q: Vector, v: Vector) -> MPCPlan:
        """Solve the tracking OCP from the measured state at time ``t`` (no fallback).

        Warm-starts from the previous plan shifted by the elapsed stages when there is
        one (the last stage duplicated), else cold-starts from the reference samples.

        Args:
            t: time [s].
            q: (nv,) joint positions [rad].
            v: (nv,) joint velocities [rad/s].

        Returns:
            The `MPCPlan` (``success`` False on a failed solve; never raises for that).

        Raises:
            InvalidArgument: bad inputs; NoReference without a reference.
        """
        q = check_vector(q, self.nv, "q")
        v = check_vector(v, self.nv, "v")
        x_init = np.concatenate([q, v])
        ref = self._reference_samples(t)
        r = self.robot
        self.solve_count += 1
        outside = outside_state_margin(q, v, r.q_min, r.q_max, r.v_max)
        if outside:
            nan_u = np.full((self.N, self.nv), np.nan)
            nan_x = np.full((self.N + 1, 2 * self.nv), np.nan)
            status = f"skipped: measured state {outside}"
            return MPCPlan(t, nan_x, nan_u, nan_u.copy(), status, 0, False, 0.0)
        start = time.perf_counter()
        plan = self._tracker.solve(t, x_init, ref, self._plan)
        plan = plan._replace(solve_time=time.perf_counter() - start)
        return plan.within_budget(self.max_solve_time)

    # -- control ---------------------------------------------------------------------
    def compute(self, t: float, q: Vector, v: Vector) -> Vector:
        """`Controller.compute`; a joint whose torque the law asked over its limit (then
        guarded or clamped inside, or its DDP feedback saturated by the plan follower) is
        flagged in ``diagnostics.saturated``."""
        self._follower.clipped[:] = False
        tau = super().compute(t, q, v)
        sat = self.diagnostics.saturated
        if sat is not None:
            for asked_over in (self.command.over_box, self._follower.clipped):
                if asked_over.any():
                    np.logical_or(sat, asked_over, out=sat)
        return tau

    def _compute(self, t: float, q: Vector, v: Vector) -> Vector:
        tau = self._law(t, q, v)
        return self.command.apply(t, q, v, tau, self.diagnostics)

    def _law(self, t: float, q: Vector, v: Vector) -> Vector:
        """The MPC's torque before the guard: re-solve when due, follow the plan, or fall
        back (see the module)."""
        d = self.diagnostics
        if t - self._t_solve >= self.dt - EPS_T:
            self._t_solve = t
            plan = self.solve(t, q, v)
            d.solver_status = plan.status
            d.iterations = plan.iterations
            d.extra = {"solve_time": plan.solve_time}
            if plan.success:
                self._plan = plan
                self._using_fallback = False
            else:
                # Keep the previous plan if it still covers t and the state is near it.
                self._using_fallback = True
                if not self._follower.usable(self._plan, t, q):
                    self._plan = None
                    self._tracker.forget()
        if self._using_fallback:
            d.fallback_used = True
            if self._plan is not None and self._follower.usable(self._plan, t, q):
                d.extra["fallback"] = 1.0  # previous plan
                return self._follower.torque(self._plan, t, q, v)
            d.extra["fallback"] = 2.0  # computed torque
            return self._follower.reference_torque(self._reference, t, q, v)  # type: ignore[arg-type]
        return self._follower.torque(self._plan, t, q, v)  # type: ignore[arg-type]

    # -- the minimum-effort Riemannian OCP -------------------------------------------
    def solve_open_loop(
        self,
        q0: Vector,
        q_goal: Vector,
        v0: Vector | None = None,
        *,
        free_initial_velocity: bool = True,
        gravity: bool = False,
    ) -> OpenLoopSolution:
        """The minimum-effort OCP from ``q0`` to ``q_goal`` in time ``T = N dt``.

        Minimises the metric effort (see `geosyn.controllers.mpc.nlp.open_loop`): for the
        kinetic-energy metric without gravity and with inactive limits, the minimiser is
        the geodesic from ``q0`` to ``q_goal``. The NLP is built on the first call for
        each ``(free_initial_velocity, gravity)`` pair and kept.

        Args:
            q0: (nv,) start configuration [rad].
            q_goal: (nv,) end configuration [rad].
            v0: (nv,) initial velocity [rad/s]: the fixed value, or the initial guess when
                free (default: ``(q_goal - q0) / T``).
            free_initial_velocity: make ``v(0)`` a decision variable.
            gravity: include the robot's gravity in the dynamics and the effort.

        Returns:
            The `OpenLoopSolution`.

        Raises:
            InvalidArgument: bad shapes or values.
            SolverFailed: the solver raised an exception.
        """
        q0 = check_vector(q0, self.nv, "q0")
        q_goal = check_vector(q_goal, self.nv, "q_goal")
        v_init = (
            (q_goal - q0) / (self.N * self.dt) if v0 is None else check_vector(v0, self.nv, "v0")
        )
        return self._open_loop.solve(q0, q_goal, v_init, free_initial_velocity, gravity)
