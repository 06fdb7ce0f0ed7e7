"""`RiccatiSolver`: box-constrained DDP (iLQR) iterations of the torque-level tracking OCP.

The OCP is the shared description (`geosyn.controllers.mpc.ocp`) with torque control
(RK4 on the ABA per stage, tracking and effort costs, hard torque limits), with the
position and velocity limits as stiff penalties instead of hard bounds and an optional clearance
penalty (`geosyn.controllers.mpc.ocp.penalties`). One iteration is two calls into compiled
code:

1. backward: the stage Jacobians along the current trajectory, then the Riccati
   recursion from the terminal cost, each stage's control update a box QP (Gauss-Newton
   Hessian, the dynamics' curvature dropped);
2. forward: the closed-loop rollout ``u_k = clip(u_bar_k + alpha k_k + K_k (x_k - x_bar_k))``,
   ``x_{k+1} = F(x_k, u_k)`` from the measured state, with its cost.

A cold solve rolls the guess out first (with a stabilising feedback, ``K_guess``) and
iterates with a backtracking line search on ``alpha`` and Levenberg-Marquardt
regularisation until the largest control update is below ``tol`` (relative to the torque
scale). A warm solve (the previous plan shifted) takes ``warm_iterations`` full steps, a
real-time iteration like Crocoddyl's one-iteration MPC. Each iteration's two graphs are
built once per horizon as CasADi MX functions calling the compiled stage functions, so
Python only enters and leaves twice per iteration.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import casadi as ca
import numpy as np

from geosyn.controllers.mpc.ddp.parameters import split_parameters
from geosyn.controllers.mpc.ddp.parts import DDPParts
from geosyn.core.calls import numpy_function
from geosyn.core.errors import InvalidArgument

__all__ = [
    "LINE_SEARCH_STEPS",
    "MAX_REGULARISATION",
    "ROUNDING",
    "RiccatiResult",
    "RiccatiSolver",
    "backward_graph",
    "forward_graph",
]

LINE_SEARCH_STEPS = (1.0, 0.5, 0.25, 0.125, 0.0625, 0.03125)
"""Step lengths ``alpha`` tried by a cold solve, longest first."""
MAX_REGULARISATION = 1e4
"""Largest control-Hessian regularisation a cold solve's line search raises to before
it gives up [1/(N m)^2]."""
ROUNDING = 1e-9
"""A cold solve whose line search finds no decrease has converged when the predicted
decrease is below this fraction of the cost (rounding, not a failure)."""


class RiccatiResult(NamedTuple):
    """One solve.

    Attributes:
        x: (N+1, 2n) states [rad, rad/s]; u: (N, n) torques [N m].
        K: (N, n, 2n) feedback gains of the last backward pass [N m / rad, N m s / rad].
        cost: cost of the returned trajectory.
        iterations: backward passes done.
        status: ``"converged"``, ``"warm step"``, ``"max_iter"`` or why it failed.
        success: a finite trajectory that a solve accepts.
    """

    x: np.ndarray
    u: np.ndarray
    K: np.ndarray
    cost: float
    iterations: int
    status: str
    success: bool


class RiccatiSolver:
    """Backward and forward passes over ``N`` stages (graphs built once; allocates).

    Args:
        parts: the stage functions (`geosyn.controllers.mpc.ddp.parts.ddp_parts`).
        N: number of stages.
        n: number of joints.
        P: the parameter vector (`geosyn.controllers.mpc.ddp.parameters.parameter_vector`).
        tol: convergence tolerance of cold solves: the largest control update divided
            by ``1 + max |u|`` [-].
        max_iter: iteration limit of cold solves.
        warm_iterations: iterations of a warm solve (full steps, no line search).
        backward: the backward pass (attribute ``backward``), a function with the inputs and outputs of
            `backward_graph` (e.g. the native C pass,
            `geosyn.controllers.mpc.ddp.native.native_backward`); None: `backward_graph`
            on ``parts``.
    """

    def __init__(
        self,
        parts: DDPParts,
        N: int,
        n: int,
        P: np.ndarray,
        *,
        tol: float,
        max_iter: int,
        warm_iterations: int,
        backward: ca.Function | None = None,
    ) -> None:
        self.N, self.n, self.P = N, n, np.asarray(P, dtype=np.float64)
        self.tol, self.max_iter, self.warm_iterations = tol, max_iter, warm_iterations
        # the regularisation's place in P (not the last entry with obstacles)
        self.reg_index = int(split_parameters(np.arange(self.P.size), n).reg[0])
        self.backward = backward_graph(parts, N, n) if backward is None else backward
        self._backward = _matrix_function(self.backward, N, (0,))
        self._forward = _matrix_function(forward_graph(parts, N, n), N, (1,))
        self._zero_k = np.zeros((n, N))
        self._zero_K = np.zeros((n, 2 * n * N))

    def solve(
        self,
        x0: np.ndarray,
        x_bar: np.ndarray,
        u_bar: np.ndarray,
        x_r: np.ndarray,
        tau_r: np.ndarray,
        *,
        warm: bool,
        K_guess: np.ndarray | None = None,
    ) -> RiccatiResult:
        """Iterate from the guess ``(x_bar, u_bar)``.

        Args:
            x0: (2n,) measured state [rad, rad/s].
            x_bar: (N+1, 2n) state guess: a rollout of ``u_bar`` (from any start) for a
                warm solve; for a cold solve the states the rollout's feedback acts on.
            u_bar: (N, n) torque guess [N m].
            x_r: (N+1, 2n) reference states; tau_r: (N, n) reference torques [N m].
            warm: a warm solve (see the class docstring).
            K_guess: (N, n, 2n) feedback of a cold solve's first rollout,
                ``u_k = clip(u_bar_k + K_k (x_k - x_bar_k))`` (None: open loop). A
                stabilising feedback keeps the first guess near ``x_bar`` when the open
                loop would drift far (and the Gauss-Newton model with it).
        """
        XR, TR = x_r.T, tau_r.T  # the graphs' buffers copy them in
        if warm:
            return self._warm_steps(x0, x_bar.T, u_bar.T, XR, TR)
        return self._cold_solve(x0, x_bar.T, u_bar.T, XR, TR, K_guess)

    def _warm_steps(
        self, x0: np.ndarray, Xb: np.ndarray, Ub: np.ndarray, XR: np.ndarray, TR: np.ndarray
    ) -> RiccatiResult:
        """``warm_iterations`` full DDP steps, no line search (the real-time iteration;
        column-major arrays as the graphs take them)."""
        P = self.P
        for it in range(self.warm_iterations):
            k, K, _ = self._backward(Xb, Ub, XR, TR, P)
            X, U, c = self._forward(x0, Xb, Ub, k, K, 1.0, XR, TR, P)
            if not np.isfinite(c[0]):  # the cost sums every state and torque squared
                return self._failed(Xb, Ub, it + 1, "non-finite warm step")
            Xb, Ub = X, U  # the next call copies its inputs in before writing X, U
        return self._result(X, U, K, float(c[0]), self.warm_iterations, "warm step", True)

    def _cold_solve(
        self,
        x0: np.ndarray,
        Xb: np.ndarray,
        Ub: np.ndarray,
        XR: np.ndarray,
        TR: np.ndarray,
        K_guess: np.ndarray | None,
    ) -> RiccatiResult:
        """Roll the guess out (with ``K_guess``), then iterate with a line search and
        Levenberg-Marquardt regularisation until converged (see `solve`)."""
        P = self.P.copy()
        reg = self.reg_index
        base_reg = float(P[reg])
        scale = 1.0 + float(np.max(np.abs(Ub))) if Ub.size else 1.0
        K0 = self._zero_K if K_guess is None else _stack_gains(K_guess)
        X, U, c = self._forward(x0, Xb, Ub, self._zero_k, K0, 0.0, XR, TR, P)
        Xb, Ub, cost = X.copy(), U.copy(), float(c[0])
        K = self._zero_K
        for it in range(self.max_iter):
            k, K, dV = (a.copy() for a in self._backward(Xb, Ub, XR, TR, P))
            if not (np.all(np.isfinite(k)) and np.all(np.isfinite(K))):
                return self._failed(Xb, Ub, it + 1, "non-finite backward pass")
            accepted, alpha, c_new = False, 1.0, np.nan
            for alpha in LINE_SEARCH_STEPS:
                X, U, c = self._forward(x0, Xb, Ub, k, K, alpha, XR, TR, P)
                c_new = float(c[0])
                if np.isfinite(c_new) and c_new <= cost + 1e-4 * alpha * min(float(dV[0]), 0.0):
                    accepted = True
                    break
            if not accepted:
                if not np.isfinite(cost):
                    return self._failed(Xb, Ub, it + 1, "non-finite rollout")
                if -float(dV[0]) <= ROUNDING * max(cost, 1.0):
                    status = "converged (no decrease left above rounding)"
                    return self._result(Xb, Ub, K, cost, it + 1, status, True)
                if P[reg] >= MAX_REGULARISATION:
                    return self._failed(Xb, Ub, it + 1, "line search failed")
                P[reg] = max(100.0 * P[reg], 1e-6)  # Levenberg-Marquardt: shorter steps
                continue
            P[reg] = max(0.1 * P[reg], base_reg)
            step = float(np.max(np.abs(alpha * k))) if k.size else 0.0
            Xb, Ub, cost = X.copy(), U.copy(), c_new
            if step <= self.tol * scale:
                return self._result(Xb, Ub, K, cost, it + 1, "converged", True)
        return self._result(Xb, Ub, K, cost, self.max_iter, "max_iter", False)

    def _result(
        self, X: np.ndarray, U: np.ndarray, K: np.ndarray, cost: float, it: int, status: str,
        success: bool,
    ) -> RiccatiResult:  # fmt: skip
        n, N = self.n, self.N
        gains = K.reshape(n, 2 * n, N, order="F").transpose(2, 0, 1).copy()
        return RiccatiResult(X.T.copy(), U.T.copy(), gains, cost, it, status, success)

    def _failed(self, X: np.ndarray, U: np.ndarray, it: int, status: str) -> RiccatiResult:
        return self._result(X, U, self._zero_K, np.nan, it, status, False)


def _matrix_function(
    fun: ca.Function, N: int, matrices: tuple[int, ...]
) -> Callable[..., tuple[np.ndarray, ...]]:
    """`numpy_function`, keeping the outputs ``matrices`` (n, N) two-dimensional when
    N = 1 (`numpy_function` shows an (n, 1) block as an (n,) vector, and wants (n,)
    arrays for (n, 1) inputs)."""
    call = numpy_function(fun)
    if N > 1:
        return call
    flat_in = [1 in (fun.size1_in(i), fun.size2_in(i)) for i in range(fun.n_in())]

    def matrix_call(*args: np.ndarray) -> tuple[np.ndarray, ...]:
        fitted = [
            np.reshape(a, -1, order="F") if flat and np.ndim(a) == 2 else a
            for a, flat in zip(args, flat_in, strict=True)
        ]
        outs = call(*fitted)
        return tuple(o.reshape(-1, 1) if i in matrices else o for i, o in enumerate(outs))

    return matrix_call


def _stack_gains(K: np.ndarray) -> np.ndarray:
    """(N, n, 2n) gains -> the (n, 2n N) block row of the graphs."""
    return np.ascontiguousarray(np.concatenate(list(K), axis=1))


class _Inputs(NamedTuple):
    X: ca.MX
    U: ca.MX
    XR: ca.MX
    TR: ca.MX
    P: ca.MX


def _inputs(N: int, n: int, n_p: int) -> _Inputs:
    return _Inputs(
        ca.MX.sym("X", 2 * n, N + 1),
        ca.MX.sym("U", n, N),
        ca.MX.sym("XR", 2 * n, N + 1),
        ca.MX.sym("TR", n, N),
        ca.MX.sym("P", n_p),
    )


def backward_graph(parts: DDPParts, N: int, n: int) -> ca.Function:
    """``(X, U, XR, TR, P) -> (k (n, N), K (n, 2n N), dV (2,))`` (MX, N calls per piece)."""
    nx = 2 * n
    if parts.lin is None or parts.riccati is None:
        raise InvalidArgument(
            "parts: built without the backward pass's stage functions (ddp_parts("
            "with_backward=False)); build them with with_backward=True"
        )
    s = _inputs(N, n, parts.riccati.size1_in("P"))
    A_all, B_all = parts.lin.map(N)(s.X[:, :N], s.U)
    end = parts.terminal(x=s.X[:, N], xr=s.XR[:, N], P=s.P)
    Vx, Vxx = end["Vx"], end["Vxx"]
    ks: list[ca.MX] = [ca.MX()] * N
    Ks: list[ca.MX] = [ca.MX()] * N
    dV = ca.MX.zeros(2)
    for k in reversed(range(N)):
        step = parts.riccati(
            Vx=Vx, Vxx=Vxx, A=A_all[:, k * nx : (k + 1) * nx], B=B_all[:, k * n : (k + 1) * n],
            x=s.X[:, k], u=s.U[:, k], xr=s.XR[:, k], tr=s.TR[:, k], P=s.P,
        )  # fmt: skip
        Vx, Vxx, ks[k], Ks[k] = step["Vx_prev"], step["Vxx_prev"], step["k"], step["K"]
        dV = dV + step["dV"]
    return ca.Function(
        "ddp_backward",
        list(s),
        [ca.horzcat(*ks), ca.horzcat(*Ks), dV],
        ["X", "U", "XR", "TR", "P"],
        ["k", "K", "dV"],
    )


def forward_graph(parts: DDPParts, N: int, n: int) -> ca.Function:
    """``(x0, X, U, k, K, alpha, XR, TR, P) -> (X', U', cost)`` (MX, N forward steps)."""
    nx = 2 * n
    s = _inputs(N, n, parts.forward.size1_in("P"))
    x0, k_all, K_all = ca.MX.sym("x0", nx), ca.MX.sym("k", n, N), ca.MX.sym("K", n, nx * N)
    alpha = ca.MX.sym("alpha")
    x, xs, us, cost = x0, [x0], [], ca.MX(0)
    for k in range(N):
        step = parts.forward(
            x=x, xb=s.X[:, k], ub=s.U[:, k], k=k_all[:, k], K=K_all[:, k * nx : (k + 1) * nx],
            alpha=alpha, xr=s.XR[:, k], tr=s.TR[:, k], P=s.P,
        )  # fmt: skip
        x = step["xn"]
        xs.append(x)
        us.append(step["u"])
        cost = cost + step["cost"]
    cost = cost + parts.terminal(x=x, xr=s.XR[:, N], P=s.P)["cost"]
    return ca.Function(
        "ddp_rollout",
        [x0, s.X, s.U, k_all, K_all, alpha, s.XR, s.TR, s.P],
        [ca.horzcat(*xs), ca.horzcat(*us), cost],
        ["x0", "X_bar", "U_bar", "k", "K", "alpha", "XR", "TR", "P"],
        ["X", "U", "cost"],
    )
