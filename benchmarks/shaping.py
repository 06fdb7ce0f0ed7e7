"""Benchmark: ShapedMetric on panda with 0, 4 and 16 sphere obstacles (compiled C).

Targets (issue 4): cost of G and of the Christoffel symbols grows linearly with the number
of obstacles, <= 2 us per (collision sphere, obstacle) pair; moving an obstacle (a write
into the parameter array) < 50 us. Builds and compiles (gcc, cached on disk) first, outside
the timing. Run: ``.venv/bin/python benchmarks/shaping.py``
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from _timing import per_call  # noqa: E402

from geosyn.metrics import KineticEnergyMetric  # noqa: E402
from geosyn.metrics.shaping import ObstacleTerm, ShapedMetric  # noqa: E402
from geosyn.robots import load_robot  # noqa: E402
from geosyn.world import Sphere  # noqa: E402

COUNTS = (0, 4, 16)


def _obstacles(count: int, rng: np.random.Generator) -> list[Sphere]:
    """Spheres in the panda's workspace, within the cutoff of some links."""
    centers = rng.uniform([0.2, -0.5, 0.1], [0.7, 0.5, 0.9], size=(count, 3))
    return [Sphere(c, 0.05) for c in centers]


def main() -> None:
    robot = load_robot("panda")
    base = KineticEnergyMetric(robot, compile=True)
    n_spheres = len(robot.collision_spheres())
    rng = np.random.default_rng(0)
    q = robot.random_q(rng)
    rows = []
    term16 = None
    for count in COUNTS:
        terms = []
        if count:
            term = ObstacleTerm(_obstacles(count, rng), capacity=count, cutoff=0.3)
            terms.append(term)
            term16 = term
        shaped = ShapedMetric(base, terms, compile=True)
        t0 = time.perf_counter()
        shaped.G(q)
        shaped.christoffel(q)
        build = time.perf_counter() - t0
        t_G = per_call(lambda s=shaped: s.G(q))
        t_gam = per_call(lambda s=shaped: s.christoffel(q))
        rows.append((count, t_G, t_gam, build))
    print(f"panda (7 DoF, {n_spheres} collision spheres), compiled C, best of 7 [us per call]")
    print("  obstacles   pairs       G   christoffel   (build+compile [s])")
    for count, t_G, t_gam, build in rows:
        print(
            f"  {count:9d} {count * n_spheres:7d} {t_G * 1e6:7.2f} {t_gam * 1e6:13.2f}"
            f"   ({build:.1f})"
        )
    (_, g0, c0, _), (_, g4, c4, _), (_, g16, c16, _) = rows
    pairs4, pairs16 = 4 * n_spheres, 16 * n_spheres
    print("  per (sphere, obstacle) pair [us], target <= 2:")
    print(
        f"    G:           {(g4 - g0) / pairs4 * 1e6:.3f} (0->4)  {(g16 - g0) / pairs16 * 1e6:.3f} (0->16)"
    )
    print(
        f"    christoffel: {(c4 - c0) / pairs4 * 1e6:.3f} (0->4)  {(c16 - c0) / pairs16 * 1e6:.3f} (0->16)"
    )
    lin_G = (g16 - g0) / max(g4 - g0, 1e-12) / 4.0
    lin_c = (c16 - c0) / max(c4 - c0, 1e-12) / 4.0
    print(
        f"  linearity (cost 0->16) / (4 x cost 0->4), 1 = linear: G {lin_G:.2f}, christoffel {lin_c:.2f}"
    )
    assert term16 is not None
    centers = rng.uniform([0.2, -0.5, 0.1], [0.7, 0.5, 0.9], size=(64, 3))
    k = [0]

    def move() -> None:
        term16.move(k[0] % 16, centers[k[0] % 64])
        k[0] += 1

    def set_all() -> None:
        term16.set_obstacles([Sphere(c, 0.05) for c in centers[:16]])

    print(
        f"  ObstacleTerm.move (one obstacle)        {per_call(move) * 1e6:8.2f} us  (target < 50)"
    )
    print(f"  ObstacleTerm.set_obstacles (16 spheres) {per_call(set_all) * 1e6:8.2f} us")


if __name__ == "__main__":
    main()
