"""Reaching with synergies: the weights whose combined geodesic brings a frame to a target,
with every configuration of the motion inside the robot's joint position limits."""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import numpy as np

from geosyn.core.types import Vector
from geosyn.core.validation import check_float, check_int, check_positive
from geosyn.metrics.geodesic import Geodesic, exp
from geosyn.robots.kinematics import frame_position
from geosyn.robots.robot import Robot
from geosyn.synergies.errors import SynergyError, synergy_input
from geosyn.synergies.synergy import (
    GeodesicSynergy,
    _check_synergies,
    as_vector,
    check_robot,
    transported_velocities,
)

#: Weight [m/rad] of a joint-limit violation against the position error in the solve.
LIMIT_WEIGHT = 10.0
#: The solve keeps the motion this far inside finite joint limits [rad or m], so that the
#: few microradians a penalised solve may leave over stay inside the true limits.
LIMIT_MARGIN = 1e-3


class ReachOutsideLimits(SynergyError):
    """No motion found inside the joint limits (or ``q_start`` is outside them).

    Attributes:
        joint: name of the joint furthest outside its limits.
        value: its position [rad or m] (at time ``t``).
        limit: the limit it passes [rad or m].
        t: time along the motion [s].
        segment: index of the segment of a sequence (`reach_sequence`), or None.
        q_start: (n,) that segment's start [rad], or None.
    """

    def __init__(
        self,
        message: str,
        joint: str,
        value: float,
        limit: float,
        t: float,
        segment: int | None = None,
        q_start: Vector | None = None,
    ) -> None:
        super().__init__(message)
        self.joint, self.value, self.limit, self.t = joint, float(value), float(limit), float(t)
        self.segment = segment
        self.q_start = None if q_start is None else np.array(q_start, dtype=np.float64)


def _limits(robot: Robot, n: int) -> tuple[np.ndarray, np.ndarray]:
    lo = np.asarray(robot.q_min, dtype=np.float64)
    hi = np.asarray(robot.q_max, dtype=np.float64)
    if lo.shape != (n,):  # a floating base: no limits on the group part
        return np.full(n, -np.inf), np.full(n, np.inf)
    return lo, hi


def _check_within(robot: Robot, traj: Geodesic, lo: np.ndarray, hi: np.ndarray, what: str) -> None:
    """Raise `ReachOutsideLimits` naming the joint furthest outside ``[lo, hi]``."""
    q = np.asarray(traj.q, dtype=np.float64)
    over = np.maximum(q - hi, 0.0) + np.maximum(lo - q, 0.0)
    if not over.size or float(over.max()) <= 0.0:
        return
    k, j = np.unravel_index(int(np.argmax(over)), over.shape)
    value = float(q[k, j])
    limit = float(hi[j] if value > hi[j] else lo[j])
    name = robot.joint_names[j] if j < len(robot.joint_names) else f"q[{j}]"
    raise ReachOutsideLimits(
        f"{what}: joint {name!r} at {value:.4g} passes its limit {limit:.4g} at"
        f" t={float(traj.t[k]):.3g} s (limits [{lo[j]:.4g}, {hi[j]:.4g}]); give another"
        " target or q_start, more synergies, or a longer duration",
        name,
        value,
        limit,
        float(traj.t[k]),
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

    Joint limits: every sample of the motion is kept inside the robot's finite position
    limits shrunk by `LIMIT_MARGIN` by a penalty residual (weight `LIMIT_WEIGHT`) on the
    violation; the best solution is chosen among those inside the limits first. A motion
    that still leaves the true limits is never returned: `ReachOutsideLimits` names the
    joint, its value, the limit and the time.

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
        ReachOutsideLimits: ``q_start`` outside the joint limits, or no motion found
            inside them.
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
    lo, hi = _limits(robot, n)
    _check_within(robot, Geodesic(np.zeros(1), q_s[None, :], np.zeros((1, n))), lo, hi, "q_start")
    finite = np.isfinite(lo) & np.isfinite(hi)
    mid = np.where(finite, 0.5 * (np.where(finite, lo, 0.0) + np.where(finite, hi, 0.0)), 0.0)
    lo_in = np.where(np.isfinite(lo), np.minimum(lo + LIMIT_MARGIN, np.where(finite, mid, hi)), lo)
    hi_in = np.where(np.isfinite(hi), np.maximum(hi - LIMIT_MARGIN, np.where(finite, mid, lo)), hi)
    Vt = transported_velocities(syns, q_s, steps=steps)
    m = Vt.shape[1]
    data = robot.model.createData()
    sqrt_lam = np.sqrt(lam)

    def residual(w: np.ndarray) -> np.ndarray:
        q = exp(metric, q_s, Vt @ w, duration=duration, steps=steps).q
        over = np.maximum(q - hi_in, 0.0) + np.maximum(lo_in - q, 0.0)
        p = frame_position(robot, q[-1], fid, data)
        return np.concatenate([p - p_star, sqrt_lam * w, LIMIT_WEIGHT * over.ravel()])

    rng = np.random.default_rng(seed)
    best_w, best_err, best_feasible, starts = np.zeros(m), np.inf, False, 0
    from scipy.optimize import least_squares  # heavy (~0.2 s): imported where used

    for attempt in range(restarts + 1):
        w0 = np.zeros(m) if attempt == 0 else weight_scale * rng.standard_normal(m)
        sol = least_squares(
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
        feasible = not np.any(sol.fun[3 + m :] > 0.0)
        if (feasible, -err) > (best_feasible, -best_err):
            best_w, best_err, best_feasible = sol.x.copy(), err, feasible
        if best_feasible and best_err <= tol:
            break
    traj = exp(metric, q_s, Vt @ best_w, duration=duration, steps=steps)
    _check_within(robot, traj, lo, hi, f"reach of {frame!r} to {np.round(p_star, 4).tolist()}")
    position = frame_position(robot, traj.q[-1], fid, data)
    error = float(np.linalg.norm(position - p_star))
    return ReachResult(best_w, position, error, traj, error <= tol, starts)
