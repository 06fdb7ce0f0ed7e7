"""The MPC's optimal-control problems as NLPs, assembled from the shared description.

Read top to bottom like a Crocoddyl example: the state ``x = (q, v)`` and the stage
dynamics (`geosyn.controllers.mpc.ocp.dynamics`) -> the cost terms with their weights
(`geosyn.controllers.mpc.ocp.costs`) -> the stage model and the shooting problem
(`geosyn.controllers.mpc.nlp.problem`) -> the solvers (`geosyn.controllers.mpc.nlp.solvers`).
`OCPBuilder` does this for the tracking OCP (the fatrop/IPOPT backend,
`geosyn.controllers.mpc.nlp.tracking`) and for the minimum-effort open-loop OCP
(`geosyn.controllers.mpc.nlp.open_loop`).
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from geosyn.controllers.mpc.nlp.options import NLPOptions
from geosyn.controllers.mpc.nlp.problem import ShootingNLP, ShootingProblem, transcribe
from geosyn.controllers.mpc.nlp.solvers import build_solvers
from geosyn.controllers.mpc.ocp.costs import (
    EFFORT_TERMS,
    StateTracking,
    TerminalStateTracking,
    stage_cost,
    terminal_cost,
)
from geosyn.controllers.mpc.ocp.dynamics import StageDynamics, stage_dynamics
from geosyn.controllers.mpc.ocp.settings import OCPSettings
from geosyn.metrics.base import Metric
from geosyn.robots.robot import Robot

__all__ = ["OCPBuilder"]


class OCPBuilder:
    """Builds the shooting problems and NLPs of one robot, metric and horizon.

    Args:
        robot: the robot (dynamics and limits).
        metric: the metric (the ``"metric"`` effort).
        settings: horizon, control mode, effort and weights.
        solver: solver plugin and options.
        max_solve_time: wall-time budget of one solve [s] (IPOPT stops at it).

    Every method allocates (CasADi graphs, solvers: seconds); build once, solve often.
    """

    def __init__(
        self,
        robot: Robot,
        metric: Metric,
        settings: OCPSettings,
        solver: NLPOptions,
        max_solve_time: float = 1.0,
    ) -> None:
        self.robot = robot
        self.metric = metric
        self.settings = settings
        self.solver = solver
        self.max_solve_time = max_solve_time
        self.n_p = int(np.asarray(metric.parameter_values()).size)

    def metric_parameters(self) -> np.ndarray:
        """(n_p,) current values of a parameterised metric's parameters (read per solve)."""
        if self.n_p == 0:
            return np.zeros(0)
        return np.asarray(self.metric.parameter_values(), dtype=np.float64).ravel()

    def dynamics(self, gravity: bool) -> StageDynamics:
        """The SX stage dynamics (see `geosyn.controllers.mpc.ocp.dynamics.stage_dynamics`)."""
        s = self.settings
        return stage_dynamics(self.robot, s.dt, s.control, s.rk4_steps, gravity)

    def problem(
        self,
        dynamics: StageDynamics,
        *,
        effort: str,
        gravity: bool,
        open_loop: bool = False,
        free_v0: bool = False,
    ) -> ShootingProblem:
        """The shooting problem with the tracking costs, or the open-loop effort alone.

        Args:
            dynamics: the stage dynamics (SX or compiled).
            effort: name of the effort term (a key of
                `geosyn.controllers.mpc.ocp.costs.EFFORT_TERMS`).
            gravity: include gravity in the effort (the dynamics carry their own).
            open_loop: no tracking costs; the last position is the goal parameter.
            free_v0: with ``open_loop``, leave the initial velocity free.
        """
        s, robot, n = self.settings, self.robot, self.robot.nv
        terms = [EFFORT_TERMS[effort](s.effort_weight, robot, self.metric, gravity)]
        terminal = None
        if not open_loop:
            model = robot.model if s.tracking == "metric" else None
            terms.insert(0, StateTracking(s.q_weight, s.v_weight, model))
            terminal = TerminalStateTracking(s.terminal_weight, model)
        return ShootingProblem(
            N=s.N,
            nv=n,
            n_p=self.n_p,
            dynamics=dynamics,
            L=stage_cost(terms, n, self.n_p),
            Lf=terminal_cost(terminal, n),
            control=s.control,
            tau_max=np.asarray(robot.tau_max, dtype=np.float64),
            q_min=np.asarray(robot.q_min, dtype=np.float64),
            q_max=np.asarray(robot.q_max, dtype=np.float64),
            v_max=np.asarray(robot.v_max, dtype=np.float64),
            open_loop=open_loop,
            free_v0=free_v0,
        )

    def tracking(self, dynamics: StageDynamics, gauss_newton: bool) -> ShootingNLP:
        """The tracking NLP and its warm and cold solvers.

        Args:
            dynamics: the stage dynamics with gravity; compiled ones for Gauss-Newton.
            gauss_newton: an MX graph with one mapped call per (compiled) stage
                function; else an SX graph with exact Hessians.
        """
        problem = self.problem(dynamics, effort=self.settings.effort, gravity=True)
        if gauss_newton:
            graph = transcribe(problem, ca.MX, mapped=True)
        else:
            graph = transcribe(problem, ca.SX, mapped=False)
        solvers = build_solvers(graph, self.solver, self.max_solve_time)
        return ShootingNLP.from_problem(problem, graph, *solvers)

    def open_loop(self, *, free_v0: bool, gravity: bool) -> ShootingNLP:
        """The minimum-metric-effort NLP between two configurations (exact Hessian)."""
        dynamics = self.dynamics(gravity)
        problem = self.problem(
            dynamics, effort="metric", gravity=gravity, open_loop=True, free_v0=free_v0
        )
        graph = transcribe(problem, ca.SX, mapped=False)
        solvers = build_solvers(graph, self.solver, self.max_solve_time)
        return ShootingNLP.from_problem(problem, graph, *solvers)
