"""Benchmark: geosyn vs geodex on the Panda planning suite (issue 11, deliver 6).

Each scene of ``planning_scenes.py`` (start, goal, obstacles) is solved by geodex
(G-RRT* + smoothing, run by ``geodex_runner.py`` in its own Python >= 3.12 venv, see
``setup_geodex.sh``) and by geosyn (`solve_geosyn`), in the same run. Both paths are then
judged the same way:

- metric length ``L = integral sqrt(qdot^T M(q) qdot)`` under ONE metric, geosyn's
  `KineticEnergyMetric` of ``load_robot("panda", armature=0.0)`` with the gripper open as
  geodex's (`benchmark_robot`, ``--gripper``) (sqrt(kg) m), on the path
  resampled every ``--check-step`` rad (midpoint rule); the energy of its constant-speed,
  unit-duration parameterisation is ``L^2 / 2``. Before the suite, M(q) is compared with
  geodex's ``robots.Panda().mass_matrix(q)`` at 20 seeded configurations;
- clearance by geosyn's geometry: `ObstacleTerm.clearances` (exact signed distance of
  robot spheres to the obstacles) with geosyn's own 15 collision spheres, and with
  geodex's 59 collision spheres moved into geosyn's joint frames (their fit residual is
  printed: it also checks that both kinematic models agree);
- geodex's own checker (VAMP) on the same resampled path.

Run: ``bash benchmarks/setup_geodex.sh && .venv/bin/python benchmarks/planning.py``
(``--help`` for options; results go to ``runs/planning/planning.json``).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import tempfile
from pathlib import Path
from typing import NamedTuple

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
import planning_scenes as ps  # noqa: E402
from planning_geodex import check_mass_matrix, geodex_run, geodex_sphere_model  # noqa: E402
from planning_geosyn import (  # noqa: E402
    CAPACITY,
    GRIPPERS,
    GeosynSetup,
    PlannerRun,
    benchmark_robot,
    solve_geosyn,
    to_geosyn,
)

from geosyn.metrics import KineticEnergyMetric, shaping  # noqa: E402
from geosyn.metrics.planning.verify import outside_limits  # noqa: E402
from geosyn.world.exact_clearance import ExactClearance  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent


# -- judging both paths the same way ----------------------------------------------------


class PathScore(NamedTuple):
    length: float  # metric length under geosyn's panda, armature 0 [sqrt(kg) m]
    clearance_geosyn: float  # min clearance, geosyn's 15 spheres [m]
    clearance_geodex: float  # min clearance, geodex's 59 spheres [m]
    clearance_mesh: float  # min exact distance to the URDF collision meshes (coal) [m]
    geodex_collision_free: bool | None  # geodex's checker on the resampled path
    points: int
    outside_limits: str  # why a sample leaves the URDF's position limits, "" when none does


def metric_length(metric: KineticEnergyMetric, path: np.ndarray) -> float:
    """``sum_k sqrt(dq_k^T M(q_mid,k) dq_k)`` over a densely resampled path (midpoint rule)."""
    dq = np.diff(path, axis=0)
    mid = 0.5 * (path[1:] + path[:-1])
    return float(
        sum(math.sqrt(max(float(d @ metric.G(m) @ d), 0.0)) for d, m in zip(dq, mid, strict=True))
    )


def min_clearance(term: shaping.ObstacleTerm, path: np.ndarray) -> float:
    """Smallest sphere-obstacle clearance [m] along the path (inf without obstacles)."""
    if not term.obstacles:
        return math.inf
    return float(min(term.clearances(q).min() for q in path))


# -- main ---------------------------------------------------------------------------------


def _fmt(x: float | None, spec: str) -> str:
    if x is None or (isinstance(x, float) and math.isnan(x)):
        return "-"
    return "inf" if x == math.inf else format(x, spec)


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description="geosyn vs geodex on the Panda planning suite")
    p.add_argument("--scenes", default="", help="comma-separated scene names (default: all)")
    p.add_argument("--budget", type=float, default=10.0, help="geosyn time budget per scene [s]")
    p.add_argument(
        "--geodex-time",
        type=float,
        default=1.0,
        help="geodex PlanSettings.time [s] (its default: 1.0)",
    )
    p.add_argument(
        "--geodex-iterations",
        type=int,
        default=0,
        help="geodex PlanSettings.iterations (0: plan by time)",
    )
    p.add_argument("--geodex-seed", type=int, default=1)
    p.add_argument(
        "--check-step",
        type=float,
        default=1e-3,
        help="resampling step of every path for lengths and checks [rad]",
    )
    p.add_argument("--margin", type=float, default=None, help="geosyn node clearance [m]")
    p.add_argument(
        "--geodex-spheres",
        action="store_true",
        help="geosyn plans with geodex's 59 spheres (a tuned variant; default: the Planner's "
        "own spheres fitted to the URDF meshes)",
    )
    p.add_argument(
        "--alternatives",
        type=int,
        default=None,
        help="geosyn: RRT-Connect seeds tried after a constrained straight-line plan "
        "(other homotopy classes; the lowest-energy plan wins)",
    )
    p.add_argument(
        "--coarse-nodes",
        type=int,
        default=None,
        help="geosyn: segments of the coarse collocation seeding the full one (0: none, "
        "the full collocation from the straight line)",
    )
    p.add_argument("--skip-geosyn", action="store_true", help="geodex only (no geosyn build)")
    p.add_argument("--gripper", choices=sorted(GRIPPERS), default="open",
                   help="the Panda's fingers (GRIPPERS; geodex's Panda is open)")  # fmt: skip
    p.add_argument("--out", default=str(ROOT / "runs" / "planning" / "planning.json"))
    args = p.parse_args(argv)
    scenes = (
        [ps.scene_by_name(n) for n in args.scenes.split(",")] if args.scenes else list(ps.SCENES)
    )
    robot = benchmark_robot(args.gripper)
    metric = KineticEnergyMetric(robot)
    work = Path(tempfile.mkdtemp(prefix="geosyn-planning-"))
    print(
        f"timings on this machine ({os.cpu_count()} cores, shared: load average "
        f"{os.getloadavg()[0]:.2f} at start)"
    )

    mm = check_mass_matrix(robot, work)
    print(
        f"M(q): geosyn panda (armature 0, pin.crba) vs geodex Panda().mass_matrix at "
        f"{mm.samples} seeded q: max |dM| {mm.max_abs:.2e} kg m^2, max ||dM||_F/||M||_F "
        f"{mm.max_rel_frobenius:.2e}, max |v^T dM v|/v^T M v {mm.max_rel_quadratic:.2e}; "
        f"joint order {'same' if mm.same_joint_order else 'DIFFERENT'}, limits differ by "
        f"{mm.max_limit_difference:.1e} rad"
    )
    gdx_spheres, fit = geodex_sphere_model(robot, work)
    print(
        f"geodex's collision model: {len(gdx_spheres)} spheres, in geosyn's joint frames "
        f"to {fit:.1e} m (kinematics agree)"
    )
    term_geosyn = shaping.ObstacleTerm((), capacity=CAPACITY).bind(robot)
    term_geodex = shaping.ObstacleTerm((), capacity=CAPACITY, spheres=gdx_spheres).bind(robot)
    mesh = ExactClearance(robot)

    geodex_run("scenes", "--out", str(work / "scenes.json"), "--check-step", str(args.check_step))
    checks = json.loads((work / "scenes.json").read_text())
    print(
        "\nscene checks (geodex's checker): start/goal free, straight joint line blocked by; "
        "start/goal clearance [m] with geosyn's / geodex's spheres"
    )
    for sc in scenes:
        c = checks[sc.name]
        line = ", ".join(c["line_blocked_by"]) or "nothing (free)"
        flag = "" if c["line_collides"] == sc.blocked else "   <-- NOT AS INTENDED"
        obstacles = [to_geosyn(ob) for ob in sc.obstacles]
        term_geosyn.set_obstacles(obstacles)
        term_geodex.set_obstacles(obstacles)
        ends = np.array([sc.q_start, sc.q_goal])
        c["end_clearance_geosyn"] = [min_clearance(term_geosyn, q[None]) for q in ends]
        c["end_clearance_geodex"] = [min_clearance(term_geodex, q[None]) for q in ends]
        mesh.set_obstacles(obstacles)
        c["end_clearance_mesh"] = [mesh.clearance(q)[0] for q in ends]
        print(
            f"  {sc.name:18s} start {'free' if c['start_valid'] else 'IN COLLISION'}, "
            f"goal {'free' if c['goal_valid'] else 'IN COLLISION'}; line: {line} "
            f"({100 * c['line_invalid_fraction']:.0f} % of it){flag}; clearance "
            + " / ".join(
                ", ".join(_fmt(x, ".3f") for x in c[k])
                for k in ("end_clearance_geosyn", "end_clearance_geodex", "end_clearance_mesh")
            )
        )

    print("\ngeodex: planning ...", flush=True)
    geodex_run(
        "plan",
        "--out",
        str(work / "geodex.json"),
        "--time",
        str(args.geodex_time),
        "--iterations",
        str(args.geodex_iterations),
        "--seed",
        str(args.geodex_seed),
        "--check-step",
        str(args.check_step),
        "--scenes",
        ",".join(s.name for s in scenes),
    )
    gdx = json.loads((work / "geodex.json").read_text())
    runs: dict[str, dict[str, PlannerRun]] = {}
    for sc in scenes:
        g = gdx["scenes"][sc.name]
        path = np.asarray(g["path"]) if g.get("path") else None
        runs[sc.name] = {
            "geodex": PlannerRun(
                g["solved"],
                g["wall_time"],
                path,
                f"first solution {g['first_solution_ms']:.1f} ms, smoothing {g['smooth_ms']:.0f} ms",
                {"geodex_cost": g["cost"], "first_solution_ms": g["first_solution_ms"]},
            )
        }

    build_time = None
    if not args.skip_geosyn:
        print("geosyn: creating the default Planner ...", flush=True)
        setup = GeosynSetup(
            robot, gdx_spheres if args.geodex_spheres else None, margin=args.margin,
            alternatives=args.alternatives, coarse_nodes=args.coarse_nodes,
        )  # fmt: skip
        build_time = setup.build_time
        print(f"geosyn: Planner created in {build_time:.1f} s "
              f"({len(setup.planner.term.spheres)} spheres); solving ...", flush=True)  # fmt: skip
        for sc in scenes:
            r = solve_geosyn(sc, setup, args.budget)
            runs[sc.name]["geosyn"] = r
            print(
                f"  {sc.name:18s} {'solved' if r.solved else 'FAILED'} in {r.wall_time:.1f} s: "
                f"{r.message}",
                flush=True,
            )

    dense: dict[str, np.ndarray] = {}
    for sc in scenes:
        for planner, r in runs[sc.name].items():
            if r.solved and r.path is not None:
                dense[f"{sc.name}/{planner}"] = ps.resample(r.path, args.check_step)
    np.savez(work / "paths.npz", **dense)
    geodex_run("check", "--paths", str(work / "paths.npz"), "--out", str(work / "check.json"))
    gcheck = json.loads((work / "check.json").read_text())

    scores: dict[str, PathScore] = {}
    for key, path in dense.items():
        sc = ps.scene_by_name(key.split("/")[0])
        obstacles = [to_geosyn(ob) for ob in sc.obstacles]
        term_geosyn.set_obstacles(obstacles)
        term_geodex.set_obstacles(obstacles)
        mesh.set_obstacles(obstacles)
        start_goal = max(np.abs(path[0] - sc.q_start).max(), np.abs(path[-1] - sc.q_goal).max())
        if start_goal > 1e-3:
            print(f"  WARNING {key}: path ends {start_goal:.1e} rad from start/goal")
        scores[key] = PathScore(
            metric_length(metric, path),
            min_clearance(term_geosyn, path),
            min_clearance(term_geodex, path),
            mesh.path_clearance(path, args.check_step).clearance,
            gcheck[key]["collision_free"],
            int(path.shape[0]),
            outside_limits(metric.robot, path),
        )

    print(
        "\n(lengths under geosyn's panda, armature 0 [sqrt(kg) m]; clearances by exact "
        "sphere-obstacle distance [m] with geosyn's 15 capsule / geodex's 59 spheres, 'mesh' = "
        "coal's exact distance to the URDF collision meshes; 'own cost' = "
        "geodex's PlanResult.cost under its own M(q); "
        "'geodex chk' = geodex's checker on the path resampled every "
        f"{args.check_step:g} rad)"
    )
    if build_time is not None:
        print(f"geosyn Planner creation (this process): {build_time:.1f} s")
    hdr = (
        f"{'scene':18s} {'planner':7s} {'solved':6s} {'wall [s]':>8s} {'length':>8s} "
        f"{'own cost':>8s} {'clr geosyn':>10s} {'clr geodex':>10s} {'clr mesh':>9s} "
        f"{'geodex chk':>10s} {'limits':>6s}"
    )
    print(hdr)
    print("-" * len(hdr))
    for sc in scenes:
        for planner, r in runs[sc.name].items():
            s = scores.get(f"{sc.name}/{planner}")
            chk = "-" if s is None else ("free" if s.geodex_collision_free else "COLLIDES")
            print(
                f"{sc.name:18s} {planner:7s} {'yes' if r.solved else 'NO':6s} "
                f"{r.wall_time:8.2f} {_fmt(s and s.length, '8.4f'):>8s} "
                f"{_fmt(r.extra.get('geodex_cost'), '8.4f'):>8s} "
                f"{_fmt(s and s.clearance_geosyn, '10.4f'):>10s} "
                f"{_fmt(s and s.clearance_geodex, '10.4f'):>10s} "
                f"{_fmt(s and s.clearance_mesh, '9.4f'):>9s} {chk:>10s} "
                f"{'-' if s is None else ('OUT' if s.outside_limits else 'ok'):>6s}"
            )
    pairs = [(scores.get(f"{sc.name}/geosyn"), scores.get(f"{sc.name}/geodex")) for sc in scenes]
    pairs = [(a, b) for a, b in pairs if a is not None and b is not None]
    if pairs:  # geodex's path may enter the meshes: a shorter path, not one for the robot
        longer = [(a, b) for a, b in pairs if a.length > b.length]
        print(f"\ngeosyn <= geodex on {len(pairs) - len(longer)} of {len(pairs)} scenes both "
              f"solved; longer than a geodex path clear of the meshes on "
              f"{sum(b.clearance_mesh >= 0 for _, b in longer)}")  # fmt: skip

    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    result = {
        "settings": vars(args),
        "load_average_start": os.getloadavg()[0],
        "mass_matrix_check": mm._asdict(),
        "geodex_sphere_fit_residual": fit,
        "geodex_spheres_in_joint_frames": [
            {"joint": s.joint, "center": list(s.center), "radius": s.radius} for s in gdx_spheres
        ],
        "geodex_version": gdx["geodex_version"],
        "geosyn_build_time": build_time,
        "scene_checks": checks,
        "runs": {
            sc.name: {
                planner: {
                    "solved": r.solved,
                    "wall_time": r.wall_time,
                    "message": r.message,
                    **r.extra,
                    **({} if (s := scores.get(f"{sc.name}/{planner}")) is None else s._asdict()),
                    "path": None if r.path is None else np.asarray(r.path).tolist(),
                }
                for planner, r in runs[sc.name].items()
            }
            for sc in scenes
        },
    }
    out.write_text(json.dumps(result, indent=1, default=float))
    print(f"\nresults: {out}")


if __name__ == "__main__":
    main()
