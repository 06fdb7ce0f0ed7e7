"""Benchmark: metric length vs wall-time budget, geosyn's default `Planner` and geodex on
the same scenes in one run (issue 22, "anytime behaviour").

For each budget ``T`` (default 0.05, 0.1, 0.2, 0.3, 1, 2 s), in turn: geodex plans every scene
with ``PlanSettings.time = T`` (its venv, `planning_geodex.geodex_run`), then geosyn's
default ``Planner(KineticEnergyMetric(panda))`` (the gripper open, as geodex's Panda:
`planning_geosyn.benchmark_robot`) plans every scene with ``budget=T``
(alternating A/B by budget, so both see the same machine load); then geosyn again with
geodex's measured wall time on each scene as its budget (geodex overshoots its budget,
by its smoothing: at equal wall time, as the issue asks; ``--no-matched`` skips it). geosyn's NLPs of every
obstacle count are built before the first budget (`Planner.prepare`, timed and printed):
the curve is the query's, not the first build's. Every returned path is then scored the
same way, as in ``planning.py``: metric length under geosyn's Panda (armature 0), coal's
exact distance to the URDF collision meshes and geodex's checker, on the path resampled
every ``--check-step`` rad. The meshes' distance: on their convex hulls
(`geosyn.world.exact_clearance.ExactClearance`, ``mesh_clearance``) and, where a hull is
entered, on the triangles as Pinocchio builds them from the URDF
(``tests/self_collision_referee.MeshObstacleReferee``, ``triangle_clearance``; where the
hulls are clear it is at least their value, which is stored): "touches the meshes" and
"clear of the URDF meshes" below are the triangles'.

Printed per budget: paths returned (geosyn: how many of them are its sampled plan, not
collocated: ``Plan.seed == "sampled"``), median and largest wall time to the returned
path (geosyn: also its CPU time and its first feasible path's time), the length ratio
geosyn / geodex on the scenes both solved, how many of them geosyn is <= geodex on, on
how many geosyn is longer than a geodex path that is clear of the URDF meshes (``>gdx
free``: the others are longer than a path that enters the robot's own geometry), and
the paths that touch the meshes (< 0) or collide for geodex's checker, geosyn's paths whose
clearance of the meshes is certified >= 0 between the resampled configurations too
(`geosyn.metrics.planning.certify`), and the paths with a sample outside the URDF's joint
position limits (geodex's checker tests its own, the
same numbers for the Panda).

Then geosyn's time to a path no longer than geodex's at its 0.3 s budget (the
acceptance's "time to its returned path"): per scene, the wall time of the smallest
budget of the curve that returns one, its median, and on how many scenes it is not later
than geodex's own (`_time_to_match`).

``--margin M`` gives geosyn's `Planner` that margin instead of its default (a variant, said
in the output). ``--problem geodex`` makes geosyn solve geodex's own problem instead of
the robot's: geodex's 59 spheres (`planning_geodex.geodex_sphere_model`) as the planner's
spheres, the robot without its file (so no exact check on the URDF meshes: the spheres
decide, as geodex's checker does) and ``--margin`` (default 1 mm: geodex keeps none, and
geosyn's sampled checks need a little between their samples). It tells how near geosyn's
search comes to geodex's on the problem geodex solves, apart from the geometry.

Run: ``bash benchmarks/setup_geodex.sh && nice -n 10 .venv/bin/python
benchmarks/planning_anytime.py`` (results in ``runs/planning/anytime.json``).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
import planning_scenes as ps  # noqa: E402
from planning import ROOT, metric_length  # noqa: E402
from planning_geodex import geodex_run, geodex_sphere_model  # noqa: E402
from planning_geosyn import CAPACITY, GRIPPERS, benchmark_robot, to_geosyn  # noqa: E402
from self_collision_referee import MeshObstacleReferee  # noqa: E402

from geosyn.metrics import KineticEnergyMetric  # noqa: E402
from geosyn.metrics.planning import Planner, PlanningError, certified_clearance  # noqa: E402
from geosyn.metrics.planning.verify import outside_limits  # noqa: E402
from geosyn.world.exact_clearance import ExactClearance  # noqa: E402


def geosyn_runs(planner: Planner, scenes: list[ps.Scene],
                budget: float | dict[str, float]) -> dict[str, dict]:  # fmt: skip
    """Each scene planned by ``planner`` within ``budget`` [s] (or ``budget[name]``): wall
    and CPU time to the returned path, first feasible time, kind, path (None when
    refused), the budget."""
    out = {}
    for sc in scenes:
        obstacles = [to_geosyn(ob) for ob in sc.obstacles]
        T = budget[sc.name] if isinstance(budget, dict) else budget
        t0, c0 = time.perf_counter(), time.process_time()
        try:
            plan = planner.plan(np.array(sc.q_start), np.array(sc.q_goal), obstacles, budget=T)
        except PlanningError as err:
            wall, cpu = time.perf_counter() - t0, time.process_time() - c0
            out[sc.name] = {"solved": False, "wall_time": wall, "cpu_time": cpu, "budget": T,
                            "message": f"{type(err).__name__}"}  # fmt: skip
            continue
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
        out[sc.name] = {
            "solved": True, "wall_time": wall, "cpu_time": cpu, "kind": plan.result.kind,
            "seed": plan.seed, "first_feasible_time": plan.first_feasible_time,
            "exact_clearance": plan.exact_clearance, "nlp_build_time": plan.nlp_build_time,
            "path": np.asarray(plan.q).tolist(), "budget": T,
        }  # fmt: skip
    return out


MATCH_BUDGET = 0.3
"""geodex's budget [s] whose paths `_time_to_match` times geosyn against (the issue's
"geosyn's time to its returned path <= geodex's at geodex's 0.3 s budget")."""


def _time_to_match(runs: dict[float, dict], scenes: list[ps.Scene]) -> None:
    """Print, per scene, geosyn's wall time to a path no longer than geodex's at
    `MATCH_BUDGET`: that of its smallest budget of the curve whose returned path is not
    longer (nominal budgets, in turn), beside geodex's own wall time; then their median
    and on how many scenes geosyn's is not later."""
    ref = runs[MATCH_BUDGET]["geodex"]
    print(f"\ngeosyn's time to a path no longer than geodex's at its {MATCH_BUDGET:g} s budget "
          "(the smallest budget of the curve that gives one):")  # fmt: skip
    walls, within = [], 0
    for sc in scenes:
        g = ref[sc.name]
        found = next(((T, r["geosyn"][sc.name]) for T, r in runs.items()
                      if g["solved"] and r["geosyn"][sc.name]["solved"]
                      and r["geosyn"][sc.name]["length"] <= g["length"]), None)  # fmt: skip
        if found is None:
            print(f"  {sc.name:18s} none (geodex {g['wall_time']:.3f} s)")
            continue
        T, row = found
        walls.append(row["wall_time"])
        within += row["wall_time"] <= g["wall_time"]
        print(f"  {sc.name:18s} {row['wall_time']:.3f} s (budget {T:g} s; geodex "
              f"{g['wall_time']:.3f} s)")  # fmt: skip
    if walls:
        print(f"  median {statistics.median(walls):.3f} s over {len(walls)} of {len(scenes)} "
              f"scenes; not later than geodex on {within}")  # fmt: skip


WHO = ("geodex", "geosyn", "geosyn_matched")
"""The runs of a budget: geodex's, geosyn's at the same budget, geosyn's with geodex's
measured wall time on each scene as its budget (``--no-matched``: not run)."""


def _summary(T: float, r: dict, g: dict[str, dict], s: dict[str, dict]) -> None:
    """One row of the table: budget ``T`` [s], geodex's runs ``g`` and geosyn's ``s``."""
    g_ok = [n for n, x in g.items() if x["solved"]]
    s_ok = [n for n, x in s.items() if x["solved"]]
    both = [n for n in s_ok if n in g_ok]
    ratios = [s[n]["length"] / g[n]["length"] for n in both]
    gw = [g[n]["wall_time"] for n in g_ok]
    sw = [s[n]["wall_time"] for n in s_ok]
    print(
        f"{T:6g} {r['load']:5.1f} | {len(g_ok):3d}/{len(g):<2d} "
        f"{_median(gw):7.3f}/{max(gw, default=math.nan):<8.3f} | {len(s_ok):3d}/{len(s):<2d} "
        f"{sum(s[n]['seed'] == 'sampled' for n in s_ok):3d} "
        f"{_median(sw):7.3f}/{max(sw, default=math.nan):<8.3f} "
        f"{_median([s[n]['cpu_time'] for n in s_ok]):7.3f} "
        f"{_median([s[n]['first_feasible_time'] for n in s_ok]):7.3f} | "
        f"{_median(ratios):7.3f} [{min(ratios, default=math.nan):.3f}, "
        f"{max(ratios, default=math.nan):.3f}] {sum(x <= 1.0 for x in ratios):4d}/{len(both):<3d} "
        f"{sum(x > 1.0 and g[n]['triangle_clearance'] >= 0 for n, x in zip(both, ratios, strict=True)):9d} | "
        f"{sum(g[n]['triangle_clearance'] < 0 for n in g_ok):6d}/{sum(s[n]['triangle_clearance'] < 0 for n in s_ok):<7d} "
        f"{sum(not s[n]['geodex_free'] for n in s_ok):10d} "
        f"{sum(s[n]['certified_clearance'] >= 0 for n in s_ok):5d}/{len(s_ok):<3d} | "
        f"{sum(g[n]['outside_limits'] for n in g_ok):6d}/{sum(s[n]['outside_limits'] for n in s_ok):<6d}"
    )  # fmt: skip


def _median(xs: list[float]) -> float:
    return statistics.median(xs) if xs else math.nan


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description="length vs budget, geosyn and geodex")
    p.add_argument("--budgets", default="0.05,0.1,0.2,0.3,1,2", help="budgets T [s]")
    p.add_argument("--scenes", default="", help="comma-separated scene names (default: all)")
    p.add_argument("--check-step", type=float, default=2e-3, help="resampling step [rad]")
    p.add_argument("--geodex-seed", type=int, default=1)
    p.add_argument("--gripper", choices=sorted(GRIPPERS), default="open",
                   help="the Panda's fingers (planning_geosyn.GRIPPERS; geodex's Panda is open)")  # fmt: skip
    p.add_argument("--out", default=str(ROOT / "runs" / "planning" / "anytime.json"))
    p.add_argument("--margin", type=float, default=None,
                   help="geosyn's Planner margin [m] (default: the Planner's; 0.001 with "
                   "--problem geodex)")  # fmt: skip
    p.add_argument("--problem", choices=("robot", "geodex"), default="robot",
                   help="robot: the default Planner on the URDF's own geometry; geodex: "
                   "geodex's own problem (its spheres, no mesh check; module docstring)")  # fmt: skip
    p.add_argument("--no-matched", dest="matched", action="store_false",
                   help="skip geosyn's runs with geodex's measured wall time as the budget")  # fmt: skip
    args = p.parse_args(argv)
    budgets = [float(b) for b in args.budgets.split(",")]
    scenes = (
        [ps.scene_by_name(n) for n in args.scenes.split(",")] if args.scenes else list(ps.SCENES)
    )
    work = Path(tempfile.mkdtemp(prefix="geosyn-anytime-"))
    print(f"{os.cpu_count()} cores, load average {os.getloadavg()[0]:.2f} at start")
    robot = benchmark_robot(args.gripper)
    options: dict[str, object] = {}
    if args.problem == "geodex":  # its spheres decide: the robot without its file
        options["spheres"] = tuple(
            s for s in geodex_sphere_model(robot, work)[0] if s.joint != "universe"
        )
        args.margin = 0.001 if args.margin is None else args.margin
    if args.margin is not None:
        options["margin"] = args.margin
        print(f"geosyn: problem {args.problem}, margin {args.margin:g} m (not the default Planner)")
    planning_robot = (
        dataclasses.replace(robot, source_file=None) if args.problem == "geodex" else robot
    )
    metric = KineticEnergyMetric(robot)
    t0 = time.perf_counter()
    planner = Planner(KineticEnergyMetric(planning_robot), capacity=CAPACITY, **options)
    build = time.perf_counter() - t0
    t0 = time.perf_counter()
    for k in sorted({len(sc.obstacles) for sc in scenes}):
        planner.prepare(k)
    prepare = time.perf_counter() - t0
    print(f"geosyn: Planner() {build:.2f} s, NLPs of every obstacle count {prepare:.2f} s")
    mesh = ExactClearance(robot)
    triangles = MeshObstacleReferee(robot, GRIPPERS[args.gripper])
    runs: dict[float, dict[str, dict]] = {}
    for T in budgets:
        geodex_run("plan", "--out", str(work / f"gdx_{T}.json"), "--time", str(T),
                   "--seed", str(args.geodex_seed), "--check-step", str(args.check_step),
                   "--scenes", ",".join(s.name for s in scenes))  # fmt: skip
        gdx = json.loads((work / f"gdx_{T}.json").read_text())["scenes"]
        gsy = geosyn_runs(planner, scenes, T)
        runs[T] = {"geodex": gdx, "geosyn": gsy, "load": os.getloadavg()[0]}  # type: ignore[dict-item]
        if args.matched:  # geosyn's budget: the wall time geodex took on the scene
            walls = {n: float(x["wall_time"]) for n, x in gdx.items()}
            runs[T]["geosyn_matched"] = geosyn_runs(planner, scenes, walls)
        print(f"  T = {T:g} s done (load {os.getloadavg()[0]:.1f})", flush=True)
    dense: dict[str, np.ndarray] = {}
    for T, r in runs.items():
        for who in [w for w in WHO if w in r]:
            for name, row in r[who].items():
                if row.get("solved") and row.get("path"):
                    dense[f"{name}/{who}/{T}"] = ps.resample(
                        np.asarray(row["path"]), args.check_step
                    )
    np.savez(work / "paths.npz", **dense)
    geodex_run("check", "--paths", str(work / "paths.npz"), "--out", str(work / "check.json"))
    gcheck = json.loads((work / "check.json").read_text())
    for key, path in dense.items():
        name, who, T = key.split("/")
        row = runs[float(T)][who][name]
        obstacles = [to_geosyn(ob) for ob in ps.scene_by_name(name).obstacles]
        mesh.set_obstacles(obstacles)
        row["length"] = metric_length(metric, path)
        row["mesh_clearance"] = hull = mesh.path_clearance(path, args.check_step).clearance
        row["triangle_clearance"] = hull  # the hulls contain the triangles: at least this
        if hull < 0.0:  # measured on the triangles only where a hull is entered
            triangles.set_obstacles(obstacles)
            row["triangle_clearance"] = triangles.path_clearance(path)
        row["certified_clearance"] = certified_clearance(mesh, path, args.check_step).bound
        row["geodex_free"] = bool(gcheck[key]["collision_free"])
        row["outside_limits"] = bool(outside_limits(robot, path))  # the URDF's position limits
        row.pop("path", None)
    print(f"\nmetric length [sqrt(kg) m] under geosyn's panda (armature 0); mesh = coal's "
          f"distance to the URDF collision meshes' triangles (Pinocchio's model of the URDF); "
          f"paths resampled every {args.check_step:g} rad")  # fmt: skip
    print(f"{'T [s]':>6s} {'load':>5s} | {'gdx ok':>6s} {'gdx wall med/max':>16s} | "
          f"{'gsy ok':>6s} {'smp':>3s} {'gsy wall med/max':>16s} {'cpu med':>7s} {'1st med':>7s} | "
          f"{'len ratio med [min, max]':>25s} {'gsy<=gdx':>8s} {'>gdx free':>9s} | {'mesh<0 gdx/gsy':>14s} {'gdxchk gsy':>10s} {'cert gsy':>9s} | "
          f"{'limits gdx/gsy':>13s}")  # fmt: skip
    for who in [w for w in WHO[1:] if w in next(iter(runs.values()))]:
        if who == "geosyn_matched":
            print("geosyn with geodex's measured wall time on each scene as its budget:")
        for T, r in runs.items():
            _summary(T, r, r["geodex"], r[who])
    for who in [w for w in WHO[1:] if w in next(iter(runs.values()))]:
        print(f"\nper scene, {who} length / geodex length (- : one of them returned nothing):")
        print(f"{'scene':18s} " + " ".join(f"{T:>8g}" for T in runs))
        for sc in scenes:
            cells = []
            for r in runs.values():
                g, s = r["geodex"][sc.name], r[who][sc.name]
                ok = g["solved"] and s["solved"]
                cells.append(f"{s['length'] / g['length']:8.3f}" if ok else
                             f"{'gsy only' if s['solved'] else ('gdx only' if g['solved'] else 'none'):>8s}")  # fmt: skip
            print(f"{sc.name:18s} " + " ".join(cells))
    if MATCH_BUDGET in runs:
        _time_to_match(runs, scenes)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps({"settings": vars(args), "build_time": build,
                               "prepare_time": prepare,
                               "runs": {str(T): r for T, r in runs.items()}}, indent=1, default=float))  # fmt: skip
    print(f"\nresults: {out}")


if __name__ == "__main__":
    main()
