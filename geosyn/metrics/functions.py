"""`MetricFunctions`: the one cache of compiled CasADi functions of a metric.

Each `Metric` object owns one, ``metric.functions``, created on first use. It holds the
metric's own functions (`G`, `dG`, `christoffel`, `coriolis`, `geodesic_acceleration`,
built from the symbolic form by `build_metric_function`) and every function other code
builds for that metric (the geodesic RK4 step, shooting maps and transport operator of
`geosyn.metrics.geodesic`, the shaping terms' sum of a `ShapedMetric`), each under a key.
Entries live as long as the metric object; ``metric.functions.clear()`` forgets them all
(the compiled C libraries stay in the disk cache, which `geosyn.core.codegen.clear_cache`
empties).

Parameterised metrics: a function takes ``metric.symbolic_parameters()`` as its last input
when that is not empty, and `MetricFunctions.evaluate` fills it from
``metric.parameter_values()`` at call time, so changing a parameter rebuilds nothing.
"""

from __future__ import annotations

from collections.abc import Callable, Hashable
from typing import TYPE_CHECKING

import casadi as ca
import numpy as np

from geosyn.core.calls import numpy_function
from geosyn.core.codegen import compile_function
from geosyn.core.validation import check_choice
from geosyn.metrics.derived import sx_metric_derivatives

if TYPE_CHECKING:
    from geosyn.metrics.base import Metric

__all__ = ["METRIC_FUNCTIONS", "MetricFunctions", "build_metric_function"]

METRIC_FUNCTIONS: tuple[str, ...] = ("G", "dG", "christoffel", "coriolis", "geodesic_acceleration")
"""Names of a metric's own compiled functions (keys of `MetricFunctions`)."""


def build_metric_function(metric: Metric, name: str, *, compile: bool) -> ca.Function:
    """Build one of the metric's own functions from its symbolic form (allocates).

    Inputs are column vectors ``q`` (n, 1) [rad], for `coriolis` and
    `geodesic_acceleration` also ``v`` (n, 1) [rad/s], then the parameters ``p`` (p, 1)
    if the metric has any. Outputs are dense:

    - ``G``: (n, n) ``metric.symbolic_G(q)``;
    - ``dG``: (n, n*n), ``[i, j*n + k] = d g_ij / d q_k``;
    - ``christoffel``: (n, n*n), ``[i, j*n + k] = Gamma_ijk`` (first kind);
    - ``coriolis``: (n, 1) ``metric.symbolic_coriolis(q, v)``;
    - ``geodesic_acceleration``: (n, 1) ``metric.symbolic_geodesic_acceleration(q, v)``.

    Args:
        metric: the metric.
        name: one of `METRIC_FUNCTIONS`.
        compile: compile to C through the disk cache (`geosyn.core.codegen`), falling
            back to CasADi's VM with a warning when no compiler works.

    Returns:
        The CasADi function.

    Raises:
        InvalidArgument: ``name`` is not one of `METRIC_FUNCTIONS`.
        NoSymbolicForm: the metric has no symbolic form.
    """
    check_choice(name, METRIC_FUNCTIONS, "name")
    n = metric.n
    q = ca.SX.sym("q", n)
    v = ca.SX.sym("v", n)
    p = metric.symbolic_parameters()
    extra, extra_names = ([p], ["p"]) if p.numel() > 0 else ([], [])
    if name in ("coriolis", "geodesic_acceleration"):
        inputs, input_names = [q, v, *extra], ["q", "v", *extra_names]
        if name == "coriolis":
            out, out_name = metric.symbolic_coriolis(q, v), "c"
        else:
            out, out_name = metric.symbolic_geodesic_acceleration(q, v), "a"
    else:
        inputs, input_names = [q, *extra], ["q", *extra_names]
        G = metric.symbolic_G(q)
        if name == "G":
            out, out_name = G, "G"
        else:
            dG, gamma = sx_metric_derivatives(G, q)
            out, out_name = (dG, "dG") if name == "dG" else (gamma, "Gamma")
    # Dense outputs: structural zeros would otherwise change shapes between metrics.
    fun = ca.Function(name, inputs, [ca.densify(out)], input_names, [out_name], {"cse": True})
    return compile_function(fun, fallback=True) if compile else fun


class _OwnFunction:
    """Attribute ``functions.<name>``: the metric's own function ``<name>``, built on first use."""

    def __set_name__(self, owner: type, name: str) -> None:
        self.name = name

    def __get__(self, obj: MetricFunctions | None, objtype: type | None = None) -> ca.Function:
        if obj is None:
            raise AttributeError(
                f"{self.name!r} is built per metric: read metric.functions.{self.name}"
            )
        return obj.get(self.name)


class MetricFunctions:
    """Compiled CasADi functions of one metric: built on first use, kept, clearable.

    The metric's own functions are attributes: ``functions.G``, ``functions.dG``,
    ``functions.christoffel``, ``functions.coriolis``, ``functions.geodesic_acceleration``
    (shapes in `build_metric_function`). Not thread-safe (the numpy wrappers reuse their
    buffers): use one metric object per thread.

    Args:
        metric: the metric whose functions these are.

    Attributes:
        builds: number of functions built so far (tests check that nothing is rebuilt).
    """

    def __init__(self, metric: Metric) -> None:
        self._metric = metric
        self._functions: dict[Hashable, ca.Function] = {}
        self._numpy: dict[Hashable, tuple[Callable[..., tuple[np.ndarray, ...]], int]] = {}
        self.builds = 0

    def __repr__(self) -> str:
        return (
            f"MetricFunctions({type(self._metric).__name__}, {sorted(map(str, self._functions))})"
        )

    def __contains__(self, key: Hashable) -> bool:
        return key in self._functions

    def __len__(self) -> int:
        return len(self._functions)

    def get(self, key: Hashable, build: Callable[[], ca.Function] | None = None) -> ca.Function:
        """The function stored under ``key``, built by ``build()`` on first use.

        Args:
            key: any hashable key; the names in `METRIC_FUNCTIONS` need no ``build``.
            build: makes the function (allocates; called at most once per key until
                `clear`).

        Raises:
            InvalidArgument: ``key`` is not built yet, has no ``build`` and is not one of
                `METRIC_FUNCTIONS`.
        """
        fun = self._functions.get(key)
        if fun is None:
            if build is None:
                name = check_choice(key, METRIC_FUNCTIONS, "key")
                fun = build_metric_function(self._metric, name, compile=self._metric.compile)
            else:
                fun = build()
            self._functions[key] = fun
            self.builds += 1
        return fun

    def evaluate(
        self, key: Hashable, *args: np.ndarray, build: Callable[[], ca.Function] | None = None
    ) -> np.ndarray:
        """Evaluate a function's first output on numpy arrays (a new array).

        The metric's parameter values are appended when the function takes one more
        input than given. Calls go through CasADi's zero-copy buffers
        (`geosyn.core.calls.numpy_function`), one wrapper per key, made on first use.

        Args:
            key: as in `get`.
            *args: the inputs, e.g. q (n,) [rad] and v (n,) [rad/s].
            build: as in `get`.

        Returns:
            The first output; (n,) for a column vector, (n, m) for a matrix.
        """
        entry = self._numpy.get(key)
        if entry is None:
            fun = self.get(key, build)
            entry = self._numpy[key] = (numpy_function(fun), fun.n_in())
        call, n_in = entry
        if n_in > len(args):
            args = (*args, self._metric.parameter_values())
        return call(*args)[0].copy()

    def clear(self) -> None:
        """Forget every function built for this metric; the next use builds it again.

        Compiled C libraries stay in the disk cache (`geosyn.core.codegen.clear_cache`
        removes them), so rebuilding a compiled function only reloads it.
        """
        self._functions.clear()
        self._numpy.clear()

    # The metric's own functions, by name (see `build_metric_function` for their shapes).
    G = _OwnFunction()
    dG = _OwnFunction()
    christoffel = _OwnFunction()
    coriolis = _OwnFunction()
    geodesic_acceleration = _OwnFunction()
