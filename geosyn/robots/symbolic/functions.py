"""The CasADi functions of a model's dynamics, built once, and graph size."""

from __future__ import annotations

from typing import NamedTuple

import casadi as ca
import numpy as np
import numpy.typing as npt
import pinocchio as pin

from geosyn.core import InvalidArgument
from geosyn.robots.symbolic.dynamics import _gravity, aba, bias, crba, rnea
from geosyn.robots.symbolic.model import _parse_model


def count_nodes(*exprs: ca.SX) -> int:
    """Size of the graph of SX expressions: ``casadi.Function(...).n_nodes()``.

    Counts the symbolic inputs, constants and operations reachable from ``exprs``, without
    common-subexpression elimination beyond the sharing already in the graph.

    Args:
        *exprs: SX expressions of any shape.

    Returns:
        Number of nodes.
    """
    leaves = ca.symvar(ca.veccat(*[ca.vec(e) for e in exprs]))
    return int(ca.Function("count_nodes", leaves, list(exprs)).n_nodes())


class DynamicsFunctions(NamedTuple):
    """Compiled-on-demand CasADi functions of one model (SX graphs, built once).

    Each is a ``casadi.Function``; call it with numpy arrays, it returns ``casadi.DM``
    (see :mod:`geosyn.core.codegen` for C code generation).
    """

    M: ca.Function  # q (nq,) -> M (nv, nv) mass matrix
    rnea: ca.Function  # q, v, a -> tau (nv,) inverse dynamics
    bias: ca.Function  # q, v -> h (nv,) C(q, v) v + g(q)
    aba: ca.Function  # q, v, tau -> a (nv,) forward dynamics
    geodesic_acceleration: ca.Function  # q, v -> a (nv,), aba with zero gravity and torque


def dynamics_functions(model: pin.Model, gravity: npt.ArrayLike) -> DynamicsFunctions:
    """Build the CasADi functions of a model's dynamics (allocates; call once).

    Args:
        model: Pinocchio model (fixed base, supported joint types only).
        gravity: (3,) gravity acceleration in the world frame [m/s^2], numeric; it is
            embedded as a constant in ``rnea``, ``bias`` and ``aba``.

    Returns:
        The functions ``M``, ``rnea``, ``bias``, ``aba`` and ``geodesic_acceleration``,
        each built with common-subexpression elimination.

    Raises:
        InvalidArgument: unsupported model, or ``gravity`` not a finite numeric (3,) array.
    """
    if isinstance(gravity, (ca.SX, ca.MX)):
        raise InvalidArgument("gravity: expected a numeric (3,) array, got a symbolic one")
    g = np.array(_gravity(gravity), dtype=float)  # validated: numeric, finite, (3,)
    _parse_model(model)
    nq, nv = model.nq, model.nv
    q = ca.SX.sym("q", nq)
    v = ca.SX.sym("v", nv)
    a = ca.SX.sym("a", nv)
    tau = ca.SX.sym("tau", nv)
    opts = {"cse": True}
    return DynamicsFunctions(
        M=ca.Function("M", [q], [crba(model, q)], ["q"], ["M"], opts),
        rnea=ca.Function(
            "rnea", [q, v, a], [rnea(model, q, v, a, g)], ["q", "v", "a"], ["tau"], opts
        ),
        bias=ca.Function("bias", [q, v], [bias(model, q, v, g)], ["q", "v"], ["h"], opts),
        aba=ca.Function(
            "aba", [q, v, tau], [aba(model, q, v, tau, g)], ["q", "v", "tau"], ["a"], opts
        ),
        geodesic_acceleration=ca.Function(
            "geodesic_acceleration",
            [q, v],
            [aba(model, q, v, np.zeros(nv), np.zeros(3))],
            ["q", "v"],
            ["a"],
            opts,
        ),
    )
