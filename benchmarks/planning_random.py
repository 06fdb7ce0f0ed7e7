"""Benchmark: seeded random queries without obstacles on the catalogue's fixed-base arms.

For each robot, the default ``Planner(KineticEnergyMetric(load_robot(name)))`` plans
between seeded random configurations (``--seed``, ``--budget`` s each) until ``--queries``
pairs were tried whose ends are free of self-collision (the planner's own end check on
the file's meshes decides; a refused end is drawn again and not counted); ``--budget``
defaults to `Planner.plan`'s own (what a user gets without asking). Prints how many
were planned, the wall time of the planner's creation (warm sphere cache unless
``GEOSYN_CACHE_DIR`` points to an empty folder) and the median plan time.

``--learn-radius R1 R2 ...``: variants of the radius within which a query raises a self
pair's floor near a contact (`geosyn.metrics.planning.sampling.SELF_LEARN_RADIUS`; ``inf``:
everywhere), each query planned with each in turn, alternating the order per query, in
one process; one line per variant.

Run: ``.venv/bin/python benchmarks/planning_random.py [--robots ur5 ur10_robot]
[--queries 8] [--budget 5] [--seed 0]``
"""

from __future__ import annotations

import argparse
import functools
import inspect
import os
import time
import warnings

import numpy as np

from geosyn.metrics import KineticEnergyMetric
from geosyn.metrics.planning import Planner
from geosyn.metrics.planning.errors import InCollision, NoPathFound
from geosyn.metrics.planning.sampling import SELF_LEARN_RADIUS, Sampling
from geosyn.robots import load_robot

ROBOTS = ("ur10_robot", "ur3_robot", "ur5", "ur5_gripper", "kinova", "xarm7", "panda")


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description="seeded random queries, no obstacles")
    p.add_argument("--robots", nargs="+", default=list(ROBOTS))
    p.add_argument("--queries", type=int, default=8)
    default = inspect.signature(Planner.plan).parameters["budget"].default
    p.add_argument("--budget", type=float, default=default,
                   help=f"seconds per query (default: the planner's own, {default:g})")  # fmt: skip
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--learn-radius", type=float, nargs="+", default=[SELF_LEARN_RADIUS],
                   help="radii [rad] of the learned self floors (module docstring)")  # fmt: skip
    args = p.parse_args(argv)
    print(f"load average {os.getloadavg()[0]:.2f} ({os.cpu_count()} cores); seed {args.seed}, "
          f"{args.queries} queries of {args.budget} s per robot")  # fmt: skip
    for name in args.robots:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # the catalogue's missing limits, said elsewhere
            robot = load_robot(name)
            t0 = time.perf_counter()
            planner = Planner(KineticEnergyMetric(robot))
        created = time.perf_counter() - t0
        rng = np.random.default_rng(args.seed)
        radii = args.learn_radius
        tried, planned = 0, dict.fromkeys(radii, 0)
        times: dict[float, list[float]] = {r: [] for r in radii}
        while tried < args.queries:
            q0, q1 = robot.random_q(rng), robot.random_q(rng)
            try:
                for r in radii if tried % 2 == 0 else radii[::-1]:
                    planner.sampling.learn_floor = functools.partial(  # type: ignore[method-assign]
                        Sampling.learn_floor, planner.sampling, radius=r
                    )
                    t = time.perf_counter()
                    try:
                        planner.plan(q0, q1, budget=args.budget, seed=0)
                        planned[r] += 1
                    except NoPathFound:
                        pass
                    times[r].append(time.perf_counter() - t)
            except InCollision:  # an end (the first variant's check): drawn again
                continue
            tried += 1
        for r in radii:
            print(f"{name:12s} planned {planned[r]}/{tried}, Planner() {created:5.2f} s, "
                  f"median query {np.median(times[r]):5.2f} s"
                  + (f" (learned floors within {r:g} rad)" if len(radii) > 1 else ""))  # fmt: skip


if __name__ == "__main__":
    main()
