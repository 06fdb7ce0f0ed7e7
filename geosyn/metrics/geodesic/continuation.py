"""Continuation strategies of the log map, for pairs where Newton from a guess fails.

- `target_continuation`: homotopy on the goal, ``q1(s) = q0 + s (q1 - q0)``, s: 0 -> 1,
  each stage warm-started by a tangent predictor.
- `parameter_continuation`: homotopy on the metric's parameters, from an easier metric
  (s = 0) to the metric itself (s = 1), secant predictor. The easier parameters come from
  `parameter_homotopy`: the shaping terms of a `ShapedMetric` that offer
  ``parameter_homotopy(s)`` (e.g. `ObstacleTerm`, whose obstacles shrink to points).

Both adapt the stage length and spend Newton iterations from one `Budget`.
"""

from __future__ import annotations

import math
from typing import Protocol, runtime_checkable

import numpy as np

from geosyn.core.errors import InvalidArgument
from geosyn.metrics.base import Metric
from geosyn.metrics.geodesic.shooting import Budget, Shooter, newton, residual_norm
from geosyn.metrics.shaping.base import ShapedMetric

__all__ = [
    "HomotopyTerm",
    "parameter_continuation",
    "parameter_homotopy",
    "target_continuation",
]

_MAX_STAGES = 200  # stages of the target continuation
_MIN_DS = 1.0 / 4096.0  # smallest continuation step
STAGE_TOL = 1e-6
"""Residual tolerance of intermediate continuation stages [rad]."""


@runtime_checkable
class HomotopyTerm(Protocol):
    """A shaping term with easier parameters for the log map's parameter continuation."""

    def parameter_homotopy(self, s: float) -> np.ndarray:
        """(p,) parameters of an easier term at ``s`` in [0, 1]; s = 1 the term itself."""
        ...


def parameter_homotopy(metric: Metric, s: float) -> np.ndarray | None:
    """Parameters of an easier metric at ``s``, for continuation in the log map.

    For a `ShapedMetric`, each parameterised term that is a `HomotopyTerm` gives its
    ``parameter_homotopy(s)`` and the other parameterised terms keep their values,
    stacked like ``metric.parameter_values()``.

    Args:
        metric: the metric.
        s: homotopy parameter in [0, 1]; 0 the easiest problem, 1 the metric itself.

    Returns:
        (p,) parameter values at ``s``, or None when the metric has no homotopy (not a
        shaped metric, or no term offers one).
    """
    if not isinstance(metric, ShapedMetric):
        return None
    terms = metric.parameter_terms
    if not any(isinstance(t, HomotopyTerm) for t in terms):
        return None
    return np.concatenate(
        [
            np.asarray(
                t.parameter_homotopy(s) if isinstance(t, HomotopyTerm) else t.parameter_values()
            )
            for t in terms
        ]
    )


def target_continuation(
    shooter: Shooter, q1: np.ndarray, tol: float, budget: Budget
) -> tuple[np.ndarray, float, bool]:
    """Homotopy on the target q1(s) = q0 + s (q1 - q0), s: 0 -> 1, tangent predictor.

    Args:
        shooter: the shooting map from q0.
        q1: (n,) goal joint positions [rad].
        tol: residual tolerance of the final stage [rad].
        budget: Newton iterations left; updated.

    Returns:
        (v0 (n,) [rad/s], residual with respect to q1 [rad], converged).
    """
    q0 = shooter.q0
    delta = q1 - q0
    s, ds = 0.0, 0.125
    v = np.zeros_like(q0)
    tangent = delta.copy()  # dv/ds at s = 0 (the metric's exp is the identity to 1st order)
    for _ in range(_MAX_STAGES):
        s_new = min(1.0, s + ds)
        guess = v + (s_new - s) * tangent
        # Intermediate stages only need to be close enough to predict the next one.
        stage_tol = tol if s_new >= 1.0 else max(tol, STAGE_TOL)
        v_new, nr_new, ok, J = newton(shooter, q0 + s_new * delta, guess, stage_tol, budget)
        if ok:
            s, v = s_new, v_new
            if s >= 1.0:
                return v, nr_new, True
            if J is not None:
                try:
                    tangent = np.linalg.solve(J, delta)
                except np.linalg.LinAlgError:
                    pass
            ds = min(2.0 * ds, 1.0 - s)
        else:
            if budget.left <= 0:
                break
            ds *= 0.5
            if ds < _MIN_DS:
                break
    # Report the residual with respect to the final target, not the last stage's.
    return v, residual_norm(shooter.end(v) - q1), False


def parameter_continuation(
    shooter: Shooter,
    metric: Metric,
    q1: np.ndarray,
    guess: np.ndarray,
    tol: float,
    budget: Budget,
) -> tuple[np.ndarray, float, bool]:
    """Homotopy on the metric parameters, `parameter_homotopy` (metric, s), s: 0 -> 1.

    Solves the easiest problem (s = 0) from ``guess``, then follows the solution with a
    secant predictor and adaptive stage length; s = 1 uses the metric's own parameters.
    The shooter is left with the metric's own parameters.

    Args:
        shooter: the shooting map from q0.
        metric: the metric (with a homotopy: `parameter_homotopy` is not None).
        q1: (n,) goal joint positions [rad].
        guess: (n,) initial guess of v0 [rad/s] for the easiest problem.
        tol: residual tolerance of the final stage [rad].
        budget: Newton iterations left; updated.

    Returns:
        (v0 (n,) [rad/s], residual [rad] (inf if the easiest problem failed), converged).

    Raises:
        InvalidArgument: a term's homotopy returned a wrong shape or non-finite values.
    """
    p_final = np.array(metric.parameter_values(), dtype=np.float64)

    def params(s: float) -> np.ndarray:
        if s >= 1.0:
            return p_final
        p = np.asarray(parameter_homotopy(metric, s), dtype=np.float64)
        if p.shape != p_final.shape or not np.all(np.isfinite(p)):
            raise InvalidArgument(
                f"the parameter homotopy of {type(metric).__name__} at s={s:g} must be a "
                f"finite array of shape {p_final.shape}, got shape {p.shape}"
            )
        return p

    try:
        shooter.set_parameters(params(0.0))
        v, r, ok, _ = newton(shooter, q1, guess.copy(), max(tol, STAGE_TOL), budget)
        if not ok:
            return v, math.inf, False
        s, ds = 0.0, 0.25
        v_prev: np.ndarray | None = None
        s_prev = 0.0
        while budget.left > 0:
            s_new = min(1.0, s + ds)
            pred = v if v_prev is None else v + (v - v_prev) * (s_new - s) / (s - s_prev)
            shooter.set_parameters(params(s_new))
            stage_tol = tol if s_new >= 1.0 else max(tol, STAGE_TOL)
            v_new, r, ok, _ = newton(shooter, q1, pred, stage_tol, budget)
            if ok:
                v_prev, s_prev, v, s = v, s, v_new, s_new
                if s >= 1.0:
                    return v, r, True
                ds = min(1.5 * ds, 0.5)
            else:
                ds *= 0.5
                if ds < _MIN_DS:
                    break
        shooter.set_parameters(p_final)
        return v, residual_norm(shooter.end(v) - q1), False
    finally:
        shooter.set_parameters(p_final)
