"""Benchmark of geosyn.sim: real-time factor per controller, and a parallel sweep.

1. Real-time factor (simulated time / wall time of `Simulation.run`) on the panda at a
   1 kHz control rate and 1 kHz physics (implicitfast), tracking a 2 s joint trajectory,
   for each controller that exists: computed torque (target >= 20x), the inverse-dynamics
   QP (>= 5x), the geodesic MPC re-solving at 50 Hz (>= 1x; acceleration level) and the
   torque-level MPC at 50 Hz with N = 20, box-DDP and fatrop (>= 2x, issue 13). Each controller is built
   and warmed up (a 50 ms run: compiled functions loaded, solver caches filled) before
   the timed run; the build time is printed separately. The best of ``--repeat`` runs is
   reported, with the share of the wall time spent inside ``controller.compute``.
2. A sweep of 16 short runs (computed torque, 2 s each, torque noise seeded per run) on
   1 and 2 worker processes (``multiprocessing``, fork; each worker builds its simulation
   once); speed-up = wall(1 worker) / wall(2 workers), target >= 1.6.

Run: ``.venv/bin/python benchmarks/sim.py [--quick]``. Timings depend on the machine's
load; the figures go to benchmarks/RESULTS.md.
"""

from __future__ import annotations

import argparse
import multiprocessing as mp
import os
import time
import traceback

import numpy as np

from geosyn.controllers import JointTrajectoryReference
from geosyn.robots import load_robot
from geosyn.sim import Simulation, TorqueNoise

SWEEP_RUN = 2.0  # simulated time of each sweep run [s]
TARGETS = {
    "computed torque": 20.0,
    "QP": 5.0,
    "MPC (50 Hz)": 1.0,
    "MPC torque ddp": 2.0,
    "MPC torque fatrop": 2.0,
}


def panda_task(duration: float = 2.0):
    """The panda, its start configuration and a smooth 0.3 rad joint trajectory."""
    robot = load_robot("panda")
    q0 = robot.neutral()
    q0[3], q0[5] = -1.5, 1.5
    t = np.linspace(0.0, duration, 21)
    sign = np.array([1.0, -1.0, 1.0, 1.0, -1.0, 1.0, 1.0])
    q = q0 + 0.3 * np.sin(0.5 * np.pi * t / duration)[:, None] ** 2 * sign
    return robot, q0, JointTrajectoryReference(t, q)


def controllers(robot):
    """(name, builder) for every controller that can be imported."""
    out = []
    try:
        from geosyn.controllers.computed_torque import ComputedTorque

        out.append(("computed torque", lambda: ComputedTorque(robot, 100.0, 20.0)))
    except ImportError as err:
        print(f"computed torque: not available ({err})")
    try:
        from geosyn.controllers.qp import QPController

        out.append(("QP", lambda: QPController(robot, 100.0, 20.0, dt=1e-3)))
    except ImportError as err:
        print(f"QP: not available ({err})")
    try:
        from geosyn.controllers.mpc import GeodesicMPC
        from geosyn.metrics import KineticEnergyMetric

        out.append(
            (
                "MPC (50 Hz)",
                lambda: GeodesicMPC(robot, KineticEnergyMetric(robot), horizon=20, dt=0.02),
            )
        )
        for solver in ("ddp", "fatrop"):  # torque level (issue 13), 50 Hz, N = 20
            out.append(
                (
                    f"MPC torque {solver}",
                    lambda solver=solver: GeodesicMPC(
                        robot,
                        KineticEnergyMetric(robot),
                        horizon=20,
                        dt=0.02,
                        control="torque",
                        solver=solver,
                    ),  # fmt: skip
                )
            )
    except ImportError as err:
        print(f"MPC: not available ({err})")
    return out


def real_time_factors(repeat: int, duration: float) -> None:
    robot, q0, ref = panda_task()
    print(f"== real-time factor, panda, 1 kHz control and physics, {duration:g} s runs ==")
    print(
        f"{'controller':18s} {'build [s]':>9s} {'RTF':>7s} {'target':>7s} {'compute':>8s} {'status'}"
    )
    for name, build in controllers(robot):
        try:
            t0 = time.perf_counter()
            ctl = build()
            sim = Simulation(robot, ctl, control_dt=1e-3)
            sim.run(q0, None, 0.05, ref)  # warm-up
            build_time = time.perf_counter() - t0
            best = None
            for _ in range(repeat):
                t0 = time.perf_counter()
                res = sim.run(q0, None, duration, ref)
                wall = time.perf_counter() - t0
                if best is None or wall < best[0]:
                    best = (wall, res)
            assert best is not None
            wall, res = best
            rtf = res.n_ticks * res.control_dt / wall
            share = float(res.compute_time.sum() / wall)
            ok = "meets" if rtf >= TARGETS[name] else "BELOW"
            print(
                f"{name:18s} {build_time:9.2f} {rtf:6.1f}x {TARGETS[name]:6.0f}x {share:7.0%}"
                f"  {res.status}, rms err {res.rms_error():.2e} rad, {ok} target"
            )
        except Exception:  # a benchmark reports every controller, even a broken one
            print(f"{name:18s} FAILED:\n{traceback.format_exc()}")


# -- sweep ------------------------------------------------------------------------------
_WORKER: dict = {}


def _init_worker() -> None:
    from geosyn.controllers.computed_torque import ComputedTorque

    robot, q0, ref = panda_task()
    sim = Simulation(robot, ComputedTorque(robot, 100.0, 20.0), disturbances=[TorqueNoise(0.5)])
    _WORKER.update(sim=sim, q0=q0, ref=ref)


def _one_run(seed: int) -> float:
    w = _WORKER
    res = w["sim"].run(w["q0"], None, SWEEP_RUN, w["ref"], seed=seed)
    return res.rms_error()


def sweep(n_runs: int = 16) -> None:
    print(
        f"== sweep of {n_runs} runs x {SWEEP_RUN:g} s (computed torque, torque noise), fork workers =="
    )
    ctx = mp.get_context("fork")
    walls = {}
    results = {}
    with ctx.Pool(1, initializer=_init_worker) as pool:  # untimed warm-up (caches, pages)
        pool.map(_one_run, range(2), chunksize=1)
    for workers in (1, 2):
        t0 = time.perf_counter()
        with ctx.Pool(workers, initializer=_init_worker) as pool:
            results[workers] = pool.map(_one_run, range(n_runs), chunksize=1)
        walls[workers] = time.perf_counter() - t0
        print(f"{workers} worker(s): {walls[workers]:.2f} s")
    same = np.allclose(results[1], results[2], rtol=0, atol=0)
    print(
        f"speed-up 2 vs 1 worker: {walls[1] / walls[2]:.2f} (target >= 1.6); results identical: {same}"
    )
    print(f"cpus visible: {os.cpu_count()}, load average: {os.getloadavg()}")


def experiment_sweep(n_seeds: int = 4) -> None:
    """The user-facing path: `geosyn sweep` of the flagship, 4 grid points x 4 seeds."""
    import shutil
    import tempfile
    from pathlib import Path

    from geosyn.experiments.sweep import sweep as run_sweep

    overrides = [
        "outputs.plots=false",
        "simulation.duration=1.5",
        "controllers=[{type: computed_torque, kp: 900, kd: 60}, {type: qp, kp: 900, kd: 60}]",
    ]
    grid = {"controllers.0.kp": ["400", "600", "900", "1200"]}
    print(f"== geosyn sweep panda_push_recovery: 4 grid points x {n_seeds} seeds, 1.5 s runs ==")
    root = Path(tempfile.mkdtemp(prefix="geosyn-bench-sweep-"))
    try:
        walls = {}
        for workers in (1, 2):
            out = root / f"w{workers}"
            t0 = time.perf_counter()
            res = run_sweep(
                "panda_push_recovery",
                grid,
                seeds=n_seeds,
                out=out,
                workers=workers,
                overrides=overrides,
                progress=False,
            )
            walls[workers] = time.perf_counter() - t0
            print(f"{workers} worker(s): {res.ran} runs in {walls[workers]:.2f} s")
        print(f"speed-up 2 vs 1 worker: {walls[1] / walls[2]:.2f} (target >= 1.6)")
    finally:
        shutil.rmtree(root, ignore_errors=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="shorter runs, one repeat")
    parser.add_argument("--repeat", type=int, default=3, help="timed runs per controller")
    parser.add_argument("--no-sweep", action="store_true")
    args = parser.parse_args()
    real_time_factors(1 if args.quick else args.repeat, 0.5 if args.quick else 2.0)
    if not args.no_sweep:
        sweep()
        experiment_sweep()


if __name__ == "__main__":
    main()
