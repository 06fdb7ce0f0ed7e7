"""The `Metric` base: a Riemannian metric G(q) on a robot's configuration space.

A subclass implements `G` (numeric) and, for derivatives, `symbolic_G` (CasADi SX). From
the symbolic form the base class builds, once and lazily, compiled CasADi functions for
dG/dq, the Christoffel symbols of the first kind, the Coriolis term and the geodesic
acceleration. Subclasses may override any numeric method with a faster path.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from functools import cached_property
from typing import NamedTuple

import casadi as ca
import numpy as np

from geosyn.core.types import Matrix, Vector
from geosyn.core.validation import check_vector
from geosyn.metrics.errors import NoSymbolicForm


class MetricFunctions(NamedTuple):
    """Compiled CasADi functions of a metric (SX graphs, evaluated by CasADi's VM or C).

    All take column vectors; shapes below are CasADi (rows, cols).

    Attributes:
        G: q (n,1) -> G (n,n).
        dG: q -> (n, n*n) with ``dG[i, j*n + k] = d g_ij / d q_k``.
        christoffel: q -> (n, n*n) with ``[i, j*n + k] = Gamma_ijk`` (first kind).
        coriolis: (q, v) -> (n,1) ``c_i = sum_jk Gamma_ijk v_j v_k``.
        geodesic_acceleration: (q, v) -> (n,1) ``-G^-1 c``.
    """

    G: ca.Function
    dG: ca.Function
    christoffel: ca.Function
    coriolis: ca.Function
    geodesic_acceleration: ca.Function


def sx_cholesky_solve(A: ca.SX, b: ca.SX) -> ca.SX:
    """Solve ``A x = b`` for symmetric positive-definite SX ``A`` by an unrolled Cholesky.

    Keeps the graph O(n^3 / 6) instead of the much larger symbolic inverse.

    Args:
        A: (n, n) SPD matrix expression.
        b: (n, m) right-hand side.

    Returns:
        (n, m) solution expression.
    """
    n = A.shape[0]
    L = [[ca.SX(0.0) for _ in range(n)] for _ in range(n)]
    for j in range(n):
        s = A[j, j]
        for k in range(j):
            s = s - L[j][k] * L[j][k]
        L[j][j] = ca.sqrt(s)
        for i in range(j + 1, n):
            s = A[i, j]
            for k in range(j):
                s = s - L[i][k] * L[j][k]
            L[i][j] = s / L[j][j]
    cols = []
    for c in range(b.shape[1]):
        y = [ca.SX(0.0)] * n
        for i in range(n):
            s = b[i, c]
            for k in range(i):
                s = s - L[i][k] * y[k]
            y[i] = s / L[i][i]
        x = [ca.SX(0.0)] * n
        for i in reversed(range(n)):
            s = y[i]
            for k in range(i + 1, n):
                s = s - L[k][i] * x[k]
            x[i] = s / L[i][i]
        cols.append(ca.vertcat(*x))
    return ca.horzcat(*cols)


def christoffel_from_dG(dG: np.ndarray) -> np.ndarray:
    """Christoffel symbols of the first kind from metric derivatives.

    .. math:: \\Gamma_{ijk} = \\tfrac12 (\\partial_k g_{ij} + \\partial_j g_{ik} - \\partial_i g_{jk})

    Args:
        dG: (n, n, n) with ``dG[i, j, k] = d g_ij / d q_k``.

    Returns:
        (n, n, n) ``Gamma[i, j, k]``, symmetric in (j, k).
    """
    return 0.5 * (dG + dG.transpose(0, 2, 1) - dG.transpose(2, 0, 1))


class Metric(ABC):
    """A Riemannian metric on an n-dimensional configuration space.

    Subclasses implement `G` and usually `symbolic_G`. Numeric methods validate their
    inputs: wrong shapes or non-finite values raise `InvalidArgument` naming the argument.

    Attributes:
        n: dimension of the configuration space.
    """

    n: int

    # -- to implement ----------------------------------------------------------------
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

    def parameter_homotopy(self, s: float) -> np.ndarray | None:
        """Parameter values of an easier metric, for continuation in the log map.

        `geosyn.metrics.geodesic.log_solve` solves at ``s = 0`` first and follows the
        solution to the current parameters at ``s = 1``. Default: no homotopy (None).

        Args:
            s: homotopy parameter in [0, 1]; 0 the easiest problem.

        Returns:
            (p,) parameter values at ``s``, or None when the metric has no homotopy.
        """
        return None

    def symbolic_geodesic_acceleration(self, q: ca.SX, v: ca.SX) -> ca.SX:
        """SX expression of the geodesic acceleration -G^-1 c(q, v).

        The default solves with an unrolled Cholesky of `symbolic_G`; subclasses with a
        recursive algorithm (ABA) override it.
        """
        return -sx_cholesky_solve(self.symbolic_G(q), self.symbolic_coriolis(q, v))

    def symbolic_coriolis(self, q: ca.SX, v: ca.SX) -> ca.SX:
        """SX expression of ``c(q, v) = C(q, v) v``, the Christoffel contraction.

        Uses ``c = d(G v)/dq v - 1/2 d(v^T G v)/dq``, which needs no (n, n, n) tensor.
        """
        Gq = self.symbolic_G(q)
        Gv = ca.mtimes(Gq, v)
        return ca.jtimes(Gv, q, v) - 0.5 * ca.gradient(ca.dot(v, Gv), q)

    # -- input checks ----------------------------------------------------------------
    def _check(self, x: object, name: str) -> np.ndarray:
        """``x`` as a finite float64 (n,) array (no copy on the fast path), else raise."""
        return check_vector(x, self.n, name)

    # -- compiled symbolic functions -----------------------------------------------------
    def build_functions(self) -> MetricFunctions:
        """Build the CasADi functions from the symbolic form (allocates; called once).

        Subclasses may override to compile them to C (see `geosyn.core.codegen`).
        """
        n = self.n
        q = ca.SX.sym("q", n)
        v = ca.SX.sym("v", n)
        p = self.symbolic_parameters()
        extra = [p] if p.numel() > 0 else []
        extra_names = ["p"] if extra else []
        Gq = self.symbolic_G(q)
        dG = ca.jacobian(ca.vec(Gq), q)  # (n*n, n), row i + j*n (column-major vec)
        # Reorder to dG[i, j*n + k] = d g_ij / d q_k.
        dG_ijk = ca.vertcat(*[ca.horzcat(*[dG[i + j * n, :] for j in range(n)]) for i in range(n)])
        gam_rows = []
        for i in range(n):
            row = []
            for j in range(n):
                for k in range(n):
                    row.append(0.5 * (dG[i + j * n, k] + dG[i + k * n, j] - dG[j + k * n, i]))
            gam_rows.append(ca.horzcat(*row))
        gam = ca.vertcat(*gam_rows)
        opts = {"cse": True}
        qn, qvn = ["q", *extra_names], ["q", "v", *extra_names]
        # Dense outputs: structural zeros would otherwise change shapes between metrics.
        Gq, dG_ijk, gam = ca.densify(Gq), ca.densify(dG_ijk), ca.densify(gam)
        return MetricFunctions(
            G=ca.Function("G", [q, *extra], [Gq], qn, ["G"], opts),
            dG=ca.Function("dG", [q, *extra], [dG_ijk], qn, ["dG"], opts),
            christoffel=ca.Function("christoffel", [q, *extra], [gam], qn, ["Gamma"], opts),
            coriolis=ca.Function(
                "coriolis",
                [q, v, *extra],
                [ca.densify(self.symbolic_coriolis(q, v))],
                qvn,
                ["c"],
                opts,
            ),
            geodesic_acceleration=ca.Function(
                "geodesic_acceleration",
                [q, v, *extra],
                [ca.densify(self.symbolic_geodesic_acceleration(q, v))],
                qvn,
                ["a"],
                opts,
            ),
        )

    def _eval(self, f: ca.Function, *args: np.ndarray) -> np.ndarray:
        """Evaluate one of `functions` on numpy arrays, appending the parameter values if
        it takes them; returns a new array (the first output, column vectors flattened).

        Calls go through CasADi's zero-copy buffers (`geosyn.core.codegen.numpy_function`),
        one wrapper per function, made on first use: ~1 us instead of ~20 us of DM
        conversion. Not thread-safe: use one metric object per thread.
        """
        wrappers = self.__dict__.setdefault("_numpy_wrappers", {})
        call = wrappers.get(id(f))
        if call is None:
            from geosyn.core.codegen import numpy_function

            call = wrappers[id(f)] = numpy_function(f)
        if f.n_in() > len(args):
            args = (*args, self.parameter_values())
        return call(*args)[0].copy()

    @cached_property
    def functions(self) -> MetricFunctions:
        """The compiled CasADi functions, built on first use and kept."""
        return self.build_functions()

    # -- numeric API -----------------------------------------------------------------
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

    def dG(self, q: Vector) -> np.ndarray:
        """Metric derivatives.

        Args:
            q: (n,) joint positions [rad].

        Returns:
            (n, n, n) with ``[i, j, k] = d g_ij / d q_k``.
        """
        q = self._check(q, "q")
        return self._eval(self.functions.dG, q).reshape(self.n, self.n, self.n)

    def christoffel(self, q: Vector) -> np.ndarray:
        """Christoffel symbols of the first kind.

        Args:
            q: (n,) joint positions [rad].

        Returns:
            (n, n, n) ``Gamma[i, j, k]``, symmetric in (j, k), such that
            ``c_i = sum_jk Gamma_ijk v_j v_k``.
        """
        q = self._check(q, "q")
        return self._eval(self.functions.christoffel, q).reshape(self.n, self.n, self.n)

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
        return self._eval(self.functions.coriolis, q, v)

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
        return self._eval(self.functions.geodesic_acceleration, q, v)

    def symbolic_G_numeric(self, q: Vector) -> Matrix:
        """G(q) evaluated through the symbolic form (a check of `G`'s fast path).

        Args:
            q: (n,) joint positions [rad].

        Returns:
            (n, n) metric tensor.
        """
        q = self._check(q, "q")
        return self._eval(self.functions.G, q)

    def energy(self, q: Vector, v: Vector) -> float:
        """Kinetic energy 1/2 v^T G(q) v [J for the kinetic-energy metric]."""
        return 0.5 * self.inner(q, v, v)
