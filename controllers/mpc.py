"""Geodesic-tracking model predictive control: a CasADi OCP solved by fatrop or IPOPT.

`GeodesicMPC` solves, every ``dt`` seconds, a multiple-shooting optimal control problem
over ``horizon`` stages with states ``x = (q, v)`` and either torque or acceleration
controls, and applies the first stage of the plan between solves with a PD on the planned
state (see `GeodesicMPC`). The problem is built once; each solve only sets parameters
(the measured state and the reference samples) and the shifted previous solution.

Speed. The per-stage dynamics (RK4 on the recursive ABA, or the recursive RNEA in
acceleration mode) dominate the cost of an interior-point iteration when their exact
second derivatives are used: for the panda an exact Lagrangian Hessian costs ~0.1-0.3 s
per iteration on CasADi's VM. With ``hessian="gauss-newton"`` (default) those functions
are compiled to C together with their Jacobian and a *structurally zero* second
derivative (CasADi picks up ``jac_F`` and ``jac_jac_F`` from the same library), so the
Lagrangian Hessian keeps only the cost's own curvature: a generalised Gauss-Newton
Hessian, exact for the quadratic tracking costs. The whole NLP is never JIT-compiled
(a gcc run on the full NLP takes minutes); only these small per-stage functions are,
and they are cached on disk (see `geosyn.core.codegen`). The NLP is an MX graph with
one mapped call per stage function (so each Jacobian is evaluated once per stage); with
``hessian="exact"`` it is a plain SX graph instead.

Measured on panda (N = 40, dt = 20 ms, 1 kHz closed loop, loaded 2-core machine; see
``benchmarks/controllers.py``): ``control="acceleration", effort="acceleration"`` is the
fast configuration (~3 warm-started fatrop iterations of ~2-3 ms each, dominated by the
RNEA Jacobians and CasADi's graph evaluation); torque control (RK4 on the ABA) costs ~4x
more per iteration because of the Jacobian of the RK4 step (~100 us per stage) and takes
~40 s to compile the first time.

fatrop ignores the multipliers passed as a warm start (tested: identical iterations); they
are still shifted and passed, which IPOPT uses with ``warm_start_init_point``.
"""

from __future__ import annotations

import hashlib
import math
import os
import shutil
import subprocess
import tempfile
import time
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any, NamedTuple, TypeVar

import casadi as ca
import numpy as np
import pinocchio as pin

from geosyn.controllers.base import Controller, check_gain
from geosyn.controllers.errors import ControllerError, SolverFailed
from geosyn.controllers.reference import Reference
from geosyn.core.codegen import CodegenError, default_cache_dir, find_compiler
from geosyn.core.errors import InvalidArgument
from geosyn.core.types import Vector
from geosyn.core.validation import check_vector
from geosyn.metrics.base import Metric, sx_cholesky_solve
from geosyn.robots.robot import Robot

__all__ = ["GeodesicMPC", "MPCPlan", "OpenLoopSolution", "SOLVERS"]

SOLVERS = ("fatrop", "ipopt")
"""Names accepted by ``GeodesicMPC(solver=...)``."""
EFFORTS = ("torque", "metric", "acceleration")
CONTROLS = ("torque", "acceleration")
HESSIANS = ("gauss-newton", "exact")

_EPS_T = 1e-9  # [s] slack when comparing clock times
# Default effort weights: [1/(N m)^2] for torque and metric efforts, [s^4/rad^2] for the
# acceleration effort (tuned on panda: tracking error ~1e-3 rad, ~3 warm iterations).
_DEFAULT_EFFORT_WEIGHT = {"torque": 1e-3, "metric": 1e-3, "acceleration": 1e-2}

# The symbol type of an NLP graph: SX (exact Hessian) or MX (Gauss-Newton, naive).
_Sym = TypeVar("_Sym", ca.SX, ca.MX)


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
    """

    t: float
    x: np.ndarray
    u: np.ndarray
    tau: np.ndarray
    status: str
    iterations: int
    success: bool
    solve_time: float


class OpenLoopSolution(NamedTuple):
    """Result of `GeodesicMPC.solve_open_loop`.

    Attributes:
        t: (N+1,) stage times from 0 [s].
        q: (N+1, nv) joint positions [rad].
        v: (N+1, nv) joint velocities [rad/s].
        tau: (N, nv) torques [N m].
        cost: optimal cost (sum over stages of the metric effort).
        status: solver status string.
        iterations: solver iterations.
        success: the solver reported success.
    """

    t: np.ndarray
    q: np.ndarray
    v: np.ndarray
    tau: np.ndarray
    cost: float
    status: str
    iterations: int
    success: bool


# -- compiled per-stage functions with a zero second derivative ------------------------
def _sx_copy(fun: ca.Function, name: str) -> ca.Function:
    """An SX function evaluating ``fun`` under a new name (for code generation)."""
    ins = [ca.SX.sym(fun.name_in(i), fun.sparsity_in(i)) for i in range(fun.n_in())]
    return ca.Function(name, ins, fun.call(ins), fun.name_in(), fun.name_out(), {"cse": True})


def _first_order_jacobian(fun: ca.Function, name: str) -> ca.Function:
    """The Jacobian of a derivative function ``fun`` with its second-order part dropped.

    Blocks with respect to the seed inputs (named ``adj_*``/``fwd_*``; the derivative is
    linear in them) are kept exactly; blocks with respect to the nominal inputs (second
    derivatives of the original function) are structurally zero.
    """
    jj = fun.jacobian()
    ins = [ca.SX.sym(jj.name_in(i), jj.sparsity_in(i)) for i in range(jj.n_in())]
    full = jj.call(ins)
    seeds = {
        fun.name_in(i) for i in range(fun.n_in()) if fun.name_in(i).startswith(("adj_", "fwd_"))
    }
    outs = []
    for i in range(jj.n_out()):
        name_out = jj.name_out(i)  # "jac_<out>_<in>"
        keep = any(name_out.endswith("_" + s_) for s_ in seeds)
        sp = jj.sparsity_out(i)
        outs.append(full[i] if keep else ca.SX(sp.size1(), sp.size2()))
    return ca.Function(name, ins, outs, jj.name_in(), jj.name_out())


def _zero_second_derivative_library(funs: list[ca.Function], tag: str) -> dict[str, ca.Function]:
    """Compile SX functions with their Jacobians and a structurally zero ``jac_jac_*``.

    CasADi's ``external`` uses ``jac_<name>`` for first derivatives and ``jac_jac_<name>``
    for the derivative of the Jacobian; declaring the latter empty removes the function's
    curvature from every Hessian built from it (Gauss-Newton). One shared library per
    set of functions, cached on disk by a hash of the generated C code.

    Raises:
        CodegenError: no compiler, or compiling/loading failed.
    """
    gen = ca.CodeGenerator(f"{tag}.c", {"with_header": False})
    for f in funs:
        jac = _sx_copy(f.jacobian(), f"jac_{f.name()}")
        gen.add(f)
        gen.add(jac)
        gen.add(_first_order_jacobian(jac, f"jac_jac_{f.name()}"))
        # Also adding adj1_<name> with a first-order-only Jacobian removes the dynamics
        # from the Hessian graph, but measured: < 10 % faster solves for a larger compile.
    source = gen.dump()
    cc = find_compiler()
    if cc is None:
        raise CodegenError("no C compiler found: neither 'gcc' nor 'cc' is on PATH")
    # -O2 for small sources; the RK4/ABA Jacobian (megabytes of straight-line code) takes
    # minutes at -O2 and gains little over -O1.
    flags = ("-O2",) if len(source) < 500_000 else ("-O1",)
    key = hashlib.sha256("\0".join([source, cc, *flags]).encode()).hexdigest()[:24]
    cache = default_cache_dir()
    library = cache / f"{tag}_{key}.so"
    if not library.is_file():
        cache.mkdir(parents=True, exist_ok=True)
        work = Path(tempfile.mkdtemp(prefix="geosyn-mpc-", dir=cache))
        try:
            c_file = work / f"{tag}.c"
            c_file.write_text(source)
            built = work / f"{tag}.so"
            cmd = [cc, *flags, "-shared", "-fPIC", "-o", str(built), str(c_file), "-lm"]
            done = subprocess.run(cmd, capture_output=True, text=True, check=False)
            if done.returncode != 0 or not built.is_file():
                raise CodegenError(
                    f"compiling {tag} failed ({done.returncode}): {done.stderr[-2000:]}",
                    command=cmd,
                    returncode=done.returncode,
                    stderr=done.stderr,
                )
            os.replace(built, library)
        finally:
            shutil.rmtree(work, ignore_errors=True)
    try:
        return {f.name(): ca.external(f.name(), str(library)) for f in funs}
    except RuntimeError as err:
        raise CodegenError(f"could not load {library}: {err}") from err


@dataclass
class _NLP:
    """A built solver and the index bookkeeping of its decision and constraint vectors."""

    solver: ca.Function
    solver_cold: ca.Function | None
    N: int
    n: int
    lbx: np.ndarray
    ubx: np.ndarray
    lbg: np.ndarray
    ubg: np.ndarray
    g_blocks: list[np.ndarray]  # per stage, indices into g (stage 0 includes the init block)
    tau_fn: ca.Function  # (x, u) -> tau, numeric evaluation of planned torques

    def cold(self) -> ca.Function:
        """The cold-start solver.

        Raises:
            ControllerError: this build has none (the naive benchmark build).
        """
        if self.solver_cold is None:
            raise ControllerError(
                "this MPC build has no cold-start solver (the naive IPOPT benchmark build "
                "is solved with its only solver, `solver`)"
            )
        return self.solver_cold


def _choice(x: object, allowed: tuple[str, ...], name: str) -> str:
    if not isinstance(x, str) or x not in allowed:
        raise InvalidArgument(f"{name} {x!r} is not supported; allowed: {', '.join(allowed)}")
    return x


class GeodesicMPC(Controller):
    """Geodesic-tracking MPC: a multiple-shooting OCP in CasADi, solved by fatrop or IPOPT.

    The OCP over ``N = horizon`` stages of length ``dt``, solved at time ``t`` from the
    measured state ``(q_m, v_m)``, with the reference sampled at ``t_k = t + k dt``:

    .. math::
        \\min_{x, u} \\sum_{k=0}^{N-1} \\|q_k - q^r_k\\|^2_{W_q} + \\|v_k - v^r_k\\|^2_{W_v}
            + \\ell(x_k, u_k) + \\|x_N - x^r_N\\|^2_{W_N}

    subject to ``x_0 = (q_m, v_m)``, ``x_{k+1} = F(x_k, u_k)`` (RK4, ``rk4_steps`` steps
    per stage, on ``qdd = ABA(q, v, tau)`` with gravity when ``control="torque"``; the
    exact double integrator with ``tau = RNEA(q, v, u)`` when ``control="acceleration"``),
    ``|tau_k| <= tau_max``, ``q_min <= q_k <= q_max`` and ``|v_k| <= v_max`` for k >= 1.
    Defaults: ``control="acceleration"`` with ``effort="acceleration"``, the configuration
    that meets the 10 ms median / 20 ms p99 per-solve budget on panda (N = 40); torque
    control (RK4 on the ABA) is ~5x slower per solve (see benchmarks/RESULTS.md).

    The effort ``ell`` is

    - ``effort="torque"``: ``w_tau |tau_k - tau^r_k|^2`` with ``tau^r`` the inverse
      dynamics of the reference (so perfect tracking costs nothing);
    - ``effort="acceleration"`` (acceleration control only): ``w_tau |u_k - a^r_k|^2``, a
      quadratic regulariser towards the reference acceleration; the torque then enters
      only the limits, which keeps the Hessian cheap (the fastest configuration);
    - ``effort="metric"``: ``w_tau (tau_k - g(q_k))^T G(q_k)^{-1} (tau_k - g(q_k))``, the
      squared Riemannian norm of the covariant acceleration ``D v / dt`` (for the kinetic
      energy metric ``G = M``: ``M qdd + C v``). ``M^{-1}`` is applied by the ABA with zero
      velocity, never by a symbolic inverse. Without gravity and constraints its minimisers
      between fixed end points are geodesics (zero cost): see `solve_open_loop`.

    Between solves (the controller re-solves when ``t`` has advanced by at least ``dt``
    since the last solve) the plan is tracked as

    .. math::
        \\tau = u^*_j + M(q) (K_p (q^*(t) - q) + K_d (v^*(t) - v))

    (torque control), or ``tau = RNEA(q, v, u^*_j + K_p (q^* - q) + K_d (v^* - v))``
    (acceleration control), with ``(q^*, v^*)`` the cubic Hermite interpolation of the
    planned states: a zero-order hold of the first control plus a feedback that keeps the
    plant on the plan despite model or integration error.

    A failed solve (solver status not successful, an exception, non-finite numbers) is
    flagged in `diagnostics` (``fallback_used``, ``solver_status``, ``iterations``) and
    falls back to the previous plan, if it still covers ``t`` and the measured state is
    within ``plan_tolerance`` of it, else to a computed torque on the reference (clipped
    to the limits by `Controller.compute`).

    Args:
        robot: the robot (its model is the OCP's dynamics).
        metric: the metric of the geodesic reference; weighs the ``"metric"`` effort.
        horizon: number of stages N (>= 1).
        dt: stage length and re-solve period [s] (> 0).
        solver: ``"fatrop"`` or ``"ipopt"``.
        q_weight: scalar or (nv,) weight on the position error [1/rad^2].
        v_weight: scalar or (nv,) weight on the velocity error [s^2/rad^2].
        tau_weight: scalar or (nv,) effort weight: [1/(N m)^2] for the torque and metric
            efforts (the metric effort uses its first entry, a scalar weight on the
            Riemannian norm), [s^4/rad^2] for the acceleration effort. None: 1e-3, 1e-3
            and 1e-2 respectively.
        terminal_weight: scalar or (2 nv,) weight on the terminal state error (q then v).
        effort: ``"torque"``, ``"metric"`` or ``"acceleration"``; None picks
            ``"acceleration"`` with acceleration control and ``"torque"`` with torque control.
        control: ``"torque"`` or ``"acceleration"``.
        rk4_steps: RK4 steps per stage (torque control), 1 or 2.
        hessian: ``"gauss-newton"`` (compiled per-stage dynamics without second
            derivatives; falls back to ``"exact"`` with a warning without a C compiler) or
            ``"exact"`` (exact Hessian of an SX graph on CasADi's VM).
        kp: scalar or (nv,) plan-tracking stiffness [1/s^2].
        kd: scalar or (nv,) plan-tracking damping [1/s].
        max_iter: solver iteration limit per tick.
        tol: solver tolerance.
        mu_init: initial barrier parameter of cold solves; warm solves use ``mu_warm``.
        mu_warm: initial barrier parameter of warm-started solves.
        plan_tolerance: max joint deviation [rad] for reusing the previous plan as fallback.
        solver_options: extra options for the solver plugin (fatrop or ipopt options), e.g.
            ``{"max_iter": 1}``; unknown keys are rejected by the plugin at build time.
        reference: optional reference.

    Raises:
        InvalidArgument: a bad argument (the message names it and lists what is allowed).

    The constructor builds the solvers (allocates; seconds, a minute on first use when the
    compiled dynamics are not cached yet); `compute` allocates only small arrays.
    """

    def __init__(
        self,
        robot: Robot,
        metric: Metric,
        horizon: int = 40,
        dt: float = 0.02,
        *,
        solver: str = "fatrop",
        q_weight: float | np.ndarray = 1e4,
        v_weight: float | np.ndarray = 1e1,
        tau_weight: float | np.ndarray | None = None,
        terminal_weight: float | np.ndarray = 1e5,
        effort: str | None = None,
        control: str = "acceleration",
        rk4_steps: int = 1,
        hessian: str = "gauss-newton",
        kp: float | np.ndarray = 400.0,
        kd: float | np.ndarray = 40.0,
        max_iter: int = 50,
        tol: float = 1e-6,
        mu_init: float = 1e-1,
        mu_warm: float = 1e-8,
        plan_tolerance: float = 0.05,
        solver_options: dict | None = None,
        reference: Reference | None = None,
    ) -> None:
        super().__init__(robot, None)
        n = self.nv
        if not isinstance(metric, Metric) or metric.n != n:
            raise InvalidArgument(
                f"metric must be a geosyn Metric of dimension nv={n}, got {metric!r}"
            )
        if isinstance(horizon, bool) or not isinstance(horizon, (int, np.integer)) or horizon < 1:
            raise InvalidArgument(f"horizon must be an integer >= 1 (stages), got {horizon!r}")
        try:
            dt_f = float(dt)
        except (TypeError, ValueError) as err:
            raise InvalidArgument(f"dt must be a finite time > 0 [s], got {dt!r}") from err
        if not (math.isfinite(dt_f) and dt_f > 0.0):
            raise InvalidArgument(f"dt must be a finite time > 0 [s], got {dt!r}")
        self.metric = metric
        self.N = int(horizon)
        self.dt = dt_f
        self.solver_name = _choice(solver, SOLVERS, "solver")
        self.control = _choice(control, CONTROLS, "control")
        if effort is None:  # the cheapest effort each control mode allows
            effort = "acceleration" if self.control == "acceleration" else "torque"
        self.effort = _choice(effort, EFFORTS, "effort")
        self.hessian = _choice(hessian, HESSIANS, "hessian")
        if self.effort == "acceleration" and self.control != "acceleration":
            raise InvalidArgument(
                f"effort 'acceleration' needs control='acceleration', got control={control!r}; "
                "with torque control use effort 'torque' or 'metric'"
            )
        if rk4_steps not in (1, 2):
            raise InvalidArgument(f"rk4_steps must be 1 or 2, got {rk4_steps!r}")
        self.rk4_steps = int(rk4_steps)
        self.q_weight = check_gain(q_weight, n, "q_weight")
        self.v_weight = check_gain(v_weight, n, "v_weight")
        if tau_weight is None:
            tau_weight = _DEFAULT_EFFORT_WEIGHT[self.effort]
        self.tau_weight = check_gain(tau_weight, n, "tau_weight")
        self.terminal_weight = check_gain(terminal_weight, 2 * n, "terminal_weight")
        self.kp = check_gain(kp, n, "kp")
        self.kd = check_gain(kd, n, "kd")
        if (
            isinstance(max_iter, bool)
            or not isinstance(max_iter, (int, np.integer))
            or max_iter < 1
        ):
            raise InvalidArgument(f"max_iter must be an integer >= 1, got {max_iter!r}")
        self.max_iter = int(max_iter)
        for name, val in (("tol", tol), ("mu_init", mu_init), ("mu_warm", mu_warm)):
            if not (isinstance(val, (int, float)) and math.isfinite(val) and val > 0):
                raise InvalidArgument(f"{name} must be a finite number > 0, got {val!r}")
        if not (math.isfinite(plan_tolerance) and plan_tolerance >= 0):
            raise InvalidArgument(f"plan_tolerance must be >= 0 [rad], got {plan_tolerance!r}")
        if solver_options is not None and not isinstance(solver_options, dict):
            raise InvalidArgument(f"solver_options must be a dict or None, got {solver_options!r}")
        self.tol = float(tol)
        self.mu_init = float(mu_init)
        self.mu_warm = float(mu_warm)
        self.plan_tolerance = float(plan_tolerance)
        self.solver_options = dict(solver_options or {})

        self._model = robot.model
        self._data = robot.model.createData()
        self._gravity = np.asarray(robot.gravity, dtype=np.float64)
        self._metric_p = np.asarray(metric.parameter_values(), dtype=np.float64).ravel()
        self._open_loop: dict[tuple, _NLP] = {}
        self.build_time = 0.0
        start = time.perf_counter()
        self._nlp = self._build_tracking()
        self.build_time = time.perf_counter() - start
        self._plan: MPCPlan | None = None
        self._lam: tuple[np.ndarray, np.ndarray] | None = None
        self._t_solve = -math.inf
        self._using_fallback = False
        self.solve_count = 0
        if reference is not None:
            self.set_reference(reference)

    # -- symbolic pieces -------------------------------------------------------------
    def _sym_dynamics(self, gravity: bool) -> tuple[ca.Function, ca.Function]:
        """SX functions F(x, u) -> x_next and TAU(x, u) -> tau for one stage."""
        n, h = self.nv, self.dt
        g = self._gravity if gravity else np.zeros(3)
        from geosyn.robots import symbolic

        x = ca.SX.sym("x", 2 * n)
        u = ca.SX.sym("u", n)
        q, v = x[:n], x[n:]
        if self.control == "torque":
            acc = symbolic.aba(self._model, q, v, u, g)
            f = ca.Function("f", [x, u], [ca.vertcat(v, acc)])
            hs = h / self.rk4_steps
            xk = x
            for _ in range(self.rk4_steps):
                k1 = f(xk, u)
                k2 = f(xk + 0.5 * hs * k1, u)
                k3 = f(xk + 0.5 * hs * k2, u)
                k4 = f(xk + hs * k3, u)
                xk = xk + (hs / 6.0) * (k1 + 2 * k2 + 2 * k3 + k4)
            tau = u
        else:
            xk = ca.vertcat(q + h * v + 0.5 * h * h * u, v + h * u)
            tau = symbolic.rnea(self._model, q, v, u, g)
        tag = "g" if gravity else "0"
        F = ca.Function(f"mpc_F{tag}", [x, u], [xk], ["x", "u"], ["xn"], {"cse": True})
        TAU = ca.Function(f"mpc_tau{tag}", [x, u], [tau], ["x", "u"], ["tau"], {"cse": True})
        return F, TAU

    def _metric_effort(self, q: ca.SX, tau: ca.SX, gravity: bool) -> ca.SX:
        """``(tau - g)^T G^-1 (tau - g)`` as SX; ABA for the kinetic-energy metric."""
        from geosyn.metrics.kinetic import KineticEnergyMetric
        from geosyn.robots import symbolic

        n = self.nv
        g = self._gravity if gravity else np.zeros(3)
        zeros = np.zeros(n)
        w = tau - symbolic.rnea(self._model, q, zeros, zeros, g) if gravity else tau
        m = self.metric
        if isinstance(m, KineticEnergyMetric) and m.robot.model is self._model:
            # aba(q, 0, tau, g) = M^-1 (tau - g(q)): one recursion, no symbolic inverse.
            minv_w = symbolic.aba(self._model, q, zeros, tau, g)
        else:
            minv_w = sx_cholesky_solve(m.symbolic_G(q), w)
        return ca.dot(w, minv_w)

    def _stage_functions(self, gravity: bool, use_gn: bool) -> tuple[ca.Function, ca.Function]:
        F, TAU = self._sym_dynamics(gravity)
        if not use_gn:
            return F, TAU
        # Torque control: the RK4 step on the ABA is the nonlinear part. Acceleration
        # control: the double integrator is linear, only the RNEA torque is compiled.
        funs = [F] if self.control == "torque" else [TAU]
        try:
            lib = _zero_second_derivative_library(
                funs, f"geosyn_mpc_{self.robot.name}_{self.control}_{len(funs)}"
            )
        except CodegenError as err:
            warnings.warn(
                f"GeodesicMPC: no compiled dynamics ({err}); using the exact Hessian instead",
                RuntimeWarning,
                stacklevel=3,
            )
            self.hessian = "exact"
            return F, TAU
        return lib.get(F.name(), F), lib.get(TAU.name(), TAU)

    # -- NLP construction ------------------------------------------------------------
    def _build_tracking(self) -> _NLP:
        return self._build_nlp(
            open_loop=False,
            free_v0=False,
            gravity=True,
            effort=self.effort,
            use_gn=self.hessian == "gauss-newton",
        )

    def _build_nlp(
        self,
        *,
        open_loop: bool,
        free_v0: bool,
        gravity: bool,
        effort: str,
        use_gn: bool,
        naive: bool = False,
    ) -> _NLP:
        """Build the multiple-shooting NLP, stage by stage as fatrop's detection expects.

        Decision vector: ``x_0, u_0, x_1, u_1, ..., x_{N-1}, u_{N-1}, x_N``. Constraints per
        stage k: the gap ``x_{k+1} - F(x_k, u_k)``, then (k = 0) the initial condition,
        then the path constraints (acceleration control: the RNEA torque), then (k = N-1,
        open-loop mode) the terminal position.
        """
        n, N = self.nv, self.N
        F, TAU = (
            self._stage_functions(gravity, use_gn) if not naive else self._sym_dynamics(gravity)
        )
        use_gn = use_gn and self.hessian == "gauss-newton" and not naive
        nx = 2 * n
        n_mp = self._metric_p.size
        # Exact Hessian: an SX graph (functions inlined, no expansion step needed).
        # Gauss-Newton: an MX graph with one mapped call per compiled stage function, so
        # CasADi evaluates each Jacobian once per stage with little graph overhead (SX
        # call nodes would be differentiated one direction at a time). Naive: MX with
        # one call per stage, not expanded.
        mapped = use_gn

        # Stage cost as one SX function (its Hessian is exact; it is quadratic except for
        # the metric effort).
        xs, us = ca.SX.sym("x", nx), ca.SX.sym("u", n)
        qrs, vrs, trs, taus = (ca.SX.sym(s, n) for s in ("qr", "vr", "tr", "tau"))
        track: ca.SX | int
        if open_loop:
            track = 0
        else:
            track = ca.dot(self.q_weight, (xs[:n] - qrs) ** 2) + ca.dot(
                self.v_weight, (xs[n:] - vrs) ** 2
            )
        if effort == "torque":
            eff = ca.dot(self.tau_weight, (taus - trs) ** 2)
        elif effort == "acceleration":
            # trs holds the reference accelerations here (see `_effort_reference`).
            eff = ca.dot(self.tau_weight, (us - trs) ** 2)
        else:
            eff = float(self.tau_weight[0]) * self._metric_effort(xs[:n], taus, gravity)
        mps = ca.SX.sym("mp", n_mp)
        if n_mp and effort == "metric" and not self._is_kinetic():
            # A parameterised metric: its symbols become the NLP parameter ``mp``.
            eff = ca.substitute(eff, self.metric.symbolic_parameters(), mps)
        L = ca.Function("L", [xs, us, taus, qrs, vrs, trs, mps], [track + eff], {"cse": True})
        Wn = self.terminal_weight
        Lf = ca.Function(
            "Lf",
            [xs, qrs, vrs],
            [0 if open_loop else ca.dot(Wn, (xs - ca.vertcat(qrs, vrs)) ** 2)],
        )

        tau_max = np.asarray(self.robot.tau_max, dtype=np.float64)
        # One call per symbol type, so that each graph is typed SX or MX throughout.
        nlp: dict[str, ca.SX] | dict[str, ca.MX]
        if use_gn or naive:
            nlp, eq, lbg, ubg, g_blocks = self._nlp_graph(
                ca.MX,
                F,
                TAU,
                L,
                Lf,
                mapped=mapped,
                open_loop=open_loop,
                free_v0=free_v0,
                tau_max=tau_max,
            )
        else:
            nlp, eq, lbg, ubg, g_blocks = self._nlp_graph(
                ca.SX,
                F,
                TAU,
                L,
                Lf,
                mapped=mapped,
                open_loop=open_loop,
                free_v0=free_v0,
                tau_max=tau_max,
            )

        # Bounds: x_0 is fixed by the initial constraint (no bounds there, so a measured
        # state slightly outside the limits stays feasible); torques bound u in torque
        # control.
        inf = np.inf
        q_lo = np.where(np.isfinite(self.robot.q_min), self.robot.q_min, -inf)
        q_hi = np.where(np.isfinite(self.robot.q_max), self.robot.q_max, inf)
        v_max = np.asarray(self.robot.v_max, dtype=np.float64)
        u_lo = -tau_max if self.control == "torque" else np.full(n, -inf)
        u_hi = tau_max if self.control == "torque" else np.full(n, inf)
        lbx, ubx = [], []
        for k in range(N + 1):
            if k == 0:
                lbx.append(np.full(nx, -inf))
                ubx.append(np.full(nx, inf))
            else:
                lbx.append(np.concatenate([q_lo, -v_max]))
                ubx.append(np.concatenate([q_hi, v_max]))
            if k < N:
                lbx.append(u_lo)
                ubx.append(u_hi)

        # No SX expansion step: the exact build is SX already, the Gauss-Newton build
        # calls compiled code (not expandable), the naive build is meant to be MX.
        common: dict[str, Any] = {"expand": False, "print_time": False, "error_on_fail": False}
        if naive:
            opts: dict[str, Any] = {
                **common,
                "ipopt": {"print_level": 0, "sb": "yes", "tol": self.tol},
            }
            solver = ca.nlpsol("mpc_naive", "ipopt", nlp, opts)
            solver_cold = None
        elif self.solver_name == "fatrop":

            def fatrop_opts(mu: float) -> dict[str, Any]:
                plugin: dict[str, Any] = {
                    "mu_init": mu,
                    "print_level": 0,
                    "tol": self.tol,
                    "max_iter": self.max_iter,
                }
                plugin.update(self.solver_options)
                return {**common, "structure_detection": "auto", "equality": eq, "fatrop": plugin}

            solver = ca.nlpsol("mpc_warm", "fatrop", nlp, fatrop_opts(self.mu_warm))
            solver_cold = ca.nlpsol("mpc_cold", "fatrop", nlp, fatrop_opts(self.mu_init))
        else:

            def ipopt_opts(mu: float, warm: bool) -> dict[str, Any]:
                plugin: dict[str, Any] = {
                    "print_level": 0,
                    "sb": "yes",
                    "tol": self.tol,
                    "max_iter": self.max_iter,
                    "mu_init": mu,
                }
                if warm:
                    plugin.update(
                        warm_start_init_point="yes",
                        warm_start_bound_push=1e-6,
                        warm_start_mult_bound_push=1e-6,
                        mu_strategy="monotone",
                    )
                plugin.update(self.solver_options)
                return {**common, "ipopt": plugin}

            solver = ca.nlpsol("mpc_warm", "ipopt", nlp, ipopt_opts(self.mu_warm, True))
            solver_cold = ca.nlpsol("mpc_cold", "ipopt", nlp, ipopt_opts(self.mu_init, False))
        Ff, TAUf = self._sym_dynamics(gravity)
        return _NLP(
            solver=solver,
            solver_cold=solver_cold,
            N=N,
            n=n,
            lbx=np.concatenate(lbx),
            ubx=np.concatenate(ubx),
            lbg=np.asarray(lbg, dtype=np.float64),
            ubg=np.asarray(ubg, dtype=np.float64),
            g_blocks=g_blocks,
            tau_fn=TAUf.map(N),
        )

    def _nlp_graph(
        self,
        S: type[_Sym],
        F: ca.Function,
        TAU: ca.Function,
        L: ca.Function,
        Lf: ca.Function,
        *,
        mapped: bool,
        open_loop: bool,
        free_v0: bool,
        tau_max: np.ndarray,
    ) -> tuple[dict[str, _Sym], list[bool], list[float], list[float], list[np.ndarray]]:
        """The NLP graph of `_build_nlp` in symbols of type ``S`` (SX or MX).

        Returns:
            The nlp dict (``x``, ``f``, ``g``, ``p``), then per constraint row whether it
            is an equality, its lower and upper bounds, and the per-stage row indices.
        """
        n, N = self.nv, self.N
        nx = 2 * n
        n_mp = self._metric_p.size
        X = [S.sym(f"x{k}", nx) for k in range(N + 1)]
        U = [S.sym(f"u{k}", n) for k in range(N)]
        x_init = S.sym("x_init", nx)
        q_goal = S.sym("q_goal", n)
        qr = S.sym("qr", n, N + 1)
        vr = S.sym("vr", n, N + 1)
        tr = S.sym("tr", n, N)
        mp = S.sym("mp", n_mp)

        w: list[_Sym] = []
        g: list[_Sym] = []
        eq: list[bool] = []
        lbg: list[float] = []
        ubg: list[float] = []
        g_blocks: list[np.ndarray] = []
        ng = 0
        for k in range(N):
            w += [X[k], U[k]]
        w.append(X[N])
        if mapped:
            Xc, Uc = ca.horzcat(*X[:N]), ca.horzcat(*U)
            x_pred, tau_all = F.map(N)(Xc, Uc), TAU.map(N)(Xc, Uc)
            x_next = [x_pred[:, k] for k in range(N)]
            taus_k = [tau_all[:, k] for k in range(N)]
            costs = L.map(N)(Xc, Uc, tau_all, qr[:, :N], vr[:, :N], tr, ca.repmat(mp, 1, N))
            J = ca.sum2(costs)
        else:
            x_next = [F(X[k], U[k]) for k in range(N)]
            taus_k = [TAU(X[k], U[k]) for k in range(N)]
            J = S(0)  # what CasADi makes of a Python 0 in `0 + L(...)`
            for k in range(N):
                J = J + L(X[k], U[k], taus_k[k], qr[:, k], vr[:, k], tr[:, k], mp)
        for k in range(N):
            start = ng
            g.append(X[k + 1] - x_next[k])
            eq += [True] * nx
            lbg += [0.0] * nx
            ubg += [0.0] * nx
            ng += nx
            if k == 0:
                init = X[0][:n] - x_init[:n] if free_v0 else X[0] - x_init
                m0 = n if free_v0 else nx
                g.append(init)
                eq += [True] * m0
                lbg += [0.0] * m0
                ubg += [0.0] * m0
                ng += m0
            tau_k = taus_k[k]
            if self.control == "acceleration":
                g.append(tau_k)
                eq += [False] * n
                lbg += list(-tau_max)
                ubg += list(tau_max)
                ng += n
            if open_loop and k == N - 1:
                g.append(X[N][:n] - q_goal)
                eq += [True] * n
                lbg += [0.0] * n
                ubg += [0.0] * n
                ng += n
            g_blocks.append(np.arange(start, ng))
        J = J + Lf(X[N], qr[:, N], vr[:, N])
        p = ca.vertcat(x_init, q_goal, ca.vec(qr), ca.vec(vr), ca.vec(tr), mp)
        nlp = {"x": ca.vertcat(*w), "f": J, "g": ca.vertcat(*g), "p": p}
        return nlp, eq, lbg, ubg, g_blocks

    def _is_kinetic(self) -> bool:
        from geosyn.metrics.kinetic import KineticEnergyMetric

        return (
            isinstance(self.metric, KineticEnergyMetric) and self.metric.robot.model is self._model
        )

    # -- packing ---------------------------------------------------------------------
    def _pack(self, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        """(N+1, 2n) states and (N, n) controls -> decision vector."""
        N = self.N
        return np.concatenate([np.hstack([x[:N], u]).ravel(), x[N]])

    def _unpack(self, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        N, n = self.N, self.nv
        body = w[: N * 3 * n].reshape(N, 3 * n)
        x = np.vstack([body[:, : 2 * n], w[N * 3 * n :][None, :]])
        return x, body[:, 2 * n :].copy()

    def _params(self, x_init: np.ndarray, q_goal: np.ndarray, qr, vr, tr) -> np.ndarray:
        return np.concatenate(
            [x_init, q_goal, qr.ravel(), vr.ravel(), tr.ravel(), self._metric_parameters()]
        )

    def _reference_samples(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(N+1, n) q_ref, v_ref, a_ref at ``t + k dt`` and (N, n) inverse-dynamics torques."""
        N, n = self.N, self.nv
        qr = np.empty((N + 1, n))
        vr = np.empty((N + 1, n))
        ar = np.empty((N + 1, n))
        sample = self._reference.sample  # type: ignore[union-attr]
        for k in range(N + 1):
            qr[k], vr[k], ar[k] = sample(t + k * self.dt)
        tr = np.empty((N, n))
        for k in range(N):
            tr[k] = pin.rnea(self._model, self._data, qr[k], vr[k], ar[k])
        return qr, vr, ar, tr

    def _metric_parameters(self) -> np.ndarray:
        """Current values of a parameterised metric's parameters (read at every solve)."""
        if self._metric_p.size == 0:
            return self._metric_p
        return np.asarray(self.metric.parameter_values(), dtype=np.float64).ravel()

    def _effort_reference(self, ar: np.ndarray, tr: np.ndarray) -> np.ndarray:
        """(N, n) the effort's reference: accelerations or inverse-dynamics torques."""
        return ar[: self.N] if self.effort == "acceleration" else tr

    # -- controller hooks ------------------------------------------------------------
    def _on_reset(self, q: Vector, v: Vector, t: float) -> None:
        self._plan = None
        self._lam = None
        self._t_solve = -math.inf
        self._using_fallback = False

    def _on_reference_changed(self) -> None:
        # A new reference invalidates the warm start (a different task).
        self._plan = None
        self._lam = None
        self._t_solve = -math.inf

    @property
    def plan(self) -> MPCPlan | None:
        """The plan of the last successful solve (None before)."""
        return self._plan

    def solve(self, t: float, q: Vector, v: Vector) -> MPCPlan:
        """Solve the tracking OCP from the measured state at time ``t`` (no fallback).

        Warm-starts from the previous plan shifted by the elapsed stages when there is
        one (the last stage duplicated), else cold-starts from the reference samples.

        Args:
            t: time [s].
            q: (nv,) joint positions [rad].
            v: (nv,) joint velocities [rad/s].

        Returns:
            The `MPCPlan` (``success`` False on a failed solve; never raises for that).

        Raises:
            InvalidArgument: bad inputs; NoReference without a reference.
        """
        if self._reference is None:
            from geosyn.controllers.errors import NoReference

            raise NoReference("GeodesicMPC.solve called before set_reference")
        q = check_vector(q, self.nv, "q")
        v = check_vector(v, self.nv, "v")
        nlp = self._nlp
        N = self.N
        qr, vr, ar, tr = self._reference_samples(t)
        x_init = np.concatenate([q, v])
        p = self._params(x_init, qr[N], qr, vr, self._effort_reference(ar, tr))
        prev = self._plan
        warm = prev is not None and self._lam is not None
        if warm:
            j = int(round((t - prev.t) / self.dt))  # type: ignore[union-attr]
            warm = 0 <= j < N
        if warm:
            idx_x = np.minimum(np.arange(N + 1) + j, N)
            idx_u = np.minimum(np.arange(N) + j, N - 1)
            x0 = prev.x[idx_x].copy()  # type: ignore[union-attr]
            u0 = prev.u[idx_u]  # type: ignore[union-attr]
            x0[0] = x_init
            lam_x_old, lam_g_old = self._lam  # type: ignore[misc]
            lx, lu = self._unpack(lam_x_old)
            lam_x = self._pack(lx[idx_x], lu[idx_u])
            lam_g = lam_g_old.copy()
            blocks = nlp.g_blocks
            for k in range(1, N):  # stage 0 keeps its own block (it holds the init rows)
                src = blocks[min(k + j, N - 1)]
                if src.size == blocks[k].size:
                    lam_g[blocks[k]] = lam_g_old[src]
            solver = nlp.solver
            args = {"x0": self._pack(x0, u0), "lam_x0": lam_x, "lam_g0": lam_g}
        else:
            x0 = np.hstack([qr, vr])
            x0[0] = x_init
            u0 = tr if self.control == "torque" else ar[:N]
            solver = nlp.cold()
            args = {"x0": self._pack(x0, u0)}
        start = time.perf_counter()
        status, iters, success = "exception", 0, False
        x_sol = u_sol = tau = None
        try:
            res = solver(p=p, lbx=nlp.lbx, ubx=nlp.ubx, lbg=nlp.lbg, ubg=nlp.ubg, **args)
            stats = solver.stats()
            status = str(stats.get("return_status", stats.get("unified_return_status", "?")))
            iters = int(stats.get("iter_count", 0))
            w = np.asarray(res["x"]).ravel()
            x_sol, u_sol = self._unpack(w)
            tau = np.asarray(nlp.tau_fn(x_sol[:N].T, u_sol.T)).T
            success = bool(stats.get("success", False)) and bool(np.all(np.isfinite(w)))
            if success:
                self._lam = (np.asarray(res["lam_x"]).ravel(), np.asarray(res["lam_g"]).ravel())
        except RuntimeError as err:
            status = f"exception: {err}".splitlines()[0][:200]
        solve_time = time.perf_counter() - start
        self.solve_count += 1
        if x_sol is None:
            x_sol = np.full((N + 1, 2 * self.nv), np.nan)
            u_sol = np.full((N, self.nv), np.nan)
            tau = np.full((N, self.nv), np.nan)
        return MPCPlan(t, x_sol, u_sol, tau, status, iters, success, solve_time)  # type: ignore[arg-type]

    def _plan_state(self, plan: MPCPlan, t: float) -> tuple[int, np.ndarray, np.ndarray]:
        """Stage index and Hermite-interpolated planned (q, v) at time ``t``."""
        n, h = self.nv, self.dt
        s = max(t - plan.t, 0.0)
        j = min(int(s / h + _EPS_T), self.N - 1)
        tau_s = min((s - j * h) / h, 1.0)
        x0, x1 = plan.x[j], plan.x[j + 1]
        q0, v0, q1, v1 = x0[:n], x0[n:], x1[:n], x1[n:]
        s2, s3 = tau_s * tau_s, tau_s * tau_s * tau_s
        h00, h10, h01, h11 = 2 * s3 - 3 * s2 + 1, s3 - 2 * s2 + tau_s, -2 * s3 + 3 * s2, s3 - s2
        q = h00 * q0 + h10 * h * v0 + h01 * q1 + h11 * h * v1
        d00, d10, d01, d11 = (
            6 * s2 - 6 * tau_s,
            3 * s2 - 4 * tau_s + 1,
            -6 * s2 + 6 * tau_s,
            3 * s2 - 2 * tau_s,
        )
        v = (d00 * q0 + d01 * q1) / h + d10 * v0 + d11 * v1
        return j, q, v

    def _track_plan(self, plan: MPCPlan, t: float, q: Vector, v: Vector) -> Vector:
        j, q_p, v_p = self._plan_state(plan, t)
        fb = self.kp * (q_p - q) + self.kd * (v_p - v)
        if self.control == "torque":
            M = pin.crba(self._model, self._data, q)
            return plan.u[j] + M @ fb
        return pin.rnea(self._model, self._data, q, v, plan.u[j] + fb).copy()

    def _plan_usable(self, plan: MPCPlan | None, t: float, q: Vector) -> bool:
        if plan is None or not plan.success or t - plan.t >= self.N * self.dt - _EPS_T:
            return False
        _, q_p, _ = self._plan_state(plan, t)
        return float(np.max(np.abs(q_p - q))) <= self.plan_tolerance

    def _fallback_torque(self, t: float, q: Vector, v: Vector) -> Vector:
        """Computed torque on the reference (PD gains kp, kd), clipped by `compute`."""
        q_ref, v_ref, a_ref = self._reference.sample(t)  # type: ignore[union-attr]
        a = a_ref + self.kp * (q_ref - q) + self.kd * (v_ref - v)
        return pin.rnea(self._model, self._data, q, v, a).copy()

    def _compute(self, t: float, q: Vector, v: Vector) -> Vector:
        d = self.diagnostics
        if t - self._t_solve >= self.dt - _EPS_T:
            self._t_solve = t
            plan = self.solve(t, q, v)
            d.solver_status = plan.status
            d.iterations = plan.iterations
            d.extra = {"solve_time": plan.solve_time}
            if plan.success:
                self._plan = plan
                self._using_fallback = False
            else:
                # Keep the previous plan if it still covers t and the state is near it.
                self._using_fallback = True
                if not self._plan_usable(self._plan, t, q):
                    self._plan = None
                    self._lam = None
        if self._using_fallback:
            d.fallback_used = True
            if self._plan is not None and self._plan_usable(self._plan, t, q):
                d.extra["fallback"] = 1.0  # previous plan
                return self._track_plan(self._plan, t, q, v)
            d.extra["fallback"] = 2.0  # computed torque
            return self._fallback_torque(t, q, v)
        return self._track_plan(self._plan, t, q, v)  # type: ignore[arg-type]

    # -- the minimum-effort Riemannian OCP -------------------------------------------
    def solve_open_loop(
        self,
        q0: Vector,
        q_goal: Vector,
        v0: Vector | None = None,
        *,
        free_initial_velocity: bool = True,
        gravity: bool = False,
    ) -> OpenLoopSolution:
        """The minimum-effort OCP between two configurations in time ``T = N dt``.

        .. math::
            \\min \\sum_k (\\tau_k - g(q_k))^T G(q_k)^{-1} (\\tau_k - g(q_k))
            \\quad \\text{s.t.}\\ q(0) = q_0,\\ q(T) = q_1,\\ \\text{dynamics and limits}

        with the initial velocity free (``free_initial_velocity=True``) or fixed to
        ``v0``, and the final velocity free. For the kinetic-energy metric without gravity
        and with inactive limits, the minimiser is the geodesic from ``q0`` to ``q_goal``
        traversed in time T (zero torque, zero cost), up to the RK4 discretisation.

        The NLP (exact Hessian, SX expansion) is built on the first call for each
        ``(free_initial_velocity, gravity)`` pair and kept.

        Args:
            q0: (nv,) start configuration [rad].
            q_goal: (nv,) end configuration [rad].
            v0: (nv,) initial velocity [rad/s]: the fixed value, or the initial guess when
                free (default: ``(q_goal - q0) / T``).
            free_initial_velocity: make ``v(0)`` a decision variable.
            gravity: include the robot's gravity in the dynamics and the effort.

        Returns:
            The `OpenLoopSolution`.

        Raises:
            InvalidArgument: bad shapes or values.
            SolverFailed: the solver raised an exception.
        """
        n, N, h = self.nv, self.N, self.dt
        q0 = check_vector(q0, n, "q0")
        q_goal = check_vector(q_goal, n, "q_goal")
        T = N * h
        v_init = (q_goal - q0) / T if v0 is None else check_vector(v0, n, "v0")
        key = (bool(free_initial_velocity), bool(gravity))
        if key not in self._open_loop:
            self._open_loop[key] = self._build_nlp(
                open_loop=True, free_v0=key[0], gravity=key[1], effort="metric", use_gn=False
            )
        nlp = self._open_loop[key]
        s = np.linspace(0.0, 1.0, N + 1)[:, None]
        x0 = np.hstack([q0 + s * (q_goal - q0), np.tile(v_init, (N + 1, 1))])
        u0 = np.zeros((N, n))
        zero = np.zeros((N + 1, n))
        p = self._params(np.concatenate([q0, v_init]), q_goal, zero, zero, zero[:N])
        solver = nlp.cold()
        try:
            res = solver(
                x0=self._pack(x0, u0), p=p, lbx=nlp.lbx, ubx=nlp.ubx, lbg=nlp.lbg, ubg=nlp.ubg
            )
        except RuntimeError as err:
            raise SolverFailed(f"open-loop OCP solve raised: {err}") from err
        stats = solver.stats()
        w = np.asarray(res["x"]).ravel()
        x, u = self._unpack(w)
        tau = np.asarray(nlp.tau_fn(x[:N].T, u.T)).T
        return OpenLoopSolution(
            t=np.arange(N + 1) * h,
            q=x[:, :n].copy(),
            v=x[:, n:].copy(),
            tau=tau,
            cost=float(res["f"]),
            status=str(stats.get("return_status", "?")),
            iterations=int(stats.get("iter_count", 0)),
            success=bool(stats.get("success", False)),
        )

    # -- reference build for benchmarks ------------------------------------------------
    def build_naive_ipopt(self) -> ca.Function:
        """The same tracking OCP for IPOPT without SX expansion (MX graph, exact Hessian).

        A reference point for benchmarks only: solve it cold with `solve_naive`.
        """
        if not hasattr(self, "_naive"):
            self._naive = self._build_nlp(
                open_loop=False,
                free_v0=False,
                gravity=True,
                effort=self.effort,
                use_gn=False,
                naive=True,
            )
        return self._naive.solver

    def solve_naive(self, t: float, q: Vector, v: Vector) -> MPCPlan:
        """Cold solve of the naive IPOPT build (see `build_naive_ipopt`)."""
        self.build_naive_ipopt()
        nlp = self._naive
        N = self.N
        qr, vr, ar, tr = self._reference_samples(t)
        x_init = np.concatenate([q, v])
        p = self._params(x_init, qr[N], qr, vr, self._effort_reference(ar, tr))
        x0 = np.tile(x_init, (N + 1, 1))
        u0 = np.zeros((N, self.nv))
        start = time.perf_counter()
        res = nlp.solver(
            x0=self._pack(x0, u0), p=p, lbx=nlp.lbx, ubx=nlp.ubx, lbg=nlp.lbg, ubg=nlp.ubg
        )
        el = time.perf_counter() - start
        stats = nlp.solver.stats()
        x, u = self._unpack(np.asarray(res["x"]).ravel())
        return MPCPlan(
            t,
            x,
            u,
            u,
            str(stats.get("return_status")),
            int(stats.get("iter_count", 0)),
            bool(stats.get("success", False)),
            el,
        )
