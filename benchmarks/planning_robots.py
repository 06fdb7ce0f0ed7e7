"""The default `Planner` on other robots' own files: budgets kept, paths checked by referees.

For each robot (catalogue names), seeded random scenes: 1-3 spheres and boxes sized and
placed by the arm's reach, random start and goal (queries whose ends collide are
skipped: `InCollision`). Each query is planned at each budget by
``Planner(KineticEnergyMetric(robot))`` as a user gets it. Printed per robot and budget:
queries, paths returned, wall time / budget (median, largest) and how many ran more
than 10 % over; every returned path is checked against the referees:

- the obstacles: coal on the URDF's collision geometry as Pinocchio builds it (the
  triangle meshes, ``tests/self_collision_referee.MeshObstacleReferee``; geosyn's exact
  check measures a mesh's convex hull, which contains it), every 2 mrad (on the SO-101's
  fine meshes ~4 min a budget);
- the joint limits;
- self-collision: Pinocchio's collision model of the URDF on the planner's self pairs
  (``tests/self_collision_referee.py``), every 10 mrad.

    .venv/bin/python benchmarks/planning_robots.py --robots ur5,so101 --budgets 0.1,1

The figures are in ``benchmarks/RESULTS.md`` (issue 22, twenty-seventh round).
"""

from __future__ import annotations

import argparse
import math
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np
import pinocchio as pin

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from self_collision_referee import MeshObstacleReferee, SelfCollisionReferee  # noqa: E402

from geosyn.metrics import KineticEnergyMetric  # noqa: E402
from geosyn.metrics.planning import Planner, PlanningError  # noqa: E402
from geosyn.metrics.planning.errors import InCollision  # noqa: E402
from geosyn.robots import load_robot  # noqa: E402
from geosyn.robots.robot import Robot  # noqa: E402
from geosyn.world import Box, Shape, Sphere  # noqa: E402
from geosyn.world.exact_clearance import checked_configurations  # noqa: E402

ROBOTS = "panda,ur5,ur10_robot,xarm7,kinova,z1,so101"
"""Default robots: fixed-base arms of the catalogue with collision meshes."""


def reach(robot: Robot, rng: np.random.Generator) -> float:
    """Largest distance [m] of a joint origin from the world origin over 50 random
    configurations of ``robot``."""
    data, far = robot.model.createData(), 0.0
    for _ in range(50):
        pin.forwardKinematics(robot.model, data, robot.random_q(rng))
        far = max(far, max(float(np.linalg.norm(M.translation)) for M in data.oMi))
    return far


def scenes(robot: Robot, count: int, seed: int) -> list[tuple[list[Shape], np.ndarray, np.ndarray]]:
    """``count`` seeded (obstacles, start (n,) [rad], goal (n,) [rad]) of ``robot``: 1-3
    spheres (radius 5-15 % of the reach) and boxes (half sides 3-20 %) above the floor
    within 70 % of the reach, ends 0.1 rad inside the limits."""
    rng = np.random.default_rng(seed)
    r, out = reach(robot, rng), []
    for _ in range(count):
        obstacles: list[Shape] = []
        for _ in range(int(rng.integers(1, 4))):
            c = rng.uniform(-0.7, 0.7, 3) * r
            c[2] = abs(c[2]) * 0.8 + 0.1 * r
            if rng.random() < 0.5:
                obstacles.append(Sphere(tuple(c), float(rng.uniform(0.05, 0.15) * r)))
            else:
                obstacles.append(Box(tuple(c), tuple(rng.uniform(0.03, 0.2, 3) * r)))
        out.append((obstacles, robot.random_q(rng, margin=0.1), robot.random_q(rng, margin=0.1)))
    return out


def faults(robot: Robot, meshes: MeshObstacleReferee, referee: SelfCollisionReferee,
           path: np.ndarray, obstacles: list[Shape]) -> list[str]:  # fmt: skip
    """What the referees find wrong with ``path`` (T, n) [rad] among ``obstacles``."""
    meshes.set_obstacles(obstacles)
    found = []
    if meshes.path_clearance(checked_configurations(path, 0.002)) < 0.0:
        found.append("enters an obstacle")
    if np.any(path < robot.q_min - 1e-9) or np.any(path > robot.q_max + 1e-9):
        found.append("leaves the joint limits")
    if any(referee.collides(q) for q in checked_configurations(path, 0.01)):
        found.append("self-collides (Pinocchio)")
    return found


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description="the default Planner on other robots")
    p.add_argument("--robots", default=ROBOTS, help="comma-separated catalogue names")
    p.add_argument("--budgets", default="0.1,0.3,1", help="budgets T [s]")
    p.add_argument("--scenes", type=int, default=16, help="random scenes per robot")
    p.add_argument("--seed", type=int, default=7)
    args = p.parse_args(argv)
    budgets = [float(b) for b in args.budgets.split(",")]
    print(f"{os.cpu_count()} cores, load average {os.getloadavg()[0]:.2f} at start")
    print(f"{'robot':11s} {'T [s]':>6s} {'queries':>7s} {'paths':>5s} "
          f"{'wall/T med':>10s} {'max':>5s} {'> 1.1':>5s}  referees")  # fmt: skip
    for name in args.robots.split(","):
        robot = load_robot(name)
        planner = Planner(KineticEnergyMetric(robot))
        meshes = MeshObstacleReferee(robot)
        referee = SelfCollisionReferee(robot, planner.sphere_check.self_pairs)
        cases = scenes(robot, args.scenes, args.seed)
        for T in budgets:
            ratios, paths, wrong = [], 0, []
            for k, (obstacles, q0, q1) in enumerate(cases):
                t0 = time.perf_counter()
                try:
                    plan = planner.plan(q0, q1, obstacles, budget=T, seed=k)
                except InCollision:
                    continue
                except PlanningError:
                    plan = None
                ratios.append((time.perf_counter() - t0) / T)
                if plan is not None:
                    paths += 1
                    path = np.asarray(plan.q)
                    wrong += [f"#{k}: {f}" for f in faults(robot, meshes, referee, path, obstacles)]
            over = sum(r > 1.1 for r in ratios)
            med = statistics.median(ratios) if ratios else math.nan
            top = max(ratios, default=math.nan)
            print(f"{name:11s} {T:6g} {len(ratios):7d} {paths:5d} {med:10.2f} {top:5.2f} "
                  f"{over:5d}  {'; '.join(wrong) if wrong else 'all clear'}", flush=True)  # fmt: skip


if __name__ == "__main__":
    main()
