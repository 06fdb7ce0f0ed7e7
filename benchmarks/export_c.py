"""Exported C controllers (issue 24) against the same Python controllers, same run.

For the Panda and the UR5, computed torque and the Riemannian PD are exported with
``-O3 -march=native``; per call over the same (t, q, v) sequence:

- Python: ``Controller.compute`` (Pinocchio), wall and CPU time;
- C through ctypes (what a Python caller of the library pays);
- C from C: a harness linked with the static library times each call with
  ``clock_gettime`` (median, p99, max) and the whole run's CPU time with ``clock()``.

Prints a Markdown table with the ratios Python / C (as pasted into RESULTS.md).

``--mpc``: the torque-level box-DDP MPC instead (`mpc_main`): the Panda's
``GeodesicMPC(control="torque", solver="ddp", joint_limit_guard=False)`` (default
weights, dt 20 ms; the exported driver has no joint-limit guard, so neither has the
Python MPC it is compared with) exported with `export_controller`'s default flags
(``-O3``), or with ``--native`` at ``-O3 -march=native`` (a tuned build for this CPU only),
and timed in the same run, rounds alternating, on
``benchmarks/mpc_vs_crocoddyl.py``'s problem (its 1 kHz Pinocchio plant and geodesic
reference, scenario ``on_reference``, 1.5 s, a solve every 20 ms; the first, cold solve
left out): the Python MPC, the C MPC through ctypes (a lean caller: a few us per call), and
Crocoddyl's BoxFDDP (one
iteration per solve, its venv ``.venv-croc``; skipped when it is missing), N = 10 and 40.
Then the shipped MuJoCo loop (``loop.c``, 1 kHz, a 60 N push) times the C MPC from C:
solve ticks and the between-solve feedback ticks (``u + K dx``) apart.

Run: ``nice -n 10 .venv/bin/python benchmarks/export_c.py [--mpc [--rounds 3] [--native]]``.
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
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


def c_policy(c: CController):
    """The C MPC as a policy of mpc_plant.run_closed_loop: (torque, iterations). A lean
    ctypes caller: buffers and their pointers made once, one call into the library per
    tick (and one for the iteration count)."""
    import ctypes

    from geosyn.export.binding import pointer

    counts, values = np.zeros(5, dtype=np.intc), np.zeros(2)
    q_buf, v_buf, tau = np.zeros(c.nq), np.zeros(c.nq), np.zeros(c.nq)
    q_ptr, v_ptr, tau_ptr = pointer(q_buf), pointer(v_buf), pointer(tau)
    info = c.lib.geosyn_controller_mpc_info
    info.restype, info.argtypes = ctypes.c_int, [ctypes.c_void_p] * 3
    compute, handle = c.lib.geosyn_controller_compute, c.handle
    counts_ptr, values_ptr = counts.ctypes.data, values.ctypes.data

    def policy(k: int, t: float, q: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, int]:
        q_buf[:] = q
        v_buf[:] = v
        if compute(handle, t, q_ptr, v_ptr, tau_ptr) != 0:
            raise RuntimeError(f"geosyn_controller_compute failed at t={t}")
        info(handle, counts_ptr, values_ptr)
        return tau.copy(), int(counts[2])

    return policy


def mpc_main(rounds: int, horizons: list[int], flags: tuple[str, ...]) -> None:
    """The MPC comparison (see the module docstring); prints a Markdown table."""
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import mpc_vs_crocoddyl as mvc
    from mpc_plant import initial_state, panda_model, run_closed_loop

    ref = mvc.ReferenceSamples.load(mvc.REFERENCE)
    # the exported driver has no joint-limit guard: the Python MPC runs without it too
    side = mvc.GeosynSide(ref, {"solver": "ddp", "max_solve_time": 1e9, "joint_limit_guard": False})
    croc = mvc.DEFAULT_CROC_PYTHON.is_file()
    if not croc:
        print(f"Crocoddyl skipped: no venv at {mvc.DEFAULT_CROC_PYTHON}", flush=True)
    runs: dict[tuple[str, int], list[dict]] = {}
    with tempfile.TemporaryDirectory() as tmp:
        exports = {}
        for N in horizons:
            mpc = side.mpc(N)
            exports[N] = export_controller(
                "panda", mpc, Path(tmp) / f"mpc{N}", reference=side.reference,
                sample_dt=1e-3, max_samples=4096, flags=flags,
            )  # fmt: skip
        q0, v0 = initial_state("on_reference", ref)
        for r in range(rounds):
            for N in horizons:
                order = ["python", "c", "croc"] if r % 2 == 0 else ["croc", "c", "python"]
                for who in order:
                    if who == "croc" and croc:
                        info = mvc.run_crocoddyl(
                            mvc.DEFAULT_CROC_PYTHON, [N], ["on_reference"], Path(tmp), f"{r}_{N}"
                        )
                        runs.setdefault(("Crocoddyl BoxFDDP", N), []).append(info["runs"][0])
                    elif who == "python":
                        s = mvc.run_geosyn(side, ref, "on_reference", N)
                        runs.setdefault(("Python ddp", N), []).append(s)
                    elif who == "c":
                        c = CController(exports[N].shared_library)
                        c.reset(q0.copy(), v0.copy())
                        roll = run_closed_loop(panda_model(), q0, v0, mvc.DURATION, c_policy(c))
                        s = mvc.summarize("on_reference", N, roll, ref, panda_model())
                        runs.setdefault(("C (ctypes)", N), []).append(s)
                        c.close()
                    print(who, N, "round", r, flush=True)
        loops = {N: run_loop(exports[N]) for N in horizons}
    print_mpc_table(runs, loops, horizons)


def run_loop(res) -> dict[str, float]:
    """loop.c with the MPC: 1 kHz MuJoCo, 2 s, a 60 N push; its "key value" lines."""
    subprocess.run(["make", "-s", "loop"], cwd=res.out_dir, check=True)
    out = subprocess.run(
        [str(res.out_dir / "loop"), str(res.model_xml), "2.0", "60", "0.5", "0.1"],
        capture_output=True, text=True, check=True,
    ).stdout  # fmt: skip
    return {k: float(v) for k, v in (line.split() for line in out.splitlines())}


def print_mpc_table(runs: dict, loops: dict, horizons: list[int]) -> None:
    def med(rows: list[dict], key: str) -> float:
        return statistics.median(float(x[key]) for x in rows)

    lines = [
        "| solver | N | warm solve median / p99 [ms] | CPU median [ms] | tracking RMS [rad]"
        " | C / this (median; CPU) |",
        "|---|---|---|---|---|---|",
    ]
    for N in horizons:
        c_rows = runs[("C (ctypes)", N)]
        for name in ("C (ctypes)", "Python ddp", "Crocoddyl BoxFDDP"):
            rows = runs.get((name, N))
            if not rows:
                continue
            ratio = ""
            if name != "C (ctypes)":
                ratio = (
                    f"{med(c_rows, 'median_ms') / med(rows, 'median_ms'):.2f}x; "
                    f"{med(c_rows, 'cpu_median_ms') / med(rows, 'cpu_median_ms'):.2f}x"
                )
            lines.append(
                f"| {name} | {N} | {med(rows, 'median_ms'):.3f} / {med(rows, 'p99_ms'):.3f}"
                f" | {med(rows, 'cpu_median_ms'):.3f} | {med(rows, 'tracking_rms'):.3g}"
                f" | {ratio} |"
            )
    lines += [
        "",
        "| loop.c (C from C, MuJoCo 1 kHz, 60 N push) | N | solve median / p99 / max [us]"
        " | feedback median / p99 / max [us] | solves / failed | RMS [rad] |",
        "|---|---|---|---|---|---|",
    ]
    for N in horizons:
        lp = loops[N]
        lines.append(
            f"| box-DDP MPC | {N} | {lp['solve_median_us']:.0f} / {lp['solve_p99_us']:.0f} /"
            f" {lp['solve_max_us']:.0f} | {lp['feedback_median_us']:.2f} /"
            f" {lp['feedback_p99_us']:.2f} / {lp['feedback_max_us']:.1f}"
            f" | {lp['solves']:.0f} / {lp['failed_solves']:.0f} | {lp['rms_error_rad']:.3g} |"
        )
    print("\n".join(lines))


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--mpc", action="store_true", help="the box-DDP MPC comparison")
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--horizon", type=int, nargs="+", default=[10, 40])
    parser.add_argument(
        "--native",
        action="store_true",
        help="export the MPC with -O3 -march=native (default: export_controller's -O3)",
    )
    args = parser.parse_args()
    if args.mpc:
        mpc_main(args.rounds, args.horizon, ("-O3", "-march=native") if args.native else ("-O3",))
    else:
        main()
