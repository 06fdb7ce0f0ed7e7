"""The tracking OCP solved as one NLP by fatrop or IPOPT (``GeodesicMPC(solver="fatrop"
| "ipopt")`` or ``solver=NLPOptions(...)``): the family's backend
(`geosyn.controllers.mpc.backend.TrackingBackend`), with its warm starts and plans.

Each solve warm-starts from the previous plan shifted by the elapsed stages (its
multipliers too, which IPOPT uses and fatrop ignores), else cold-starts from the
reference samples. With the robot file's dry joint friction, the controls are the
torques net of its feed-forward and the torque limits move with it
(`geosyn.controllers.mpc.nlp.problem.ShootingNLP.net_bounds`). `nlp_backend` builds it:
with ``hessian="gauss-newton"`` on the compiled, curvature-free stage dynamics
(`geosyn.controllers.mpc.ocp.compiled`), or, without a C compiler, on an SX graph with
exact Hessians (recorded in ``notes``).
"""

from __future__ import annotations

import math

import numpy as np

from geosyn.controllers.mpc.backend import TrackingProblem
from geosyn.controllers.mpc.nlp.builder import OCPBuilder
from geosyn.controllers.mpc.nlp.options import NLPOptions
from geosyn.controllers.mpc.nlp.problem import ShootingNLP, SolveResult, pack_parameters
from geosyn.controllers.mpc.ocp.compiled import cached_stage_dynamics
from geosyn.controllers.mpc.ocp.dynamics import joint_friction, stage_friction
from geosyn.controllers.mpc.ocp.plan import MPCPlan, ReferenceSamples
from geosyn.core.codegen import CodegenError
from geosyn.core.errors import InvalidArgument

__all__ = ["NLPTracking", "nlp_backend", "tracking_parameters"]


def tracking_parameters(
    builder: OCPBuilder, x_init: np.ndarray, ref: ReferenceSamples
) -> np.ndarray:
    """The tracking NLP's parameter vector (`pack_parameters`) for a solve from ``x_init``.

    Args:
        builder: the OCP builder (settings and metric parameters).
        x_init: (2 nv,) measured state [rad, rad/s].
        ref: the reference samples at ``t + k dt``.
    """
    s = builder.settings
    effort_ref = ref.a[: s.N] if s.effort == "acceleration" else ref.tau
    return pack_parameters(
        x_init, ref.q[s.N], ref.q, ref.v, effort_ref, builder.metric_parameters()
    )


class NLPTracking:
    """Solves the tracking NLP from measured states and keeps its warm start.

    Args:
        nlp: the built tracking NLP with its solvers.
        builder: the OCP builder (settings and metric parameters).
        hessian: the Hessian the NLP uses.
        notes: settings not honoured at build time (see `TrackingBackend`).
    """

    def __init__(
        self,
        nlp: ShootingNLP,
        builder: OCPBuilder,
        hessian: str = "gauss-newton",
        notes: dict[str, str] | None = None,
    ) -> None:
        self.nlp = nlp
        self.builder = builder
        self.hessian = hessian
        self.notes = dict(notes or {})
        self._lam: tuple[np.ndarray, np.ndarray] | None = None

    def forget(self) -> None:
        """Drop the multipliers: the next solve is cold."""
        self._lam = None

    def solve(
        self, t: float, x_init: np.ndarray, ref: ReferenceSamples, previous: MPCPlan | None
    ) -> MPCPlan:
        """One solve at ``t`` (``solve_time`` NaN: the caller times it).

        Args:
            t: time [s].
            x_init: (2 nv,) measured state [rad, rad/s].
            ref: the reference samples at ``t + k dt``.
            previous: the last successful plan (or None): warm start when it covers ``t``
                and its multipliers are kept.

        Returns:
            The `MPCPlan` (``success`` False on a failed solve or a solver exception).
        """
        nlp, s = self.nlp, self.builder.settings
        N, n = s.N, x_init.size // 2
        lam = self._lam
        j = -1 if previous is None or lam is None else int(round((t - previous.t) / s.dt))
        if previous is not None and lam is not None and 0 <= j < N:
            solver, guess = nlp.solver, nlp.shifted_guess(previous.x, previous.u, lam, j, x_init)
        else:
            x0 = np.hstack([ref.q, ref.v])
            x0[0] = x_init
            u0 = ref.tau if s.control == "torque" else ref.a[:N]
            solver, guess = nlp.cold(), {"x0": nlp.pack(x0, u0)}
        friction = stage_friction(self.builder.robot, ref.v, N)
        bounds = None if friction is None else nlp.net_bounds(friction)
        try:
            res = nlp.run(solver, tracking_parameters(self.builder, x_init, ref), guess, bounds)
        except RuntimeError as err:
            nan_u, nan_x = np.full((N, n), np.nan), np.full((N + 1, 2 * n), np.nan)
            status = f"exception: {err}".splitlines()[0][:200]
            res = SolveResult(nan_x, nan_u, nan_u.copy(), math.nan, status, 0, False, None)
        if res.success:
            self._lam = res.multipliers
        tau = res.tau if friction is None else res.tau + friction
        return MPCPlan(
            t, res.x, res.u, tau, res.status, res.iterations, res.success, math.nan, None,
            friction,
        )  # fmt: skip


def nlp_backend(problem: TrackingProblem, options: NLPOptions) -> NLPTracking:
    """The fatrop or IPOPT backend of ``problem`` (allocates; seconds, up to a minute on
    a first build that compiles the stage dynamics).

    Raises:
        InvalidArgument: ``clearance_margin`` (a stiff penalty of the DDP family only).
    """
    s = problem.settings
    if s.clearance_margin is not None:
        raise InvalidArgument(
            f"clearance_margin needs solver='ddp' (a stiff clearance penalty), got "
            f"solver={options.solver!r}"
        )
    joint_friction(problem.robot)  # refuses a dry friction at or over a torque limit
    builder = OCPBuilder(problem.robot, problem.metric, s, options, problem.max_solve_time)
    if problem.hessian == "gauss-newton":
        try:
            dynamics = cached_stage_dynamics(
                problem.robot, s.dt, s.control, s.rk4_steps, True, progress=problem.progress
            )
            return NLPTracking(builder.tracking(dynamics, gauss_newton=True), builder)
        except CodegenError as err:
            note = f"'exact' instead of 'gauss-newton': no compiled dynamics ({err})"
            nlp = builder.tracking(builder.dynamics(gravity=True), gauss_newton=False)
            return NLPTracking(nlp, builder, "exact", {"hessian": note})
    nlp = builder.tracking(builder.dynamics(gravity=True), gauss_newton=False)
    return NLPTracking(nlp, builder, "exact")
