"""The tracking OCP solved by box-DDP (``GeodesicMPC(solver="ddp")`` or
``solver=DDPOptions(...)``): the family's backend
(`geosyn.controllers.mpc.backend.TrackingBackend`), with its warm starts and plans.

``solver="ddp"`` needs ``control="torque"`` and ``effort="torque"`` or ``"metric"`` (the
robot's own kinetic-energy metric). What it solves is the OCP of `GeodesicMPC` with two
differences, both stated in its docstring: the position and velocity limits are stiff
penalties (``DDPOptions.limit_weight``, zero inside the limits) instead of hard bounds,
and a warm solve is a fixed number of full DDP steps (``DDPOptions.warm_iterations``)
instead of a solve to tolerance. With ``clearance_margin`` and obstacle slots it adds the
clearance penalty (`geosyn.controllers.mpc.ocp.penalties.ClearancePenalty`).
"""

from __future__ import annotations

import math
import re
from typing import NamedTuple

import casadi as ca
import numpy as np
import pinocchio as pin

from geosyn.controllers.mpc.backend import TrackingProblem
from geosyn.controllers.mpc.ddp.native import native_backward
from geosyn.controllers.mpc.ddp.options import DDPOptions
from geosyn.controllers.mpc.ddp.parameters import DDPCosts, parameter_vector
from geosyn.controllers.mpc.ddp.parts import DDPParts, ForwardInputs, ddp_parts
from geosyn.controllers.mpc.ddp.riccati import RiccatiSolver, backward_graph, forward_graph
from geosyn.controllers.mpc.ocp.costs import is_robot_kinetic_metric
from geosyn.controllers.mpc.ocp.dynamics import dry_friction, joint_friction
from geosyn.controllers.mpc.ocp.plan import MPCPlan, ReferenceSamples
from geosyn.core.calls import numpy_function
from geosyn.core.codegen import CodegenError
from geosyn.core.errors import InvalidArgument

__all__ = ["DDPGraphs", "DDPTracking", "check_ddp_problem", "ddp_backend"]


class DDPGraphs(NamedTuple):
    """The solver of a `DDPTracking` as uncompiled CasADi graphs (for code generation,
    e.g. `geosyn.export`): the same functions the compiled solver evaluates.

    Attributes:
        parts: the stage functions (`DDPParts`: ``lin``, ``riccati``, ``forward``,
            ``terminal``) on CasADi's virtual machine.
        backward: ``(X (2n, N+1), U (n, N), XR (2n, N+1), TR (n, N), P) -> (k (n, N),
            K (n, 2n N), dV (2,))``, one backward pass over the horizon (CasADi's graph;
            with ``DDPOptions(backward="native")`` the solver runs the hand-written C of
            `geosyn.controllers.mpc.ddp.native` instead, equal up to rounding).
        rollout: ``(x0, X_bar, U_bar, k, K, alpha, XR, TR, P) -> (X, U, cost)``, one
            closed-loop rollout.
        P: (n_p,) a copy of the parameter vector the solver uses
            (`geosyn.controllers.mpc.ddp.parameters.parameter_vector`, then the
            clearance's values with obstacles).
        N: stages; n: joints; dt: stage length [s].
    """

    parts: DDPParts
    backward: ca.Function
    rollout: ca.Function
    P: np.ndarray
    N: int
    n: int
    dt: float


def check_ddp_problem(problem: TrackingProblem) -> None:
    """Refuse what ``solver="ddp"`` cannot solve (the message names the argument).

    Raises:
        InvalidArgument: control other than ``"torque"``, effort other than
            ``"torque"`` or ``"metric"`` (the latter only with the robot's own
            kinetic-energy metric), ``hessian="exact"``, or ``clearance_margin``
            without obstacles.
    """
    settings = problem.settings
    if settings.control != "torque" or settings.effort not in ("torque", "metric"):
        raise InvalidArgument(
            "solver='ddp' solves the torque-level OCP with the torque or metric effort: it "
            f"needs control='torque' and effort='torque' or 'metric', got "
            f"control={settings.control!r}, effort={settings.effort!r}; use solver 'fatrop' "
            "or 'ipopt' otherwise"
        )
    if settings.clearance_margin is not None and problem.obstacles is None:
        raise InvalidArgument(
            "clearance_margin needs obstacles: GeodesicMPC(obstacles=[geosyn.world shapes])"
        )
    if settings.effort == "metric" and not is_robot_kinetic_metric(problem.metric, problem.robot):
        raise InvalidArgument(
            "effort='metric' with solver='ddp' needs the robot's own KineticEnergyMetric, "
            f"got {type(problem.metric).__name__}; use solver 'fatrop' or 'ipopt' for other "
            "metrics"
        )
    if problem.hessian != "gauss-newton":
        raise InvalidArgument(
            f"hessian={problem.hessian!r} is not available with solver='ddp' (its Riccati "
            "recursion uses the Gauss-Newton Hessian); use 'gauss-newton'"
        )


def ddp_backend(problem: TrackingProblem, options: DDPOptions) -> DDPTracking:
    """The box-DDP backend of ``problem``: compiled stage functions, or, without a C
    compiler, the same functions on CasADi's virtual machine (recorded in ``notes``).

    Raises:
        InvalidArgument: what `check_ddp_problem` refuses.
    """
    check_ddp_problem(problem)
    try:
        return DDPTracking(problem, options)
    except CodegenError as err:
        tracking = DDPTracking(problem, options, compiled=False)
        tracking.notes["compiled"] = f"DDP stage functions on CasADi's VM: not compiled ({err})"
        return tracking


class DDPTracking:
    """Builds the DDP solver of a tracking problem and turns its solves into plans.

    Args:
        problem: the tracking problem (torque control; see `check_ddp_problem`). Its
            ``kp`` (n,) [1/s^2] and ``kd`` (n,) [1/s] give the feedback
            ``M(q_r) (kp (q_r - q) + kd (v_r - v))`` that rolls out a cold solve's first
            guess around the reference; its obstacle slots are read at every solve.
        options: the `DDPOptions`.
        compiled: compile the stage functions (False: CasADi's virtual machine).

    Raises:
        CodegenError: compiling failed (only when ``compiled``).
    """

    hessian = "gauss-newton"

    def __init__(
        self, problem: TrackingProblem, options: DDPOptions, *, compiled: bool = True
    ) -> None:
        self.options = options
        self.notes: dict[str, str] = {}
        s, robot = problem.settings, problem.robot
        n = robot.nv
        self.N, self.n, self.dt = s.N, n, s.dt
        self._friction = joint_friction(robot)  # the stage torque f_c tanh(v_r / v_s)
        P = parameter_vector(
            s.q_weight, s.v_weight, s.effort_weight, s.terminal_weight, robot.q_min,
            robot.q_max, robot.v_max, robot.tau_max, options.limit_weight,
            options.regularisation, self._friction,
        )  # fmt: skip
        self._slots = problem.obstacles if s.clearance_margin is not None else None
        clearance = None
        if self._slots is not None:
            clearance = self._slots.clearance_function()
            extra = [[s.clearance_margin, options.clearance_weight], self._slots.values()]
            P = np.concatenate([P, *extra])
        n_obstacle = 0 if self._slots is None else self._slots.values().size
        self._obstacles = slice(P.size - n_obstacle, P.size)
        costs = DDPCosts(robot, problem.metric, s.effort, s.tracking, clearance)
        native = compiled and options.backward == "native"
        parts = ddp_parts(
            robot, s.dt, s.rk4_steps, costs, compiled=compiled, progress=problem.progress,
            with_backward=not native,
        )  # fmt: skip
        self._costs, self._rk4_steps, self._robot = costs, s.rk4_steps, robot
        backward = None
        if options.backward == "native":
            backward = self._native(problem, compiled, P.size)
        self.solver = RiccatiSolver(
            parts, s.N, n, P, tol=options.tol, max_iter=options.max_iter,
            warm_iterations=options.warm_iterations, backward=backward,
        )  # fmt: skip
        self._model, self._data = robot.model, robot.model.createData()
        self._pd = np.hstack([np.diag(problem.kp), np.diag(problem.kd)])  # (n, 2n)
        self._step = numpy_function(parts.forward)
        self._zero_K = np.zeros((n, 2 * n))

    def _native(self, problem: TrackingProblem, compiled: bool, n_p: int) -> ca.Function | None:
        """The native backward pass (`geosyn.controllers.mpc.ddp.native`), or None (the
        CasADi graph's) when the stage functions are not compiled, recorded in
        ``notes``."""
        if not compiled:
            self.notes["backward"] = (
                "DDP backward pass: CasADi's graph on its VM (the native C pass needs a C compiler)"
            )
            return None
        s, robot = problem.settings, problem.robot
        name = re.sub(r"\W", "_", f"geosyn_ddp_native_{robot.name}_{s.effort}_{s.tracking}")
        return native_backward(
            robot, s.dt, s.rk4_steps, s.N, self._costs, n_p, name=name, progress=problem.progress
        )

    @property
    def parameters(self) -> np.ndarray:
        """(n_p,) a copy of the parameter vector ``P`` of the solver (see `DDPGraphs`)."""
        return self.solver.P.copy()

    def graphs(self) -> DDPGraphs:
        """The solver's functions as uncompiled CasADi graphs (`DDPGraphs`; builds
        graphs, about a second for 7 joints; allocates)."""
        parts = ddp_parts(self._robot, self.dt, self._rk4_steps, self._costs, compiled=False)
        N, n = self.N, self.n
        return DDPGraphs(
            parts, backward_graph(parts, N, n), forward_graph(parts, N, n), self.parameters,
            N, n, self.dt,
        )  # fmt: skip

    def forget(self) -> None:
        """Nothing to drop: a DDP warm start is the previous plan itself (with its
        gains), which the controller passes to `solve` or not."""

    def solve(
        self, t: float, x_init: np.ndarray, ref: ReferenceSamples, previous: MPCPlan | None
    ) -> MPCPlan:
        """Solve from ``x_init`` at ``t``: warm from ``previous`` shifted when it covers
        ``t``, else cold from the reference's inverse-dynamics torques.

        Args:
            t: time [s].
            x_init: (2n,) measured state [rad, rad/s].
            ref: the reference samples at ``t + k dt``.
            previous: the last successful plan (or None).

        Returns:
            The `MPCPlan`, with the feedback gains ``K`` (N, n, 2n).
        """
        N = self.N
        if self._slots is not None:  # the obstacles as they are now (they may move)
            self.solver.P[self._obstacles] = self._slots.values()
        x_r = np.hstack([ref.q, ref.v])
        j = -1 if previous is None else int(round((t - previous.t) / self.dt))
        if previous is not None and previous.K is not None and 0 <= j < N:
            x_bar, u_bar = self._shifted(previous, j, x_r, ref.tau)
            res = self.solver.solve(x_init, x_bar, u_bar, x_r, ref.tau, warm=True)
        else:
            K = np.array([-pin.crba(self._model, self._data, q) @ self._pd for q in ref.q[:N]])
            res = self.solver.solve(x_init, x_r, ref.tau, x_r, ref.tau, warm=False, K_guess=K)
        ok = res.success and bool(np.all(np.isfinite(res.x)) and np.all(np.isfinite(res.u)))
        friction = None if self._friction is None else dry_friction(self._friction, ref.v[:N])
        tau = res.u.copy() if friction is None else res.u + friction
        return MPCPlan(
            t, res.x, res.u, tau, res.status, res.iterations, ok, math.nan, res.K, friction
        )

    def _shifted(
        self, plan: MPCPlan, j: int, x_r: np.ndarray, tau_r: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """The plan shifted by ``j`` stages; the tail holds the last torque and is
        integrated (so the guess is a rollout)."""
        N = self.N
        x = np.empty_like(plan.x)
        u = np.empty_like(plan.u)
        x[: N + 1 - j] = plan.x[j:]
        u[: N - j] = plan.u[j:]
        for k in range(N - j, N):
            u[k] = plan.u[-1]
            inputs = ForwardInputs(
                x=x[k], xb=x[k], ub=u[k], k=u[k], K=self._zero_K, alpha=0.0, xr=x_r[k],
                tr=tau_r[k], P=self.solver.P,
            )  # fmt: skip
            x[k + 1] = self._step(*inputs)[1]
        return x, u
