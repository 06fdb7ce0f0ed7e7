"""Whole-body torque control of a floating-base robot standing on flat ground (proxsuite).

Each tick solves one QP over the joint accelerations ``a`` (nv) and the contact forces
``f`` (3 per contact point, world axes); the joint torques follow from the dynamics:

.. math::
    \\min_{a, f}\\ \\tfrac12 \\|a - a^*\\|_W^2 + \\tfrac{\\epsilon}{2} \\|f\\|^2
    \\quad \\text{s.t.} \\quad
    [M a + h - J_p^T f]_{base} = 0, \\qquad J_c a + \\dot J_c v = -k_c J_c v,

    |f_x|, |f_y| \\le \\mu f_z, \\quad f_z \\ge f_{min}, \\quad
    -\\tau_{max} \\le [M a + h - J_p^T f]_{joints} \\le \\tau_{max},

with ``M a + h = S^T tau + J_p^T f`` the floating-base dynamics (``h`` Coriolis and
gravity, ``S`` the joint selection), ``J_c`` the held frames' Jacobians (6 rows for a
sole with several contact points, 3 linear rows for a point foot) and ``J_p`` the contact
points' world-frame Jacobians, friction cones linearised as pyramids with a flat floor
(normal +z). The task ``a* = a_ref + K_p (q_ref - q) + K_d (v_ref - v)`` tracks a
stance-constrained reference (`StanceSynergyReference`), the configuration error taken on
the group (``pinocchio.difference``). The QP has ``nv + 3P`` variables, ``6 + rows(J_c)``
equalities and ``5P + n`` inequalities; it is dense and rebuilt each tick.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import ClassVar

import numpy as np
import pinocchio as pin
import proxsuite

from geosyn.controllers.base import FRICTION_VELOCITY, Controller, check_gain
from geosyn.controllers.errors import ControllerError
from geosyn.controllers.reference import Reference
from geosyn.core.types import Matrix, Vector
from geosyn.core.validation import check_positive
from geosyn.robots.robot import Robot

__all__ = ["WholeBodyController"]

_INF = 1e20  # proxsuite's "no bound"
_LOCAL = pin.ReferenceFrame.LOCAL
_ALIGNED = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED


def _skew(p: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -p[2], p[1]], [p[2], 0.0, -p[0]], [-p[1], p[0], 0.0]])


class WholeBodyController(Controller):
    """Inverse-dynamics QP with contact forces, friction pyramids and torque limits.

    Args:
        robot: a floating-base robot (`Robot.floating`); a fixed-base robot is refused.
        contacts: names of the contact frames (feet) held on the ground.
        points: (P, 3) contact points in each contact frame [m]; 3 or more points make a
            sole (the frame's 6-D motion is held), one point a point foot (3-D).
        reference: the stance-constrained reference (``sample`` gives ``q`` (nq,)).
        kp: configuration gain [1/s^2], scalar or (nv,).
        kd: velocity gain [1/s], scalar or (nv,).
        weights: task weights W, scalar or (nv,) (base twist first, then joints).
        mu: friction coefficient of the pyramids (use a margin below the real one).
        f_min: smallest normal force per point [N] (keeps every point loaded).
        contact_gain: ``k_c`` [1/s], damps the held frames' measured velocity.
        force_regularisation: ``epsilon`` [(m/s^2)^2 / N^2].
        compensate_friction: add the file's joint dry friction ``f_c tanh(v_c / v_s)``
            to ``h`` (MuJoCo applies it to the plant), in the direction of the corrected
            velocity ``v_c = v_ref + (K_p / K_d) (q_ref - q)`` so that a joint held by its
            friction is still pulled back to the reference. The viscous damping ``D v`` is
            left to the feedback: fed forward from the measured velocity at 1 kHz it
            destabilises light joints (``D dt / I > 2`` on TALOS's grippers).
        friction_velocity: ``v_s`` [rad/s or m/s], the dry friction's smoothing speed.

    Attributes:
        forces: (P_total, 3) contact forces of the last solve, world axes [N], foot by
            foot in ``contacts`` order, points in ``points`` order.
        acceleration: (nv,) the last solve's acceleration [m/s^2, rad/s^2].

    Diagnostics (``diagnostics.extra``): ``min_normal_force`` [N], ``max_friction_ratio``
    (|f_t| / f_z over the points), ``total_normal_force`` [N], the QP residuals. A QP
    that proxsuite does not solve sets ``solver_status`` and returns the last solved
    torque (``fallback_used``).
    """

    accepts_floating_base: ClassVar[bool] = True

    def __init__(
        self,
        robot: Robot,
        contacts: Sequence[str],
        points: Matrix,
        reference: Reference | None = None,
        *,
        kp: float | Vector = 100.0,
        kd: float | Vector = 20.0,
        weights: float | Vector = 1.0,
        mu: float = 0.6,
        f_min: float = 1.0,
        contact_gain: float = 10.0,
        force_regularisation: float = 1e-6,
        compensate_friction: bool = True,
        friction_velocity: float = FRICTION_VELOCITY,
    ) -> None:
        if not isinstance(robot, Robot) or not robot.floating:
            what = robot.name if isinstance(robot, Robot) else type(robot).__name__
            raise ControllerError(
                f"WholeBodyController needs a floating-base robot, got {what!r}; fixed-base"
                " robots take QPController or ComputedTorque"
            )
        super().__init__(robot, None)
        contacts = [contacts] if isinstance(contacts, str) else list(contacts)
        if not contacts:
            raise ControllerError("contacts must name at least one contact frame")
        self.contacts = tuple(contacts)
        self._fids = [robot.frame_id(c) for c in contacts]  # UnknownFrame lists them
        pts = np.asarray(points, dtype=np.float64)
        if pts.ndim != 2 or pts.shape[1] != 3 or pts.shape[0] not in (1, 3, 4, 5, 6, 7, 8):
            raise ControllerError(f"points must have shape (P, 3), P = 1 or 3..8; got {pts.shape}")
        self.points = pts
        self._sole = pts.shape[0] >= 3
        nv = self.nv
        self.kp = check_gain(kp, nv, "kp")
        self.kd = check_gain(kd, nv, "kd")
        self.weights = check_gain(weights, nv, "weights")
        self.mu = check_positive(mu, "mu")
        self.f_min = float(check_gain(f_min, 1, "f_min")[0])
        self.contact_gain = float(check_gain(contact_gain, 1, "contact_gain")[0])
        self.force_regularisation = check_positive(force_regularisation, "force_regularisation")
        self.compensate_friction = bool(compensate_friction)
        self.friction_velocity = check_positive(friction_velocity, "friction_velocity")
        self._friction = np.asarray(robot.frictionloss, dtype=np.float64)
        self.n_points = len(contacts) * pts.shape[0]
        nf = 3 * self.n_points
        rows_c = (6 if self._sole else 3) * len(contacts)
        self._nx, self._neq, self._nin = nv + nf, 6 + rows_c, 5 * self.n_points + nv - 6
        self._H = np.diag(np.concatenate([self.weights, np.full(nf, self.force_regularisation)]))
        self._C = np.zeros((self._nin, self._nx))
        self._l = np.full(self._nin, -_INF)
        self._u = np.zeros(self._nin)
        for i in range(self.n_points):  # friction pyramid rows, constant in f
            r, c = 5 * i, nv + 3 * i
            self._C[r : r + 4, c : c + 2] = [[1, 0], [-1, 0], [0, 1], [0, -1]]
            self._C[r : r + 4, c + 2] = -self.mu
            self._C[r + 4, c + 2] = 1.0
            self._l[r + 4], self._u[r + 4] = self.f_min, _INF
        self.qp = proxsuite.proxqp.dense.QP(self._nx, self._neq, self._nin)
        s = self.qp.settings
        s.eps_abs, s.eps_rel, s.max_iter, s.verbose = 1e-8, 0.0, 1000, False
        self._initialised = False
        self._tau_last = np.zeros(nv)
        self.forces = np.zeros((self.n_points, 3))
        self.acceleration = np.zeros(nv)
        if reference is not None:
            self.set_reference(reference)

    # -- one tick -----------------------------------------------------------------------
    def _matrices(self, q: Vector, v: Vector) -> tuple[Matrix, Vector, Matrix, Vector, Matrix]:
        """``(M, h, J_c, Jdot_c v, J_p)`` at (q, v)."""
        model, data = self._model, self._data
        pin.forwardKinematics(model, data, q, v, np.zeros(self.nv))
        pin.computeJointJacobians(model, data, q)
        pin.updateFramePlacements(model, data)
        Jc, bias, Jp = [], [], []
        for fid in self._fids:
            Jw = pin.getFrameJacobian(model, data, fid, _ALIGNED)
            if self._sole:  # the sole's 6-D motion, local frame
                Jc.append(pin.getFrameJacobian(model, data, fid, _LOCAL))
                bias.append(pin.getFrameAcceleration(model, data, fid, _LOCAL).vector)
            else:  # the point's linear motion, world axes (classical acceleration)
                Jc.append(Jw[:3])
                bias.append(pin.getFrameClassicalAcceleration(model, data, fid, _ALIGNED).linear)
            R = data.oMf[fid].rotation
            Jp += [Jw[:3] - _skew(R @ p) @ Jw[3:] for p in self.points]
        M = pin.crba(model, data, q)
        M = np.triu(M) + np.triu(M, 1).T
        h = pin.nonLinearEffects(model, data, q, v)
        return M, h, np.vstack(Jc), np.concatenate(bias), np.vstack(Jp)

    def _compute(self, t: float, q: Vector, v: Vector) -> Vector:
        if self._reference is None:  # the base class checks first; for mypy
            raise ControllerError("no reference")
        nv, d = self.nv, self.diagnostics
        q_ref, v_ref, a_ref = self._reference.sample(t)
        error = pin.difference(self._model, q, q_ref)
        a_star = a_ref + self.kp * error + self.kd * (v_ref - v)
        M, h, Jc, bias, Jp = self._matrices(q, v)
        if self.compensate_friction:  # the plant's joint friction joins the bias torques
            v_c = v_ref + self.kp / np.maximum(self.kd, 1e-9) * error
            h = h + self._friction * np.tanh(v_c / self.friction_velocity)
        JpT = Jp.T
        A = np.zeros((self._neq, self._nx))
        A[:6, :nv], A[:6, nv:] = M[:6], -JpT[:6]
        A[6:, :nv] = Jc
        b = np.concatenate([-h[:6], -bias - self.contact_gain * (Jc @ v)])
        C, lo, up = self._C, self._l, self._u
        k = 5 * self.n_points
        C[k:, :nv], C[k:, nv:] = M[6:], -JpT[6:]
        lo[k:] = -self._tau_max[6:] - h[6:]
        up[k:] = self._tau_max[6:] - h[6:]
        g = np.concatenate([-self.weights * a_star, np.zeros(3 * self.n_points)])
        qp = self.qp
        if not self._initialised:
            qp.init(self._H, g, A, b, C, lo, up)
            self._initialised = True
        else:
            qp.settings.initial_guess = (
                proxsuite.proxqp.InitialGuess.WARM_START_WITH_PREVIOUS_RESULT
            )
            qp.update(g=g, A=A, b=b, C=C, l=lo, u=up)
        qp.solve()
        info = qp.results.info
        d.iterations = int(info.iter)
        if info.status.name != "PROXQP_SOLVED":
            d.solver_status = "failed" if "MAX_ITER" not in info.status.name else "max_iter"
            d.fallback_used = True
            return self._tau_last.copy()
        x = qp.results.x
        a, f = x[:nv], x[nv:]
        tau = M @ a + h - JpT @ f
        tau[:6] = 0.0  # zero to the QP's tolerance: the base is not actuated
        self.forces = f.reshape(-1, 3).copy()
        self.acceleration = a.copy()
        fz = self.forces[:, 2]
        d.extra["min_normal_force"] = float(fz.min())
        d.extra["total_normal_force"] = float(fz.sum())
        d.extra["max_friction_ratio"] = float(
            (np.linalg.norm(self.forces[:, :2], axis=1) / np.maximum(fz, 1e-12)).max()
        )
        d.extra["primal_residual"] = float(info.pri_res)
        d.extra["dual_residual"] = float(info.dua_res)
        self._tau_last = tau
        return tau

    def _on_reset(self, q: Vector, v: Vector, t: float) -> None:
        self._initialised = False
        self._tau_last = np.zeros(self.nv)
