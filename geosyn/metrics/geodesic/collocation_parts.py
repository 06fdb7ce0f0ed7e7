"""Parts of `geosyn.metrics.geodesic.collocation`: the result type, the per-node CasADi
functions of the collocation NLP, the IPOPT deadline callback, and path resampling."""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any, NamedTuple

import casadi as ca
import numpy as np

from geosyn.core.errors import InvalidArgument
from geosyn.metrics.base import Metric

if TYPE_CHECKING:
    from geosyn.metrics.shaping.obstacle import ObstacleTerm

__all__ = [
    "ACTIVE_TOL",
    "KINDS",
    "WARM_START",
    "CollocationResult",
    "refine_by_shooting",
    "resample_path",
]

ACTIVE_TOL = 1e-6
"""A clearance within this of the margin [m], or a joint within it of a limit [rad], is
counted as an active constraint."""

KINDS = ("geodesic", "discrete geodesic", "constrained", "feasible", "failed")
"""What a `CollocationResult` is (see `CollocationResult.kind`)."""


class CollocationResult(NamedTuple):
    """A path from `Collocation.solve`, with what it is.

    Attributes:
        t: (T,) path parameter [s] on [0, 1] (unit duration).
        q: (T, n) path [rad]: the shooting geodesic sampled at ``steps + 1`` points for
            kind ``"geodesic"``, else the collocation nodes (piecewise linear between).
        kind: ``"geodesic"``: satisfies the geodesic equation of the metric, found by
            shooting (`log_solve`) from the collocated path, end point residual
            ``geodesic_residual``; ``"discrete geodesic"``: no constraint active, a
            stationary point of the discrete energy (second-order accurate in ``1/N``)
            that shooting could not refine (``message`` says why); ``"constrained"``:
            minimum-energy path with ``active`` clearance or joint-limit constraints
            active, not a geodesic; ``"feasible"``: a collision-free path that is not
            (yet) of minimum energy, which a planner returns when its budget ends before
            an optimum is reached (`geosyn.metrics.planning.Plan`); ``"failed"``: IPOPT
            did not converge (``status``).
        energy: ``integral qdot^T G qdot dt`` of the nodes, midpoint rule [kg m^2 / s^2
            for the kinetic-energy metric]; ``sqrt(energy)`` bounds the length from above.
        nodes: (N + 1, n) the collocation nodes [rad].
        v0: (n,) initial velocity [rad/s] (shooting's for a geodesic, else the
            second-order one-sided difference of the nodes).
        min_clearance: smallest node clearance [m] (inf without obstacles).
        active: number of active clearance and joint-limit constraints.
        geodesic_residual: shooting's end point residual [rad] (NaN unless a geodesic).
        kkt_residual: IPOPT's final dual infeasibility (scaled).
        iterations: IPOPT iterations.
        status: IPOPT's return status.
        wall_time: wall-clock time of the solve [s].
        message: one line on what was done.
        multipliers: IPOPT's final multipliers ``(lam_x (nx,), lam_g (ng,))`` of the
            bounds and constraints, for a warm start (`Collocation.solve`'s ``warm``).
    """

    t: np.ndarray
    q: np.ndarray
    kind: str
    energy: float
    nodes: np.ndarray
    v0: np.ndarray
    min_clearance: float
    active: int
    geodesic_residual: float
    kkt_residual: float
    iterations: int
    status: str
    wall_time: float
    message: str
    multipliers: tuple[np.ndarray, np.ndarray] | None = None

    @property
    def success(self) -> bool:
        """True unless ``kind == "failed"``."""
        return self.kind != "failed"


class Deadline(ca.Callback):
    """IPOPT iteration callback that stops the solve once a wall-clock deadline passes."""

    def __init__(self, nx: int, ng: int) -> None:
        ca.Callback.__init__(self)
        self.nx, self.ng = nx, ng
        self.deadline = math.inf
        self.construct("collocation_deadline", {})

    def reset(self, budget: float) -> None:
        self.deadline = time.perf_counter() + budget

    def get_n_in(self) -> int:
        return int(ca.nlpsol_n_out())

    def get_n_out(self) -> int:
        return 1

    def get_name_in(self, i: int) -> str:
        return str(ca.nlpsol_out(i))

    def get_name_out(self, i: int) -> str:
        return "ret"

    def get_sparsity_in(self, i: int) -> ca.Sparsity:
        name = ca.nlpsol_out(i)
        size = {"x": self.nx, "lam_x": self.nx, "g": self.ng, "lam_g": self.ng}.get(name, 1)
        return ca.Sparsity.dense(size, 1) if name != "lam_p" else ca.Sparsity.dense(0, 1)

    def eval(self, arg: Sequence[ca.DM]) -> list[ca.DM]:
        return [ca.DM(1.0 if time.perf_counter() > self.deadline else 0.0)]


def node_functions(
    metric: Metric, clearance: ObstacleTerm | None, constraint_hessian: bool, softmin: float | None
) -> tuple[ca.Function, ...]:
    """Per-node SX functions: segment energy (+ derivatives), clearances (+ derivatives)."""
    n = metric.n
    qa, qb = ca.SX.sym("qa", n), ca.SX.sym("qb", n)
    pm = metric.symbolic_parameters()
    qm = ca.SX.sym("qm", n)  # symbolic_G may differentiate in q: build it on a symbol
    G = ca.Function("G", [qm, pm], [metric.symbolic_G(qm)])(0.5 * (qa + qb), pm)
    dq = qb - qa
    e = ca.dot(dq, ca.mtimes(G, dq))
    hess, grad = ca.hessian(e, ca.vertcat(qa, qb))
    opts = {"cse": True}
    seg = ca.Function("colloc_segment", [qa, qb, pm], [e], opts)
    seg_d = ca.Function("colloc_segment_d", [qa, qb, pm], [e, grad, ca.densify(hess)], opts)
    q = ca.SX.sym("q", n)
    if clearance is None:
        c, pc = ca.SX.ones(1) * 1.0, ca.SX(0, 1)
    else:
        c = clearance.symbolic_clearances(q, softmin)
        pc = clearance.symbolic_parameters()
    clr = ca.Function("colloc_clearance", [q, pc], [c], opts)
    jc = ca.densify(ca.jacobian(c, q))
    clr_j = ca.Function("colloc_clearance_j", [q, pc], [c, jc], opts)
    if not constraint_hessian:
        return seg, seg_d, clr, clr_j
    if clearance is not None and softmin is not None:
        from geosyn.metrics.geodesic.collocation_clearance import clearance_hessian

        return seg, seg_d, clr, clr_j, clearance_hessian(clearance, softmin)
    lam = ca.SX.sym("lam", c.numel())
    hc = ca.hessian(ca.dot(lam, c), q)[0]
    clr_d = ca.Function("colloc_clearance_d", [q, pc, lam], [ca.densify(hc)], opts)
    return seg, seg_d, clr, clr_j, clr_d


def resample_path(path: np.ndarray, segments: int, n: int) -> np.ndarray:
    """(segments + 1, n) points evenly spaced by joint-space arc length along ``path``.

    Args:
        path: (T, n) piecewise-linear path [rad], T >= 2.
        segments: number of segments of the result, >= 1.
        n: dimension.

    Raises:
        InvalidArgument: ``path`` has the wrong shape or is not finite.
    """
    path = np.asarray(path, dtype=np.float64)
    if path.ndim != 2 or path.shape[1] != n or path.shape[0] < 2:
        raise InvalidArgument(f"init must have shape (T, {n}) with T >= 2, got {path.shape}")
    if not np.all(np.isfinite(path)):
        raise InvalidArgument("init must be finite")
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(path, axis=0), axis=1))])
    if s[-1] == 0.0:
        return np.repeat(path[:1], segments + 1, axis=0)
    u = np.linspace(0.0, s[-1], segments + 1)
    return np.column_stack([np.interp(u, s, path[:, i]) for i in range(n)])


def interpolate_path(path: np.ndarray, times: np.ndarray, segments: int, n: int) -> np.ndarray:
    """(segments + 1, n) points of ``path`` at ``segments + 1`` evenly spaced times on [0, 1].

    Args:
        path: (T, n) path [rad], T >= 2, linear between its samples.
        times: (T,) increasing path parameter of the samples, spanning [0, 1].
        segments: number of segments of the result, >= 1.
        n: dimension.

    Raises:
        InvalidArgument: ``path`` or ``times`` has the wrong shape, or ``times`` does not
            increase.
    """
    path = np.asarray(path, dtype=np.float64)
    if path.ndim != 2 or path.shape[1] != n or path.shape[0] < 2 or not np.isfinite(path).all():
        raise InvalidArgument(f"init must be finite with shape (T, {n}), T >= 2, got {path.shape}")
    times = np.asarray(times, dtype=np.float64)
    if times.shape != (len(path),) or not np.all(np.diff(times) > 0):
        raise InvalidArgument(
            f"init_t must be increasing with shape ({len(path)},) (one time per init sample)"
        )
    u = np.linspace(0.0, 1.0, segments + 1)
    return np.column_stack([np.interp(u, times, path[:, i]) for i in range(n)])


WARM_START = {
    "warm_start_init_point": "yes",
    "mu_init": 1e-3,
    "warm_start_bound_push": 1e-9,
    "warm_start_bound_frac": 1e-9,
    "warm_start_slack_bound_push": 1e-9,
    "warm_start_slack_bound_frac": 1e-9,
    "warm_start_mult_bound_push": 1e-9,
}
"""IPOPT options of a warm-started solve (`Collocation.solve` with ``warm``): start from
the given primal and dual point, barely pushed into the interior."""


def refine_by_shooting(
    metric: Metric,
    q0: np.ndarray,
    q1: np.ndarray,
    v0: np.ndarray,
    steps: int,
    bounds: tuple[np.ndarray, np.ndarray],
    clearances: Callable[[np.ndarray], np.ndarray],
) -> tuple[Any, Any, np.ndarray | None, str]:
    """Refine a discrete geodesic by shooting: `log_solve` from its initial velocity
    ``v0`` (n,) [rad/s], then `exp` with ``steps`` RK4 steps.

    Args:
        metric: the metric; q0, q1: (n,) ends [rad].
        v0: (n,) initial velocity of the discrete geodesic [rad/s].
        steps: RK4 steps.
        bounds: (n,) lower and upper joint bounds [rad] the geodesic must keep.
        clearances: ``(T, n) -> clearances`` of a path (negative: collision).

    Returns:
        ``(log result, geodesic, its clearances, "")`` when the geodesic stays free and
        within the bounds, else ``(None, None, None, why not)``.
    """
    from geosyn.metrics.errors import GeodesicNotFound
    from geosyn.metrics.geodesic.exp_map import exp
    from geosyn.metrics.geodesic.log_map import log_solve

    lo, hi = bounds
    try:
        res = log_solve(metric, q0, q1, v_init=v0, steps=steps, max_iter=20, continuation=False)
    except GeodesicNotFound as err:
        return None, None, None, f"shooting did not converge from it ({err.residual:.1e} rad)"
    geo = exp(metric, q0, res.v0, 1.0, steps)
    clear = clearances(geo.q)
    if clear.min() >= 0.0 and np.all(geo.q >= lo - ACTIVE_TOL) and np.all(geo.q <= hi + ACTIVE_TOL):
        return res, geo, clear, ""
    return (
        None,
        None,
        None,
        (
            f"the shooting geodesic leaves the free space (clearance {clear.min():.3g} m) or "
            "the joint limits"
        ),
    )
