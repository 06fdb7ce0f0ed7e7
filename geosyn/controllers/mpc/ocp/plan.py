"""The plan record every solver family returns (`MPCPlan`) and the reference samples
(`ReferenceSamples`) a plan is solved for; following a plan in time is
`geosyn.controllers.mpc.follow`."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import pinocchio as pin

from geosyn.controllers.reference import Reference

__all__ = [
    "EPS_T",
    "MPCPlan",
    "ReferenceSampler",
    "ReferenceSamples",
    "sample_reference",
]

EPS_T = 1e-9
"""Slack when comparing clock times [s]."""


class MPCPlan(NamedTuple):
    """One solve of the OCP.

    Attributes:
        t: time of the solve [s]; stage k is at ``t + k dt``.
        x: (N+1, 2 nv) planned states ``(q, v)`` [rad, rad/s].
        u: (N, nv) planned controls (torques [N m] or accelerations [rad/s^2]); with
            ``friction``, torques net of it.
        tau: (N, nv) planned commanded torques [N m] (``friction`` included).
        status: solver status string.
        iterations: solver iterations.
        success: the solver reported success and the result is finite.
        solve_time: wall-clock time of the solver call [s].
        K: (N, nv, 2 nv) feedback gains of a DDP solve (``solver="ddp"``), else None:
            the torque ``u_j + K_j (x - x^*)`` minimises the stage's local model.
        friction: (N, nv) the known dry-friction feed-forward of each stage [N m]
            (`geosyn.controllers.mpc.ocp.dynamics.stage_friction`), added to the
            controls' torque when commanding, or None for a robot without dry friction.
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
    friction: np.ndarray | None = None

    def within_budget(self, budget: float) -> MPCPlan:
        """This plan, or when it succeeded in more than ``budget`` [s] of solve time,
        a copy flagged as failed with the overrun in its status."""
        if self.success and self.solve_time > budget:
            status = f"over budget: {self.solve_time:.3g} s > max_solve_time {budget:.3g} s"
            return self._replace(success=False, status=f"{status} ({self.status})")
        return self


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
    reference: Reference,
    model: pin.Model,
    data: pin.Data,
    t: float,
    N: int,
    dt: float,
    damping: np.ndarray | None = None,
) -> ReferenceSamples:
    """Sample a reference at ``t + k dt``, k = 0..N, with its inverse dynamics
    ``RNEA + D v`` (allocates).

    Args:
        reference: the reference.
        model: Pinocchio model for the inverse dynamics.
        data: its workspace.
        t: time of the first sample [s].
        N: number of stages.
        dt: stage length [s].
        damping: (nv,) viscous joint damping D [N m s/rad], or None.
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
    if damping is not None:
        tr += damping * vr[:N]
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
        damping: (nv,) viscous joint damping D [N m s/rad] of the inverse dynamics, or None.
    """

    def __init__(self, model: pin.Model, data: pin.Data, damping: np.ndarray | None = None) -> None:
        self._model, self._data = model, data
        self._damping = damping
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
            out = sample_reference(reference, self._model, self._data, t, N, dt, self._damping)
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
            if self._damping is not None:
                tau[k] += self._damping * v[k]
        return ReferenceSamples(q, v, a, tau)
