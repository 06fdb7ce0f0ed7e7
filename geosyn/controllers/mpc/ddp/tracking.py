"""The tracking OCP solved by box-DDP (``GeodesicMPC(solver="ddp")``): options, warm
starts and plans.

``solver="ddp"`` needs ``control="torque"`` and ``effort="torque"`` or ``"metric"`` (the
robot's own kinetic-energy metric). What it solves is
the OCP of `GeodesicMPC` with two differences, both stated in its docstring: the position
and velocity limits are stiff penalties (``limit_weight``, zero inside the limits)
instead of hard bounds, and a warm solve is a fixed number of full DDP steps
(``warm_iterations``) instead of a solve to tolerance. Its ``solver_options`` are
`DDP_OPTIONS`; ``tol`` and ``max_iter`` apply to cold solves; ``mu_init``/``mu_warm``
(barrier parameters) do not apply.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np
import pinocchio as pin

from geosyn.controllers.mpc.costs import is_robot_kinetic_metric
from geosyn.controllers.mpc.ddp import ddp_parts
from geosyn.controllers.mpc.ddp_clearance import (
    clearance_function,
    clearance_values,
    obstacle_terms,
)
from geosyn.controllers.mpc.ddp_costs import parameter_vector
from geosyn.controllers.mpc.plan import MPCPlan, ReferenceSamples
from geosyn.controllers.mpc.riccati import RiccatiSolver
from geosyn.controllers.mpc.settings import OCPSettings, SolverSettings
from geosyn.core.calls import numpy_function
from geosyn.core.errors import InvalidArgument
from geosyn.core.validation import check_int, check_positive
from geosyn.metrics.base import Metric
from geosyn.metrics.shaping import ObstacleTerm
from geosyn.robots.robot import Robot

__all__ = ["DDP_OPTIONS", "DDPTracking", "check_ddp_settings", "ddp_options"]

DDP_OPTIONS: dict[str, Any] = {
    "warm_iterations": 1,
    "limit_weight": 1e6,
    "regularisation": 1e-9,
    "clearance_weight": 1e6,
}
"""``solver_options`` of ``solver="ddp"`` and their defaults: DDP iterations per warm
solve (1: a real-time iteration), the weight of the soft position and velocity limits
([1/rad^2] and [s^2/rad^2]), and the value added to the diagonal of each stage's control
Hessian [1/(N m)^2], and the weight of the clearance penalty [1/m^2]
(``clearance_margin``; `geosyn.controllers.mpc.ddp_clearance`: 1e6 keeps a 3 cm margin to
within 2 mm on the panda test scene; 1e8 made that closed loop unstable)."""


def ddp_options(options: dict[str, Any]) -> dict[str, Any]:
    """`DDP_OPTIONS` updated by ``options`` (validated).

    Raises:
        InvalidArgument: an unknown key or a bad value (named).
    """
    unknown = sorted(set(options) - set(DDP_OPTIONS))
    if unknown:
        raise InvalidArgument(
            f"solver_options {unknown} are not options of solver 'ddp'; "
            f"allowed: {sorted(DDP_OPTIONS)}"
        )
    merged = {**DDP_OPTIONS, **options}
    return {
        "warm_iterations": check_int(
            merged["warm_iterations"], "solver_options['warm_iterations']", low=1
        ),
        "limit_weight": check_positive(merged["limit_weight"], "solver_options['limit_weight']"),
        "regularisation": float(
            check_positive(merged["regularisation"], "solver_options['regularisation']")
        ),
        "clearance_weight": check_positive(
            merged["clearance_weight"], "solver_options['clearance_weight']"
        ),
    }


def check_ddp_settings(settings: OCPSettings, hessian: str, metric: Metric, robot: Robot) -> None:
    """Refuse what ``solver="ddp"`` cannot solve (the message names the argument).

    Raises:
        InvalidArgument: control other than ``"torque"``, effort other than
            ``"torque"`` or ``"metric"`` (the latter only with the robot's own
            kinetic-energy metric), or ``hessian="exact"``.
    """
    if settings.control != "torque" or settings.effort not in ("torque", "metric"):
        raise InvalidArgument(
            "solver='ddp' solves the torque-level OCP with the torque or metric effort: it "
            f"needs control='torque' and effort='torque' or 'metric', got "
            f"control={settings.control!r}, effort={settings.effort!r}; use solver 'fatrop' "
            "or 'ipopt' otherwise"
        )
    if settings.clearance_margin is not None:
        obstacle_terms(metric)  # raises when the metric has no obstacle terms
    if settings.effort == "metric" and not is_robot_kinetic_metric(metric, robot):
        raise InvalidArgument(
            "effort='metric' with solver='ddp' needs the robot's own KineticEnergyMetric, "
            f"got {type(metric).__name__}; use solver 'fatrop' or 'ipopt' for other metrics"
        )
    if hessian != "gauss-newton":
        raise InvalidArgument(
            f"hessian={hessian!r} is not available with solver='ddp' (its Riccati "
            "recursion uses the Gauss-Newton Hessian); use 'gauss-newton'"
        )


class DDPTracking:
    """Builds the DDP solver of a robot and settings and turns its solves into plans.

    Args:
        robot: the robot.
        settings: the OCP settings (torque control and effort).
        solver: the solver settings (``name == "ddp"``; options as `ddp_options`).
        kp: (n,) stiffness [1/s^2] and kd: (n,) damping [1/s] of the feedback
            ``M(q_r) (kp (q_r - q) + kd (v_r - v))`` that rolls out a cold solve's first
            guess around the reference.
        metric: the metric whose obstacle terms give the clearance cost (used with
            ``settings.clearance_margin``).
        compiled: compile the stage functions (False: CasADi's virtual machine).
        progress: receives progress lines of a first build.

    Raises:
        InvalidArgument: bad ``solver_options``.
        CodegenError: compiling failed (only when ``compiled``).
    """

    def __init__(
        self,
        robot: Robot,
        settings: OCPSettings,
        solver: SolverSettings,
        kp: np.ndarray,
        kd: np.ndarray,
        metric: Metric | None = None,
        *,
        compiled: bool = True,
        progress: Callable[[str], None] | None = None,
    ) -> None:
        self.options = ddp_options(solver.options)
        s, n = settings, robot.nv
        self.N, self.n, self.dt = s.N, n, s.dt
        P = parameter_vector(
            s.q_weight, s.v_weight, s.effort_weight, s.terminal_weight, robot.q_min,
            robot.q_max, robot.v_max, robot.tau_max, self.options["limit_weight"],
            self.options["regularisation"],
        )  # fmt: skip
        self._terms: tuple[ObstacleTerm, ...] = ()
        clearance = None
        if s.clearance_margin is not None and metric is not None:
            self._terms = obstacle_terms(metric)
            clearance = clearance_function(self._terms)
            weight = self.options["clearance_weight"]
            extra = [[s.clearance_margin, weight], clearance_values(self._terms)]
            P = np.concatenate([P, *extra])
        n_obstacle = int(sum(t.parameter_values().size for t in self._terms))
        self._obstacles = slice(P.size - n_obstacle, P.size)
        parts = ddp_parts(
            robot, s.dt, s.rk4_steps, s.effort, clearance, s.tracking,
            compiled=compiled, progress=progress,
        )  # fmt: skip
        self.solver = RiccatiSolver(
            parts, s.N, n, P, tol=solver.tol, max_iter=solver.max_iter,
            warm_iterations=self.options["warm_iterations"],
        )  # fmt: skip
        self._model, self._data = robot.model, robot.model.createData()
        self._pd = np.hstack([np.diag(kp), np.diag(kd)])  # (n, 2n)
        self._step = numpy_function(parts.forward)
        self._zero_K = np.zeros((n, 2 * n))

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
        if self._terms:  # the obstacles as they are now (they may move)
            self.solver.P[self._obstacles] = clearance_values(self._terms)
        x_r = np.hstack([ref.q, ref.v])
        j = -1 if previous is None else int(round((t - previous.t) / self.dt))
        if previous is not None and previous.K is not None and 0 <= j < N:
            x_bar, u_bar = self._shifted(previous, j, x_r, ref.tau)
            res = self.solver.solve(x_init, x_bar, u_bar, x_r, ref.tau, warm=True)
        else:
            K = np.array([-pin.crba(self._model, self._data, q) @ self._pd for q in ref.q[:N]])
            res = self.solver.solve(x_init, x_r, ref.tau, x_r, ref.tau, warm=False, K_guess=K)
        ok = res.success and bool(np.all(np.isfinite(res.x)) and np.all(np.isfinite(res.u)))
        return MPCPlan(
            t, res.x, res.u, res.u.copy(), res.status, res.iterations, ok, math.nan, res.K
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
            step = self._step(
                x[k], x[k], u[k], u[k], self._zero_K, 0.0, x_r[k], tau_r[k], self.solver.P
            )
            x[k + 1] = step[1]
        return x, u
