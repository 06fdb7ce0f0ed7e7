"""The minimum-effort Riemannian OCP between two configurations, solved open loop.

.. math::
    \\min \\sum_k (\\tau_k - g(q_k))^T G(q_k)^{-1} (\\tau_k - g(q_k))
    \\quad \\text{s.t.}\\ q(0) = q_0,\\ q(T) = q_1,\\ \\text{dynamics and limits}

For the kinetic-energy metric without gravity and with inactive limits its minimiser is
the geodesic from ``q_0`` to ``q_1`` traversed in time ``T = N dt`` (zero torque, zero
cost), up to the RK4 discretisation.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from geosyn.controllers.errors import SolverFailed
from geosyn.controllers.mpc.nlp.builder import OCPBuilder
from geosyn.controllers.mpc.nlp.problem import ShootingNLP, pack_parameters

__all__ = ["OpenLoopOCP", "OpenLoopSolution"]


class OpenLoopSolution(NamedTuple):
    """Result of `GeodesicMPC.solve_open_loop`.

    Attributes:
        t: (N+1,) stage times from 0 [s].
        q: (N+1, nv) joint positions [rad].
        v: (N+1, nv) joint velocities [rad/s].
        tau: (N, nv) torques [N m].
        cost: optimal cost (sum over stages of the metric effort).
        status: solver status string.
        iterations: solver iterations.
        success: the solver reported success.
    """

    t: np.ndarray
    q: np.ndarray
    v: np.ndarray
    tau: np.ndarray
    cost: float
    status: str
    iterations: int
    success: bool


class OpenLoopOCP:
    """The open-loop minimum-effort OCP of a builder's robot, metric and horizon.

    The NLP (exact Hessian, SX graph) is built on the first `solve` for each
    ``(free_v0, gravity)`` pair and kept.

    Args:
        builder: the OCP builder (robot, metric, horizon, solver settings).
    """

    def __init__(self, builder: OCPBuilder) -> None:
        self.builder = builder
        self._nlps: dict[tuple[bool, bool], ShootingNLP] = {}

    def solve(
        self, q0: np.ndarray, q_goal: np.ndarray, v_init: np.ndarray, free_v0: bool, gravity: bool
    ) -> OpenLoopSolution:
        """Solve from ``q0`` to ``q_goal`` in time ``T = N dt``, cold-started on the line.

        Args:
            q0: (nv,) start configuration [rad], validated.
            q_goal: (nv,) end configuration [rad], validated.
            v_init: (nv,) initial velocity [rad/s]: fixed, or the guess when ``free_v0``.
            free_v0: make ``v(0)`` a decision variable.
            gravity: include the robot's gravity in the dynamics and the effort.

        Raises:
            SolverFailed: the solver raised an exception.
        """
        b = self.builder
        n, N, h = b.robot.nv, b.settings.N, b.settings.dt
        key = (bool(free_v0), bool(gravity))
        if key not in self._nlps:
            self._nlps[key] = b.open_loop(free_v0=key[0], gravity=key[1])
        nlp = self._nlps[key]
        s = np.linspace(0.0, 1.0, N + 1)[:, None]
        x0 = np.hstack([q0 + s * (q_goal - q0), np.tile(v_init, (N + 1, 1))])
        zero = np.zeros((N + 1, n))
        p = pack_parameters(
            np.concatenate([q0, v_init]), q_goal, zero, zero, zero[:N], b.metric_parameters()
        )
        try:
            res = nlp.run(nlp.cold(), p, {"x0": nlp.pack(x0, np.zeros((N, n)))})
        except RuntimeError as err:
            raise SolverFailed(f"open-loop OCP solve raised: {err}", status="exception") from err
        return OpenLoopSolution(
            t=np.arange(N + 1) * h,
            q=res.x[:, :n].copy(),
            v=res.x[:, n:].copy(),
            tau=res.tau,
            cost=res.cost,
            status=res.status,
            iterations=res.iterations,
            success=res.success,
        )
