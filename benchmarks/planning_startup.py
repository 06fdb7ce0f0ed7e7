"""Benchmark: what a user waits for before the first plan (issue 22, deliver 3).

Runs, each in a fresh Python process, ``Planner(KineticEnergyMetric(load_robot("panda")))``
(every default; ``--gripper open``: the fingers locked open, as the planning benchmarks'
`planning_geosyn.benchmark_robot`, whose finger meshes the spheres are then fitted to as well)
and its first query (a scene of ``planning_scenes.py``): first with an
empty cache folder (``GEOSYN_CACHE_DIR`` a new temporary folder: the spheres are fitted
to the URDF meshes and the per-node functions built), then ``--repeat`` times with that
cache warm. Prints wall and CPU time of the import, the planner's creation and the first
plan, and when the first plan's first feasible path was found after the creation (the
query builds the NLPs of its own obstacle slot count first, `Plan.nlp_build_time`; with
the default ``alternatives`` the query then spends time on other seeds).

``--robot NAME`` (another robot of the catalogue, every default): the first query is
between seeded random configurations without obstacles (seed 0, 2 s budget; a pair the
planner refuses, e.g. a start in self-collision, is counted and the next pair tried, at
most 8).

Run: ``.venv/bin/python benchmarks/planning_startup.py [--scene quickstart] [--repeat 2]
[--gripper closed|open] [--robot so101]``
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))
from planning_geosyn import GRIPPERS  # noqa: E402

CHILD = """
import json, sys, time
w0, c0 = time.perf_counter(), time.process_time()
import numpy as np
sys.path.insert(0, {bench!r})
import planning_scenes as ps
from planning_geosyn import benchmark_robot, to_geosyn
from geosyn.metrics import KineticEnergyMetric
from geosyn.metrics.planning import Planner
w1, c1 = time.perf_counter(), time.process_time()
planner = Planner(KineticEnergyMetric(benchmark_robot({gripper!r})))
w2, c2 = time.perf_counter(), time.process_time()
sc = ps.scene_by_name({scene!r})
plan = planner.plan(np.array(sc.q_start), np.array(sc.q_goal),
                    [to_geosyn(o) for o in sc.obstacles], budget=30.0)
w3, c3 = time.perf_counter(), time.process_time()
print(json.dumps({{"import": [w1 - w0, c1 - c0], "create": [w2 - w1, c2 - c1],
                  "plan": [w3 - w2, c3 - c2], "exact": plan.exact_clearance,
                  "first": plan.nlp_build_time + plan.first_feasible_time,
                  "build": plan.nlp_build_time,
                  "spheres": len(planner.term.spheres)}}))
"""

CHILD_ROBOT = """
import json, time
w0, c0 = time.perf_counter(), time.process_time()
import numpy as np
from geosyn.core.errors import GeosynError
from geosyn.metrics import KineticEnergyMetric
from geosyn.metrics.planning import Planner
from geosyn.robots import load_robot
robot = load_robot({robot!r})
w1, c1 = time.perf_counter(), time.process_time()
planner = Planner(KineticEnergyMetric(robot))
w2, c2 = time.perf_counter(), time.process_time()
rng, refused, plan = np.random.default_rng(0), 0, None
for _ in range(8):
    qa, qb = robot.random_q(rng), robot.random_q(rng)
    try:
        plan = planner.plan(qa, qb, [], budget=2.0)
        break
    except GeosynError:
        refused += 1
w3, c3 = time.perf_counter(), time.process_time()
print(json.dumps({{"import": [w1 - w0, c1 - c0], "create": [w2 - w1, c2 - c1],
                  "plan": [w3 - w2, c3 - c2], "refused": refused,
                  "exact": plan.exact_clearance if plan else float("nan"),
                  "spheres": len(planner.term.spheres)}}))
"""


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description="geosyn Planner: first use and new-process times")
    p.add_argument("--scene", default="quickstart")
    p.add_argument("--repeat", type=int, default=2, help="new processes with the warm cache")
    p.add_argument("--gripper", choices=sorted(GRIPPERS), default="closed",
                   help="closed: load_robot('panda') as a user gets it; open: as the "
                        "planning benchmarks' robot (planning_geosyn.benchmark_robot)")  # fmt: skip
    p.add_argument(
        "--robot",
        default="panda",
        help="a catalogue robot; not panda: seeded random queries, no obstacles",
    )
    args = p.parse_args(argv)
    bench = str(Path(__file__).resolve().parent)
    code = CHILD.format(bench=bench, scene=args.scene, gripper=args.gripper)
    if args.robot != "panda":
        code = CHILD_ROBOT.format(robot=args.robot)
    what = f"gripper {args.gripper}" if args.robot == "panda" else f"robot {args.robot}"
    print(f"load average {os.getloadavg()[0]:.2f} ({os.cpu_count()} cores, shared machine); "
          f"{what}")  # fmt: skip
    with tempfile.TemporaryDirectory(prefix="geosyn-cache-") as cache:
        env = {**os.environ, "GEOSYN_CACHE_DIR": cache}
        for i in range(1 + args.repeat):
            out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                                 text=True, check=True)  # fmt: skip
            r = json.loads(out.stdout.strip().splitlines()[-1])
            what = "empty cache" if i == 0 else f"warm cache, new process {i}"
            head = (
                f"{what:28s} import {r['import'][0]:5.2f} s (cpu {r['import'][1]:5.2f}), "
                f"Planner() {r['create'][0]:5.2f} s (cpu {r['create'][1]:5.2f}), "
                f"first plan {r['plan'][0]:5.2f} s (cpu {r['plan'][1]:5.2f}); "
                f"creation + first plan {r['create'][0] + r['plan'][0]:5.2f} s; "
            )
            if "first" in r:
                head += (f"its first feasible path {r['first']:5.2f} s after creation (NLPs "
                         f"of its slot count built in {r['build']:4.2f} s of it); ")  # fmt: skip
            else:
                head += f"{r['refused']} random pair(s) refused first; "
            print(head + f"{r['spheres']} spheres, exact clearance {r['exact']:.4f} m")


if __name__ == "__main__":
    main()
