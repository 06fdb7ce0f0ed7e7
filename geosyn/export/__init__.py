"""Export: a geosyn controller as a self-contained C library for other stacks.

`export_controller(robot, controller, out_dir)` writes ``geosyn_controller.h`` (a small
C API: create, destroy, nq, reset, set_reference, compute, error), the CasADi-generated C
of the controller's rigid-body terms, a hand-written C driver, ``libgeosyn_controller.so``
and ``.a`` (libc and libm only), a CMake package config, a README with the numbers it
was built with, and ``loop.c``, a closed-loop program against the robot's MJCF in
MuJoCo's C library. Exportable: `ComputedTorque`, `RiemannianPD`, and the torque-level
box-DDP MPC (``GeodesicMPC(solver="ddp", control="torque")``, no obstacles;
`geosyn.export.mpc_law`).
"""

if not __name__.startswith("geosyn."):  # the folder imported as a top-level package
    raise ImportError(f"import geosyn.export, not {__name__}: one module, one name")


from geosyn.export.binding import CController, load_library
from geosyn.export.errors import ExportError
from geosyn.export.export import ExportResult, LoopPush, export_controller
from geosyn.export.law import ControlLaw
from geosyn.export.laws import LAWS, control_law
from geosyn.export.samples import ReferenceSamples, SamplingError, sample_reference

__all__ = [
    "LAWS",
    "CController",
    "ControlLaw",
    "ExportError",
    "ExportResult",
    "LoopPush",
    "ReferenceSamples",
    "SamplingError",
    "control_law",
    "export_controller",
    "load_library",
    "sample_reference",
]
