"""Whole-body QP on floating bases standing in MuJoCo (issue 26): longer runs than the
tests, pushes of growing size, MuJoCo's default friction cones beside the scene's.

Prints, per case: slip and sink of the feet [mm], tracking RMS (all coordinates, and the
base with the legs), lowest base height, QP failures, and the CPU time per control tick
beside the CPU time of one MuJoCo control period measured in the same run (their ratio).

    nice -n 10 .venv/bin/python benchmarks/floating_whole_body.py
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import mujoco
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from whole_body_scene import build_scene, run_standing, standing_synergy  # noqa: E402

from geosyn.controllers import WholeBodyController  # noqa: E402
from geosyn.robots.floating import to_mujoco  # noqa: E402

GAINS = {"talos_reduced": {}, "go2": {"kp": 400.0, "kd": 40.0}}


def mujoco_period_cpu(scene_xml: str, q0: np.ndarray, nv: int) -> float:
    """CPU time of the MuJoCo steps of one 1 ms control period, standing [s]."""
    m = mujoco.MjModel.from_xml_string(scene_xml)
    d = mujoco.MjData(m)
    d.qpos[:], d.qvel[:] = to_mujoco(q0, np.zeros(nv))
    sub = int(round(1e-3 / m.opt.timestep))
    start = time.process_time()
    for _ in range(500 * sub):
        mujoco.mj_step(m, d)
    return (time.process_time() - start) / 500


def main() -> None:
    print(
        "| robot | push [N], 0.2 s | cones | slip [mm] | sink [mm] | RMS all / base+legs |"
        " lowest base [m] | QP failures | CPU per tick [ms] (x MuJoCo period) |"
    )
    for name in ("talos_reduced", "go2"):
        for push, cone, impratio in (
            (50.0, "elliptic", 10.0),
            (50.0, "pyramidal", 1.0),
            (100.0, "elliptic", 10.0),
        ):
            scene = build_scene(name, cone=cone, impratio=impratio)
            _, _, ref = standing_synergy(scene, duration=1.5, t0=0.2)
            ctrl = WholeBodyController(scene.robot, scene.feet, scene.corners, ref, **GAINS[name])
            run = run_standing(
                scene, ctrl, ref, duration=3.0, push=(0.0, push, 0.0), push_window=(1.0, 1.2)
            )
            mj = mujoco_period_cpu(scene.xml, scene.q0, scene.robot.nv)
            tick = run.cpu / 3000
            print(
                f"| {name} | {push:.0f} | {cone}, impratio {impratio:g} |"
                f" {run.slip * 1e3:.2f} | {run.lift * 1e3:.2f} |"
                f" {run.rms:.3f} / {run.rms_base_legs:.3f} | {run.min_base_height:.3f} |"
                f" {run.qp_failures} | {tick * 1e3:.2f} ({tick / mj:.1f} x) |",
                flush=True,
            )


if __name__ == "__main__":
    main()
