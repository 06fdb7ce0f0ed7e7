"""Real-time factor of `Simulation.run` for two source trees, timed in the same run.

Panda, computed torque (kp 100, kd 20), 1 kHz control and physics, a 2 s joint
trajectory (the task of ``benchmarks/sim.py``). Each tree runs in its own subprocess
(``PYTHONPATH`` = the tree), alternating, ``--rounds`` times; each subprocess warms up
and reports the best of ``--repeat`` runs, wall and CPU time. The ratio of the medians
compares the two trees on the same machine load.

Run: ``nice -n 10 .venv/bin/python benchmarks/sim_rtf.py [--before DIR] [--after DIR]``
(a tree is a directory holding ``geosyn/``; default ``after`` is this checkout).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
from pathlib import Path

CHILD = r"""
import json, sys, time
import numpy as np
from geosyn.controllers import ComputedTorque, JointTrajectoryReference
from geosyn.robots import load_robot
from geosyn.sim import Simulation

repeat, duration = int(sys.argv[1]), float(sys.argv[2])
robot = load_robot("panda")
q0 = robot.neutral()
q0[3], q0[5] = -1.5, 1.5
t = np.linspace(0.0, duration, 21)
sign = np.array([1.0, -1.0, 1.0, 1.0, -1.0, 1.0, 1.0])
ref = JointTrajectoryReference(t, q0 + 0.3 * np.sin(0.5 * np.pi * t / duration)[:, None] ** 2 * sign)
sim = Simulation(robot, ComputedTorque(robot, 100.0, 20.0), control_dt=1e-3)
sim.run(q0, None, 0.05, ref)
best = None
for _ in range(repeat):
    w0, c0 = time.perf_counter(), time.process_time()
    res = sim.run(q0, None, duration, ref)
    wall, cpu = time.perf_counter() - w0, time.process_time() - c0
    if best is None or wall < best[0]:
        best = (wall, cpu, float(res.rms_error()))
print(json.dumps({"rtf_wall": duration / best[0], "rtf_cpu": duration / best[1], "rms": best[2]}))
"""


def measure(tree: Path, repeat: int, duration: float) -> dict[str, float]:
    env = dict(os.environ, PYTHONPATH=str(tree))
    out = subprocess.run(
        [sys.executable, "-c", CHILD, str(repeat), str(duration)],
        env=env, capture_output=True, text=True, check=True, cwd="/tmp",
    )  # fmt: skip
    return json.loads(out.stdout.strip().splitlines()[-1])


def main() -> None:
    root = Path(__file__).resolve().parents[1]
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--before", type=Path, default=None)
    p.add_argument("--after", type=Path, default=root)
    p.add_argument("--rounds", type=int, default=3)
    p.add_argument("--repeat", type=int, default=3)
    p.add_argument("--duration", type=float, default=2.0)
    a = p.parse_args()
    trees = {"after": a.after} if a.before is None else {"before": a.before, "after": a.after}
    got: dict[str, list[dict[str, float]]] = {k: [] for k in trees}
    for _ in range(a.rounds):
        for name, tree in trees.items():
            got[name].append(measure(tree, a.repeat, a.duration))
    print(f"panda, computed torque, {a.duration:g} s at 1 kHz; median of {a.rounds} rounds")
    med, cpu = {}, {}
    for name, rows in got.items():
        med[name] = statistics.median(r["rtf_wall"] for r in rows)
        cpu[name] = statistics.median(r["rtf_cpu"] for r in rows)
        rms = rows[0]["rms"]
        print(f"{name:7s} RTF wall {med[name]:6.1f}x  RTF cpu {cpu[name]:6.1f}x  rms {rms:.3e} rad")
    if "before" in med:
        print(
            f"after / before: wall RTF {med['after'] / med['before']:.3f},"
            f" CPU RTF {cpu['after'] / cpu['before']:.3f}"
        )


if __name__ == "__main__":
    main()
