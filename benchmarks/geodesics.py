"""Benchmark of geosyn.metrics.geodesic: exp speed and log (cold / warm-started) times.

Run: ``.venv/bin/python benchmarks/geodesics.py``. Prints figures and ratios; no
assertions. Timings are wall-clock medians and depend on the machine's load.

- exp: 1000 RK4 steps on panda (compiled loop) vs 4000 Python calls of ``pin.aba``
  (the work of 1000 RK4 steps done per call from Python), measured in the same run.
- log: 50 seeded pairs ~1 rad apart (Euclidean); cold = straight-line guess; warm =
  ``v_init`` is the solution of the pair (q0, q1) and the target moved by 0.05 rad.
"""

from __future__ import annotations

import time

import numpy as np
import pinocchio as pin

from geosyn.metrics import KineticEnergyMetric
from geosyn.metrics.geodesic import exp, log_solve
from geosyn.robots import load_robot


def _median_time(fun, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fun()
        times.append(time.perf_counter() - t0)
    return float(np.median(times))


def bench_exp() -> None:
    robot = load_robot("panda")
    metric = KineticEnergyMetric(robot)
    rng = np.random.default_rng(0)
    q0 = robot.random_q(rng, margin=0.3)
    v0 = rng.uniform(-1.0, 1.0, robot.nv)
    t0 = time.perf_counter()
    exp(metric, q0, v0, 1.0, 1000)
    first = time.perf_counter() - t0
    t_exp = _median_time(lambda: exp(metric, q0, v0, 1.0, 1000), 20)
    model = pin.Model(robot.model)
    model.gravity = pin.Motion.Zero()
    data = model.createData()
    zero = np.zeros(robot.nv)

    def aba_calls() -> None:
        for _ in range(4000):
            pin.aba(model, data, q0, v0, zero)

    t_aba = _median_time(aba_calls, 20)
    print(f"exp panda 1000 RK4 steps: first call (build + compile/load) {first * 1e3:.1f} ms")
    print(f"exp panda 1000 RK4 steps: {t_exp * 1e3:.2f} ms (median of 20)")
    print(f"4000 x pin.aba from Python: {t_aba * 1e3:.2f} ms ({t_aba / 4000 * 1e6:.2f} us/call)")
    print(f"ratio exp / aba-calls: {t_exp / t_aba:.3f} (target <= 1.0)")


def _pairs(robot, count: int, dist: float, seed: int):
    rng = np.random.default_rng(seed)
    lo = np.where(np.isfinite(robot.q_min), robot.q_min + 0.1, -np.inf)
    hi = np.where(np.isfinite(robot.q_max), robot.q_max - 0.1, np.inf)
    pairs = []
    while len(pairs) < count:
        q0 = robot.random_q(rng, margin=0.2)
        d = rng.standard_normal(robot.nv)
        q1 = q0 + dist * d / np.linalg.norm(d)
        move = rng.standard_normal(robot.nv)
        q1b = q1 + 0.05 * move / np.linalg.norm(move)
        if np.all(q1 > lo) and np.all(q1 < hi) and np.all(q1b > lo) and np.all(q1b < hi):
            pairs.append((q0, q1, q1b))
    return pairs


def bench_log(name: str) -> None:
    robot = load_robot(name)
    metric = KineticEnergyMetric(robot)
    pairs = _pairs(robot, 50, 1.0, seed=42)
    log_solve(metric, pairs[0][0], pairs[0][1])  # build the functions once
    cold, warm, it_cold, it_warm, methods = [], [], [], [], {}
    for q0, q1, q1b in pairs:
        t0 = time.perf_counter()
        res = log_solve(metric, q0, q1)
        cold.append(time.perf_counter() - t0)
        it_cold.append(res.iterations)
        methods[res.method] = methods.get(res.method, 0) + 1
        t0 = time.perf_counter()
        res_w = log_solve(metric, q0, q1b, v_init=res.v0)
        warm.append(time.perf_counter() - t0)
        it_warm.append(res_w.iterations)
    for label, times, its, target in (
        ("cold", cold, it_cold, 100),
        ("warm", warm, it_warm, 20),
    ):
        ms = 1e3 * np.asarray(times)
        print(
            f"log {name} {label}: median {np.median(ms):.2f} ms, p90 {np.percentile(ms, 90):.2f}"
            f" ms, max {ms.max():.2f} ms (target median <= {target} ms); Newton iterations"
            f" median {np.median(its):.0f}, max {max(its)}"
        )
    print(f"log {name} cold methods: {methods}")


def main() -> None:
    bench_exp()
    for name in ("panda", "planar2"):
        bench_log(name)


if __name__ == "__main__":
    main()
