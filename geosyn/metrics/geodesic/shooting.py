"""Shooting for the log map: the map v0 -> q(1), its Jacobian, and damped Newton on it.

The Jacobian dq(1)/dv0 comes from forward differences of the compiled shooting map, all
n + 1 trajectories in one batched call, and is refreshed by Broyden updates between fresh
evaluations. An exact variational Jacobian by automatic differentiation would compile
about an order of magnitude more C code, for no gain in speed.
"""

from __future__ import annotations

import math
import time

import casadi as ca
import numpy as np

from geosyn.metrics.base import Metric
from geosyn.metrics.geodesic.exp_map import numpy_rk4, rk4_map, rk4_step, step_input

__all__ = ["Budget", "Shooter", "newton", "residual_norm"]

# Forward-difference step of the shooting Jacobian, relative to max(1, |v0|_inf):
# ~sqrt(machine epsilon), so the Jacobian is exact to ~1e-8 relative.
_FD_STEP = 1e-7


def _shoot_functions(metric: Metric, steps: int) -> tuple[ca.Function, ca.Function]:
    """Shooting map ``(x0, theta) -> q(T)`` and its (n+1)-column batch, for ``steps``."""
    n = metric.n

    def build_one() -> ca.Function:
        acc = rk4_map(metric, steps)
        x0 = ca.MX.sym("x0", 2 * n)
        theta = ca.MX.sym("theta", acc.size1_in(1))
        states = acc(x0, ca.repmat(theta, 1, steps))
        return ca.Function("geodesic_shoot", [x0, theta], [states[:n, steps - 1]])

    one = metric.functions.get(("geodesic_shoot", steps), build_one)
    batch = metric.functions.get(("geodesic_shoot_batch", steps), lambda: one.map(n + 1))
    return one, batch


class Shooter:
    """Shooting map v0 -> q(1) from a fixed q0 and its forward-difference Jacobian.

    Args:
        metric: the metric.
        q0: (n,) start joint positions [rad].
        steps: RK4 steps over the unit duration.
    """

    def __init__(self, metric: Metric, q0: np.ndarray, steps: int) -> None:
        self.metric = metric
        self.n = metric.n
        self.q0 = q0
        self.steps = steps
        self.dt = 1.0 / steps
        self.theta = step_input(metric, self.dt)
        self.symbolic = rk4_step(metric) is not None
        if self.symbolic:
            self._one, self._batch = _shoot_functions(metric, steps)

    def set_parameters(self, values: np.ndarray) -> None:
        """Shoot with these metric parameter values (p,) instead of the metric's own."""
        self.theta = np.concatenate([[self.dt], values])

    def end(self, v0: np.ndarray) -> np.ndarray:
        """(n,) q(1) [rad] for initial velocity v0 (NaN if the integration blew up)."""
        if self.symbolic:
            return np.asarray(self._one(np.concatenate([self.q0, v0]), self.theta)).ravel()
        return numpy_rk4(self.metric, self.q0, v0, self.dt, self.steps)[-1, : self.n]

    def end_fine(self, v0: np.ndarray) -> np.ndarray:
        """(n,) q(1) [rad] with twice the steps (the discretisation check of a solution)."""
        if not self.symbolic:
            return numpy_rk4(self.metric, self.q0, v0, 0.5 * self.dt, 2 * self.steps)[-1, : self.n]
        one, _ = _shoot_functions(self.metric, 2 * self.steps)
        theta = self.theta.copy()
        theta[0] = 0.5 * self.dt
        return np.asarray(one(np.concatenate([self.q0, v0]), theta)).ravel()

    def end_and_jacobian(self, v0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """q(1) (n,) [rad] and d q(1) / d v0 (n, n) [s] by forward differences."""
        n = self.n
        h = _FD_STEP * max(1.0, float(np.max(np.abs(v0))))
        V = np.repeat(v0[:, None], n + 1, axis=1)
        V[np.arange(n), np.arange(1, n + 1)] += h
        if self.symbolic:
            X0 = np.vstack([np.repeat(self.q0[:, None], n + 1, axis=1), V])
            Q = np.asarray(self._batch(X0, np.tile(self.theta[:, None], (1, n + 1))))
        else:
            Q = np.column_stack([self.end(V[:, j]) for j in range(n + 1)])
        return Q[:, 0], (Q[:, 1:] - Q[:, :1]) / h


class Budget:
    """Newton iterations left and used by one strategy of the log map, and a deadline.

    Args:
        max_iter: iterations allowed.
        deadline: `time.monotonic()` after which no iteration is left [s] (default: none).
    """

    def __init__(self, max_iter: int, deadline: float = math.inf) -> None:
        self._left = max_iter
        self.used = 0
        self.deadline = deadline

    @property
    def left(self) -> int:
        """Iterations left: 0 once the deadline has passed."""
        return self._left if time.monotonic() < self.deadline else 0

    @left.setter
    def left(self, value: int) -> None:
        self._left = value

    @property
    def expired(self) -> bool:
        """True once the deadline has passed."""
        return time.monotonic() >= self.deadline


def residual_norm(r: np.ndarray) -> float:
    """Euclidean norm of a residual [rad]; inf if it is not finite."""
    return float(np.linalg.norm(r)) if np.all(np.isfinite(r)) else math.inf


def newton(
    shooter: Shooter, target: np.ndarray, v: np.ndarray, tol: float, budget: Budget
) -> tuple[np.ndarray, float, bool, np.ndarray | None]:
    """Damped Newton-Broyden on q(1; v) = target.

    A fresh (finite-difference) Jacobian is followed by cheap Broyden updates while they
    halve the residual at each step; otherwise the Jacobian is recomputed, and a step
    with a fresh Jacobian that does not decrease the residual is backtracked.

    Args:
        shooter: the shooting map.
        target: (n,) goal joint positions [rad].
        v: (n,) initial guess of v0 [rad/s].
        tol: residual tolerance [rad].
        budget: iterations (Jacobian evaluations) left; updated.

    Returns:
        (v, residual, converged, last Jacobian).
    """
    r = shooter.end(v) - target
    nr = residual_norm(r)
    J: np.ndarray | None = None
    fresh = False
    while nr > tol:
        if budget.left <= 0 or not math.isfinite(nr):
            return v, nr, False, J
        if J is None:
            _, J = shooter.end_and_jacobian(v)
            fresh = True
        budget.left -= 1
        budget.used += 1
        try:
            dv = np.linalg.solve(J, -r)
        except np.linalg.LinAlgError:
            dv = np.linalg.lstsq(J, -r, rcond=None)[0]
        r_try = shooter.end(v + dv) - target
        nr_try = residual_norm(r_try)
        if nr_try <= 0.5 * nr:
            # Good Broyden update: the secant condition J dv = r_try - r.
            J = J + np.outer(r_try - r - J @ dv, dv) / float(dv @ dv)
            v, r, nr, fresh = v + dv, r_try, nr_try, False
            continue
        if not fresh:
            J = None  # the secant model is off: recompute at the current v
            continue
        alpha = 1.0
        while nr_try >= (1.0 - 1e-4 * alpha) * nr:
            alpha *= 0.5
            if alpha < 1e-4:
                return v, nr, False, J  # line search stalled: a local minimum of |r|
            r_try = shooter.end(v + alpha * dv) - target
            nr_try = residual_norm(r_try)
        v, r, nr, J = v + alpha * dv, r_try, nr_try, None
    return v, nr, True, J
