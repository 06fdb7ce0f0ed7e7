"""Issue 23 bounds: worst QP tick at the largest allowed iteration settings, and
``exp(method="dop853")`` at a huge |v0|, each against a reference timed in the same run.

Run: ``.venv/bin/python benchmarks/hardening_bounds.py``. Prints wall and CPU times and
ratios; no assertions. Figures depend on the machine's load.

- QP (panda, 1 kHz, velocity noise std 2 rad/s, ``eps_abs`` at its smallest allowed
  value 1e-15, so proxsuite never converges): worst of 20 ticks at the default
  ``max_iter * max_inner_iter = 100 * 30`` (reference) and at the bounds
  (``1000 * 10``, ``10 * 1000``).
- exp with DOP853 (panda): |v0| = 1 (reference, converges) and |v0| = 1e5, 1e8 (stopped
  by ``MAX_DOP853_EVALUATIONS``).
"""

from __future__ import annotations

import time

import numpy as np

from geosyn.controllers import JointTrajectoryReference
from geosyn.controllers.qp import QPController
from geosyn.core import GeosynError
from geosyn.metrics import KineticEnergyMetric, exp
from geosyn.robots import load_robot

Q0 = np.array([0.0, -0.3, 0.0, -2.0, 0.0, 1.8, 0.8])


def worst_qp_tick(robot, max_iter: int, max_inner_iter: int) -> tuple[float, float]:
    """(wall, CPU) of the worst of 20 noisy ticks [s]."""
    ref = JointTrajectoryReference(np.array([0.0, 1.0]), np.stack([Q0, Q0 + 0.2]))
    qp = QPController(
        robot, 900.0, 60.0, 1e-3, reference=ref, eps_abs=1e-15,
        max_iter=max_iter, max_inner_iter=max_inner_iter,
    )  # fmt: skip
    rng = np.random.default_rng(0)
    qp.reset(Q0, np.zeros(7))
    wall = cpu = 0.0
    for k in range(20):
        v = rng.normal(0.0, 2.0, 7)
        w0, c0 = time.perf_counter(), time.process_time()
        qp.compute(k * 1e-3, Q0 + 0.01 * k, v)
        wall = max(wall, time.perf_counter() - w0)
        cpu = max(cpu, time.process_time() - c0)
    return wall, cpu


def timed_exp(metric, speed: float) -> tuple[float, float, str]:
    w0, c0 = time.perf_counter(), time.process_time()
    try:
        exp(metric, Q0, np.full(7, speed / np.sqrt(7)), method="dop853")
        outcome = "returned"
    except GeosynError as err:
        outcome = type(err).__name__
    return time.perf_counter() - w0, time.process_time() - c0, outcome


def main() -> None:
    robot = load_robot("panda")
    ref_wall, ref_cpu = worst_qp_tick(robot, 100, 30)
    print(
        f"QP worst tick, default 100 x 30: {ref_wall * 1e3:.1f} ms wall, {ref_cpu * 1e3:.1f} ms CPU"
    )
    for mi, mii in ((1000, 10), (10, 1000)):
        wall, cpu = worst_qp_tick(robot, mi, mii)
        print(
            f"QP worst tick, {mi} x {mii}: {wall * 1e3:.1f} ms wall, {cpu * 1e3:.1f} ms CPU"
            f" ({cpu / ref_cpu:.1f} x the default's CPU)"
        )
    metric = KineticEnergyMetric(robot)
    ref_wall, ref_cpu, _ = timed_exp(metric, 1.0)
    print(f"exp dop853 |v0| = 1: {ref_wall:.3f} s wall, {ref_cpu:.3f} s CPU")
    for speed in (1e5, 1e8):
        wall, cpu, outcome = timed_exp(metric, speed)
        print(
            f"exp dop853 |v0| = {speed:g}: {outcome} after {wall:.2f} s wall, {cpu:.2f} s CPU"
            f" ({cpu / ref_cpu:.0f} x |v0| = 1)"
        )


if __name__ == "__main__":
    main()
