"""The tracking OCP solved as one NLP by fatrop or IPOPT (``GeodesicMPC(solver="fatrop"
| "ipopt")``): warm starts and plans.

Each solve warm-starts from the previous plan shifted by the elapsed stages (its
multipliers too, which IPOPT uses and fatrop ignores), else cold-starts from the
reference samples. The counterpart for ``solver="ddp"`` is
`geosyn.controllers.mpc.ddp_tracking.DDPTracking`; both turn a solve into an `MPCPlan`.
"""

from __future__ import annotations

import math

import numpy as np

from geosyn.controllers.mpc.ocp import OCPBuilder
from geosyn.controllers.mpc.plan import MPCPlan, ReferenceSamples
from geosyn.controllers.mpc.problem import ShootingNLP, SolveResult, pack_parameters

__all__ = ["NLPTracking", "tracking_parameters"]


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
    """

    def __init__(self, nlp: ShootingNLP, builder: OCPBuilder) -> None:
        self.nlp = nlp
        self.builder = builder
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
        try:
            res = nlp.run(solver, tracking_parameters(self.builder, x_init, ref), guess)
        except RuntimeError as err:
            nan_u, nan_x = np.full((N, n), np.nan), np.full((N + 1, 2 * n), np.nan)
            status = f"exception: {err}".splitlines()[0][:200]
            res = SolveResult(nan_x, nan_u, nan_u.copy(), math.nan, status, 0, False, None)
        if res.success:
            self._lam = res.multipliers
        return MPCPlan(t, res.x, res.u, res.tau, res.status, res.iterations, res.success, math.nan)
