"""Metric shaping: `MetricTerm` and `ShapedMetric`, a base metric plus shaping terms.

A shaping term adds a symmetric positive semi-definite matrix to a base metric (usually
the kinetic-energy metric), in the style of Riemannian motion policies:

.. math:: G(q, \\dot q) = G_0(q) + \\sum_k G_k(q, \\dot q)

`ShapedMetric` is itself a `Metric`, so geodesics (exp, log), transport, synergies and
controllers take it unchanged. Its Christoffel symbols come from the CasADi symbolic form
of the sum, term derivatives included.

Parameters. A term may depend on a numeric parameter vector besides ``q`` (an
`ObstacleTerm` keeps the poses and sizes of its obstacles there). The term owns a CasADi
symbol for it (`MetricTerm.symbolic_parameters`) and a numpy array of its current values
(`MetricTerm.parameter_values`). Every compiled function of a `ShapedMetric` takes the
stacked parameter vector as an extra last input, filled from the terms at call time, so
changing parameter values rebuilds nothing. Code that builds its own CasADi functions from
``metric.symbolic_*`` (exp, log) must do the same with ``metric.symbolic_parameters()``
and ``metric.parameter_values()``; both are empty for a metric without parameters.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable, Sequence

import casadi as ca
import numpy as np

from geosyn.core.errors import InvalidArgument
from geosyn.core.types import Matrix, Vector
from geosyn.core.validation import check_vector
from geosyn.metrics.base import Metric, MetricFunctions, sx_cholesky_solve
from geosyn.metrics.shaping.errors import (
    InvalidTermArgument,
    TermAlreadyBound,
    TermNotBound,
)
from geosyn.robots.robot import Robot

__all__ = ["MetricTerm", "ShapedMetric"]


def _numpy_call(fun: ca.Function) -> Callable[..., tuple[np.ndarray, ...]]:
    from geosyn.core.codegen import numpy_function

    return numpy_function(fun)


def _maybe_compile(fun: ca.Function, compile: bool) -> ca.Function:
    if not compile:
        return fun
    from geosyn.core.codegen import compile_function

    return compile_function(fun, fallback=True)


class MetricTerm(ABC):
    """A shaping term: a symmetric PSD matrix ``G_term(q)`` or ``G_term(q, qdot)``.

    A term is created with its own settings, then bound to one robot with `bind` (a
    `ShapedMetric` binds its terms to ``base.robot``). After binding, `symbolic_G` gives the
    CasADi form and `G` evaluates it through a CasADi function built once, on first use.

    Subclasses implement `symbolic_G` and may override `_on_bind` (validation against the
    robot), `symbolic_parameters` and `parameter_values` (for terms with parameters).

    Attributes:
        velocity_dependent: True if `symbolic_G` uses ``v`` (velocity-gated terms). With
            ``v=None`` such a term is evaluated at ``v = 0``.
        build_count: how many times the numeric function was built (for tests that check
            nothing is rebuilt).
    """

    velocity_dependent: bool = False

    def __init__(self) -> None:
        self._robot: Robot | None = None
        self._call: Callable[..., tuple[np.ndarray, ...]] | None = None
        self.build_count = 0

    # -- binding ---------------------------------------------------------------------
    def bind(self, robot: Robot) -> MetricTerm:
        """Bind the term to a robot (validates robot-dependent settings; cheap).

        Binding again to the same robot is a no-op.

        Args:
            robot: the robot whose configuration space the term lives on.

        Returns:
            The term itself.

        Raises:
            InvalidArgument: ``robot`` is not a `Robot`.
            TermAlreadyBound: the term is already bound to a different robot.
        """
        if not isinstance(robot, Robot):
            raise InvalidArgument(f"robot must be a geosyn Robot, got {type(robot).__name__}")
        if self._robot is robot:
            return self
        if self._robot is not None:
            raise TermAlreadyBound(
                f"{type(self).__name__} is bound to robot {self._robot.name!r}; "
                f"create a new term for robot {robot.name!r}"
            )
        self._on_bind(robot)
        self._robot = robot
        return self

    def _on_bind(self, robot: Robot) -> None:
        """Validate and precompute robot-dependent data (override; default nothing)."""
        return None

    @property
    def robot(self) -> Robot:
        """The bound robot.

        Raises:
            TermNotBound: `bind` was not called.
        """
        if self._robot is None:
            raise TermNotBound(
                f"{type(self).__name__} is not bound to a robot; call term.bind(robot) or "
                "pass it to ShapedMetric(base, [term])"
            )
        return self._robot

    @property
    def n(self) -> int:
        """Dimension of the configuration space of the bound robot."""
        return self.robot.nv

    # -- symbolic --------------------------------------------------------------------
    @abstractmethod
    def symbolic_G(self, q: ca.SX, v: ca.SX | None = None) -> ca.SX:
        """CasADi expression of the term.

        Args:
            q: (n, 1) SX joint positions [rad].
            v: (n, 1) SX joint velocities [rad/s]; used only by velocity-dependent terms,
                which take ``v = 0`` when it is None.

        Returns:
            (n, n) symmetric PSD SX expression [kg m^2 when added to the kinetic-energy
            metric]. It may contain `symbolic_parameters`.
        """

    def symbolic_parameters(self) -> ca.SX:
        """(p, 1) SX parameter symbol of the term (empty by default)."""
        return ca.SX(0, 1)

    def parameter_values(self) -> np.ndarray:
        """(p,) current parameter values (empty by default). Not a copy: do not modify."""
        return np.zeros(0)

    def parameter_homotopy(self, s: float) -> np.ndarray:
        """(p,) parameters of an easier term at ``s`` in [0, 1] (default: unchanged)."""
        return self.parameter_values()

    # -- numeric ---------------------------------------------------------------------
    def build_function(self) -> ca.Function:
        """CasADi function ``(q, v, p) -> G_term`` (allocates; called once by `G`)."""
        n = self.n
        q = ca.SX.sym("q", n)
        v = ca.SX.sym("v", n)
        p = self.symbolic_parameters()
        g = self.symbolic_G(q, v if self.velocity_dependent else None)
        self.build_count += 1
        return ca.Function(
            f"{type(self).__name__}_G",
            [q, v, p],
            [ca.densify(g)],
            ["q", "v", "p"],
            ["G"],
            {"cse": True},
        )

    def G(self, q: Vector, v: Vector | None = None) -> Matrix:
        """The term's matrix.

        The first call builds the CasADi function (allocates); later calls only evaluate.

        Args:
            q: (n,) joint positions [rad].
            v: (n,) joint velocities [rad/s]; None means zero (only velocity-dependent
                terms use it).

        Returns:
            (n, n) symmetric PSD matrix (a new array).
        """
        n = self.n
        q = check_vector(q, n, "q")
        v = np.zeros(n) if v is None else check_vector(v, n, "v")
        if self._call is None:
            self._call = _numpy_call(self.build_function())
        return self._call(q, v, self.parameter_values())[0].copy()


class ShapedMetric(Metric):
    """A base metric plus shaping terms; itself a `Metric`.

    .. math:: G(q, \\dot q) = G_0(q) + \\sum_k G_k(q, \\dot q)

    Geodesic equation. For terms that do not depend on velocity this is the ordinary
    Levi-Civita geodesic equation of the summed metric,
    ``G(q) qdd + c(q, qd) = 0`` with ``c_i = sum_jk Gamma_ijk qd_j qd_k``.
    For velocity-gated terms (``G_k(q, qdot)``) we follow RMPflow's simplification: the
    curvature term is built from ``dG/dq`` only, with ``qdot`` frozen inside ``G``, and
    the terms from ``dG/dqdot`` (RMPflow's ``Xi``) are dropped:

    .. math::
        G(q, \\dot q)\\, \\ddot q + \\Big[\\partial_q\\big(G(q, u) u\\big) u
        - \\tfrac12 \\partial_q\\big(u^T G(q, u) u\\big)\\Big]_{u = \\dot q} = 0

    so the energy ``1/2 qd^T G(q, qd) qd`` is not exactly conserved along such curves. With
    no velocity-gated term both forms agree. `G`, `dG` and `christoffel` without a velocity
    evaluate velocity-gated terms at ``qdot = 0``; `coriolis` and `geodesic_acceleration`
    use the given velocity.

    Parameters: `symbolic_parameters` stacks the terms' parameter symbols and
    `parameter_values` their current values; every compiled function in `functions` takes
    the parameter vector as its last input: ``G(q, p)``, ``dG(q, p)``,
    ``christoffel(q, p)``, ``coriolis(q, v, p)``, ``geodesic_acceleration(q, v, p)``.
    Changing a term's parameter values (moving an obstacle) rebuilds nothing.

    Args:
        base: the base metric; must have a ``robot`` attribute (e.g.
            `KineticEnergyMetric`) and a symbolic form for derivatives.
        terms: shaping terms; each is bound to ``base.robot``.
        compile: compile the CasADi functions to C (cached on disk, see
            `geosyn.core.codegen`) when they are first built.

    `G` uses the base metric's numeric fast path plus one compiled function for the sum of
    the terms; it allocates only its result. `build_count` counts builds of the compiled
    functions (for tests that check that nothing is rebuilt).
    """

    def __init__(
        self, base: Metric, terms: Sequence[MetricTerm] = (), *, compile: bool = False
    ) -> None:
        if not isinstance(base, Metric):
            raise InvalidTermArgument(f"base must be a geosyn Metric, got {type(base).__name__}")
        robot = getattr(base, "robot", None)
        if not isinstance(robot, Robot):
            raise InvalidTermArgument(
                f"base must have a `robot` attribute holding a geosyn Robot (as "
                f"KineticEnergyMetric does), got {type(base).__name__} without one"
            )
        if isinstance(terms, MetricTerm):
            terms = [terms]
        terms = list(terms)
        for i, t in enumerate(terms):
            if not isinstance(t, MetricTerm):
                raise InvalidTermArgument(
                    f"terms[{i}] must be a MetricTerm, got {type(t).__name__}"
                )
        if len({id(t) for t in terms}) != len(terms):
            raise InvalidTermArgument("terms must not contain the same term object twice")
        self.base = base
        self.robot = robot
        self.n = base.n
        self.compile = bool(compile)
        self.terms: tuple[MetricTerm, ...] = tuple(t.bind(robot) for t in terms)
        self.velocity_dependent = any(t.velocity_dependent for t in self.terms)
        params = [t.symbolic_parameters() for t in self.terms]
        self._p_sym = ca.vertcat(ca.SX(0, 1), *params)
        self._param_terms = [t for t, p in zip(self.terms, params, strict=True) if p.numel()]
        self._terms_call: Callable[..., tuple[np.ndarray, ...]] | None = None
        self._calls: dict[str, Callable[..., tuple[np.ndarray, ...]]] = {}
        self._built: dict[str, ca.Function] = {}
        self._zero = np.zeros(self.n)
        self.build_count = 0

    def __repr__(self) -> str:
        names = ", ".join(type(t).__name__ for t in self.terms)
        return f"ShapedMetric({self.base!r}, [{names}])"

    # -- parameters ------------------------------------------------------------------
    def symbolic_parameters(self) -> ca.SX:
        """(p, 1) SX: the terms' parameter symbols stacked in term order (may be empty)."""
        return self._p_sym

    def parameter_values(self) -> np.ndarray:
        """(p,) current parameter values of the terms, stacked in term order.

        With a single parameterized term this is that term's live array (no copy): read
        it, do not modify it.
        """
        if not self._param_terms:
            return np.zeros(0)
        if len(self._param_terms) == 1:
            return self._param_terms[0].parameter_values()
        return np.concatenate([t.parameter_values() for t in self._param_terms])

    def parameter_homotopy(self, s: float) -> np.ndarray | None:
        """Each parameterised term's easier parameters at ``s`` (e.g. obstacles shrunk
        towards their centres), stacked in term order; None without parameters."""
        if not self._param_terms:
            return None
        return np.concatenate([np.asarray(t.parameter_homotopy(s)) for t in self._param_terms])

    # -- symbolic --------------------------------------------------------------------
    def symbolic_terms_G(self, q: ca.SX, v: ca.SX | None = None) -> ca.SX:
        """SX sum of the terms (velocity-gated terms at ``v = 0`` when ``v`` is None)."""
        out = ca.SX.zeros(self.n, self.n)
        for t in self.terms:
            out = out + t.symbolic_G(q, v if t.velocity_dependent else None)
        return out

    def symbolic_G(self, q: ca.SX, v: ca.SX | None = None) -> ca.SX:  # type: ignore[override]
        """SX of ``G_0(q) + sum_k G_k(q, v)`` (``v = None``: velocity-gated terms at 0)."""
        return self.base.symbolic_G(q) + self.symbolic_terms_G(q, v)

    def symbolic_coriolis(self, q: ca.SX, v: ca.SX) -> ca.SX:
        """SX ``c(q, v)``: the base metric's plus each term's ``dG/dq`` contraction.

        For a term ``G_k``: ``d(G_k(q, u) u)/dq u - 1/2 d(u^T G_k(q, u) u)/dq`` at ``u = v``
        (``u`` held fixed inside velocity-gated terms; see the class docstring).
        """
        c = self.base.symbolic_coriolis(q, v)
        if self.terms:
            gt = self.symbolic_terms_G(q, v)
            gv = ca.mtimes(gt, v)
            c = c + ca.jtimes(gv, q, v) - 0.5 * ca.gradient(ca.dot(v, gv), q)
        return c

    def symbolic_geodesic_acceleration(self, q: ca.SX, v: ca.SX) -> ca.SX:
        """SX ``-G(q, v)^-1 c(q, v)`` by an unrolled Cholesky solve."""
        if not self.terms:
            return self.base.symbolic_geodesic_acceleration(q, v)
        return -sx_cholesky_solve(self.symbolic_G(q, v), self.symbolic_coriolis(q, v))

    # -- compiled functions ----------------------------------------------------------
    def build_functions(self) -> MetricFunctions:
        """Build (and with ``compile=True`` compile) all functions, with the parameter input.

        Allocates; called once, on first use of `functions`. The numeric methods build
        only the function they need (see `build_function`), so e.g. `christoffel` does not
        pay for the geodesic acceleration.
        """
        return MetricFunctions(*(self._function(name) for name in MetricFunctions._fields))

    def build_function(self, name: str) -> ca.Function:
        """Build one function of `MetricFunctions` by field name (allocates).

        Args:
            name: one of ``G``, ``dG``, ``christoffel``, ``coriolis``,
                ``geodesic_acceleration``.

        Returns:
            The CasADi function (dense outputs; compiled to C with ``compile=True``) taking
            ``(q, p)`` or ``(q, v, p)``.
        """
        n = self.n
        q = ca.SX.sym("q", n)
        v = ca.SX.sym("v", n)
        p = self._p_sym
        opts = {"cse": True}
        dense = ca.densify
        if name == "G":
            f = ca.Function(
                "shaped_G", [q, p], [dense(self.symbolic_G(q))], ["q", "p"], ["G"], opts
            )
        elif name in ("dG", "christoffel"):
            dG = ca.jacobian(ca.vec(self.symbolic_G(q)), q)  # (n*n, n), row i + j*n
            if name == "dG":
                out = ca.vertcat(
                    *[ca.horzcat(*[dG[i + j * n, :] for j in range(n)]) for i in range(n)]
                )
            else:
                out = ca.vertcat(
                    *[
                        ca.horzcat(
                            *[
                                0.5 * (dG[i + j * n, k] + dG[i + k * n, j] - dG[j + k * n, i])
                                for j in range(n)
                                for k in range(n)
                            ]
                        )
                        for i in range(n)
                    ]
                )
            f = ca.Function(f"shaped_{name}", [q, p], [dense(out)], ["q", "p"], [name], opts)
        elif name == "coriolis":
            c = dense(self.symbolic_coriolis(q, v))
            f = ca.Function("shaped_coriolis", [q, v, p], [c], ["q", "v", "p"], ["c"], opts)
        elif name == "geodesic_acceleration":
            a = dense(self.symbolic_geodesic_acceleration(q, v))
            f = ca.Function(
                "shaped_geodesic_acceleration", [q, v, p], [a], ["q", "v", "p"], ["a"], opts
            )
        else:
            raise InvalidTermArgument(
                f"name {name!r} is not a metric function; allowed: "
                f"{', '.join(MetricFunctions._fields)}"
            )
        self.build_count += 1
        return _maybe_compile(f, self.compile)

    def _function(self, name: str) -> ca.Function:
        fun = self._built.get(name)
        if fun is None:
            fun = self.build_function(name)
            self._built[name] = fun
        return fun

    def build_terms_function(self) -> ca.Function:
        """CasADi function ``(q, v, p) -> sum_k G_k(q, v)`` (allocates; called once)."""
        n = self.n
        q = ca.SX.sym("q", n)
        v = ca.SX.sym("v", n)
        f = ca.Function(
            "shaped_terms_G",
            [q, v, self._p_sym],
            [ca.densify(self.symbolic_terms_G(q, v))],
            ["q", "v", "p"],
            ["G"],
            {"cse": True},
        )
        self.build_count += 1
        return _maybe_compile(f, self.compile)

    def _call(self, name: str) -> Callable[..., tuple[np.ndarray, ...]]:
        call = self._calls.get(name)
        if call is None:
            call = _numpy_call(self._function(name))
            self._calls[name] = call
        return call

    # -- numeric API -----------------------------------------------------------------
    def terms_G(self, q: Vector, v: Vector | None = None) -> Matrix:
        """Sum of the shaping terms only (no base metric).

        Args:
            q: (n,) joint positions [rad].
            v: (n,) joint velocities [rad/s]; None means zero.

        Returns:
            (n, n) symmetric PSD matrix (a new array).
        """
        q = self._check(q, "q")
        v = self._zero if v is None else self._check(v, "v")
        if not self.terms:
            return np.zeros((self.n, self.n))
        if self._terms_call is None:
            self._terms_call = _numpy_call(self.build_terms_function())
        return self._terms_call(q, v, self.parameter_values())[0].copy()

    def G(self, q: Vector, v: Vector | None = None) -> Matrix:  # type: ignore[override]
        """Shaped metric tensor ``G_0(q) + sum_k G_k(q, v)``.

        Args:
            q: (n,) joint positions [rad].
            v: (n,) joint velocities [rad/s] for velocity-gated terms; None means zero.

        Returns:
            (n, n) symmetric positive-definite matrix [kg m^2 over the kinetic-energy
            metric] (a new array).
        """
        q = self._check(q, "q")
        g = np.array(self.base.G(q), dtype=np.float64)
        if self.terms:
            g += self.terms_G(q, v)
        return g

    def dG(self, q: Vector) -> np.ndarray:
        """(n, n, n) ``[i, j, k] = d g_ij / d q_k`` (velocity-gated terms at ``qdot = 0``)."""
        q = self._check(q, "q")
        out = self._call("dG")(q, self.parameter_values())[0]
        return np.array(out).reshape(self.n, self.n, self.n)

    def christoffel(self, q: Vector) -> np.ndarray:
        """(n, n, n) Christoffel symbols of the first kind ``Gamma[i, j, k]``.

        Velocity-gated terms are taken at ``qdot = 0``.
        """
        q = self._check(q, "q")
        out = self._call("christoffel")(q, self.parameter_values())[0]
        return np.array(out).reshape(self.n, self.n, self.n)

    def coriolis(self, q: Vector, v: Vector) -> Vector:
        """(n,) curvature term ``c(q, v)`` of the geodesic equation (see the class doc)."""
        q = self._check(q, "q")
        v = self._check(v, "v")
        return self._call("coriolis")(q, v, self.parameter_values())[0].copy()

    def geodesic_acceleration(self, q: Vector, v: Vector) -> Vector:
        """(n,) ``-G(q, v)^-1 c(q, v)`` [rad/s^2]."""
        q = self._check(q, "q")
        v = self._check(v, "v")
        return self._call("geodesic_acceleration")(q, v, self.parameter_values())[0].copy()
