"""Reaching with synergies: the weights whose combined geodesic brings a frame to a target."""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
import scipy.optimize

from geosyn.core.types import Vector
from geosyn.core.validation import check_float, check_int, check_positive
from geosyn.metrics.geodesic import Geodesic, exp
from geosyn.robots.kinematics import frame_position
from geosyn.robots.robot import Robot
from geosyn.synergies.errors import synergy_input
from geosyn.synergies.synergy import (
    GeodesicSynergy,
    _check_synergies,
    as_vector,
    check_robot,
    transported_velocities,
)


class ReachResult(NamedTuple):
    """Outcome of `reach`.

    Attributes:
        weights: (m,) synergy weights [-].
        position: (3,) frame position at the end of the motion [m].
        error: distance from ``position`` to the target [m].
        trajectory: the combined geodesic from ``q_start`` over ``duration``.
        converged: ``error <= tol``.
        starts: least-squares solves done (1 + restarts used).
    """

    weights: Vector
    position: Vector
    error: float
    trajectory: Geodesic
    converged: bool
    starts: int


def reach(
    synergies: Sequence[GeodesicSynergy],
    target: Vector,
    frame: str,
    robot: Robot,
    q_start: Vector | None = None,
    duration: float = 1.0,
    lam: float = 1e-6,
    *,
    steps: int = 100,
    tol: float = 1e-4,
    restarts: int = 5,
    weight_scale: float = 1.0,
    seed: int = 0,
) -> ReachResult:
    """Synergy weights that bring ``frame`` to ``target`` at the end of the combined motion.

    .. math:: \\min_w \\; |p(w) - p^*|^2 + \\lambda |w|^2, \\qquad
              p(w) = \\mathrm{FK}\\big(\\exp_{q_s}(t \\textstyle\\sum_i w_i v_i)\\big|_{t=T}\\big)

    with :math:`v_i` the synergies' initial velocities transported to ``q_start`` (once,
    before the solve). Solved by Levenberg-Marquardt (``scipy.optimize.least_squares``,
    finite-difference Jacobian: m + 1 geodesic integrations per iteration), first from
    ``w = 0``, then, while the error exceeds ``tol``, from up to ``restarts`` seeded
    random weights (normal, std ``weight_scale``); the best solution is returned. A
    target that is not reached is reported by ``converged=False``, not raised.

    Args:
        synergies: m synergies sharing one metric.
        target: (3,) target position in the world frame [m].
        frame: frame name of ``robot``.
        robot: the robot whose frame is positioned (its nv must equal the metric's n).
        q_start: (n,) start configuration [rad]; defaults to the first synergy's base.
        duration: motion duration T [s], > 0.
        lam: Tikhonov weight on |w|^2 [m^2], >= 0.
        steps: RK4 steps of each geodesic.
        tol: success threshold on the position error [m].
        restarts: random restarts allowed after the first solve.
        weight_scale: std of the random restart weights [-].
        seed: seed of the restart weights.

    Returns:
        The `ReachResult`.

    Raises:
        InvalidSynergyInput: bad input.
        UnknownFrame: ``frame`` is not in the robot.
        SynergyNotConverged: a synergy base could not be joined to ``q_start``.
    """
    syns = _check_synergies(synergies)
    metric = syns[0].metric
    n = metric.n
    check_robot(robot, n)
    p_star = as_vector(target, 3, "target")
    with synergy_input("duration"):
        duration = check_positive(duration, "duration", unit="s")
    with synergy_input("lam"):
        lam = check_float(lam, "lam", low=0.0, unit="m^2")
    with synergy_input("restarts"):
        restarts = check_int(restarts, "restarts", low=0)
    fid = robot.frame_id(frame)
    q_s = syns[0].q0.copy() if q_start is None else as_vector(q_start, n, "q_start")
    Vt = transported_velocities(syns, q_s, steps=steps)
    m = Vt.shape[1]
    data = robot.model.createData()
    sqrt_lam = np.sqrt(lam)

    def endpoint(w: np.ndarray) -> Vector:
        g = exp(metric, q_s, Vt @ w, duration=duration, steps=steps)
        return frame_position(robot, g.q[-1], fid, data)

    def residual(w: np.ndarray) -> np.ndarray:
        return np.concatenate([endpoint(w) - p_star, sqrt_lam * w])

    rng = np.random.default_rng(seed)
    best_w, best_err, starts = np.zeros(m), np.inf, 0
    for attempt in range(restarts + 1):
        w0 = np.zeros(m) if attempt == 0 else weight_scale * rng.standard_normal(m)
        sol = scipy.optimize.least_squares(
            residual,
            w0,
            method="lm",
            x_scale=1.0,
            xtol=1e-12,
            ftol=1e-12,
            gtol=1e-12,
            max_nfev=100 * (m + 1),
        )
        starts += 1
        err = float(np.linalg.norm(sol.fun[:3]))
        if err < best_err:
            best_w, best_err = sol.x.copy(), err
        if best_err <= tol:
            break
    traj = exp(metric, q_s, Vt @ best_w, duration=duration, steps=steps)
    position = frame_position(robot, traj.q[-1], fid, data)
    error = float(np.linalg.norm(position - p_star))
    return ReachResult(best_w, position, error, traj, error <= tol, starts)
