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
(`MetricTerm.parameter_values`). A `ShapedMetric` stacks them; its compiled functions
(``metric.functions``, see `geosyn.metrics.functions`) take the stacked vector as a last
input, filled from the terms at call time, so changing parameter values rebuilds nothing.
Code that builds its own CasADi functions from ``metric.symbolic_*`` (exp, log) does the
same with ``metric.symbolic_parameters()`` and ``metric.parameter_values()``. A term may
also offer ``parameter_homotopy(s)`` (easier parameters, e.g. obstacles shrunk to points),
which the log map's parameter continuation uses (`geosyn.metrics.geodesic.continuation`).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable, Sequence

import casadi as ca
import numpy as np

from geosyn.core.calls import numpy_function
from geosyn.core.codegen import compile_function
from geosyn.core.errors import InvalidArgument
from geosyn.core.types import Matrix, Vector
from geosyn.core.validation import check_vector
from geosyn.metrics.base import Metric, check_metric
from geosyn.metrics.derived import sx_cholesky_solve, sx_coriolis
from geosyn.metrics.shaping.errors import (
    InvalidTermArgument,
    TermAlreadyBound,
    TermNotBound,
)
from geosyn.robots.robot import Robot

__all__ = ["MetricTerm", "ShapedMetric"]


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
            self._call = numpy_function(self.build_function())
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

    What it adds to `Metric`: the symbolic form of the sum (`symbolic_G`,
    `symbolic_coriolis`, `symbolic_geodesic_acceleration`), the stacked term parameters
    and a numeric `G` on the base metric's fast path plus one compiled function for the
    terms (`terms_G`); dG, Christoffel symbols, Coriolis term and geodesic acceleration
    come from `Metric`. Parameters: `symbolic_parameters` stacks the terms' parameter
    symbols and `parameter_values` their current values, filled in at call time, so
    changing a term's parameter values (moving an obstacle) rebuilds nothing.

    Args:
        base: the base metric; must have a ``robot`` attribute (e.g.
            `KineticEnergyMetric`) and a symbolic form for derivatives.
        terms: shaping terms; each is bound to ``base.robot``.
        compile: compile the CasADi functions to C (cached on disk, see
            `geosyn.core.codegen`) when they are first built.

    `G` allocates only its result.

    Attributes:
        base: the base metric.
        robot: the base metric's robot.
        terms: the shaping terms, in order.
        parameter_terms: the terms with a parameter vector, in order (their values make
            up `parameter_values`).
        velocity_dependent: True if some term depends on the velocity.
    """

    def __init__(
        self, base: Metric, terms: Sequence[MetricTerm] = (), *, compile: bool = False
    ) -> None:
        if not isinstance(base, Metric):
            raise InvalidTermArgument(f"base must be a geosyn Metric, got {type(base).__name__}")
        check_metric(base)  # refuses a floating base's metric (configurations on SE(3))
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
        self.parameter_terms: tuple[MetricTerm, ...] = tuple(
            t for t, p in zip(self.terms, params, strict=True) if p.numel()
        )
        self._zero = np.zeros(self.n)

    def __repr__(self) -> str:
        names = ", ".join(type(t).__name__ for t in self.terms)
        return f"ShapedMetric({self.base!r}, [{names}])"

    @property
    def build_count(self) -> int:
        """How many compiled functions were built for this metric (``functions.builds``)."""
        return self.functions.builds

    # -- parameters ------------------------------------------------------------------
    def symbolic_parameters(self) -> ca.SX:
        """(p, 1) SX: the terms' parameter symbols stacked in term order (may be empty)."""
        return self._p_sym

    def parameter_values(self) -> np.ndarray:
        """(p,) current parameter values of the terms, stacked in term order.

        With a single parameterized term this is that term's live array (no copy): read
        it, do not modify it.
        """
        if not self.parameter_terms:
            return np.zeros(0)
        if len(self.parameter_terms) == 1:
            return self.parameter_terms[0].parameter_values()
        return np.concatenate([t.parameter_values() for t in self.parameter_terms])

    # -- symbolic --------------------------------------------------------------------
    def symbolic_terms_G(self, q: ca.SX, v: ca.SX | None = None) -> ca.SX:
        """SX sum of the terms (velocity-gated terms at ``v = 0`` when ``v`` is None)."""
        out = ca.SX.zeros(self.n, self.n)
        for t in self.terms:
            out = out + t.symbolic_G(q, v if t.velocity_dependent else None)
        return out

    def symbolic_G(self, q: ca.SX, v: ca.SX | None = None) -> ca.SX:
        """SX of ``G_0(q) + sum_k G_k(q, v)`` (``v = None``: velocity-gated terms at 0)."""
        return self.base.symbolic_G(q) + self.symbolic_terms_G(q, v)

    def symbolic_coriolis(self, q: ca.SX, v: ca.SX) -> ca.SX:
        """SX ``c(q, v)``: the base metric's plus the terms' ``dG/dq`` contraction.

        For the terms ``G_k``: ``d(G_k(q, u) u)/dq u - 1/2 d(u^T G_k(q, u) u)/dq`` at
        ``u = v`` (``u`` held fixed inside velocity-gated terms; see the class docstring).
        """
        c = self.base.symbolic_coriolis(q, v)
        if not self.terms:
            return c
        return sx_coriolis(self.symbolic_terms_G(q, v), q, v, plus=c)

    def symbolic_geodesic_acceleration(self, q: ca.SX, v: ca.SX) -> ca.SX:
        """SX ``-G(q, v)^-1 c(q, v)`` by an unrolled Cholesky solve."""
        if not self.terms:
            return self.base.symbolic_geodesic_acceleration(q, v)
        return -sx_cholesky_solve(self.symbolic_G(q, v), self.symbolic_coriolis(q, v))

    # -- numeric ---------------------------------------------------------------------
    def _build_terms_function(self) -> ca.Function:
        """CasADi function ``(q, v, p) -> sum_k G_k(q, v)`` (allocates; built once)."""
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
        return compile_function(f, fallback=True) if self.compile else f

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
        return self.functions.evaluate("terms_G", q, v, build=self._build_terms_function)

    def G(self, q: Vector, v: Vector | None = None) -> Matrix:
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
