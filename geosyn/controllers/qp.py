"""Inverse-dynamics QP with torque, joint-position and joint-velocity limits (proxsuite)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import pinocchio as pin
import proxsuite

from geosyn.controllers.base import FRICTION_VELOCITY
from geosyn.controllers.computed_torque import ComputedTorque
from geosyn.controllers.limit_bounds import AccelerationBounds, check_braking_acceleration
from geosyn.controllers.reference import Reference
from geosyn.core.errors import InvalidArgument
from geosyn.core.types import Vector
from geosyn.core.validation import check_float, check_int
from geosyn.robots.robot import Robot

if TYPE_CHECKING:
    from geosyn.metrics.base import Metric

_STATUS = {
    "PROXQP_SOLVED": "ok",
    "PROXQP_MAX_ITER_REACHED": "max_iter",
    "PROXQP_PRIMAL_INFEASIBLE": "infeasible",
    "PROXQP_SOLVED_CLOSEST_PRIMAL_FEASIBLE": "infeasible",
    "PROXQP_DUAL_INFEASIBLE": "dual_infeasible",
    "PROXQP_NOT_RUN": "failed",
}

MIN_DT = 1e-6
"""Shortest control period [s] (a 1 MHz loop; the constraints divide by ``dt**2``)."""
MAX_DT = 1.0
"""Longest control period [s] the QP accepts (its constraints look one period ahead)."""
MAX_HORIZON = 10.0
"""Longest ``position_horizon`` [s]."""
MAX_EPS = 1e6
"""Largest torque regularisation weight ``eps``."""
MIN_EPS_ABS = 1e-15
"""Smallest proxsuite tolerance ``eps_abs`` (below float64 resolution of the torques)."""
MAX_ITER = 1000
"""Largest ``max_iter`` and ``max_inner_iter`` (10,000 outer iterations of one inner
iteration each cost 150 ms of CPU per tick)."""
MAX_INNER_ITERATIONS = 10_000
"""Largest ``max_iter * max_inner_iter``: proxsuite has no wall-time limit, and about a
million inner iterations took 8 s. At this bound (three times the default 100 * 30) the
worst tick of the Panda under velocity noise with an unreachable ``eps_abs`` costs about
40 ms of CPU (1000 * 10; measured, ``benchmarks/RESULTS.md``)."""


class QPController(ComputedTorque):
    """Inverse-dynamics QP over ``x = (qdd, tau)`` (2 nv variables), solved by proxsuite.

    The computed-torque law (`ComputedTorque`) under torque, position and velocity limits:
    its desired acceleration is the QP's target, and its torque the fallback.

    .. math::
        \\min_{\\ddot q, \\tau}\\; \\|\\ddot q - \\ddot q_d\\|^2 + \\epsilon \\|\\tau\\|^2
        \\quad \\text{s.t.}\\quad M(q)\\ddot q - \\tau = -h(q, \\dot q),\\;
        -\\tau_{max} \\le \\tau \\le \\tau_{max},\\; \\ddot q_{lo} \\le \\ddot q \\le \\ddot q_{hi}

    with ``h = C(q, v) v + g(q)`` and the computed-torque acceleration
    ``qdd_d = a_ref + Kd (v_ref - v) + Kp (q_ref - q)``. All inequalities are boxes on
    ``x`` (proxsuite's box constraints). The acceleration box intersects, per joint:

    - velocity limits one step ahead: ``|v + qdd dt| <= v_max``;
    - position limits ``position_horizon`` ahead:
      ``q_min <= q + v T + 1/2 qdd T^2 <= q_max`` (``T = dt`` by default);
    - with ``braking_acceleration`` ``b`` (horizon-aware braking): the next velocity
      stays under the braking curve, ``v + qdd dt <= sqrt(2 b (q_max - q - v dt))`` and
      symmetrically at ``q_min``, so the joint can always stop before the limit with
      deceleration ``b``. Recommended whenever the reference may hit a limit.

    The QP is built and ``init``-ed once in the constructor (again by `reset`, at the
    reset state); each tick writes ``M``,
    ``h`` and the bounds into preallocated arrays, calls ``update`` and solves warm-started
    from the previous result. When the acceleration box is empty (detected before the
    solve) or proxsuite does not report ``PROXQP_SOLVED``, the controller returns the
    computed-torque law ``M qdd_d + h`` (clipped to the torque limits by `compute`),
    sets ``diagnostics.fallback_used`` and records the status.

    Limitation: the kinematic limits are imposed one step (or ``position_horizon``)
    ahead, which does not guarantee viability. From a state where the torque limits
    cannot keep every joint within its velocity or braking bound (e.g. several joints at
    ``v_max`` with large Coriolis torques under very high gains) the QP is infeasible and
    the fallback is taken, flagged. Moderate gains and a ``braking_acceleration`` below
    the deceleration the motors can deliver keep the robot in the viable region.

    Args:
        robot: the robot (dynamics, limits ``q_min, q_max, v_max, tau_max``).
        kp: position gain, scalar or (nv,) [1/s^2], >= 0.
        kd: velocity gain, scalar or (nv,) [1/s], >= 0.
        dt: control period [s], in [`MIN_DT`, `MAX_DT`].
        eps: torque regularisation weight [(rad/s^2)^2 / (N m)^2], in (0, `MAX_EPS`].
        position_horizon: look-ahead of the position constraint [s], in [dt,
            `MAX_HORIZON`]; None for dt.
        braking_acceleration: optional scalar or (nv,) deceleration [rad/s^2] of the
            braking-curve constraint; None disables it.
        eps_abs: proxsuite absolute tolerance (primal and dual residuals), in
            [`MIN_EPS_ABS`, 1].
        max_iter: proxsuite outer-iteration limit per tick, in [1, `MAX_ITER`]; with
            ``max_inner_iter``, ``max_iter * max_inner_iter <= MAX_INNER_ITERATIONS``.
        max_inner_iter: proxsuite inner-iteration limit per outer iteration
            (``max_iter_in``). Together they bound one tick's solve to ``max_iter *
            max_inner_iter`` inner iterations: proxsuite has no wall-time limit, and with
            its defaults (1500 per outer iteration) one tick under velocity noise took
            8 s and a million iterations. A solve that hits the bound falls back, flagged
            (``solver_status = "max_iter"``).
        metric: optional metric used only for reference generation and replanning.
        reference: optional reference to track.
        compensate_friction, friction_velocity: joint friction in the bias torques, as
            for `ComputedTorque`.

    Attributes:
        qp: the proxsuite ``dense.QP`` (its ``results`` hold the last solve).

    ``compute`` allocates only small temporaries (reference sample, Pinocchio results).
    """

    def __init__(
        self,
        robot: Robot,
        kp: float | np.ndarray,
        kd: float | np.ndarray,
        dt: float,
        *,
        eps: float = 1e-6,
        position_horizon: float | None = None,
        braking_acceleration: float | np.ndarray | None = None,
        eps_abs: float = 1e-7,
        max_iter: int = 100,
        max_inner_iter: int = 30,
        metric: Metric | None = None,
        reference: Reference | None = None,
        compensate_friction: bool | None = None,
        friction_velocity: float = FRICTION_VELOCITY,
    ) -> None:
        super().__init__(
            robot,
            kp,
            kd,
            metric,
            reference,
            compensate_friction=compensate_friction,
            friction_velocity=friction_velocity,
        )
        n = self.nv
        self.dt = check_float(dt, "dt", low=MIN_DT, high=MAX_DT, unit="s")
        self.eps = check_float(eps, "eps", low=0.0, high=MAX_EPS, low_open=True)
        horizon = (
            self.dt
            if position_horizon is None
            else check_float(
                position_horizon, "position_horizon", low=0.0, high=MAX_HORIZON, low_open=True
            )
        )
        if horizon < self.dt:
            raise InvalidArgument(f"position_horizon must be >= dt={self.dt} [s], got {horizon}")
        self.position_horizon = horizon
        self.braking_acceleration = check_braking_acceleration(braking_acceleration, n)
        self.eps_abs = check_float(eps_abs, "eps_abs", low=MIN_EPS_ABS, high=1.0)
        self.max_iter = check_int(max_iter, "max_iter", low=1, high=MAX_ITER)
        self.max_inner_iter = check_int(max_inner_iter, "max_inner_iter", low=1, high=MAX_ITER)
        if self.max_iter * self.max_inner_iter > MAX_INNER_ITERATIONS:
            raise InvalidArgument(
                f"max_iter * max_inner_iter must be <= {MAX_INNER_ITERATIONS} (one tick's"
                f" bound on proxsuite's inner iterations), got {self.max_iter} *"
                f" {self.max_inner_iter} = {self.max_iter * self.max_inner_iter}"
            )
        # The acceleration box (`geosyn.controllers.limit_bounds`, shared with the MPC's
        # joint-limit guard); its q_max is a view (tests move a limit through it).
        self._bounds = AccelerationBounds(
            robot.q_min, robot.q_max, robot.v_max, horizon, self.braking_acceleration
        )
        self._q_max = self._bounds.q_max
        self._zero = np.zeros(n)
        # Preallocated QP data.
        self._H = np.zeros((2 * n, 2 * n))
        self._H[:n, :n] = 2.0 * np.eye(n)
        self._H[n:, n:] = 2.0 * self.eps * np.eye(n)
        self._g = np.zeros(2 * n)
        self._A = np.zeros((n, 2 * n))
        self._A[:, n:] = -np.eye(n)
        self._b = np.zeros(n)
        self._lbox = np.zeros(2 * n)
        self._ubox = np.zeros(2 * n)
        self._lbox[n:] = -self._tau_max
        self._ubox[n:] = self._tau_max
        self.qp = proxsuite.proxqp.dense.QP(2 * n, n, 0, True)
        self._warm = False
        # init once here (at the neutral configuration); reset() re-inits at its state.
        self._fill(robot.neutral(), np.zeros(n))
        self._init_qp()

    # -- building -----------------------------------------------------------------------
    def _fill(self, q: Vector, v: Vector) -> None:
        """Write M, h and the bounds at (q, v) into the preallocated arrays."""
        n = self.nv
        model, data = self._model, self._data
        self._A[:, :n] = pin.crba(model, data, q)
        np.negative(pin.rnea(model, data, q, v, self._zero), out=self._b)
        if self.compensate_friction:  # joint friction joins the bias torques
            self._b -= self.joint_friction(v, self._v_ref)
        bounds = self._bounds
        bounds.update(q, v, self.dt)
        self._ubox[:n] = bounds.upper
        self._lbox[:n] = bounds.lower

    def _init_qp(self) -> None:
        s = self.qp.settings
        s.eps_abs = self.eps_abs
        s.eps_rel = 0.0
        s.max_iter = self.max_iter
        s.max_iter_in = self.max_inner_iter
        s.verbose = False
        s.initial_guess = proxsuite.proxqp.InitialGuess.EQUALITY_CONSTRAINED_INITIAL_GUESS
        self.qp.init(self._H, self._g, self._A, self._b, None, None, None, self._lbox, self._ubox)
        self._warm = False
        self._guess_is_warm = False

    def _on_reset(self, q: Vector, v: Vector, t: float) -> None:
        self._fill(q, v)
        self._init_qp()

    # -- control ----------------------------------------------------------------------
    def _compute(self, t: float, q: Vector, v: Vector) -> Vector:
        n = self.nv
        a_des = self.desired_acceleration(t, q, v)
        self._fill(q, v)
        np.multiply(a_des, -2.0, out=self._g[:n])
        d = self.diagnostics
        if np.any(self._lbox[:n] > self._ubox[:n]):
            d.solver_status = "infeasible"
            d.extra["empty_acceleration_box"] = 1.0
            return self._fallback(a_des)
        qp = self.qp
        if self._warm != self._guess_is_warm:
            # Warm start from the previous result only when that result was a solution.
            qp.settings.initial_guess = (
                proxsuite.proxqp.InitialGuess.WARM_START_WITH_PREVIOUS_RESULT
                if self._warm
                else proxsuite.proxqp.InitialGuess.EQUALITY_CONSTRAINED_INITIAL_GUESS
            )
            self._guess_is_warm = self._warm
        qp.update(g=self._g, A=self._A, b=self._b, l_box=self._lbox, u_box=self._ubox)
        qp.solve()
        info = qp.results.info
        d.iterations = int(info.iter)
        status = _STATUS.get(info.status.name, "failed")
        if status != "ok":
            d.solver_status = status
            self._warm = False
            return self._fallback(a_des)
        self._warm = True
        d.extra["primal_residual"] = float(info.pri_res)
        d.extra["dual_residual"] = float(info.dua_res)
        return qp.results.x[n:].copy()

    def _fallback(self, a_des: Vector) -> Vector:
        self.diagnostics.fallback_used = True
        return self._b * -1.0 + self._A[:, : self.nv] @ a_des
