"""Direct collocation of the geodesic energy: a boundary-value solver that does not shoot.

A path from ``q0`` to ``q1`` on ``t in [0, 1]`` is discretised into ``N + 1`` nodes
``q_0 = q0, q_1, ..., q_N = q1`` (piecewise linear, ``h = 1/N``) and its energy by the
midpoint rule,

.. math:: E_h(q_1, \\dots, q_{N-1}) = \\sum_{k=0}^{N-1} \\frac{1}{h}\\,
          \\Delta q_k^T\\, G\\big(\\tfrac{q_k + q_{k+1}}{2}\\big)\\, \\Delta q_k
          \\approx \\int_0^1 \\dot q^T G(q)\\, \\dot q\\, dt ,

is minimised by IPOPT over the interior nodes, within the joint limits and, optionally,
subject to ``clearance >= margin`` at every interior node (the robot's collision spheres
against the obstacles of an `ObstacleTerm`). Stationary points of ``E_h`` without active
constraints are discrete geodesics (a variational integrator of the geodesic equation,
second order in ``h``); with active constraints the result is a minimum-energy constrained
path, which is not a geodesic and is reported as such (`CollocationResult.kind`).

Build once, solve often. The NLP is assembled from two small per-node CasADi functions,
the energy of one segment with its gradient and Hessian, and the clearances of one node
with their Jacobian and multiplier-weighted Hessian, mapped over the nodes; IPOPT gets
these hand-assembled derivatives (block-tridiagonal Hessian, block-diagonal constraint
Jacobian). Start, goal, metric parameters and obstacle poses are NLP *parameters*, so one
`Collocation` serves every query and scene of the same robot, node count and obstacle
capacity; with ``compile=True`` the two per-node functions are compiled to C once
(`geosyn.core.codegen`, cached on disk, independent of the node count).
"""

from __future__ import annotations

import math
import time
from typing import TYPE_CHECKING, Any

import casadi as ca
import numpy as np

from geosyn.core.errors import InvalidArgument
from geosyn.core.types import Vector
from geosyn.core.validation import (
    check_choice,
    check_float,
    check_int,
    check_positive,
    check_vector,
)
from geosyn.metrics.base import Metric, check_metric
from geosyn.metrics.geodesic.collocation_nlp import assemble_nlp, per_node_functions
from geosyn.metrics.geodesic.collocation_parts import (
    ACTIVE_TOL,
    KINDS,
    WARM_START,
    CollocationResult,
    Deadline,
    interpolate_path,
    refine_by_shooting,
    resample_path,
)

if TYPE_CHECKING:
    from geosyn.metrics.shaping.obstacle import ObstacleTerm

__all__ = ["COMPILE", "HESSIANS", "KINDS", "Collocation", "CollocationResult", "resample_path"]

HESSIANS = ("exact", "energy", "limited-memory")
"""Choices of `Collocation`'s ``hessian`` argument."""

COMPILE = ("all", "first-order", "none")
"""Choices of `Collocation`'s ``compile`` argument."""

BATCH = 64
"""Configurations per call of the batched clearance check (`Collocation.node_clearances`)."""


class Collocation:
    """Minimum-energy paths by direct collocation (IPOPT); see the module docstring.

    Args:
        metric: the metric (velocity-independent, with a symbolic form, e.g.
            `KineticEnergyMetric` or a `ShapedMetric` without gated terms).
        nodes: number of segments ``N`` of the path, >= 2.
        clearance: an `ObstacleTerm` bound to the metric's robot whose spheres and
            obstacles (its current parameter values, read at each solve) give the
            constraints ``clearance >= margin`` at the interior nodes; None: no
            constraints besides the joint limits.
        margin: smallest clearance at the nodes [m], >= 0 (paths are piecewise linear
            between nodes: keep a margin, and check between nodes).
        joint_limits: keep the nodes within the robot's position limits (needs
            ``metric.robot``).
        compile: which per-node functions to compile to C (cached on disk), `COMPILE`:
            ``"all"`` (or True), ``"none"`` (or False: CasADi's VM), or
            ``"first-order"`` (all but the clearances' Hessian, which stays in the VM,
            and with the clearances' Jacobian by automatic differentiation rather than
            by its structure, `geosyn.metrics.geodesic.collocation_clearance`).
        tol: IPOPT's tolerance.
        hessian: what IPOPT gets as the Hessian of the Lagrangian (`HESSIANS`):
            ``"exact"`` (energy and clearances; the clearances' second derivatives are
            the costliest function to compile with many spheres), ``"energy"`` (the
            energy's only: cheap, but IPOPT then often stalls where clearance constraints
            are active) or ``"limited-memory"`` (IPOPT's L-BFGS, no second derivatives).
        softmin: one constraint per node and obstacle, the smooth minimum over the
            robot spheres with this sharpness [1/m] (conservative, at most
            ``log(n_spheres) / softmin`` below the exact minimum: 4 mm for 59 spheres at
            the default 1000 /m); None: one constraint per node, sphere and obstacle
            (exact, but many constraints with many spheres).
        subdivisions: also constrain the clearance at this many evenly spaced points
            inside each segment, >= 0 (1: the midpoints, which catch thin obstacles that
            nodes would straddle; 3: the quarter points, so that a path checked 4x finer
            than its nodes keeps the margin there by construction).
        ipopt_options: extra IPOPT options (without the ``ipopt.`` prefix), applied over
            the defaults, e.g. ``{"print_level": 5}``.

    The constructor builds the NLP (allocates; with ``compile`` a C compile on the first
    use of a robot and capacity, cached on disk afterwards); `solve` only writes
    parameters and runs IPOPT.

    Raises:
        InvalidArgument: bad settings, a velocity-dependent metric, or a ``clearance``
            term bound to a robot of a different dimension.
    """

    def __init__(
        self,
        metric: Metric,
        *,
        nodes: int = 24,
        clearance: ObstacleTerm | None = None,
        margin: float = 0.01,
        joint_limits: bool = True,
        compile: bool | str = False,
        tol: float = 1e-8,
        hessian: str = "exact",
        softmin: float | None = 1000.0,
        subdivisions: int = 1,
        ipopt_options: dict[str, Any] | None = None,
    ) -> None:
        t0 = time.perf_counter()
        self.metric = check_metric(metric)
        if getattr(metric, "velocity_dependent", False):
            raise InvalidArgument(
                "metric: collocation needs a velocity-independent metric; use a ShapedMetric "
                "without velocity-gated terms (gate='none')"
            )
        self.nodes = N = check_int(nodes, "nodes", low=2)
        self.margin = check_float(margin, "margin", low=0.0)
        self.tol = check_positive(tol, "tol")
        self.clearance = clearance
        n = self.n = metric.n
        if clearance is not None and clearance.n != n:
            raise InvalidArgument(
                f"clearance: term is bound to a robot with {clearance.n} joints, metric has {n}"
            )
        robot: Any = getattr(metric, "robot", None)
        if joint_limits and robot is None:
            raise InvalidArgument("joint_limits: the metric has no robot; pass joint_limits=False")
        if joint_limits:
            self.q_min = np.array(robot.q_min, dtype=np.float64)
            self.q_max = np.array(robot.q_max, dtype=np.float64)
        else:
            self.q_min, self.q_max = np.full(n, -np.inf), np.full(n, np.inf)
        self.hessian = check_choice(hessian, HESSIANS, "hessian")
        self.constraint_hessian = self.hessian == "exact"
        self.softmin = None if softmin is None else check_positive(softmin, "softmin", "1/m")
        mode: object = compile
        if isinstance(compile, bool):
            mode = "all" if compile else "none"
        self.compile = check_choice(mode, COMPILE, "compile")
        funcs = per_node_functions(
            metric, clearance, self.constraint_hessian, self.softmin, self.compile
        )
        clr = funcs[2]
        self.constraints_per_node = m = clr.size1_out(0) if clearance is not None else 0
        npm = metric.symbolic_parameters().numel()
        npc = 0 if clearance is None else clearance.symbolic_parameters().numel()
        subdivisions = check_int(subdivisions, "subdivisions", low=0)
        self.subdivisions = subdivisions if m else 0
        nlp_parts = assemble_nlp(
            funcs, n, N, npm, npc, m, self.subdivisions, self.constraint_hessian
        )
        x, p, f, g = nlp_parts.x, nlp_parts.p, nlp_parts.f, nlp_parts.g
        grad_f, jac_g, hess_l = nlp_parts.grad_f, nlp_parts.jac_g, nlp_parts.hess_l
        self._deadline = Deadline(x.numel(), g.numel())
        opts: dict[str, Any] = {
            "iteration_callback": self._deadline,
            "grad_f": grad_f,
            "print_time": False,
            "calc_lam_p": False,
            "ipopt.print_level": 0,
            "ipopt.sb": "yes",
            "ipopt.tol": self.tol,
            "ipopt.max_iter": 500,
            # a faster monotone barrier decrease than IPOPT's 0.2: fewer iterations on
            # benchmarks/planning.py, the worst scene's most of all (RESULTS.md)
            "ipopt.mu_linear_decrease_factor": 0.05,
            # the solution projected onto the original bounds (the joint limits): IPOPT
            # relaxes them by 1e-8 relative, and a path at a limit came back 5e-9 rad
            # beyond it and was refused (`geosyn.metrics.planning.verify.LIMIT_TOL`)
            "ipopt.honor_original_bounds": "yes",
        }
        opts.update({f"ipopt.{k}": v for k, v in (ipopt_options or {}).items()})
        if m:
            opts["jac_g"] = jac_g
        if self.hessian == "limited-memory":
            opts["ipopt.hessian_approximation"] = "limited-memory"
        else:
            opts["hess_lag"] = hess_l
        nlp: dict[str, Any] = {"x": x, "p": p, "f": f, "g": g}
        self._solver = ca.nlpsol("collocation", "ipopt", nlp, opts)
        self._nlp, self._opts = nlp, opts
        self._warm_solver: Any = None
        self._variants: dict[float, Any] = {}
        self._clearance_fn = clr if m else None
        self._clearance_batch: dict[int, ca.Function] = {}
        self.build_time = time.perf_counter() - t0

    def __repr__(self) -> str:
        return (
            f"Collocation({self.metric!r}, nodes={self.nodes}, "
            f"constraints_per_node={self.constraints_per_node}, margin={self.margin})"
        )

    def _warm(self) -> Any:
        """The IPOPT solver with the warm-start options (built on first use)."""
        if self._warm_solver is None:
            opts = dict(self._opts)
            opts.update({f"ipopt.{k}": v for k, v in WARM_START.items()})
            self._warm_solver = ca.nlpsol("collocation_warm", "ipopt", self._nlp, opts)
        return self._warm_solver

    def solver(self, mu_init: float | None = None) -> Any:
        """The IPOPT solver, or its variant with IPOPT's initial barrier parameter
        ``mu_init`` (> 0; built on first use, then kept: allocates once)."""
        if mu_init is None:
            return self._solver
        mu_init = check_positive(mu_init, "mu_init")
        if mu_init not in self._variants:
            opts = dict(self._opts)
            opts["ipopt.mu_init"] = mu_init
            self._variants[mu_init] = ca.nlpsol("collocation_mu", "ipopt", self._nlp, opts)
        return self._variants[mu_init]

    @property
    def point_times(self) -> np.ndarray:
        """(P,) path parameter on [0, 1] of each constrained point, in the order of the
        constraint blocks: the interior nodes, then each subdivision's points."""
        N, s = self.nodes, self.subdivisions
        inner = [(np.arange(N) + (i + 1) / (s + 1)) / N for i in range(s)]
        return np.concatenate([np.arange(1, N) / N, *inner])

    def slot_clearances(self, q: Vector) -> np.ndarray:
        """(m,) the constrained clearances [m] of one configuration ``q`` (n,) [rad]: one
        per obstacle slot (the smooth minimum over the spheres; `INACTIVE_CLEARANCE` on
        empty slots), or per sphere and slot without ``softmin``; (0,) without a term."""
        q = check_vector(q, self.n, "q")
        if self._clearance_fn is None:
            return np.zeros(0)
        pc = np.asarray(self.clearance.parameter_values(), dtype=float)  # type: ignore[union-attr]
        return np.asarray(self._clearance_fn(q, pc)).ravel()

    def _warm_multipliers(self, warm: CollocationResult) -> dict[str, np.ndarray]:
        """lam_x0, lam_g0 from ``warm``: its constraint blocks at the same points (the
        nodes, and subdivisions at the same segment fraction), zero elsewhere."""
        lam_x, lam_g = warm.multipliers  # type: ignore[misc]
        N, m, s = self.nodes, self.constraints_per_node, self.subdivisions
        out = np.zeros(m * (N - 1 + s * N))
        if m and lam_g.size:
            out[: m * (N - 1)] = lam_g[: m * (N - 1)]
            s_old = (lam_g.size // m - (N - 1)) // N
            for i in range(s_old):
                t = (i + 1) * (s + 1)
                if t % (s_old + 1) == 0:  # (i + 1) / (s_old + 1) == j / (s + 1)
                    j = t // (s_old + 1) - 1
                    old = lam_g[m * (N - 1 + i * N) : m * (N - 1 + (i + 1) * N)]
                    out[m * (N - 1 + j * N) : m * (N - 1 + (j + 1) * N)] = old
        return {"lam_x0": lam_x, "lam_g0": out}

    def parameters(self, q0: np.ndarray, q1: np.ndarray) -> np.ndarray:
        """(2n + p,) NLP parameters: start, goal, metric and obstacle parameters."""
        parts = [q0, q1, np.asarray(self.metric.parameter_values(), dtype=float)]
        if self.clearance is not None:
            parts.append(np.asarray(self.clearance.parameter_values(), dtype=float))
        return np.concatenate(parts)

    def node_clearances(self, path: np.ndarray) -> np.ndarray:
        """(T,) smallest clearance [m] of each configuration of ``path`` (T, n).

        Inf without a clearance term or obstacles. Evaluated in batches of `BATCH`
        configurations (or `BATCH` / 8 for short paths; mapped functions built on first use).
        """
        path = np.asarray(path, dtype=float).reshape(-1, self.n)
        if self._clearance_fn is None or not self.clearance.obstacles:  # type: ignore[union-attr]
            return np.full(len(path), math.inf)
        T = len(path)
        size = BATCH if T > BATCH // 8 else BATCH // 8
        if size not in self._clearance_batch:
            self._clearance_batch[size] = self._clearance_fn.map(size)
        fn = self._clearance_batch[size]
        pc = np.asarray(self.clearance.parameter_values(), dtype=float)  # type: ignore[union-attr]
        padded = np.vstack([path, np.repeat(path[-1:], (-T) % size, axis=0)])
        out = [
            np.asarray(fn(padded[i : i + size].T, pc)).min(axis=0)
            for i in range(0, len(padded), size)
        ]
        return np.concatenate(out)[:T]

    def solve(
        self,
        q0: Vector,
        q1: Vector,
        *,
        init: np.ndarray | None = None,
        warm: CollocationResult | None = None,
        budget: float = 10.0,
        refine: bool = True,
        steps: int = 100,
        init_t: np.ndarray | None = None,
        lower: np.ndarray | None = None,
        mu_init: float | None = None,
    ) -> CollocationResult:
        """Minimum-energy path from ``q0`` to ``q1``; see `CollocationResult` for its kind.

        Args:
            q0: (n,) start [rad].
            q1: (n,) goal [rad].
            init: (T, n) initial path from ``q0`` to ``q1`` (T >= 2, resampled by arc
                length to the nodes), e.g. a sampled path around obstacles; None: the
                straight line.
            warm: a result of a collocation with the same node count (e.g. fewer
                subdivisions) to start from: its nodes (instead of ``init``) and its
                multipliers (constraints at points this NLP shares with it; zero at
                the others), with IPOPT's warm-start options (`WARM_START`).
            budget: IPOPT's wall-time limit [s], > 0 (the shooting refinement is extra,
                bounded by its iteration budget).
            refine: when no constraint is active, refine the discrete geodesic by
                shooting (`log_solve` from its initial velocity) to the exact geodesic.
            steps: RK4 steps of the shooting refinement, >= 1.
            init_t: (T,) increasing path parameter on [0, 1] of ``init``'s samples: then
                ``init`` is interpolated linearly at the node times (e.g. the nodes of a
                coarser collocation) instead of resampled by joint-space arc length.
            lower: (P, m) lower bounds [m] of the constrained clearances at the points
                `point_times` (one row per point, in that order) instead of ``margin``
                everywhere, e.g. an inflated margin for a coarse seed; None: ``margin``.
            mu_init: IPOPT's initial barrier parameter (> 0; None: the solver's, 0.1),
                e.g. small from an initial path that is already near a solution (a
                ``warm`` start uses `WARM_START`'s instead).

        Returns:
            The path and what it is. A failed IPOPT solve is returned with kind
            ``"failed"`` (its best iterate in ``nodes``), never raised: callers decide.

        Raises:
            InvalidArgument: bad shapes or values.
        """
        n, N = self.n, self.nodes
        t0 = time.perf_counter()
        q0 = check_vector(q0, n, "q0")
        q1 = check_vector(q1, n, "q1")
        budget = check_positive(budget, "budget", "s")
        steps = check_int(steps, "steps", low=1)
        if warm is not None and (warm.multipliers is None or len(warm.nodes) != N + 1):
            raise InvalidArgument(
                f"warm: needs a result with multipliers of a collocation with {N} segments"
            )
        if warm is not None:
            init, init_t = warm.nodes, None
        if init is not None and init_t is not None:
            guess = interpolate_path(init, init_t, N, n)
        else:
            guess = resample_path(np.array([q0, q1]) if init is None else init, N, n)
        rows = len(self.point_times) if self.constraints_per_node else 0
        lbg: float | np.ndarray = self.margin
        if lower is not None:
            lower = np.asarray(lower, dtype=np.float64)
            bad = np.isnan(lower) | np.isposinf(lower)
            if lower.shape != (rows, self.constraints_per_node) or bad.any():
                raise InvalidArgument(
                    f"lower must have shape ({rows}, {self.constraints_per_node}) (points, "
                    f"constraints per point) without NaN or +inf, got {lower.shape}"
                )
            lbg = lower.ravel()
        guess[0], guess[-1] = q0, q1
        lo = np.clip(np.minimum(self.q_min, self.q_max), -1e20, 1e20)
        hi = np.clip(self.q_max, -1e20, 1e20)
        x0 = np.clip(guess[1:-1], lo, hi).ravel()
        self._deadline.reset(budget)
        solver, extra = self.solver(mu_init), {}
        if warm is not None:
            solver, extra = self._warm(), self._warm_multipliers(warm)
        sol = solver(
            **extra,
            x0=x0,
            p=self.parameters(q0, q1),
            lbx=np.tile(lo, N - 1),
            ubx=np.tile(hi, N - 1),
            lbg=lbg,
            ubg=np.inf,
        )
        stats = solver.stats()
        status = str(stats.get("return_status", "unknown"))
        iterations = int(stats.get("iter_count", 0))
        kkt = float(stats["iterations"]["inf_du"][-1]) if stats.get("iterations") else math.nan
        nodes = np.vstack([q0, np.asarray(sol["x"]).reshape(N - 1, n), q1])
        energy = float(sol["f"])
        g = np.asarray(sol["g"]).ravel()
        has_obstacles = self.clearance is not None and bool(self.clearance.obstacles)
        min_clear = float(g.min()) if has_obstacles else math.inf
        at_limit = int(np.sum((nodes[1:-1] - lo < ACTIVE_TOL) | (hi - nodes[1:-1] < ACTIVE_TOL)))
        active = int(np.sum(g - lbg < ACTIVE_TOL)) + at_limit
        v0 = N * (-1.5 * nodes[0] + 2.0 * nodes[1] - 0.5 * nodes[2])
        t = np.linspace(0.0, 1.0, N + 1)
        ok = bool(stats.get("success", False))
        wall = time.perf_counter() - t0
        mult = (np.asarray(sol["lam_x"]).ravel(), np.asarray(sol["lam_g"]).ravel())
        base = dict(energy=energy, nodes=nodes, min_clearance=min_clear, active=active,
                    kkt_residual=kkt, iterations=iterations, status=status,
                    multipliers=mult)  # fmt: skip
        if not ok:
            msg = f"IPOPT: {status} after {iterations} iterations ({wall:.2f} s of {budget:g} s)"
            return CollocationResult(t, nodes, "failed", v0=v0, geodesic_residual=math.nan,
                                     wall_time=wall, message=msg, **base)  # type: ignore[arg-type]  # fmt: skip
        if active:
            bound = f"clearance margin {self.margin:g} m" if lower is None else "clearance bounds"
            msg = (f"minimum-energy path with {active} active constraint(s) "
                   f"({bound} or joint limits): not a geodesic")  # fmt: skip
            return CollocationResult(t, nodes, "constrained", v0=v0, geodesic_residual=math.nan,
                                     wall_time=wall, message=msg, **base)  # type: ignore[arg-type]  # fmt: skip
        why = "refinement not asked (refine=False)"
        if refine:
            res, geo, clear, why = refine_by_shooting(
                self.metric, q0, q1, v0, steps, (lo, hi), self.node_clearances
            )
            if res is not None and geo is not None and clear is not None:
                wall = time.perf_counter() - t0
                msg = (f"geodesic: collocation ({iterations} IPOPT iterations), then "
                       f"shooting ({res.method}, residual {res.residual:.1e} rad)")  # fmt: skip
                base["min_clearance"] = float(clear.min()) if clear.size else math.inf
                return CollocationResult(geo.t, geo.q, "geodesic", v0=res.v0,
                                         geodesic_residual=res.residual, wall_time=wall,
                                         message=msg, **base)  # type: ignore[arg-type]  # fmt: skip
        wall = time.perf_counter() - t0
        msg = f"discrete geodesic of {N} segments (no constraint active); {why}"
        return CollocationResult(t, nodes, "discrete geodesic", v0=v0, geodesic_residual=math.nan,
                                 wall_time=wall, message=msg, **base)  # type: ignore[arg-type]  # fmt: skip
