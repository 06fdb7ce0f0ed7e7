"""Stance: a floating-base robot with contact frames held fixed, and its induced metric.

Holding k frames (a foot, both feet, a hand on a handle) at their world poses restricts
the configurations to the submanifold

.. math:: \\mathcal{S} = \\{ q \\in SE(3) \\times R^n : T_{world,f_i}(q) = T_i^0,\\ i = 1..k \\}

of dimension nv - 6k (a quadruped's point feet hold positions only, ``points=True``:
``p_f_i(q) = p_i^0``, dimension nv - 3k), the nonlinear generalisation of the linear couplings
``q = S z + c``. Its tangent space at q is the null space of the stacked frame Jacobians
``J(q)`` (6k, nv) (local frames), and its metric is the one induced by the kinetic
energy: ``<u, w> = u^T M(q) w`` for tangent u, w; in a basis ``N(q)`` of the null space,
``G_S = N^T M N``.

Geodesics of the induced metric are the robot's passive motions with the frames held
(d'Alembert): ``M a + C v = J^T lambda``, ``J a + Jdot v = 0``, i.e.

.. math:: a = a_0 - M^{-1} J^T (J M^{-1} J^T)^{-1} (J a_0 + \\dot J v), \\qquad
    a_0 = -M^{-1} C v.

`Stance.geodesic` integrates them on the group (`geosyn.metrics.geodesic.group_rk4`)
and returns to the submanifold after each step (Newton on the frame poses, then the
M-orthogonal projection of the velocity onto the tangent space), so the frames stay put
to round-off instead of drifting with the integration error.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pinocchio as pin
import scipy.linalg

from geosyn.core.types import Matrix, Vector
from geosyn.core.validation import check_int, check_positive, check_vector
from geosyn.metrics.errors import StanceError
from geosyn.metrics.floating import FloatingKineticEnergyMetric
from geosyn.metrics.geodesic.exp_map import MAX_STEPS, Geodesic
from geosyn.metrics.geodesic.group_rk4 import group_rk4

__all__ = ["Stance"]

_RANK_TOL = 1e-9  # smallest accepted singular value of J, relative to the largest
_NEWTON_TOL = 1e-13  # pose residual at which the return to the submanifold stops
_TANGENT_TOL = 1e-9  # |J v0| accepted as tangent [m/s, rad/s]
_ALIGNED = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED


class Stance:
    """Frames of a floating-base robot held at their poses of a reference configuration.

    Args:
        metric: the floating-base kinetic-energy metric.
        frames: names of the frames held (6-D each: position and orientation), at least
            one, no repeats.
        q_ref: (nq,) configuration whose frame poses are held.
        points: hold only the frames' positions (point feet of a quadruped: 3
            constraints per frame, world axes) instead of their full poses (6).

    Raises:
        StanceError: no frames, repeated frames, or a stance that over-constrains the
            robot at ``q_ref`` (ck >= nv with c = 6, or 3 for points, or dependent
            constraints: J(q_ref) has rank < ck; the message gives the rank and the
            frames).
        UnknownFrame: a frame that is not in the robot (the message lists them).
        FloatingBaseError: ``q_ref``'s quaternion is not unit.

    Attributes:
        metric: the metric.
        frames: the frame names.
        targets: the held world poses (`pinocchio.SE3`), one per frame.
        points: whether only positions are held.
        dimension: dimension of the submanifold, nv - 6k (nv - 3k for points).
    """

    def __init__(
        self,
        metric: FloatingKineticEnergyMetric,
        frames: Sequence[str],
        q_ref: Vector,
        *,
        points: bool = False,
    ):
        if not isinstance(metric, FloatingKineticEnergyMetric):
            raise StanceError(
                f"a stance holds frames of a floating-base robot: metric must be a"
                f" FloatingKineticEnergyMetric, got {type(metric).__name__}"
            )
        frames = [frames] if isinstance(frames, str) else list(frames)
        if not frames or len(set(frames)) != len(frames):
            raise StanceError(f"frames must name at least one frame, each once; got {frames}")
        self.metric = metric
        self.robot = metric.robot
        self.frames = tuple(frames)
        self.points = bool(points)
        self._rows = 3 if self.points else 6
        self._ids = [self.robot.frame_id(f) for f in frames]  # UnknownFrame lists them
        self._model = self.robot.model
        self._data = self._model.createData()
        q_ref = self.robot.check_q(q_ref, "q_ref")
        pin.framesForwardKinematics(self._model, self._data, q_ref)
        self.targets = tuple(pin.SE3(self._data.oMf[i]) for i in self._ids)
        k, nv = self._rows * len(frames), self.robot.nv
        self.dimension = nv - k
        s = np.linalg.svd(self.jacobian(q_ref), compute_uv=False)
        rank = int(np.sum(s > _RANK_TOL * s[0]))
        if k >= nv or rank < k:
            raise StanceError(
                f"stance {list(frames)} over-constrains robot {self.robot.name!r}: {k}"
                f" constraints ({self._rows} per frame) of rank {rank} on nv = {nv} velocities; hold"
                " fewer frames, frames on different bodies, or frames not aligned in a"
                " singular configuration"
            )

    def __repr__(self) -> str:
        return f"Stance({self.robot.name!r}, frames={list(self.frames)})"

    # -- the constraint --------------------------------------------------------------
    def residual(self, q: Vector) -> Vector:
        """(6k,) pose errors ``log6(T_i^0^-1 T_f_i(q))`` [m, rad], zero on the stance;
        (3k,) position errors ``p_i(q) - p_i^0`` [m] for ``points``."""
        q = self.robot.check_q(q)
        pin.framesForwardKinematics(self._model, self._data, q)
        return self._residual()

    def _residual(self) -> Vector:
        if self.points:  # world-frame position errors
            return np.concatenate(
                [
                    self._data.oMf[i].translation - t.translation
                    for t, i in zip(self.targets, self._ids, strict=True)
                ]
            )
        return np.concatenate(
            [
                pin.log6(t.actInv(self._data.oMf[i])).vector
                for t, i in zip(self.targets, self._ids, strict=True)
            ]
        )

    def jacobian(self, q: Vector) -> Matrix:
        """(6k, nv) the held frames' Jacobians in their local frames (linear rows first);
        (3k, nv) the points' linear Jacobians in world axes for ``points``."""
        q = self.robot.check_q(q)
        pin.computeJointJacobians(self._model, self._data, q)
        pin.updateFramePlacements(self._model, self._data)
        return self._jacobian()

    def _jacobian(self) -> Matrix:
        if self.points:
            return np.vstack(
                [pin.getFrameJacobian(self._model, self._data, i, _ALIGNED)[:3] for i in self._ids]
            )
        return np.vstack(
            [
                pin.getFrameJacobian(self._model, self._data, i, pin.ReferenceFrame.LOCAL)
                for i in self._ids
            ]
        )

    def jacobian_time_variation(self, q: Vector, v: Vector) -> Matrix:
        """(6k, nv) or (3k, nv): ``d/dt J(q(t))`` along ``q(t) = q exp(t v)`` (Pinocchio's
        ``getFrameJacobianTimeVariation``, same frames and rows as `jacobian`).

        Args:
            q: (nq,) configuration.
            v: (nv,) velocity.
        """
        q = self.robot.check_q(q)
        v = check_vector(v, self.robot.nv, "v")
        model, data = self._model, self._data
        pin.computeJointJacobiansTimeVariation(model, data, q, v)
        pin.updateFramePlacements(model, data)
        if self.points:
            return np.vstack(
                [pin.getFrameJacobianTimeVariation(model, data, i, _ALIGNED)[:3] for i in self._ids]
            )
        return np.vstack(
            [
                pin.getFrameJacobianTimeVariation(model, data, i, pin.ReferenceFrame.LOCAL)
                for i in self._ids
            ]
        )

    def tangent_basis(self, q: Vector) -> Matrix:
        """(nv, nv - 6k) an orthonormal basis of the tangent space (J's null space)."""
        return np.asarray(scipy.linalg.null_space(self.jacobian(q)))

    def G(self, q: Vector) -> Matrix:
        """(nv - 6k, nv - 6k) the induced metric ``N^T M N`` in `tangent_basis` coordinates."""
        N = self.tangent_basis(q)
        return N.T @ self.metric.G(q) @ N

    # -- the induced geodesics ---------------------------------------------------------
    def _kkt(self, q: Vector, v: Vector) -> tuple[Matrix, Matrix, Vector]:
        """``(M, J, Jdot v)`` at (q, v) (one kinematics pass)."""
        model, data = self._model, self._data
        pin.forwardKinematics(model, data, q, v, np.zeros(model.nv))
        pin.computeJointJacobians(model, data, q)
        pin.updateFramePlacements(model, data)
        J = self._jacobian()
        if self.points:  # classical acceleration of the points, world axes
            bias = np.concatenate(
                [
                    pin.getFrameClassicalAcceleration(model, data, i, _ALIGNED).linear
                    for i in self._ids
                ]
            )
        else:
            bias = np.concatenate(
                [
                    pin.getFrameAcceleration(model, data, i, pin.ReferenceFrame.LOCAL).vector
                    for i in self._ids
                ]
            )
        return np.array(pin.crba(model, data, q)), J, bias

    def acceleration(self, q: Vector, v: Vector) -> Vector:
        """(nv,) the geodesic acceleration of the induced metric (frames held, no gravity).

        Args:
            q: (nq,) configuration on the stance.
            v: (nv,) tangent velocity (``J v = 0``).
        """
        M, J, bias = self._kkt(q, v)
        a0 = self.metric.geodesic_acceleration(q, v)
        L = scipy.linalg.cho_factor(M)
        MiJt = scipy.linalg.cho_solve(L, J.T)
        lam = np.linalg.solve(J @ MiJt, J @ a0 + bias)
        return np.asarray(a0 - MiJt @ lam)

    def project(self, q: Vector, v: Vector) -> tuple[Vector, Vector]:
        """Return to the stance: Newton on the frame poses, then the M-orthogonal
        projection of ``v`` onto the tangent space.

        Args:
            q: (nq,) configuration near the stance.
            v: (nv,) velocity.

        Returns:
            ``(q, v)`` on the stance (residual <= 1e-13 unless 10 iterations do not
            reach it) with ``J v = 0``.
        """
        model, data = self._model, self._data
        for _ in range(10):
            pin.computeJointJacobians(model, data, q)
            pin.updateFramePlacements(model, data)
            r = self._residual()
            if np.abs(r).max() <= _NEWTON_TOL:
                break
            J = self._jacobian()
            q = pin.integrate(model, q, -J.T @ np.linalg.solve(J @ J.T, r))
        J = self._jacobian() if np.abs(r).max() <= _NEWTON_TOL else self.jacobian(q)
        M = pin.crba(model, data, q)
        MiJt = scipy.linalg.cho_solve(scipy.linalg.cho_factor(M), J.T)
        return q, v - MiJt @ np.linalg.solve(J @ MiJt, J @ v)

    def geodesic(self, q0: Vector, v0: Vector, duration: float = 1.0, steps: int = 100) -> Geodesic:
        """The geodesic of the induced metric from ``(q0, v0)``: a passive motion with the
        frames held, integrated on the group (RKMK4) and returned to the stance each step.

        Args:
            q0: (nq,) configuration on the stance (residual <= 1e-9).
            v0: (nv,) tangent velocity (``|J v0| <= 1e-9``; `project` makes one).
            duration: integration time [s], > 0.
            steps: number of steps, in [1, `MAX_STEPS`].

        Returns:
            The sampled geodesic; ``q`` (T, nq), ``v`` (T, nv).

        Raises:
            StanceError: ``q0`` off the stance or ``v0`` not tangent (values given).
        """
        q0 = self.robot.check_q(q0, "q0")
        v0 = check_vector(v0, self.robot.nv, "v0")
        duration = check_positive(duration, "duration", "s")
        steps = check_int(steps, "steps", low=1, high=MAX_STEPS)
        off = float(np.abs(self.residual(q0)).max())
        moving = float(np.abs(self.jacobian(q0) @ v0).max())
        if off > 1e-9 or moving > _TANGENT_TOL:
            raise StanceError(
                f"q0, v0 must be on {self!r}: pose error {off:.3g} (<= 1e-9 m, rad) and"
                f" held-frame velocity {moving:.3g} (<= {_TANGENT_TOL:g} m/s, rad/s);"
                " Stance.project(q, v) returns to it"
            )
        t = np.linspace(0.0, duration, steps + 1)
        Q, V = group_rk4(
            self.metric, q0, v0, duration / steps, steps, self.acceleration, self.project
        )
        return Geodesic(t, Q, V)
