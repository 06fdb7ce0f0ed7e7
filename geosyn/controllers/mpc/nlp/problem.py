"""The multiple-shooting problem: stages -> NLP graph -> a solvable, indexed NLP.

`ShootingProblem` holds one stage model (dynamics and costs) repeated over N stages,
with the bounds and end conditions; `transcribe` writes it as an NLP graph, stage by
stage as fatrop's structure detection expects; `ShootingNLP` is the built NLP with its
solvers and the index bookkeeping of its decision and constraint vectors (packing,
shifted warm starts, one solve).

Decision vector: ``x_0, u_0, x_1, u_1, ..., x_{N-1}, u_{N-1}, x_N``. Constraints per stage
k: the gap ``x_{k+1} - F(x_k, u_k)``, then (k = 0) the initial condition, then the path
constraints (acceleration control: the RNEA torque within the limits), then (k = N-1,
open-loop problems) the terminal position. Parameters:
``(x_init, q_goal, vec(q_ref), vec(v_ref), vec(effort_ref), metric_p)``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, NamedTuple, TypeVar

import casadi as ca
import numpy as np

from geosyn.controllers.mpc.nlp.bounded import BoundedSolver
from geosyn.controllers.mpc.ocp.dynamics import StageDynamics
from geosyn.core.types import Vector

__all__ = [
    "NLPGraph",
    "ShootingNLP",
    "ShootingProblem",
    "SolveResult",
    "pack_parameters",
    "transcribe",
]

# The symbol type of an NLP graph: SX (exact Hessian) or MX (calls to compiled stages).
_Sym = TypeVar("_Sym", ca.SX, ca.MX)


@dataclass(frozen=True, eq=False)
class ShootingProblem:
    """N stages of one stage model, with bounds and end conditions.

    Attributes:
        N: number of stages.
        nv: number of joints (the state has 2 nv entries, the control nv).
        n_p: number of metric parameters (the last NLP parameters).
        dynamics: the stage dynamics ``F`` and torque map ``TAU``.
        L: stage cost ``(x, u, tau, q_ref, v_ref, effort_ref, metric_p) -> scalar``.
        Lf: terminal cost ``(x, q_ref, v_ref) -> scalar``.
        control: ``"torque"`` (bounds on u are the torque limits) or ``"acceleration"``
            (the torque ``TAU`` is a path constraint).
        tau_max: (nv,) torque limits [N m].
        q_min: (nv,) lower position limits [rad] (may be -inf).
        q_max: (nv,) upper position limits [rad] (may be +inf).
        v_max: (nv,) velocity limits [rad/s].
        open_loop: constrain the last position to the parameter ``q_goal``.
        free_v0: fix only the initial position (the initial velocity is free).
    """

    N: int
    nv: int
    n_p: int
    dynamics: StageDynamics
    L: ca.Function
    Lf: ca.Function
    control: str
    tau_max: Vector
    q_min: Vector
    q_max: Vector
    v_max: Vector
    open_loop: bool = False
    free_v0: bool = False

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Lower and upper bounds of the decision vector.

        ``x_0`` is fixed by the initial constraint and has no bounds (so a measured state
        slightly outside the limits stays feasible); later states have the position and
        velocity limits; the torque limits bound ``u`` in torque control.
        """
        n, inf = self.nv, np.inf
        q_lo = np.where(np.isfinite(self.q_min), self.q_min, -inf)
        q_hi = np.where(np.isfinite(self.q_max), self.q_max, inf)
        torque = self.control == "torque"
        u_lo = -self.tau_max if torque else np.full(n, -inf)
        u_hi = self.tau_max if torque else np.full(n, inf)
        free = np.full(2 * n, inf)
        x_lo, x_hi = np.concatenate([q_lo, -self.v_max]), np.concatenate([q_hi, self.v_max])
        lbx = [-free, u_lo] + [x_lo, u_lo] * (self.N - 1) + [x_lo]
        ubx = [free, u_hi] + [x_hi, u_hi] * (self.N - 1) + [x_hi]
        return np.concatenate(lbx), np.concatenate(ubx)


class NLPGraph(NamedTuple):
    """An NLP graph and the description of its constraint rows.

    Attributes:
        nlp: ``{"x", "f", "g", "p"}`` for ``casadi.nlpsol``.
        equality: per constraint row, whether it is an equality (fatrop's hint).
        lbg: per row lower bound.
        ubg: per row upper bound.
        g_blocks: per stage, the indices of its rows in ``g`` (stage 0 holds the
            initial-condition rows).
        torque_rows: (N, nv) the rows of the torque path constraint (acceleration
            control), else None.
    """

    nlp: dict[str, Any]
    equality: list[bool]
    lbg: np.ndarray
    ubg: np.ndarray
    g_blocks: list[np.ndarray]
    torque_rows: np.ndarray | None = None


def transcribe(problem: ShootingProblem, symbol: type[_Sym], mapped: bool) -> NLPGraph:
    """Write the problem as an NLP graph in symbols of type ``symbol`` (allocates).

    Args:
        problem: the shooting problem.
        symbol: ``casadi.SX`` (functions inlined; exact Hessians) or ``casadi.MX``.
        mapped: one mapped call per stage function (MX only), so that CasADi evaluates
            each Jacobian once per stage with little graph overhead (SX call nodes
            would be differentiated one direction at a time); else one call per stage.

    Returns:
        The `NLPGraph`.
    """
    S = symbol
    n, N, nx = problem.nv, problem.N, 2 * problem.nv
    F, TAU, L = problem.dynamics.F, problem.dynamics.TAU, problem.L
    X = [S.sym(f"x{k}", nx) for k in range(N + 1)]
    U = [S.sym(f"u{k}", n) for k in range(N)]
    x_init, q_goal = S.sym("x_init", nx), S.sym("q_goal", n)
    qr, vr, tr = S.sym("qr", n, N + 1), S.sym("vr", n, N + 1), S.sym("tr", n, N)
    mp = S.sym("mp", problem.n_p)
    w: list[_Sym] = []
    for k in range(N):
        w += [X[k], U[k]]
    w.append(X[N])
    if mapped:
        Xc, Uc = ca.horzcat(*X[:N]), ca.horzcat(*U)
        x_pred, tau_all = F.map(N)(Xc, Uc), TAU.map(N)(Xc, Uc)
        x_next = [x_pred[:, k] for k in range(N)]
        taus = [tau_all[:, k] for k in range(N)]
        J = ca.sum2(L.map(N)(Xc, Uc, tau_all, qr[:, :N], vr[:, :N], tr, ca.repmat(mp, 1, N)))
    else:
        x_next = [F(X[k], U[k]) for k in range(N)]
        taus = [TAU(X[k], U[k]) for k in range(N)]
        J = S(0)  # what CasADi makes of a Python 0 in `0 + L(...)`
        for k in range(N):
            J = J + L(X[k], U[k], taus[k], qr[:, k], vr[:, k], tr[:, k], mp)
    J = J + problem.Lf(X[N], qr[:, N], vr[:, N])

    g: list[_Sym] = []
    equality: list[bool] = []
    lbg: list[np.ndarray] = []
    ubg: list[np.ndarray] = []

    def add(row: _Sym, lo: np.ndarray, hi: np.ndarray, eq: bool) -> None:
        g.append(row)
        equality.extend([eq] * lo.size)
        lbg.append(lo)
        ubg.append(hi)

    g_blocks: list[np.ndarray] = []
    torque_rows: list[np.ndarray] = []
    ng = 0
    for k in range(N):
        start = ng
        add(X[k + 1] - x_next[k], np.zeros(nx), np.zeros(nx), True)
        if k == 0:
            init = X[0][:n] - x_init[:n] if problem.free_v0 else X[0] - x_init
            m0 = n if problem.free_v0 else nx
            add(init, np.zeros(m0), np.zeros(m0), True)
        if problem.control == "acceleration":
            torque_rows.append(np.arange(len(equality), len(equality) + n))
            add(taus[k], -problem.tau_max, problem.tau_max, False)
        if problem.open_loop and k == N - 1:
            add(X[N][:n] - q_goal, np.zeros(n), np.zeros(n), True)
        ng = len(equality)
        g_blocks.append(np.arange(start, ng))
    p = ca.vertcat(x_init, q_goal, ca.vec(qr), ca.vec(vr), ca.vec(tr), mp)
    nlp = {"x": ca.vertcat(*w), "f": J, "g": ca.vertcat(*g), "p": p}
    rows = np.array(torque_rows) if torque_rows else None
    return NLPGraph(nlp, equality, np.concatenate(lbg), np.concatenate(ubg), g_blocks, rows)


def pack_parameters(
    x_init: np.ndarray,
    q_goal: np.ndarray,
    q_ref: np.ndarray,
    v_ref: np.ndarray,
    effort_ref: np.ndarray,
    metric_p: np.ndarray,
) -> np.ndarray:
    """The NLP parameter vector.

    Args:
        x_init: (2 nv,) initial state [rad, rad/s].
        q_goal: (nv,) goal position of open-loop problems [rad].
        q_ref: (N+1, nv) reference positions [rad].
        v_ref: (N+1, nv) reference velocities [rad/s].
        effort_ref: (N, nv) effort reference (torques [N m] or accelerations [rad/s^2]).
        metric_p: (n_p,) metric parameters.
    """
    return np.concatenate(
        [x_init, q_goal, q_ref.ravel(), v_ref.ravel(), effort_ref.ravel(), metric_p]
    )


class SolveResult(NamedTuple):
    """One solver call on a `ShootingNLP`.

    Attributes:
        x: (N+1, 2 nv) states [rad, rad/s].
        u: (N, nv) controls.
        tau: (N, nv) torques [N m].
        cost: optimal cost.
        status: solver status string.
        iterations: solver iterations.
        success: the solver reported success and the result is finite.
        multipliers: ``(lam_x, lam_g)`` on success, else None.
    """

    x: np.ndarray
    u: np.ndarray
    tau: np.ndarray
    cost: float
    status: str
    iterations: int
    success: bool
    multipliers: tuple[np.ndarray, np.ndarray] | None


@dataclass
class ShootingNLP:
    """A built NLP: its solvers and the bookkeeping of its vectors.

    Attributes:
        solver: the (warm-start) solver.
        solver_cold: the cold-start solver, or None if there is only one.
        N: number of stages.
        n: number of joints.
        lbx: decision-vector lower bounds.
        ubx: decision-vector upper bounds.
        lbg: constraint lower bounds.
        ubg: constraint upper bounds.
        g_blocks: per stage, indices into g (stage 0 includes the init block).
        tau_fn: ``(x (2 nv, N), u (nv, N)) -> tau (nv, N)``, planned torques [N m].
        torque_rows: (N, n) rows of ``g`` bounding the torque (acceleration control),
            or None (torque control: the controls are the torques).
    """

    solver: BoundedSolver
    solver_cold: BoundedSolver | None
    N: int
    n: int
    lbx: np.ndarray
    ubx: np.ndarray
    lbg: np.ndarray
    ubg: np.ndarray
    g_blocks: list[np.ndarray]
    tau_fn: ca.Function
    torque_rows: np.ndarray | None = None

    @classmethod
    def from_problem(
        cls,
        problem: ShootingProblem,
        graph: NLPGraph,
        solver: BoundedSolver,
        solver_cold: BoundedSolver | None,
    ) -> ShootingNLP:
        """Bundle the solvers of ``graph`` with the bounds and indices of ``problem``."""
        lbx, ubx = problem.bounds()
        tau_fn = problem.dynamics.TAU.map(problem.N)
        return cls(
            solver=solver,
            solver_cold=solver_cold,
            N=problem.N,
            n=problem.nv,
            lbx=lbx,
            ubx=ubx,
            lbg=graph.lbg,
            ubg=graph.ubg,
            g_blocks=graph.g_blocks,
            tau_fn=tau_fn,
            torque_rows=graph.torque_rows,
        )

    def cold(self) -> BoundedSolver:
        """The cold-start solver (the only solver when there is no separate one)."""
        return self.solver if self.solver_cold is None else self.solver_cold

    def pack(self, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        """(N+1, 2n) states and (N, n) controls -> decision vector."""
        N = self.N
        return np.concatenate([np.hstack([x[:N], u]).ravel(), x[N]])

    def unpack(self, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Decision vector -> (N+1, 2n) states and (N, n) controls."""
        N, n = self.N, self.n
        body = w[: N * 3 * n].reshape(N, 3 * n)
        x = np.vstack([body[:, : 2 * n], w[N * 3 * n :][None, :]])
        return x, body[:, 2 * n :].copy()

    def shifted_guess(
        self,
        x: np.ndarray,
        u: np.ndarray,
        multipliers: tuple[np.ndarray, np.ndarray],
        j: int,
        x_init: np.ndarray,
    ) -> dict[str, np.ndarray]:
        """A warm start: a previous solution shifted by ``j`` stages.

        The last stage is repeated; the first state is replaced by the measured one.
        Constraint multipliers move with their stage; stage 0 keeps its own (it holds the
        initial-condition rows).

        Args:
            x: (N+1, 2n) previous states.
            u: (N, n) previous controls.
            multipliers: previous ``(lam_x, lam_g)``.
            j: stages elapsed since the previous solve, in [0, N).
            x_init: (2n,) measured state.

        Returns:
            ``{"x0", "lam_x0", "lam_g0"}`` for the solver call.
        """
        N = self.N
        idx_x = np.minimum(np.arange(N + 1) + j, N)
        idx_u = np.minimum(np.arange(N) + j, N - 1)
        x0 = x[idx_x].copy()
        x0[0] = x_init
        lam_x_old, lam_g_old = multipliers
        lx, lu = self.unpack(lam_x_old)
        lam_g = lam_g_old.copy()
        blocks = self.g_blocks
        for k in range(1, N):
            src = blocks[min(k + j, N - 1)]
            if src.size == blocks[k].size:
                lam_g[blocks[k]] = lam_g_old[src]
        return {
            "x0": self.pack(x0, u[idx_u]),
            "lam_x0": self.pack(lx[idx_x], lu[idx_u]),
            "lam_g0": lam_g,
        }

    def net_bounds(self, offset: np.ndarray) -> dict[str, np.ndarray]:
        """The bounds with the torque limits moved onto the torque net of a known stage
        torque (allocates): each stage's torque box shifted by ``-offset`` (the controls'
        bounds in torque control, the torque rows of ``g`` in acceleration control), so
        that the torque plus ``offset`` keeps the limits.

        Args:
            offset: (N, n) known torque of each stage [N m] (the dry-friction
                feed-forward, `geosyn.controllers.mpc.ocp.dynamics.stage_friction`).

        Returns:
            ``{"lbx", "ubx", "lbg", "ubg"}`` for `run`.
        """
        lbx, ubx, lbg, ubg = self.lbx, self.ubx, self.lbg, self.ubg
        if self.torque_rows is None:
            n = self.n
            idx = (np.arange(self.N) * 3 * n + 2 * n)[:, None] + np.arange(n)
            lbx, ubx = lbx.copy(), ubx.copy()
            lbx[idx] -= offset
            ubx[idx] -= offset
        else:
            lbg, ubg = lbg.copy(), ubg.copy()
            lbg[self.torque_rows] -= offset
            ubg[self.torque_rows] -= offset
        return {"lbx": lbx, "ubx": ubx, "lbg": lbg, "ubg": ubg}

    def run(
        self,
        solver: BoundedSolver,
        p: np.ndarray,
        guess: dict[str, np.ndarray],
        bounds: dict[str, np.ndarray] | None = None,
    ) -> SolveResult:
        """One call of ``solver`` (allocates the result arrays).

        Args:
            solver: `solver` or the result of `cold`.
            p: parameter vector (`pack_parameters`).
            guess: ``{"x0"}`` and optionally ``{"lam_x0", "lam_g0"}``.
            bounds: ``{"lbx", "ubx", "lbg", "ubg"}`` (`net_bounds`), or None: the
                problem's own.

        Returns:
            The `SolveResult` (``success`` False on a failed solve).

        Raises:
            RuntimeError: CasADi or the solver plugin raised.
        """
        if bounds is None:
            bounds = {"lbx": self.lbx, "ubx": self.ubx, "lbg": self.lbg, "ubg": self.ubg}
        res = solver(p=p, **bounds, **guess)
        stats = solver.stats()
        status = str(stats.get("return_status", stats.get("unified_return_status", "?")))
        w = np.asarray(res["x"]).ravel()
        x, u = self.unpack(w)
        tau = np.asarray(self.tau_fn(x[: self.N].T, u.T)).T
        success = bool(stats.get("success", False)) and bool(np.all(np.isfinite(w)))
        lam = None
        if success:
            lam = (np.asarray(res["lam_x"]).ravel(), np.asarray(res["lam_g"]).ravel())
        return SolveResult(
            x, u, tau, float(res["f"]), status, int(stats.get("iter_count", 0)), success, lam
        )
