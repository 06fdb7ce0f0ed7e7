"""The choices, defaults and validated settings of the geodesic-tracking OCP.

`OCPSettings` says what the optimal-control problem is (horizon, control mode, weights,
clearance), whichever solver family solves it; how it is solved is the family's options
class (`geosyn.controllers.mpc.nlp.options.NLPOptions`,
`geosyn.controllers.mpc.ddp.options.DDPOptions`). `ocp_settings` validates
`GeodesicMPC`'s arguments into `OCPSettings`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from geosyn.controllers.base import check_gain
from geosyn.core.errors import InvalidArgument
from geosyn.core.types import Vector
from geosyn.core.validation import check_choice, check_float, check_int, check_positive

__all__ = [
    "MAX_SOLVER_ITER",
    "MIN_SOLVER_TOL",
    "CONTROLS",
    "DEFAULT_EFFORT_WEIGHT",
    "EFFORTS",
    "HESSIANS",
    "MAX_HORIZON",
    "MAX_STAGE_DT",
    "MIN_STAGE_DT",
    "STATE_MARGIN",
    "TRACKINGS",
    "OCPSettings",
    "ocp_settings",
    "outside_state_margin",
]

EFFORTS = ("torque", "metric", "acceleration")
"""Names accepted by ``GeodesicMPC(effort=...)``."""
CONTROLS = ("torque", "acceleration")
"""Names accepted by ``GeodesicMPC(control=...)``."""
HESSIANS = ("gauss-newton", "exact")
"""Names accepted by ``GeodesicMPC(hessian=...)``."""
TRACKINGS = ("euclidean", "metric")
"""Names accepted by ``GeodesicMPC(tracking=...)``."""
MAX_HORIZON = 1000
"""Most stages of the OCP (the NLP and its solver grow with the horizon: a graph of
10^6 stages would take hours and gigabytes to build)."""
MIN_STAGE_DT = 1e-6
"""Shortest stage length [s]."""
MAX_STAGE_DT = 1.0
"""Longest stage length [s] (one RK4 step per stage: longer steps mean nothing)."""
MIN_SOLVER_TOL = 1e-14
"""Smallest solver tolerance of every family (float64 resolution of O(1) residuals;
below it a solve never converges)."""
MAX_SOLVER_ITER = 1_000_000
"""Largest iteration limit of every family (the wall-time budget bounds a solve anyway)."""

STATE_MARGIN = (0.1, 1.0)
"""How far a measured state may lie outside the OCP's state bounds and still be solved:
(positions [rad] beyond ``q_min``/``q_max``, velocities as a fraction of ``v_max``
beyond it). Farther out, the bounds on ``x_1`` cannot be met (the torque limits cannot
brake that fast), the NLP is infeasible, and `GeodesicMPC` falls back without solving."""

DEFAULT_EFFORT_WEIGHT = {"torque": 1e-3, "metric": 1e-3, "acceleration": 1e-2}
"""Effort weight when none is given: [1/(N m)^2] for the torque and metric efforts,
[s^4/rad^2] for the acceleration effort (tuned on panda, see benchmarks/RESULTS.md)."""


@dataclass(frozen=True)
class OCPSettings:
    """What the tracking OCP is: horizon, dynamics and cost weights (validated).

    Attributes:
        N: number of stages (>= 1).
        dt: stage length [s].
        control: ``"torque"`` or ``"acceleration"``: what the decision ``u_k`` is.
        effort: ``"torque"``, ``"metric"`` or ``"acceleration"``: the effort cost.
        rk4_steps: RK4 steps per stage (torque control).
        q_weight: (nv,) position-error weight [1/rad^2].
        v_weight: (nv,) velocity-error weight [s^2/rad^2].
        effort_weight: (nv,) effort weight ([1/(N m)^2] or [s^4/rad^2]).
        terminal_weight: (2 nv,) terminal state-error weight (q then v).
        clearance_margin: obstacle clearance kept by a stiff penalty [m]
            (`geosyn.controllers.mpc.ocp.obstacles`), or None.
        tracking: ``"euclidean"`` or ``"metric"``: the norm of the tracking errors.
    """

    N: int
    dt: float
    control: str
    effort: str
    rk4_steps: int
    q_weight: Vector
    v_weight: Vector
    effort_weight: Vector
    terminal_weight: Vector
    clearance_margin: float | None = None
    tracking: str = "euclidean"


def ocp_settings(
    nv: int,
    horizon: object,
    dt: object,
    control: object,
    effort: object,
    rk4_steps: object,
    q_weight: object,
    v_weight: object,
    tau_weight: object,
    terminal_weight: object,
    clearance_margin: object = None,
    tracking: object = "euclidean",
) -> OCPSettings:
    """Validate the OCP arguments of `GeodesicMPC` (same names and meaning).

    Args:
        nv: number of joints.
        horizon: number of stages, in [1, `MAX_HORIZON`].
        dt: stage length [s], in [`MIN_STAGE_DT`, `MAX_STAGE_DT`].
        control: one of `CONTROLS`.
        effort: one of `EFFORTS`, or None for the cheapest one the control allows.
        rk4_steps: 1 or 2.
        q_weight: scalar or (nv,) [1/rad^2].
        v_weight: scalar or (nv,) [s^2/rad^2].
        tau_weight: scalar or (nv,), or None for `DEFAULT_EFFORT_WEIGHT`.
        terminal_weight: scalar or (2 nv,).
        clearance_margin: None or a margin [m] (> 0).
        tracking: one of `TRACKINGS`.

    Raises:
        InvalidArgument: a bad argument (named in the message, with what is allowed).
    """
    N = check_int(horizon, "horizon", low=1, high=MAX_HORIZON)
    dt_s = check_float(dt, "dt", low=MIN_STAGE_DT, high=MAX_STAGE_DT, unit="s")
    control_ = check_choice(control, CONTROLS, "control")
    if effort is None:  # the cheapest effort each control mode allows
        effort = "acceleration" if control_ == "acceleration" else "torque"
    effort_ = check_choice(effort, EFFORTS, "effort")
    if effort_ == "acceleration" and control_ != "acceleration":
        raise InvalidArgument(
            f"effort 'acceleration' needs control='acceleration', got control={control!r}; "
            "with torque control use effort 'torque' or 'metric'"
        )
    return OCPSettings(
        N=N,
        dt=dt_s,
        control=control_,
        effort=effort_,
        rk4_steps=check_int(rk4_steps, "rk4_steps", low=1, high=2),
        q_weight=check_gain(q_weight, nv, "q_weight"),
        v_weight=check_gain(v_weight, nv, "v_weight"),
        effort_weight=check_gain(
            DEFAULT_EFFORT_WEIGHT[effort_] if tau_weight is None else tau_weight, nv, "tau_weight"
        ),
        terminal_weight=check_gain(terminal_weight, 2 * nv, "terminal_weight"),
        clearance_margin=(
            None
            if clearance_margin is None
            else check_positive(clearance_margin, "clearance_margin", "m")
        ),
        tracking=check_choice(tracking, TRACKINGS, "tracking"),
    )


def outside_state_margin(
    q: np.ndarray, v: np.ndarray, q_min: Vector, q_max: Vector, v_max: Vector
) -> str:
    """Why a measured state lies beyond `STATE_MARGIN` of the state bounds ('' if not).

    Args:
        q: (nv,) joint positions [rad].
        v: (nv,) joint velocities [rad/s] (non-finite entries count as beyond).
        q_min: (nv,) lower position limits [rad] (may be -inf).
        q_max: (nv,) upper position limits [rad] (may be +inf).
        v_max: (nv,) velocity limits [rad/s].
    """
    dq, fv = STATE_MARGIN
    over_q = np.maximum(np.asarray(q_min) - q, q - np.asarray(q_max))
    if np.any(over_q > dq):
        i = int(np.argmax(over_q))
        return f"q[{i}] = {q[i]:.4g} rad is {over_q[i]:.3g} rad outside its limits"
    over_v = np.where(np.isfinite(v), np.abs(v) - (1.0 + fv) * np.asarray(v_max), np.inf)
    if np.any(over_v > 0.0):
        i = int(np.argmax(over_v))
        return f"|v[{i}]| = {abs(v[i]):.4g} rad/s is above {1.0 + fv:g} v_max"
    return ""
