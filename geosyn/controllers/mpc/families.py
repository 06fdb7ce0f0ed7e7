"""The solver families the MPC knows: the ``solver=`` shorthands (`SOLVERS`), each
options class's backend builder (`BACKENDS`), and the validation of ``solver=``.

A third family (an options class and a backend implementing
`geosyn.controllers.mpc.backend.TrackingBackend`) is one line in `BACKENDS` (and, for a
shorthand name, one in `SOLVERS`).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from geosyn.controllers.mpc.backend import TrackingBackend, TrackingProblem
from geosyn.controllers.mpc.ddp.options import DDPOptions
from geosyn.controllers.mpc.ddp.tracking import check_ddp_problem, ddp_backend
from geosyn.controllers.mpc.nlp.options import NLPOptions
from geosyn.controllers.mpc.nlp.tracking import nlp_backend
from geosyn.core.errors import InvalidArgument
from geosyn.core.validation import check_choice

__all__ = ["BACKENDS", "SOLVERS", "SolverOptions", "default_solver_options", "solver_options"]

SolverOptions = NLPOptions | DDPOptions
"""The options classes of the solver families."""

SOLVERS: dict[str, Callable[[], SolverOptions]] = {
    "fatrop": lambda: NLPOptions("fatrop"),
    "ipopt": lambda: NLPOptions("ipopt"),
    "ddp": DDPOptions,
}
"""``GeodesicMPC(solver=name)`` shorthands: each name means its family's default options."""

BACKENDS: dict[type, Callable[[TrackingProblem, Any], TrackingBackend]] = {
    NLPOptions: nlp_backend,
    DDPOptions: ddp_backend,
}
"""The backend builder of each options class (`geosyn.controllers.mpc.backend`)."""


def solver_options(solver: object) -> SolverOptions:
    """The options ``GeodesicMPC(solver=...)`` means: a `SOLVERS` name's defaults, or an
    options object of a `BACKENDS` class as it is.

    Raises:
        InvalidArgument: an unknown name, or another object.
    """
    if isinstance(solver, str):
        return SOLVERS[check_choice(solver, tuple(SOLVERS), "solver")]()
    if type(solver) not in BACKENDS:
        raise InvalidArgument(
            f"solver must be one of {', '.join(SOLVERS)} or an options object "
            f"({', '.join(t.__name__ for t in BACKENDS)}), got {solver!r}"
        )
    return solver  # type: ignore[return-value]


def default_solver_options(problem: TrackingProblem) -> SolverOptions:
    """The options ``GeodesicMPC(solver=None)`` means: box-DDP (`DDPOptions()`) wherever
    it solves the problem (`check_ddp_problem`: ``control="torque"``, effort ``"torque"``
    or ``"metric"`` with the robot's own kinetic-energy metric, ``hessian="gauss-newton"``,
    obstacles given with a ``clearance_margin``), else fatrop (``NLPOptions("fatrop")``:
    acceleration control, the acceleration effort, an exact Hessian, other metrics).

    Box-DDP is the fastest torque-level solver (benchmarks/RESULTS.md, against
    Crocoddyl); its soft joint limits are made hard in closed loop by the controller's
    joint-limit guard (`geosyn.controllers.limit_guard`).
    """
    try:
        check_ddp_problem(problem)
    except InvalidArgument:
        return NLPOptions("fatrop")
    return DDPOptions()
