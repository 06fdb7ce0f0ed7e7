"""The README of an export: what it is, how to build against it, and the numbers it was
built with."""

from __future__ import annotations

import json
from typing import TYPE_CHECKING

import casadi as ca
import numpy as np

from geosyn import __version__ as geosyn_version

if TYPE_CHECKING:
    from geosyn.export.export import ExportResult

_EXAMPLE = """\
#include <stdio.h>
#include "geosyn_controller.h"

int main(void) {
    geosyn_controller* ctl = geosyn_controller_create();
    int nq = geosyn_controller_nq(ctl);
    double q[32] = {0}, v[32] = {0}, tau[32];
    int rc = geosyn_controller_compute(ctl, 0.0, q, v, tau);
    if (rc) printf("error: %s\\n", geosyn_controller_error(rc));
    else printf("nq %d, tau[0] %.3f N m\\n", nq, tau[0]);
    geosyn_controller_destroy(ctl);
    return rc;
}"""


def export_readme(result: ExportResult, settings: dict[str, object], compiler: str) -> str:
    """Text of the export's ``README.md``."""
    s, err = result.samples, result.sampling_error
    rows = {
        "robot": result.robot,
        "nq": result.nq,
        "controller": result.kind,
        **settings,
        "built-in reference": (
            f"{s.t.size} samples, t = {s.t[0]:.6g} .. {s.t[-1]:.6g} s,"
            f" spacing {np.diff(s.t).max():.6g} s"
        ),
        "interpolation error at midpoints (q [rad], v [rad/s], a [rad/s^2])": (
            f"{err.q:.3g}, {err.v:.3g}, {err.a:.3g}"
        ),
        "max samples of set_reference": result.max_samples,
        "loop push": (
            f"{result.push.force:g} N on {result.push.body} along"
            f" {list(result.push.direction)}, t = {result.push.start:g} s for"
            f" {result.push.length:g} s"
        ),
        "compiler": f"{result.compiler} ({compiler}), flags {' '.join(result.flags)}",
        "geosyn / casadi": f"{geosyn_version} / {ca.CasadiMeta.version()}",
    }
    table = "\n".join(
        f"| {k} | {json.dumps(v) if isinstance(v, list) else v} |" for k, v in rows.items()
    )
    mpc = ""
    if result.kind == "ddp_mpc":
        mpc = (
            "- `geosyn_mpc.c/.h` (the MPC's driver: solves, warm starts, plan following,\n"
            "  fallbacks), `geosyn_mpc_fun.c/.h` (CasADi-generated backward pass, rollout,\n"
            "  rollout step and mass matrix of geosyn's box-DDP solver);\n"
            "  `geosyn_controller_mpc_info` (`geosyn_controller_ext.h`) reads its solve\n"
            "  counts, status and fallback.\n"
        )
    return f"""\
# geosyn_controller: {result.kind} for {result.robot}

Exported by `geosyn export` (geosyn.export.export_controller). A self-contained C library:
it needs only libc and libm. The API is `geosyn_controller.h` (create once, then
reset / set_reference / compute; every call returns 0 or an error code and leaves the
controller usable; compute never allocates).

## Files

- `geosyn_controller.h`: the C API. `libgeosyn_controller.so`, `libgeosyn_controller.a`.
- `geosyn_controllerConfig.cmake`: `find_package(geosyn_controller REQUIRED PATHS <this dir>)`,
  then `target_link_libraries(app PRIVATE geosyn_controller::geosyn_controller)`
  (or `geosyn_controller::static`).
- `geosyn_controller.c` (driver), `geosyn_law.c/.h` (CasADi-generated rigid-body terms),
  `geosyn_controller_config.h` (the numbers below): `make lib` rebuilds the libraries.
{mpc}- `loop.c`, `loop_config.h`, `robot.xml`: `make loop && ./loop` runs the controller in a
  closed loop against the robot's MJCF with MuJoCo's C library (`MUJOCO_DIR=...`), with a
  push, and prints the tracking error and the per-tick time (median, p99, max).

## Example

```c
{_EXAMPLE}
```

`cc -I. example.c libgeosyn_controller.a -lm -o example`

## Built with

| setting | value |
| --- | --- |
{table}
"""
