"""Per-solve time of the box-DDP MPC (``GeodesicMPC(solver="ddp")``), one or more source
trees timed in the same run (e.g. before and after a refactor).

Run (in geosyn's venv)::

    .venv/bin/python benchmarks/mpc_ddp_solve_time.py [--tree /path/to/old/checkout ...]
        [--horizon 10 40] [--solves 300] [--rounds 3] [--backward native casadi]

Each tree (a folder holding a ``geosyn`` package; default: this repository) is timed in
its own subprocess, the trees alternating round by round so that machine load hits them
alike. A round builds the Panda's torque-level MPC (default weights, N stages of 20 ms,
effort ``"torque"``) on a geodesic reference, cold-solves at t = 0, then times
``--solves`` warm solves (``GeodesicMPC.solve``: reference sampling, one DDP iteration)
along the plan (each solve starts from the previous plan's second state). Printed: the
median wall and CPU time per warm solve over the rounds' medians, and each variant's ratio
to the first one's. ``--backward`` times each tree with each DDP backward pass
(``DDPOptions(backward=...)``: ``native``, the hand-written C, or ``casadi``, the CasADi
graph; ``default``: ``solver="ddp"`` as the tree defines it, for trees older than the option).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
Q0 = [0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785]  # Panda "ready" [rad]
V0 = [0.4, 0.3, -0.3, 0.4, 0.5, -0.4, 0.6]  # [rad/s]


def worker(horizon: int, solves: int, backward: str = "default") -> dict[str, float]:
    """Time warm DDP solves in this process (imports geosyn from ``sys.path``)."""
    import numpy as np

    from geosyn.controllers import GeodesicMPC, GeodesicReference
    from geosyn.controllers.mpc import DDPOptions
    from geosyn.metrics import KineticEnergyMetric
    from geosyn.robots import load_robot
    from geosyn.synergies.synergy import GeodesicSynergy

    robot = load_robot("panda")
    metric = KineticEnergyMetric(robot)
    duration = (solves + horizon + 5) * 0.02
    ref = GeodesicReference(
        GeodesicSynergy(metric, np.array(Q0), np.array(V0)),
        time_scale=8.0,
        duration=duration,
        steps=int(duration / 0.005),
    )
    solver = "ddp" if backward == "default" else DDPOptions(backward=backward)
    mpc = GeodesicMPC(
        robot, metric, horizon=horizon, dt=0.02, control="torque", solver=solver, reference=ref
    )
    q, v = np.array(Q0), np.array(V0) / 8.0
    plan = mpc.solve(0.0, q, v)
    mpc._plan = plan  # the warm start of the next solve, as GeodesicMPC.compute keeps it
    wall, cpu = [], []
    for k in range(1, solves + 1):
        q, v = plan.x[1, :7], plan.x[1, 7:]
        w0, c0 = time.perf_counter(), time.process_time()
        plan = mpc.solve(k * 0.02, q, v)
        wall.append(time.perf_counter() - w0)
        cpu.append(time.process_time() - c0)
        if not plan.success:
            raise SystemExit(f"solve {k} failed: {plan.status}")
        mpc._plan = plan
    return {"wall": float(np.median(wall)), "cpu": float(np.median(cpu))}


def _run(tree: Path, horizon: int, solves: int, backward: str) -> dict[str, float]:
    env = {**os.environ, "PYTHONPATH": str(tree)}
    cmd = [sys.executable, __file__, "--worker", str(horizon), str(solves), backward]
    out = subprocess.run(cmd, env=env, capture_output=True, text=True, check=True, cwd=tree)
    return json.loads(out.stdout.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tree", type=Path, action="append", default=None)
    parser.add_argument("--horizon", type=int, nargs="+", default=[10, 40])
    parser.add_argument("--solves", type=int, default=300)
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument(
        "--backward", nargs="+", default=["default"], choices=["default", "native", "casadi"]
    )
    parser.add_argument("--worker", nargs=3, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.worker:
        horizon, solves, backward = args.worker
        print(json.dumps(worker(int(horizon), int(solves), backward)))
        return
    variants = [(t, b) for t in [REPO] + (args.tree or []) for b in args.backward]
    for horizon in args.horizon:
        results: dict[tuple[Path, str], list[dict[str, float]]] = {v: [] for v in variants}
        for _ in range(args.rounds):
            for tree, backward in variants:
                results[tree, backward].append(_run(tree, horizon, args.solves, backward))
        base = None
        for tree, backward in variants:
            wall = statistics.median(r["wall"] for r in results[tree, backward])
            cpu = statistics.median(r["cpu"] for r in results[tree, backward])
            base = base or (wall, cpu)
            print(
                f"N={horizon:3d}  {str(tree):30s} {backward:8s} warm solve {1e6 * wall:7.1f} us "
                f"wall ({wall / base[0]:.3f}x), {1e6 * cpu:7.1f} us CPU ({cpu / base[1]:.3f}x)"
            )


if __name__ == "__main__":
    main()
