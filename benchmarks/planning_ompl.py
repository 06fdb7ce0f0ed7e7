"""Benchmark referee: are the queries geosyn's default `Planner` refuses solvable? A UR5
among a table, a wall and a panel, against OMPL's RRT-Connect on the URDF's meshes (issue
22, "true on the real robot").

Seeded random queries whose ends are free (Pinocchio's collision model of the URDF: the
boxes grown by ``--inflate``, default the planner's exact floor, 7 mm; geosyn's self pairs)
are planned by the default ``Planner(KineticEnergyMetric(ur5))`` at its default budget;
then OMPL's RRT-Connect (its own venv, `ompl_runner.py`: OMPL, Pinocchio and coal, no
geosyn) searches each query for ``--ompl-time`` seconds on the same collision model. A
query geosyn refuses and OMPL solves is a planner failure; one that neither solves is not
shown solvable. OMPL's paths are only feasible (RRT-Connect and its simplifier): their
times say that a path exists, not what geosyn's optimised, certified paths should cost.

Run: ``bash benchmarks/setup_ompl.sh && nice -n 10 .venv/bin/python
benchmarks/planning_ompl.py [--seed 0] [--queries 12] [--ompl-time 60]``.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pinocchio as pin

sys.path.insert(0, str(Path(__file__).parent))
from ompl_runner import collision_model  # noqa: E402

from geosyn.metrics import KineticEnergyMetric  # noqa: E402
from geosyn.metrics.planning import Planner, PlanningError  # noqa: E402
from geosyn.robots import load_robot  # noqa: E402
from geosyn.robots.collision_spheres import file_spheres  # noqa: E402
from geosyn.world import Box  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
RUNNER = Path(__file__).resolve().parent / "ompl_runner.py"
OMPL_PYTHON = Path(os.environ.get("OMPL_PYTHON", ROOT / ".venv-ompl" / "bin" / "python"))

BOXES = (  # (name, centre [m], half extents [m]): under the base, in front, at the side
    ("table", (0.0, 0.0, -0.06), (0.8, 0.8, 0.05)),
    ("wall", (0.55, 0.0, 0.45), (0.05, 0.6, 0.45)),
    ("panel", (0.0, 0.55, 0.35), (0.35, 0.03, 0.35)),
)
BASE_LINKS = ("world", "base_link")  # on the table: not checked against the boxes


def main() -> None:
    p = argparse.ArgumentParser(description="geosyn's refusals against OMPL on the meshes")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--queries", type=int, default=12)
    p.add_argument("--ompl-time", type=float, default=60.0, help="OMPL's time per query [s]")
    p.add_argument("--inflate", type=float, default=0.007, help="boxes grown by [m]")
    args = p.parse_args()
    if not OMPL_PYTHON.exists():
        raise SystemExit(f"no OMPL venv at {OMPL_PYTHON}: run `bash benchmarks/setup_ompl.sh`")
    robot = load_robot("ur5")
    spec = {
        "urdf": robot.source_file, "q_min": robot.q_min.tolist(), "q_max": robot.q_max.tolist(),
        "pairs": [list(x) for x in file_spheres(robot).self_pairs], "boxes": BOXES,
        "base_links": BASE_LINKS,
    }  # fmt: skip
    model, gm, md, gd = collision_model(spec, args.inflate)
    planner = Planner(KineticEnergyMetric(robot))
    obstacles = [Box(np.array(c), np.array(h)) for _, c, h in BOXES]
    rng, queries = np.random.default_rng(args.seed), []
    while len(queries) < args.queries:
        q0, q1 = robot.random_q(rng), robot.random_q(rng)
        if any(pin.computeCollisions(model, md, gm, gd, q, True) for q in (q0, q1)):
            continue
        t0 = time.perf_counter()
        try:
            plan, why = planner.plan(q0, q1, obstacles), ""
        except PlanningError as err:
            plan, why = None, type(err).__name__
        queries.append({"q0": q0.tolist(), "q1": q1.tolist(), "geosyn": plan is not None,
                        "geosyn_wall": time.perf_counter() - t0, "why": why})  # fmt: skip
    work = Path(tempfile.mkdtemp(prefix="geosyn-ompl-"))
    (work / "queries.json").write_text(json.dumps({**spec, "queries": queries}))
    subprocess.run([str(OMPL_PYTHON), str(RUNNER), "--queries", str(work / "queries.json"),
                    "--out", str(work / "ompl.json"), "--time", str(args.ompl_time),
                    "--inflate", str(args.inflate)], check=True, stdout=subprocess.DEVNULL)  # fmt: skip
    rows = json.loads((work / "ompl.json").read_text())["rows"]
    print(f"UR5 among {', '.join(b[0] for b in BOXES)}; seed {args.seed}; boxes grown by "
          f"{args.inflate * 1e3:g} mm; geosyn: default Planner, default budget; OMPL: "
          f"RRT-Connect, {args.ompl_time:g} s")  # fmt: skip
    print(
        f"{'query':>5s} | {'geosyn':>8s} {'wall [s]':>8s} | {'OMPL':>8s} {'wall [s]':>8s} {'checks':>8s} {'dense hits':>10s}"
    )
    for k, (q, r) in enumerate(zip(queries, rows, strict=True)):
        hits = f"{r['dense_colliding']}/{r['dense']}" if r["found"] else "-"
        print(f"{k + 1:5d} | {'planned' if q['geosyn'] else 'refused':>8s} {q['geosyn_wall']:8.2f} | "
              f"{'found' if r['found'] else 'none':>8s} {r['wall']:8.2f} {r['checks']:8d} {hits:>10s}")  # fmt: skip
    refused = [r for q, r in zip(queries, rows, strict=True) if not q["geosyn"]]
    print(f"geosyn planned {sum(q['geosyn'] for q in queries)} of {len(queries)}; of its "
          f"{len(refused)} refusals OMPL solved {sum(r['found'] for r in refused)} in "
          f"{args.ompl_time:g} s each")  # fmt: skip


if __name__ == "__main__":
    main()
