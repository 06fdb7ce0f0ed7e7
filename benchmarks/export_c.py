"""Exported C controllers (issue 24) against the same Python controllers, same run.

For the Panda and the UR5, computed torque and the Riemannian PD are exported with
``-O3 -march=native``; per call over the same (t, q, v) sequence:

- Python: ``Controller.compute`` (Pinocchio), wall and CPU time;
- C through ctypes (what a Python caller of the library pays);
- C from C: a harness linked with the static library times each call with
  ``clock_gettime`` (median, p99, max) and the whole run's CPU time with ``clock()``.

Prints a Markdown table with the ratios Python / C (as pasted into RESULTS.md).
Run: ``nice -n 10 .venv/bin/python benchmarks/export_c.py``.
"""

from __future__ import annotations

import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np

from geosyn.controllers import ComputedTorque, GeodesicReference, RiemannianPD
from geosyn.export import CController, export_controller
from geosyn.metrics import KineticEnergyMetric
from geosyn.robots import load_robot
from geosyn.synergies import GeodesicSynergy

Q0 = {
    "panda": np.array([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785]),
    "ur5": np.array([0.0, -1.2, 1.4, -1.6, -1.57, 0.0]),
}
CALLS = 20000
HARNESS = r"""
#include <stdio.h>
#include <stdlib.h>
#include <time.h>
#include "geosyn_controller.h"
static int cmp(const void* a, const void* b) {
    double x = *(const double*)a, y = *(const double*)b; return (x > y) - (x < y); }
int main(int argc, char** argv) {
    long n = atol(argv[1]);
    geosyn_controller* c = geosyn_controller_create();
    int nq = geosyn_controller_nq(c);
    double q[64], v[64], tau[64];
    double* us = malloc(sizeof(double) * n);
    FILE* f = fopen(argv[2], "rb");
    double* states = malloc(sizeof(double) * n * (1 + 2 * nq));
    if (fread(states, sizeof(double), n * (1 + 2 * nq), f) != (size_t)(n * (1 + 2 * nq))) return 2;
    clock_t cpu0 = clock();
    for (long k = 0; k < n; ++k) {
        const double* s = states + k * (1 + 2 * nq);
        for (int j = 0; j < nq; ++j) { q[j] = s[1 + j]; v[j] = s[1 + nq + j]; }
        struct timespec a, b;
        clock_gettime(CLOCK_MONOTONIC, &a);
        geosyn_controller_compute(c, s[0], q, v, tau);
        clock_gettime(CLOCK_MONOTONIC, &b);
        us[k] = 1e6 * (b.tv_sec - a.tv_sec) + 1e-3 * (b.tv_nsec - a.tv_nsec);
    }
    double cpu = (double)(clock() - cpu0) / CLOCKS_PER_SEC, mean = 0.0;
    for (long k = 0; k < n; ++k) mean += us[k] / n;
    qsort(us, n, sizeof(double), cmp);
    printf("%.4f %.4f %.4f %.4f %.4f\n", us[n / 2], us[(long)(0.99 * n)], us[n - 1], mean,
           1e6 * cpu / n);
    return 0;
}
"""


def controller(robot_name: str, kind: str) -> ComputedTorque | RiemannianPD:
    robot = load_robot(robot_name)
    syn = GeodesicSynergy(KineticEnergyMetric(robot), Q0[robot_name], np.full(robot.nv, 0.3))
    ref = GeodesicReference(syn, duration=1.0, rest_to_rest=True)
    if kind == "computed_torque":
        return ComputedTorque(robot, 400.0, 40.0, reference=ref)
    return RiemannianPD(robot, 20.0, 50.0, reference=ref)


def states(ctl: ComputedTorque | RiemannianPD, n: int) -> np.ndarray:
    rng = np.random.default_rng(0)
    rows = []
    for t in np.linspace(0.0, 1.2, n):
        q, v, _ = ctl.reference.sample(float(t))  # type: ignore[union-attr]
        rows.append(np.r_[t, q + 0.01 * rng.standard_normal(q.size), v])
    return np.array(rows)


def per_call(fn, rows: np.ndarray, nq: int) -> tuple[float, float]:
    """(wall, CPU) mean time per call [us] over the sequence."""
    args = [(float(r[0]), r[1 : 1 + nq].copy(), r[1 + nq :].copy()) for r in rows]
    w0, c0 = time.perf_counter(), time.process_time()
    for t, q, v in args:
        fn(t, q, v)
    n = len(args)
    return 1e6 * (time.perf_counter() - w0) / n, 1e6 * (time.process_time() - c0) / n


def main() -> None:
    lines = [
        "| robot | controller | Python wall / CPU [us] | C via ctypes wall / CPU [us]"
        " | C from C median / p99 / max [us] | C from C wall mean / CPU [us]"
        " | Python / C from C (wall mean; CPU) |",
        "|---|---|---|---|---|---|---|",
    ]
    with tempfile.TemporaryDirectory() as tmp:
        for robot_name in ("panda", "ur5"):
            for kind in ("computed_torque", "riemannian_pd"):
                ctl = controller(robot_name, kind)
                out = Path(tmp) / f"{robot_name}_{kind}"
                res = export_controller(robot_name, ctl, out, flags=("-O3", "-march=native"))
                ctl.set_reference(res.samples.reference())
                rows = states(ctl, CALLS)
                py = per_call(ctl.compute, rows, res.nq)
                c = CController(res.shared_library)
                cc = per_call(c.compute, rows, res.nq)
                (out / "bench.c").write_text(HARNESS)
                subprocess.run(
                    ["cc", "-O3", "-march=native", f"-I{out}", "bench.c",
                     "libgeosyn_controller.a", "-lm", "-o", "bench"],
                    cwd=out, check=True,
                )  # fmt: skip
                rows.astype(np.float64).tofile(out / "states.bin")
                text = subprocess.run(
                    [str(out / "bench"), str(CALLS), str(out / "states.bin")],
                    capture_output=True, text=True, check=True,
                ).stdout  # fmt: skip
                med, p99, mx, mean, cpu = (float(x) for x in text.split())
                lines.append(
                    f"| {robot_name} | {kind} | {py[0]:.1f} / {py[1]:.1f} | {cc[0]:.2f} / {cc[1]:.2f}"
                    f" | {med:.2f} / {p99:.2f} / {mx:.1f} | {mean:.2f} / {cpu:.2f}"
                    f" | {py[0] / mean:.0f}x; {py[1] / cpu:.0f}x |"
                )
                print(lines[-1], flush=True)
    print("\n".join(lines))


if __name__ == "__main__":
    main()
