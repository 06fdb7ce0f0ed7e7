"""`DDPOptions`: how the box-DDP family solves the tracking OCP (``solver="ddp"``)."""

from __future__ import annotations

from dataclasses import dataclass

from geosyn.controllers.mpc.ocp.settings import MAX_SOLVER_ITER, MIN_SOLVER_TOL
from geosyn.core.errors import InvalidArgument
from geosyn.core.validation import check_float, check_int, check_positive

__all__ = ["BACKWARDS", "DDPOptions"]

BACKWARDS = ("native", "casadi")
"""The backward passes of `DDPOptions.backward`."""


@dataclass(frozen=True)
class DDPOptions:
    """Options of the box-DDP solver (``GeodesicMPC(solver=DDPOptions(...))``; the string
    ``"ddp"`` means ``DDPOptions()``). Validated on construction.

    Attributes:
        tol: convergence tolerance of cold solves: the largest control update divided by
            ``1 + max |u|`` [-], in [`MIN_SOLVER_TOL`, 1].
        max_iter: iteration limit of cold solves, in [1, `MAX_SOLVER_ITER`].
        warm_iterations: DDP iterations per warm solve (1: a real-time iteration, like
            Crocoddyl's one-iteration MPC), in [1, `MAX_SOLVER_ITER`].
        limit_weight: weight of the soft position and velocity limits ([1/rad^2],
            [s^2/rad^2]; zero inside the limits).
        regularisation: added to the diagonal of each stage's control Hessian
            [1/(N m)^2] (a cold solve's Levenberg-Marquardt steps raise it).
        clearance_weight: weight of the clearance penalty [1/m^2] (``clearance_margin``;
            1e6 keeps a 3 cm margin to within 2 mm on the panda test scene, 1e8 made
            that closed loop unstable).
        backward: how the backward pass runs: ``"native"`` (default), the hand-written C
            loops over small dense blocks (``native/geosyn_ddp.c``, the code the C export
            runs; several times faster for 7 joints, and a far shorter first compile), or
            ``"casadi"``, CasADi's unrolled graph of the same mathematics
            (`geosyn.controllers.mpc.ddp.riccati.backward_graph`: the reference the native
            pass is tested against). Both agree up to rounding.

    Raises:
        InvalidArgument: a value out of range (named).
    """

    tol: float = 1e-6
    max_iter: int = 50
    warm_iterations: int = 1
    limit_weight: float = 1e6
    regularisation: float = 1e-9
    clearance_weight: float = 1e6
    backward: str = "native"

    def __post_init__(self) -> None:
        checked = {
            "tol": check_float(self.tol, "tol", low=MIN_SOLVER_TOL, high=1.0),
            "max_iter": check_int(self.max_iter, "max_iter", low=1, high=MAX_SOLVER_ITER),
            "warm_iterations": check_int(
                self.warm_iterations, "warm_iterations", low=1, high=MAX_SOLVER_ITER
            ),
            "limit_weight": check_positive(self.limit_weight, "limit_weight"),
            "regularisation": check_positive(self.regularisation, "regularisation"),
            "clearance_weight": check_positive(self.clearance_weight, "clearance_weight"),
        }
        if self.backward not in BACKWARDS:
            raise InvalidArgument(
                f"backward: {self.backward!r} is not a DDP backward pass; allowed: "
                + ", ".join(repr(b) for b in BACKWARDS)
            )
        for name, value in checked.items():
            object.__setattr__(self, name, value)

    @property
    def name(self) -> str:
        """The solver's name, ``"ddp"``."""
        return "ddp"
