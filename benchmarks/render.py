"""Benchmark of video frames (`geosyn.sim.Clip`): seconds per frame, against MuJoCo's own
renderer timed in the same run.

For each robot, a 2 s held motion is filmed at 25 fps, 640 x 480: geosyn's frames (the
robot's own meshes where its file has them, paths, overlay texts, shadows as chosen by
`geosyn.sim.render_scene`) and its capsule frames, against ``mujoco.Renderer`` drawing the
same capsule scene (``update_scene`` + ``render``, nothing else). The three are timed
alternately (A/B/C, ``--repeat`` rounds, best round reported); the frame loop only (the
scene is built before). Target: < 0.5 s per frame (issue 12). GIF encoding is not
included (``Clip.save`` adds ~10 ms per 640 x 480 frame).

Run: ``.venv/bin/python benchmarks/render.py [--repeat N]``. Timings depend on the
machine's load; the figures go to benchmarks/RESULTS.md.
"""

from __future__ import annotations

import argparse
import os
import time
import warnings

# mujoco.Renderer reads MUJOCO_GL once, at import (geosyn's renderer does not need it).
os.environ.setdefault("MUJOCO_GL", "egl")

import numpy as np

from geosyn.robots import load_robot
from geosyn.sim import Clip, Motion, build_scene

FPS, WIDTH, HEIGHT, DURATION = 25.0, 640, 480, 2.0


def motion(robot) -> Motion:
    t = np.arange(0.0, DURATION + 1e-9, 0.01)
    q = robot.neutral() + 0.3 * np.outer(np.sin(np.pi * t / DURATION), np.ones(robot.nq))
    return Motion(t, q, q + 0.02)


def time_clip(clip: Clip) -> float:
    """Seconds per frame of the frame loop (the first frame, which builds the context, is
    excluded)."""
    frames = clip.frames()
    next(frames)
    t0 = time.perf_counter()
    n = sum(1 for _ in frames)
    return (time.perf_counter() - t0) / n


def time_mujoco(robot, m: Motion) -> float:
    """Seconds per frame of ``mujoco.Renderer`` on the same capsule scene (EGL)."""
    import mujoco

    scene = build_scene(robot, decor=True)
    data = mujoco.MjData(scene.model)
    idx = np.linspace(0, len(m.t) - 1, int(DURATION * FPS) + 1).round().astype(int)
    with mujoco.Renderer(scene.model, HEIGHT, WIDTH) as renderer:
        renderer.render()
        t0 = time.perf_counter()
        for k in idx[1:]:
            data.qpos[scene.qpos_adr] = m.q[k]
            mujoco.mj_forward(scene.model, data)
            renderer.update_scene(data)
            renderer.render()
        return (time.perf_counter() - t0) / (len(idx) - 1)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    warnings.simplefilter("ignore")
    print(f"{'robot':<10} {'geosyn [s/frame]':>17} {'capsules':>9} {'mujoco':>7}  ratio  drawn as")
    for name in ("panda", "ur5", "talos_arm"):
        robot = load_robot(name)
        m = motion(robot)
        kw = dict(fps=FPS, width=WIDTH, height=HEIGHT, label=name)
        best = {"geosyn": np.inf, "capsules": np.inf, "mujoco": np.inf}
        for _ in range(args.repeat):
            best["geosyn"] = min(best["geosyn"], time_clip(Clip(m, robot, **kw)))
            best["capsules"] = min(best["capsules"], time_clip(Clip(m, robot, meshes=False, **kw)))
            best["mujoco"] = min(best["mujoco"], time_mujoco(robot, m))
        note = Clip(m, robot).mesh_note() or "own meshes"
        print(
            f"{name:<10} {best['geosyn']:>17.3f} {best['capsules']:>9.3f} {best['mujoco']:>7.3f}"
            f"  {best['geosyn'] / best['mujoco']:5.1f}  {note}"
        )


if __name__ == "__main__":
    main()
