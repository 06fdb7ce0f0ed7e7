"""The exported form of one controller configuration (`ControlLaw`), read by every
exportable controller's law (`geosyn.export.laws`, `geosyn.export.mpc_law`)."""

from __future__ import annotations

from dataclasses import dataclass, field

import casadi as ca
import numpy as np

#: C name of the generated CasADi function (``geosyn_law.c`` / ``geosyn_law.h``).
LAW_FUNCTION = "geosyn_law"


@dataclass(frozen=True)
class ControlLaw:
    """The exported form of one controller configuration.

    Attributes:
        kind: ``"computed_torque"`` or ``"riemannian_pd"`` (the C driver's law).
        function: CasADi function of the rigid-body terms, named `LAW_FUNCTION`.
        arrays: ``{C name: (nq,) values}`` of per-joint constants (gains [1/s^2, 1/s,
            N m s/rad], torque limits [N m], friction).
        scalars: ``{C macro: value}`` of scalar constants (an int is written as one).
        settings: the controller's settings as written in the export's README.
        generated: more CasADi functions generated to C (``geosyn_mpc_fun.c``), named
            as the driver calls them.
        c_files: more hand-written C files of the driver (from ``c/``).
    """

    kind: str
    function: ca.Function
    arrays: dict[str, np.ndarray]
    scalars: dict[str, float | int] = field(default_factory=dict)
    settings: dict[str, object] = field(default_factory=dict)
    generated: tuple[ca.Function, ...] = ()
    c_files: tuple[str, ...] = ()


__all__ = ["LAW_FUNCTION", "ControlLaw"]
