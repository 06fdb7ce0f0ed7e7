"""Benchmark: KineticEnergyMetric.G on trees with several root joints against pin.crba.

Target (issue 10): G ~1x pin.crba on hands and humanoids (the NaN check of the fast path
used to fall back to a second pin.crba there: 3.2-3.9x). Measured alternately in one run.
Run: ``.venv/bin/python benchmarks/trees.py``
"""

from __future__ import annotations

import sys
import warnings
from pathlib import Path

import numpy as np
import pinocchio as pin

sys.path.insert(0, str(Path(__file__).parent))
from _timing import per_call  # noqa: E402

from geosyn.metrics import KineticEnergyMetric  # noqa: E402
from geosyn.robots import load_robot  # noqa: E402

ROBOTS = {
    "two_fingers (MJCF fixture)": (
        Path(__file__).parents[1] / "tests" / "fixtures" / "two_fingers.xml",
        {"tau_max": 1.0},
    ),
    "allegro_right_hand": ("allegro_right_hand", {}),
    "talos_reduced (fixed base)": ("talos_reduced", {"fixed_base": True}),
    "panda (one root)": ("panda", {}),
}


def main() -> None:
    print("G(q) time per call [us], pin.crba and metric.G measured alternately (best of 5)")
    for label, (name, options) in ROBOTS.items():
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            robot = load_robot(name, **options)
        model = robot.model
        roots = sum(model.parents[j] == 0 for j in range(1, model.njoints))
        metric = KineticEnergyMetric(robot)
        q = robot.random_q(np.random.default_rng(0))
        data = model.createData()
        t_crba = t_G = float("inf")

        def crba(model=model, data=data, q=q):  # bound now (not late in the loop)
            return pin.crba(model, data, q)

        def G(metric=metric, q=q):
            return metric.G(q)

        for _ in range(5):
            t_crba = min(t_crba, per_call(crba, repeat=3))
            t_G = min(t_G, per_call(G, repeat=3))
        print(
            f"  {label:<28} nv={robot.nv:>2} roots={roots:>2}  pin.crba {t_crba * 1e6:7.2f}"
            f"  G {t_G * 1e6:7.2f}  {t_G / t_crba:5.2f}x"
        )


if __name__ == "__main__":
    main()
