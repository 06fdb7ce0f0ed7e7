"""An MPC plan, the reference samples it is solved for, and how it is followed in time."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import pinocchio as pin

from geosyn.controllers.reference import Reference
from geosyn.core.interpolation import hermite_point
from geosyn.core.types import Vector

__all__ = [
    "EPS_T",
    "MPCPlan",
    "PlanFollower",
    "ReferenceSampler",
    "ReferenceSamples",
    "plan_state",
    "sample_reference",
]

EPS_T = 1e-9
"""Slack when comparing clock times [s]."""


class MPCPlan(NamedTuple):
    """One solve of the OCP.

    Attributes:
        t: time of the solve [s]; stage k is at ``t + k dt``.
        x: (N+1, 2 nv) planned states ``(q, v)`` [rad, rad/s].
        u: (N, nv) planned controls (torques [N m] or accelerations [rad/s^2]).
        tau: (N, nv) planned torques [N m].
        status: solver status string.
        iterations: solver iterations.
        success: the solver reported success and the result is finite.
        solve_time: wall-clock time of the solver call [s].
        K: (N, nv, 2 nv) feedback gains of a DDP solve (``solver="ddp"``), else None:
            the torque ``u_j + K_j (x - x^*)`` minimises the stage's local model.
    """

    t: float
    x: np.ndarray
    u: np.ndarray
    tau: np.ndarray
    status: str
    iterations: int
    success: bool
    solve_time: float
    K: np.ndarray | None = None


class ReferenceSamples(NamedTuple):
    """The reference at the stage times ``t + k dt``.

    Attributes:
        q: (N+1, nv) positions [rad].
        v: (N+1, nv) velocities [rad/s].
        a: (N+1, nv) accelerations [rad/s^2].
        tau: (N, nv) inverse-dynamics torques of the first N samples [N m].
    """

    q: np.ndarray
    v: np.ndarray
    a: np.ndarray
    tau: np.ndarray


def sample_reference(
    reference: Reference, model: pin.Model, data: pin.Data, t: float, N: int, dt: float
) -> ReferenceSamples:
    """Sample a reference at ``t + k dt``, k = 0..N, with its inverse dynamics (allocates).

    Args:
        reference: the reference.
        model: Pinocchio model for the inverse dynamics.
        data: its workspace.
        t: time of the first sample [s].
        N: number of stages.
        dt: stage length [s].
    """
    n = reference.n
    qr = np.empty((N + 1, n))
    vr = np.empty((N + 1, n))
    ar = np.empty((N + 1, n))
    sample = reference.sample
    for k in range(N + 1):
        qr[k], vr[k], ar[k] = sample(t + k * dt)
    tr = np.empty((N, n))
    for k in range(N):
        tr[k] = pin.rnea(model, data, qr[k], vr[k], ar[k])
    return ReferenceSamples(qr, vr, ar, tr)


class ReferenceSampler:
    """`sample_reference` that reuses the samples of the previous call (allocates).

    A receding-horizon controller samples ``t + k dt`` with ``t`` advancing by whole
    stages: the samples it shares with the previous call are shifted instead of
    evaluated again (the reference and its inverse dynamics at a time differing only by
    the rounding of ``t + k dt``), so a solve samples one new stage, not ``N + 1``.

    Args:
        model: Pinocchio model for the inverse dynamics.
        data: its workspace.
    """

    def __init__(self, model: pin.Model, data: pin.Data) -> None:
        self._model, self._data = model, data
        self._last: tuple[Reference, float, int, float, ReferenceSamples] | None = None

    def clear(self) -> None:
        """Forget the previous samples (a new reference)."""
        self._last = None

    def sample(self, reference: Reference, t: float, N: int, dt: float) -> ReferenceSamples:
        """The samples of `sample_reference` (the next call reads them: do not modify)."""
        last = self._last
        j = -1
        if last is not None and last[0] is reference and last[2] == N and last[3] == dt:
            j = int(round((t - last[1]) / dt))
            if abs(t - last[1] - j * dt) > EPS_T:
                j = -1
        if 0 <= j <= N and last is not None:
            out = self._shifted(last[4], reference, t, N, dt, j)
        else:
            out = sample_reference(reference, self._model, self._data, t, N, dt)
        self._last = (reference, t, N, dt, out)
        return out

    def _shifted(
        self, prev: ReferenceSamples, reference: Reference, t: float, N: int, dt: float, j: int
    ) -> ReferenceSamples:
        """``prev`` shifted by ``j`` stages: samples at stages ``N - j + 1 .. N`` and the
        inverse dynamics at ``N - j .. N - 1`` are new."""
        q, v, a = (np.empty_like(x) for x in prev[:3])
        tau = np.empty_like(prev.tau)
        keep = N + 1 - j
        q[:keep], v[:keep], a[:keep], tau[: N - j] = (
            prev.q[j:],
            prev.v[j:],
            prev.a[j:],
            prev.tau[j:],
        )
        for k in range(keep, N + 1):
            q[k], v[k], a[k] = reference.sample(t + k * dt)
        for k in range(N - j, N):
            tau[k] = pin.rnea(self._model, self._data, q[k], v[k], a[k])
        return ReferenceSamples(q, v, a, tau)


def plan_state(plan: MPCPlan, t: float, dt: float) -> tuple[int, np.ndarray, np.ndarray]:
    """Stage index and planned ``(q, v)`` at time ``t``: cubic Hermite between stages.

    Args:
        plan: the plan.
        t: time [s]; before ``plan.t`` it is the first state, past the horizon the last.
        dt: stage length [s].

    Returns:
        ``(j, q, v)``: the stage ``j`` containing ``t``, (nv,) positions [rad] and
        velocities [rad/s].
    """
    N = plan.u.shape[0]
    n = plan.u.shape[1]
    s = max(t - plan.t, 0.0)
    j = min(int(s / dt + EPS_T), N - 1)
    frac = min((s - j * dt) / dt, 1.0)
    x0, x1 = plan.x[j], plan.x[j + 1]
    q, v = hermite_point(x0[:n], x0[n:], x1[:n], x1[n:], dt, frac)
    return j, q, v


class PlanFollower:
    """Follows a plan between solves, and the reference when there is no plan.

    On a plan, the first control of the current stage ``j`` is held and a feedback keeps
    the plant on the planned states:

    .. math::
        \\tau = u^*_j + M(q) (K_p (q^*(t) - q) + K_d (v^*(t) - v))

    (torque control), or ``tau = RNEA(q, v, u^*_j + K_p (q^* - q) + K_d (v^* - v))``
    (acceleration control), with ``(q^*, v^*)`` the cubic Hermite interpolation of the
    planned states (`plan_state`). A plan with DDP gains (``plan.K``) is followed by its
    own feedback, saturated at the torque limits like the DDP rollout:
    ``tau = clip(u^*_j + K_j ((q, v) - (q^*, v^*)), -tau_max, tau_max)``.

    Args:
        model: Pinocchio model of the plant.
        data: its workspace (shared with the caller; used per call).
        control: ``"torque"`` or ``"acceleration"``: what the plan's controls are.
        dt: stage length [s].
        kp: (nv,) stiffness [1/s^2].
        kd: (nv,) damping [1/s].
        plan_tolerance: max joint deviation from a plan that may still be followed [rad].
        tau_max: (nv,) torque limits [N m] saturating the DDP feedback (None: no plan
            with gains is expected).

    Each method allocates only (nv,) arrays (and ``M`` in torque control).
    """

    def __init__(
        self,
        model: pin.Model,
        data: pin.Data,
        control: str,
        dt: float,
        kp: Vector,
        kd: Vector,
        plan_tolerance: float,
        tau_max: Vector | None = None,
    ) -> None:
        self._model, self._data = model, data
        self.tau_max = None if tau_max is None else np.asarray(tau_max, dtype=np.float64)
        self.torque_control = control == "torque"
        self.dt, self.kp, self.kd = dt, kp, kd
        self.plan_tolerance = plan_tolerance

    def torque(self, plan: MPCPlan, t: float, q: Vector, v: Vector) -> Vector:
        """(nv,) torque [N m] that follows ``plan`` at time ``t`` from the state ``(q, v)``."""
        j, q_p, v_p = plan_state(plan, t, self.dt)
        if plan.K is not None and self.tau_max is not None:
            tau = plan.u[j] + plan.K[j] @ np.concatenate([q - q_p, v - v_p])
            return np.clip(tau, -self.tau_max, self.tau_max)
        fb = self.kp * (q_p - q) + self.kd * (v_p - v)
        if self.torque_control:
            M = pin.crba(self._model, self._data, q)
            return plan.u[j] + M @ fb
        return pin.rnea(self._model, self._data, q, v, plan.u[j] + fb).copy()

    def usable(self, plan: MPCPlan | None, t: float, q: Vector) -> bool:
        """A successful plan that still covers ``t`` and is within tolerance of ``q``."""
        if plan is None or not plan.success:
            return False
        if t - plan.t >= plan.u.shape[0] * self.dt - EPS_T:
            return False
        _, q_p, _ = plan_state(plan, t, self.dt)
        return float(np.max(np.abs(q_p - q))) <= self.plan_tolerance

    def reference_torque(self, reference: Reference, t: float, q: Vector, v: Vector) -> Vector:
        """(nv,) computed torque [N m] on ``reference`` with the same gains (no plan)."""
        q_ref, v_ref, a_ref = reference.sample(t)
        a = a_ref + self.kp * (q_ref - q) + self.kd * (v_ref - v)
        return pin.rnea(self._model, self._data, q, v, a).copy()
