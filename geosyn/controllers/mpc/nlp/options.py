"""`NLPOptions`: how the interior-point family (fatrop, IPOPT) solves the tracking OCP."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

from geosyn.controllers.mpc.ocp.settings import MAX_SOLVER_ITER, MIN_SOLVER_TOL
from geosyn.core.errors import InvalidArgument
from geosyn.core.validation import check_choice, check_float, check_int, check_positive

__all__ = ["MAX_ITER", "MIN_TOL", "NLP_SOLVERS", "NLPOptions"]

NLP_SOLVERS = ("fatrop", "ipopt")
"""Interior-point plugins of ``casadi.nlpsol`` the family uses."""
MIN_TOL = MIN_SOLVER_TOL
"""Smallest ``tol`` (`geosyn.controllers.mpc.ocp.settings.MIN_SOLVER_TOL`)."""
MAX_ITER = MAX_SOLVER_ITER
"""Largest ``max_iter`` (the wall-time budget bounds a solve anyway: `bounded`)."""


@dataclass(frozen=True)
class NLPOptions:
    """Options of the fatrop and IPOPT solvers (``GeodesicMPC(solver=NLPOptions(...))``;
    the strings ``"fatrop"`` and ``"ipopt"`` mean ``NLPOptions("fatrop")`` and
    ``NLPOptions("ipopt")``). Validated on construction.

    Attributes:
        solver: ``"fatrop"`` (interior point on the stage structure, Riccati) or
            ``"ipopt"`` (general sparse interior point).
        tol: solver tolerance, in [`MIN_TOL`, 1].
        max_iter: iteration limit per solve, in [1, `MAX_ITER`].
        mu_init: initial barrier parameter of cold solves.
        mu_warm: initial barrier parameter of warm-started solves.
        plugin_options: extra options of the plugin (fatrop or ipopt options, e.g.
            ``{"max_iter": 1}``), applied last (they win, unchecked by geosyn); unknown
            keys are rejected by the plugin at build time.

    Raises:
        InvalidArgument: a value out of range (named).
    """

    solver: str = "fatrop"
    tol: float = 1e-6
    max_iter: int = 50
    mu_init: float = 1e-1
    mu_warm: float = 1e-8
    plugin_options: Mapping[str, bool | int | float | str] | None = None

    def __post_init__(self) -> None:
        if self.plugin_options is not None and not isinstance(self.plugin_options, Mapping):
            raise InvalidArgument(
                f"plugin_options must be a dict or None, got {self.plugin_options!r}"
            )
        checked = {
            "solver": check_choice(self.solver, NLP_SOLVERS, "solver"),
            "tol": check_float(self.tol, "tol", low=MIN_TOL, high=1.0),
            "max_iter": check_int(self.max_iter, "max_iter", low=1, high=MAX_ITER),
            "mu_init": check_positive(self.mu_init, "mu_init"),
            "mu_warm": check_positive(self.mu_warm, "mu_warm"),
            "plugin_options": dict(self.plugin_options or {}),
        }
        for name, value in checked.items():
            object.__setattr__(self, name, value)

    def __hash__(self) -> int:  # the plugin options are a dict: hash their items
        items = tuple(sorted((self.plugin_options or {}).items()))
        return hash((self.solver, self.tol, self.max_iter, self.mu_init, self.mu_warm, items))

    @property
    def name(self) -> str:
        """The plugin's name, ``"fatrop"`` or ``"ipopt"``."""
        return self.solver
