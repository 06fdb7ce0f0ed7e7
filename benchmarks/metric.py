"""Benchmark: kinetic-energy metric calls on panda against Pinocchio, measured in one run.

Targets (issue 2): G and geodesic acceleration <= 1.5x pin.crba / pin.aba.
Run: ``.venv/bin/python benchmarks/metric.py``
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pinocchio as pin

sys.path.insert(0, str(Path(__file__).parent))
from _timing import per_call  # noqa: E402

from geosyn.metrics import KineticEnergyMetric  # noqa: E402
from geosyn.robots import load_robot  # noqa: E402


def main() -> None:
    robot = load_robot("panda")
    metric = KineticEnergyMetric(robot, compile=True)
    rng = np.random.default_rng(0)
    q = robot.random_q(rng)
    v = rng.normal(size=robot.nv)
    model0 = pin.Model(robot.model)
    model0.gravity = pin.Motion.Zero()
    data, data0 = robot.model.createData(), model0.createData()
    zero = np.zeros(robot.nv)
    metric.christoffel(q)  # build + compile once, outside the timing

    # Reference and target are measured alternately, best of several rounds each, so a
    # change of machine load between them does not bias the ratio.
    t_crba = t_G = t_aba = t_acc = float("inf")
    for _ in range(5):
        t_crba = min(t_crba, per_call(lambda: pin.crba(robot.model, data, q), repeat=3))
        t_G = min(t_G, per_call(lambda: metric.G(q), repeat=3))
        t_aba = min(t_aba, per_call(lambda: pin.aba(model0, data0, q, v, zero), repeat=3))
        t_acc = min(t_acc, per_call(lambda: metric.geodesic_acceleration(q, v), repeat=3))
    t_gam = per_call(lambda: metric.christoffel(q))
    t_cor = per_call(lambda: metric.coriolis(q, v))
    f_sym = metric.functions.geodesic_acceleration
    t_acc_c = per_call(lambda: f_sym(q, v))

    print("panda (7 DoF), time per call [us] (Pinocchio and geosyn measured alternately)")
    print(f"  pin.crba                         {t_crba * 1e6:8.2f}")
    print(f"  pin.aba (zero gravity, torque)   {t_aba * 1e6:8.2f}")
    print(
        f"  metric.G                         {t_G * 1e6:8.2f}   {t_G / t_crba:5.2f}x pin.crba  (target <= 1.5x)"
    )
    print(
        f"  metric.geodesic_acceleration     {t_acc * 1e6:8.2f}   {t_acc / t_aba:5.2f}x pin.aba   (target <= 1.5x)"
    )
    print(f"  metric.coriolis                  {t_cor * 1e6:8.2f}")
    print(
        f"  metric.christoffel (compiled C)  {t_gam * 1e6:8.2f}   {t_gam / t_crba:5.2f}x pin.crba"
    )
    print(
        f"  symbolic ABA, plain casadi call   {t_acc_c * 1e6:8.2f}   {t_acc_c / t_aba:5.2f}x pin.aba"
    )


if __name__ == "__main__":
    main()
