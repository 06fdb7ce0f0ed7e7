"""The `Metric` base: a Riemannian metric G(q) on a robot's configuration space.

What a metric is: its dimension `n`, the tensor `G(q)` and, for derivatives, the CasADi
form `symbolic_G` with the parameters it may depend on (`symbolic_parameters`,
`parameter_values`). Everything else derives from these in one place: the symbolic
formulas in `geosyn.metrics.derived`, compiled once per metric into
``metric.functions`` (a `geosyn.metrics.functions.MetricFunctions`; its ``clear()``
forgets them), and evaluated by the numeric methods here (`dG`, `christoffel`,
`coriolis`, `geodesic_acceleration`, `inner`, `norm`, `energy`).

A subclass implements `G` and usually `symbolic_G`; it may override `G`, `coriolis` and
`geodesic_acceleration` with faster numeric paths and `symbolic_coriolis` /
`symbolic_geodesic_acceleration` with better symbolic algorithms (RNEA, ABA).
"""

from __future__ import annotations

import math
import sys
from abc import ABC, abstractmethod
from functools import cached_property

import casadi as ca
import numpy as np

from geosyn.core.errors import InvalidArgument
from geosyn.core.types import Matrix, Vector
from geosyn.core.validation import check_rows, check_vector
from geosyn.metrics.derived import (
    christoffel_from_dG,
    sx_cholesky_solve,
    sx_coriolis,
)
from geosyn.metrics.errors import FloatingBaseUnsupported, NoSymbolicForm
from geosyn.metrics.functions import MetricFunctions

__all__ = ["Metric", "check_metric", "christoffel_from_dG", "sx_cholesky_solve"]


class Metric(ABC):
    """A Riemannian metric on an n-dimensional configuration space.

    Subclasses implement `G` and usually `symbolic_G`. Numeric methods validate their
    inputs: wrong shapes or non-finite values raise `InvalidArgument` naming the argument.

    Attributes:
        n: dimension of the configuration space.
        compile: compile the metric's own functions (`functions`) to C, cached on disk
            (default False: CasADi's VM).
    """

    n: int
    compile: bool = False

    # -- what a metric is ------------------------------------------------------------
    @abstractmethod
    def G(self, q: Vector) -> Matrix:
        """Metric tensor.

        Args:
            q: (n,) joint positions [rad].

        Returns:
            (n, n) symmetric positive-definite metric tensor (for the kinetic-energy
            metric: the mass matrix [kg m^2]).
        """

    def symbolic_G(self, q: ca.SX) -> ca.SX:
        """CasADi SX expression of G(q).

        Args:
            q: (n, 1) SX symbol.

        Returns:
            (n, n) SX expression.

        Raises:
            NoSymbolicForm: this metric has none.
        """
        raise NoSymbolicForm(f"{type(self).__name__} has no symbolic form")

    def symbolic_parameters(self) -> ca.SX:
        """SX symbols (p, 1) that the symbolic forms may depend on besides q and v.

        Parameterised metrics (e.g. obstacle poses in a shaped metric) return their
        parameter symbols here, so compiled functions take them as a last input and
        changing a parameter never rebuilds anything. Default: no parameters (0, 1).
        """
        return ca.SX(0, 1)

    def parameter_values(self) -> np.ndarray:
        """(p,) current numeric values of `symbolic_parameters` (default: empty)."""
        return np.zeros(0)

    # -- symbolic derived quantities (override with a faster algorithm) ----------------
    def symbolic_coriolis(self, q: ca.SX, v: ca.SX) -> ca.SX:
        """SX expression of ``c(q, v) = C(q, v) v``, the Christoffel contraction.

        The default differentiates `symbolic_G` (`geosyn.metrics.derived`); subclasses
        with a recursive algorithm (RNEA) override it.
        """
        return sx_coriolis(self.symbolic_G(q), q, v)

    def symbolic_geodesic_acceleration(self, q: ca.SX, v: ca.SX) -> ca.SX:
        """SX expression of the geodesic acceleration -G^-1 c(q, v).

        The default solves with an unrolled Cholesky of `symbolic_G`; subclasses with a
        recursive algorithm (ABA) override it.
        """
        return -sx_cholesky_solve(self.symbolic_G(q), self.symbolic_coriolis(q, v))

    @cached_property
    def functions(self) -> MetricFunctions:
        """This metric's compiled functions, built on first use and kept.

        The one cache of compiled code for this metric object (the geodesic functions
        included); ``metric.functions.clear()`` empties it.
        """
        return MetricFunctions(self)

    # -- numeric derived quantities ----------------------------------------------------
    def _check(self, x: object, name: str) -> np.ndarray:
        """``x`` as a finite float64 (n,) array (no copy on the fast path), else raise."""
        return check_vector(x, self.n, name)

    def inner(self, q: Vector, u: Vector, v: Vector) -> float:
        """Riemannian inner product <u, v>_q = u^T G(q) v.

        Args:
            q: (n,) joint positions [rad].
            u, v: (n,) tangent vectors [rad/s].
        """
        u = self._check(u, "u")
        v = self._check(v, "v")
        return float(u @ self.G(q) @ v)

    def norm(self, q: Vector, v: Vector) -> float:
        """Riemannian norm sqrt(v^T G(q) v) [sqrt(2 J) for the kinetic-energy metric]."""
        return math.sqrt(max(self.inner(q, v, v), 0.0))

    def energy(self, q: Vector, v: Vector) -> float:
        """Kinetic energy 1/2 v^T G(q) v [J for the kinetic-energy metric]."""
        return 0.5 * self.inner(q, v, v)

    def dG(self, q: Vector) -> np.ndarray:
        """Metric derivatives.

        Args:
            q: (n,) joint positions [rad].

        Returns:
            (n, n, n) with ``[i, j, k] = d g_ij / d q_k``.
        """
        q = self._check(q, "q")
        return self.functions.evaluate("dG", q).reshape(self.n, self.n, self.n)

    def quadratic_gradient(self, q: Vector, d: Vector) -> Vector:
        """Gradient in ``q`` of the quadratic form ``d^T G(q) d``.

        Args:
            q: (n,) joint positions [rad].
            d: (n,) a tangent vector (e.g. a path segment) [rad].

        Returns:
            (n,) ``[k] = d^T (d G / d q_k) d`` (for the kinetic-energy metric [kg m^2]).
        """
        d = self._check(d, "d")
        return np.einsum("i,ijk,j->k", d, self.dG(q), d)

    def G_many(self, Q: np.ndarray) -> np.ndarray:
        """`G` at each of K configurations, their input checked once.

        Args:
            Q: (K, n) joint positions [rad], one configuration per row.

        Returns:
            (K, n, n) ``[k] = G(Q[k])``.
        """
        Q = check_rows(Q, self.n, "Q")
        out = np.empty((len(Q), self.n, self.n))
        for k, q in enumerate(Q):
            out[k] = self.G(q)
        return out

    def quadratic_gradients(self, Q: np.ndarray, D: np.ndarray) -> np.ndarray:
        """`quadratic_gradient` at K pairs (configuration, tangent vector), their input
        checked once.

        Args:
            Q: (K, n) joint positions [rad], one configuration per row.
            D: (K, n) tangent vectors [rad], ``D[k]`` at ``Q[k]``.

        Returns:
            (K, n) ``[k] = quadratic_gradient(Q[k], D[k])``.
        """
        Q, D = self._pairs(Q, D)
        out = np.empty_like(D)
        for k, (q, d) in enumerate(zip(Q, D, strict=True)):
            out[k] = self.quadratic_gradient(q, d)
        return out

    def _pairs(self, Q: object, D: object) -> tuple[np.ndarray, np.ndarray]:
        """``Q`` and ``D`` as finite float64 (K, n) arrays of one K, else raise."""
        Q, D = check_rows(Q, self.n, "Q"), check_rows(D, self.n, "D")
        if len(Q) != len(D):
            raise InvalidArgument(f"D must have as many rows as Q ({len(Q)}), got shape {D.shape}")
        return Q, D

    def christoffel(self, q: Vector) -> np.ndarray:
        """Christoffel symbols of the first kind.

        Args:
            q: (n,) joint positions [rad].

        Returns:
            (n, n, n) ``Gamma[i, j, k]``, symmetric in (j, k), such that
            ``c_i = sum_jk Gamma_ijk v_j v_k``.
        """
        q = self._check(q, "q")
        return self.functions.evaluate("christoffel", q).reshape(self.n, self.n, self.n)

    def coriolis(self, q: Vector, v: Vector) -> Vector:
        """Coriolis and centrifugal term ``C(q, v) v``.

        Args:
            q: (n,) joint positions [rad].
            v: (n,) joint velocities [rad/s].

        Returns:
            (n,) ``c_i = sum_jk Gamma_ijk v_j v_k`` [N m for the kinetic-energy metric].
        """
        q = self._check(q, "q")
        v = self._check(v, "v")
        return self.functions.evaluate("coriolis", q, v)

    def geodesic_acceleration(self, q: Vector, v: Vector) -> Vector:
        """Acceleration of the geodesic through (q, v): ``-G(q)^-1 C(q, v) v``.

        Args:
            q: (n,) joint positions [rad].
            v: (n,) joint velocities [rad/s].

        Returns:
            (n,) joint accelerations [rad/s^2].
        """
        q = self._check(q, "q")
        v = self._check(v, "v")
        return self.functions.evaluate("geodesic_acceleration", q, v)


def check_metric(metric: object) -> Metric:
    """Return ``metric`` if it is a `Metric` on a vector space, else raise.

    Args:
        metric: candidate metric.

    Raises:
        InvalidArgument: not a `Metric`.
        FloatingBaseUnsupported: a floating base's metric (``metric.nq != metric.n``);
            the message names the calling function.
    """
    if not isinstance(metric, Metric):
        raise InvalidArgument(f"metric must be a geosyn Metric, got {type(metric).__name__}")
    nq = getattr(metric, "nq", metric.n)
    if nq != metric.n:  # a floating base: configurations on SE(3) x R^n, not vectors
        frame = sys._getframe(1)  # the refused operation, for the message
        caller = frame.f_code.co_name
        if caller == "__init__" and "self" in frame.f_locals:
            caller = type(frame.f_locals["self"]).__name__
        raise FloatingBaseUnsupported(
            f"{caller}: {metric!r} is a floating base's metric (nq={nq} != nv={metric.n});"
            f" {caller} treats configurations as vectors in R^n and does not work on"
            " SE(3) x R^n yet. Available there: exp, metric.G/inner/energy/integrate;"
            " or load the robot with fixed_base=True"
        )
    return metric
