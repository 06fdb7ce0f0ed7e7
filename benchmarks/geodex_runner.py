"""The geodex side of `benchmarks/planning.py` (issue 11); runs in the geodex venv.

pygeodex (imports as ``geodex``) needs Python >= 3.12, so this script runs in its own venv
(``bash benchmarks/setup_geodex.sh`` creates ``.venv-geodex``) as a subprocess of
``planning.py``; it imports only numpy, geodex and ``planning_scenes.py``. Subcommands:

- ``plan --out FILE.json``: plan every scene with ``geodex.plan`` (G-RRT* with informed
  sampling, then its smoother; ``PlanSettings`` defaults unless ``--time`` /
  ``--iterations`` / ``--seed`` say otherwise) and record the wall time, success, the
  path, its metric length under geodex's own ``mass_matrix`` and geodex's checker on the
  path resampled every ``--check-step`` rad.
- ``check --paths IN.npz --out OUT.json``: geodex's checker on given paths (one array
  per scene name, (T, 7) [rad]): per-path validity and the first invalid index.
- ``scenes --out FILE.json``: start, goal and the straight joint line of every scene
  against the whole scene and against each obstacle alone (which one blocks).
- ``mass-matrix --q IN.npz --out OUT.npz``: ``robots.Panda().mass_matrix(q)`` at the
  rows of ``q`` (N, 7), plus joint names and limits.
- ``spheres --q IN.npz --out OUT.npz``: geodex's (VAMP) collision spheres at each row of
  ``q``: (N, S, 4) world [x, y, z, radius] [m].

geodex's collision model (``geodex.vamp``): the Panda is 59 spheres (radii 0.012-0.08 m,
the base, links, hand and fingers), checked against the scene's primitives (boxes,
spheres, cylinders; no capsule and no half-space type, so a capsule here becomes a
cylinder plus two end spheres, which is the same set, and a half-space a 20 x 20 x 2 m
slab), plus self-collision and joint limits. ``Scene.add_box`` takes full sizes.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
import geodex  # noqa: E402
from geodex import vamp  # noqa: E402
from planning_scenes import (  # noqa: E402
    SCENES,
    Box,
    Capsule,
    Cylinder,
    HalfSpace,
    Sphere,
    frame_with_z_axis,
    matrix_quaternion_xyzw,
    resample,
    rpy_matrix,
    scene_by_name,
    straight_line,
)

ROBOT = "panda"
HALFSPACE_SLAB = (10.0, 10.0, 1.0)
"""Half sizes [m] of the box standing in for a half-space (its top face on the plane)."""


def add_obstacle(scene: geodex.Scene, ob: object) -> None:
    """Add one `planning_scenes` obstacle to a geodex Scene (see the module docstring)."""
    if isinstance(ob, Box):
        q = matrix_quaternion_xyzw(rpy_matrix(ob.rpy))
        scene.add_box(
            position=list(ob.center), size=[2 * h for h in ob.half_extents], orientation=list(q)
        )
    elif isinstance(ob, Sphere):
        scene.add_sphere(center=list(ob.center), radius=ob.radius)
    elif isinstance(ob, Cylinder):
        q = matrix_quaternion_xyzw(rpy_matrix(ob.rpy))
        scene.add_cylinder(
            position=list(ob.center),
            radius=ob.radius,
            height=2 * ob.half_length,
            orientation=list(q),
        )
    elif isinstance(ob, Capsule):
        p0, p1 = np.asarray(ob.p0), np.asarray(ob.p1)
        axis = p1 - p0
        q = matrix_quaternion_xyzw(frame_with_z_axis(axis))
        scene.add_cylinder(
            position=list(0.5 * (p0 + p1)),
            radius=ob.radius,
            height=float(np.linalg.norm(axis)),
            orientation=list(q),
        )
        scene.add_sphere(center=list(ob.p0), radius=ob.radius)
        scene.add_sphere(center=list(ob.p1), radius=ob.radius)
    elif isinstance(ob, HalfSpace):
        n = np.asarray(ob.normal, dtype=float)
        R = frame_with_z_axis(n)
        center = ob.offset * n - HALFSPACE_SLAB[2] * n
        scene.add_box(
            position=list(center),
            size=[2 * h for h in HALFSPACE_SLAB],
            orientation=list(matrix_quaternion_xyzw(R)),
        )
    else:
        raise TypeError(f"unknown obstacle type {type(ob).__name__}")


def build_scene(obstacles: tuple) -> geodex.Scene:
    scene = geodex.Scene()
    for ob in obstacles:
        add_obstacle(scene, ob)
    return scene


def checker(obstacles: tuple) -> vamp.CollisionChecker:
    """geodex's VAMP checker of the Panda in these obstacles (limits and self-collision too)."""
    return vamp.make_vamp_checker(ROBOT, build_scene(obstacles).env())


def validity(chk: vamp.CollisionChecker, path: np.ndarray) -> tuple[bool, int | None, float]:
    """(all valid, first invalid index or None, fraction invalid) of the rows of ``path``."""
    path = np.ascontiguousarray(path, dtype=np.float64)
    if chk.all_valid(path):
        return True, None, 0.0
    bad = np.array([not chk.is_valid(q) for q in path])
    return False, int(np.argmax(bad)), float(bad.mean())


def metric_length(robot: geodex.robots.RobotModel, path: np.ndarray) -> float:
    """Length ``sum_k sqrt(dq_k^T M(q_mid,k) dq_k)`` of a densely sampled path (midpoint rule)."""
    dq = np.diff(path, axis=0)
    mid = 0.5 * (path[1:] + path[:-1])
    return float(
        sum(math.sqrt(max(d @ robot.mass_matrix(m) @ d, 0.0)) for d, m in zip(dq, mid, strict=True))
    )


# -- subcommands ------------------------------------------------------------------------


def cmd_plan(args: argparse.Namespace) -> None:
    robot = geodex.robots.Panda()
    names = args.scenes.split(",") if args.scenes else [s.name for s in SCENES]
    out = {
        "geodex_version": geodex.__version__,
        "settings": {
            "time": args.time,
            "iterations": args.iterations,
            "seed": args.seed,
            "check_step": args.check_step,
        },
        "scenes": {},
    }
    for name in names:
        sc = scene_by_name(name)
        t0 = time.perf_counter()
        env = build_scene(sc.obstacles).env()
        t_env = time.perf_counter() - t0
        settings = geodex.PlanSettings(time=args.time, iterations=args.iterations, seed=args.seed)
        t0 = time.perf_counter()
        res = geodex.plan(robot, np.array(sc.q_start), np.array(sc.q_goal), env, settings=settings)
        wall = time.perf_counter() - t0
        row: dict = {
            "solved": bool(res.solved),
            "wall_time": wall,
            "scene_build_time": t_env,
            "time_ms": res.time_ms,
            "first_solution_ms": res.first_solution_ms,
            "smooth_ms": res.smooth_ms,
            "smoothed": bool(res.smoothed),
            "cost": float(res.cost),
        }
        if res.solved and len(res.path):
            path = np.asarray(res.path)
            dense = resample(path, args.check_step)
            ok, first_bad, frac = validity(vamp.make_vamp_checker(ROBOT, env), dense)
            length = metric_length(robot, dense)
            row.update(
                path=path.tolist(),
                raw_path=np.asarray(res.raw_path).tolist(),
                waypoints=int(path.shape[0]),
                dense_points=int(dense.shape[0]),
                metric_length=length,
                energy=0.5 * length**2,
                collision_free=ok,
                first_invalid=first_bad,
                invalid_fraction=frac,
                start_error=float(np.abs(path[0] - sc.q_start).max()),
                goal_error=float(np.abs(path[-1] - sc.q_goal).max()),
            )
        out["scenes"][name] = row
        print(
            f"geodex {name:18s} solved={row['solved']!s:5s} wall={wall:6.2f}s "
            f"cost={row['cost']:.4f} free={row.get('collision_free')}",
            file=sys.stderr,
        )
    Path(args.out).write_text(json.dumps(out, indent=1))


def cmd_check(args: argparse.Namespace) -> None:
    data = np.load(args.paths)
    out = {}
    for name in data.files:
        sc = scene_by_name(name.split("/")[0])
        ok, first_bad, frac = validity(checker(sc.obstacles), data[name])
        out[name] = {
            "collision_free": ok,
            "first_invalid": first_bad,
            "invalid_fraction": frac,
            "points": int(data[name].shape[0]),
        }
    Path(args.out).write_text(json.dumps(out, indent=1))


def cmd_scenes(args: argparse.Namespace) -> None:
    out = {}
    for sc in SCENES:
        full = checker(sc.obstacles)
        line = straight_line(sc, args.check_step)
        ok, first_bad, frac = validity(full, line)
        hits = []
        for ob in sc.obstacles:
            if not validity(checker((ob,)), line)[0]:
                hits.append(ob.name)
        self_ok = validity(checker(()), line)[0]
        if not self_ok:
            hits.append("self-collision")
        per_start = [
            ob.name for ob in sc.obstacles if not checker((ob,)).is_valid(np.array(sc.q_start))
        ]
        per_goal = [
            ob.name for ob in sc.obstacles if not checker((ob,)).is_valid(np.array(sc.q_goal))
        ]
        out[sc.name] = {
            "start_valid": bool(full.is_valid(np.array(sc.q_start))),
            "goal_valid": bool(full.is_valid(np.array(sc.q_goal))),
            "start_hits": per_start,
            "goal_hits": per_goal,
            "line_collides": not ok,
            "line_invalid_fraction": frac,
            "line_first_invalid_s": None if first_bad is None else first_bad / (len(line) - 1),
            "line_blocked_by": hits,
            "blocked_expected": sc.blocked,
        }
    Path(args.out).write_text(json.dumps(out, indent=1))


def cmd_mass_matrix(args: argparse.Namespace) -> None:
    robot = geodex.robots.Panda()
    q = np.load(args.q)["q"]
    M = np.stack([robot.mass_matrix(np.ascontiguousarray(x)) for x in q])
    lo, hi = robot.joint_limits()
    np.savez(args.out, M=M, lower=lo, upper=hi, joint_names=np.array(vamp.robot_joint_names(ROBOT)))


def cmd_spheres(args: argparse.Namespace) -> None:
    q = np.load(args.q)["q"]
    S = np.stack([vamp.robot_spheres(ROBOT, np.ascontiguousarray(x)) for x in q])
    np.savez(args.out, spheres=S, end_effector=vamp.robot_end_effector(ROBOT))


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = p.add_subparsers(dest="cmd", required=True)
    pp = sub.add_parser("plan")
    pp.add_argument("--out", required=True)
    pp.add_argument("--scenes", default="", help="comma-separated names (default: all)")
    pp.add_argument("--time", type=float, default=1.0, help="PlanSettings.time [s] (default 1.0)")
    pp.add_argument(
        "--iterations", type=int, default=0, help="PlanSettings.iterations (0: by time)"
    )
    pp.add_argument("--seed", type=int, default=1, help="PlanSettings.seed (0: fresh)")
    pp.add_argument("--check-step", type=float, default=1e-3, help="resampling step [rad]")
    pc = sub.add_parser("check")
    pc.add_argument("--paths", required=True)
    pc.add_argument("--out", required=True)
    ps = sub.add_parser("scenes")
    ps.add_argument("--out", required=True)
    ps.add_argument("--check-step", type=float, default=1e-3)
    for name in ("mass-matrix", "spheres"):
        pm = sub.add_parser(name)
        pm.add_argument("--q", required=True)
        pm.add_argument("--out", required=True)
    args = p.parse_args(argv)
    {
        "plan": cmd_plan,
        "check": cmd_check,
        "scenes": cmd_scenes,
        "mass-matrix": cmd_mass_matrix,
        "spheres": cmd_spheres,
    }[args.cmd](args)


if __name__ == "__main__":
    main()
