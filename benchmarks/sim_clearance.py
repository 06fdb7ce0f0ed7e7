"""What the run's exact clearance and the file's contact geometry cost a simulation.

Panda, computed torque (kp 400, kd 40) at 1 kHz, a 1.5 s move past a box 2.6 cm under
its fingers. Variants, alternating in each round, one `Simulation` each (built untimed,
one untimed warm-up run):

- ``free``: no obstacle;
- ``box, no check``: the box, ``mesh_resolution=None`` (only the spheres' clearance);
- ``box``: the default, the motion checked after the run on the URDF's meshes;
- ``box, contact``: ``contact=True``, the box colliding with the file's geometry.

Prints the median over rounds of wall and CPU time per run [ms] and the ratio to
``box, no check``. ``--rounds N`` (default 7).
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np
import pinocchio as pin

from geosyn.controllers import ComputedTorque, JointTrajectoryReference
from geosyn.robots import load_robot
from geosyn.sim import Simulation
from geosyn.world import Box

Q0 = np.array([0.0, -0.3, 0.0, -2.2, 0.0, 2.0, 0.8])  # [rad]
Q1 = np.array([0.6, 0.1, 0.0, -1.8, 0.0, 2.0, 0.8])  # [rad]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=7)
    args = ap.parse_args()
    robot = load_robot("panda")
    data = robot.model.createData()
    pin.framesForwardKinematics(robot.model, data, Q1)
    hand = np.asarray(data.oMf[robot.model.getFrameId("panda_hand")].translation)
    box = Box(tuple(hand + [0.0, 0.0, -0.16]), (0.1, 0.1, 0.02))
    ref = JointTrajectoryReference(np.array([0.0, 1.0]), np.array([Q0, Q1]))
    variants = {
        "free": {},
        "box, no check": {"obstacles": [box], "mesh_resolution": None},
        "box": {"obstacles": [box]},
        "box, contact": {"obstacles": [box], "contact": True},
    }
    sims = {
        k: Simulation(robot, ComputedTorque(robot, 400.0, 40.0), **kw) for k, kw in variants.items()
    }
    for sim in sims.values():
        sim.run(Q0, duration=1.5, reference=ref)  # warm-up: the coal shapes are built here
    wall: dict[str, list[float]] = {k: [] for k in sims}
    cpu: dict[str, list[float]] = {k: [] for k in sims}
    last = {}
    for _ in range(args.rounds):
        for k, sim in sims.items():
            w0, c0 = time.perf_counter(), time.process_time()
            last[k] = sim.run(Q0, duration=1.5, reference=ref)
            wall[k].append(time.perf_counter() - w0)
            cpu[k].append(time.process_time() - c0)
    base_w, base_c = (
        statistics.median(wall["box, no check"]),
        statistics.median(cpu["box, no check"]),
    )
    print(
        f"{'variant':<15} {'wall [ms]':>10} {'cpu [ms]':>10} {'wall/no check':>14} {'cpu/no check':>13}  mesh / sphere clearance [mm], max contact [N]"
    )
    for k in sims:
        w, c, r = statistics.median(wall[k]), statistics.median(cpu[k]), last[k]
        print(
            f"{k:<15} {w * 1e3:10.1f} {c * 1e3:10.1f} {w / base_w:14.3f} {c / base_c:13.3f}  "
            f"{r.mesh_clearance * 1e3:.2f} / {np.min(r.clearance) * 1e3:.2f}, {np.max(r.contact_force):.1f}"
        )


if __name__ == "__main__":
    main()
