"""Benchmark: geosyn vs geodex on the Panda planning suite (issue 11, deliver 6).

Each scene of ``planning_scenes.py`` (start, goal, obstacles) is solved by geodex
(G-RRT* + smoothing, run by ``geodex_runner.py`` in its own Python >= 3.12 venv, see
``setup_geodex.sh``) and by geosyn (`solve_geosyn`), in the same run. Both paths are then
judged the same way:

- metric length ``L = integral sqrt(qdot^T M(q) qdot)`` under ONE metric, geosyn's
  `KineticEnergyMetric` of ``load_robot("panda", armature=0.0)`` (sqrt(kg) m), on the path
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
import multiprocessing as mp
import os
import subprocess
import sys
import tempfile
import time
import traceback
from multiprocessing.connection import Connection
from pathlib import Path
from typing import NamedTuple

import numpy as np
import pinocchio as pin

sys.path.insert(0, str(Path(__file__).parent))
import planning_scenes as ps  # noqa: E402

from geosyn.metrics import KineticEnergyMetric, shaping  # noqa: E402
from geosyn.robots import CollisionSphere, Robot, load_robot  # noqa: E402

try:  # the shapes live in geosyn.world since the issue-9 layout, in shaping before it
    from geosyn import world as shapes  # noqa: E402
except ImportError:
    from geosyn.metrics import shaping as shapes  # type: ignore[no-redef]  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
RUNNER = Path(__file__).resolve().parent / "geodex_runner.py"
GEODEX_PYTHON = Path(os.environ.get("GEODEX_PYTHON", ROOT / ".venv-geodex" / "bin" / "python"))


class PlannerRun(NamedTuple):
    """One planner on one scene.

    Attributes:
        solved: the planner reports a path from start to goal.
        wall_time: wall-clock time of the query [s] (geosyn: without the first-use build).
        path: (T, 7) joint path [rad], None when not solved.
        message: how it was solved, or why not.
        extra: planner-specific numbers (geodex's own cost, geosyn's residual, ...).
    """

    solved: bool
    wall_time: float
    path: np.ndarray | None
    message: str
    extra: dict


# -- geodex, through its venv ----------------------------------------------------------


def geodex_run(*args: str) -> None:
    """Run ``geodex_runner.py`` with ``args`` in the geodex venv; raise with its stderr."""
    if not GEODEX_PYTHON.exists():
        raise SystemExit(
            f"geodex venv not found at {GEODEX_PYTHON}: run `bash benchmarks/setup_geodex.sh` "
            "(or set GEODEX_PYTHON to a Python >= 3.12 with pygeodex installed)"
        )
    proc = subprocess.run([str(GEODEX_PYTHON), str(RUNNER), *args], capture_output=True, text=True)
    if proc.returncode != 0:
        raise RuntimeError(f"geodex_runner {args[0]} failed:\n{proc.stderr}")


class MassMatrixCheck(NamedTuple):
    """geosyn's M(q) (pin.crba) vs geodex's ``mass_matrix(q)`` at seeded configurations."""

    samples: int
    max_abs: float  # max |M_ij - Mg_ij| [kg m^2]
    max_rel_frobenius: float  # max ||M - Mg||_F / ||M||_F
    max_rel_quadratic: float  # max over q, v of |v^T (Mg - M) v| / v^T M v
    same_joint_order: bool
    max_limit_difference: float  # [rad]


def check_mass_matrix(
    robot: Robot, workdir: Path, samples: int = 20, seed: int = 0
) -> MassMatrixCheck:
    """Compare M(q) of ``robot`` with geodex's Panda at ``samples`` seeded random q."""
    import scipy.linalg

    rng = np.random.default_rng(seed)
    Q = np.stack([robot.random_q(rng) for _ in range(samples)])
    np.savez(workdir / "q.npz", q=Q)
    geodex_run("mass-matrix", "--q", str(workdir / "q.npz"), "--out", str(workdir / "M.npz"))
    out = np.load(workdir / "M.npz")
    data = robot.model.createData()
    abs_, fro, quad = [], [], []
    for q, Mg in zip(Q, out["M"], strict=True):
        M = pin.crba(robot.model, data, q)
        M = np.triu(M) + np.triu(M, 1).T
        abs_.append(np.abs(M - Mg).max())
        fro.append(np.linalg.norm(M - Mg) / np.linalg.norm(M))
        quad.append(np.abs(scipy.linalg.eigh(Mg - M, M, eigvals_only=True)).max())
    names = [str(n) for n in out["joint_names"]]
    limits = max(np.abs(out["lower"] - robot.q_min).max(), np.abs(out["upper"] - robot.q_max).max())
    return MassMatrixCheck(
        samples, max(abs_), max(fro), max(quad), names == list(robot.joint_names), float(limits)
    )


def geodex_sphere_model(robot: Robot, workdir: Path, samples: int = 6, seed: int = 1):
    """geodex's (VAMP) collision spheres as geosyn `CollisionSphere`s in joint frames.

    geodex reports its spheres in the world at a configuration; each is rigidly attached
    to one link, so its coordinates in that link's joint frame (geosyn's kinematics) are
    the same at every q. Each sphere goes to the joint frame where they vary least over
    ``samples`` seeded configurations.

    Returns:
        (spheres, residual): the spheres and the largest variation of an assigned sphere's
        local coordinates [m] (~1e-7 m: geodex's float32; larger means the two kinematic
        models differ).
    """
    rng = np.random.default_rng(seed)
    Q = np.stack([robot.random_q(rng) for _ in range(samples)])
    np.savez(workdir / "qs.npz", q=Q)
    geodex_run("spheres", "--q", str(workdir / "qs.npz"), "--out", str(workdir / "S.npz"))
    S = np.load(workdir / "S.npz")["spheres"]  # (samples, n_spheres, 4)
    model, data = robot.model, robot.model.createData()
    local = np.zeros((samples, model.njoints, S.shape[1], 3))
    for k, q in enumerate(Q):
        pin.forwardKinematics(model, data, q)
        for j in range(model.njoints):
            T = data.oMi[j]
            local[k, j] = (S[k, :, :3] - T.translation) @ T.rotation
    spread = local.std(axis=0).max(axis=-1)  # (njoints, n_spheres)
    joint = spread.argmin(axis=0)
    residual = float(spread[joint, np.arange(S.shape[1])].max())
    spheres = tuple(
        CollisionSphere(
            str(model.names[int(j)]),
            tuple(float(c) for c in local[:, j, i].mean(axis=0)),
            float(S[0, i, 3]),
        )
        for i, j in enumerate(joint)
    )
    return spheres, residual


# -- geosyn ----------------------------------------------------------------------------


def to_geosyn(ob: ps.Obstacle) -> object:
    """The geosyn shape (`geosyn.world`) of a scene obstacle.

    A `Cylinder` becomes the `Capsule` on its axis with its radius and length: a superset
    of the cylinder (hemispherical caps of one radius at both ends) until geosyn has a
    cylinder shape.
    """
    if isinstance(ob, ps.Box):
        return shapes.Box(ob.center, ob.half_extents, ps.rpy_matrix(ob.rpy))
    if isinstance(ob, ps.Sphere):
        return shapes.Sphere(ob.center, ob.radius)
    if isinstance(ob, ps.Capsule):
        return shapes.Capsule(ob.p0, ob.p1, ob.radius)
    if isinstance(ob, ps.Cylinder):
        axis = ps.rpy_matrix(ob.rpy)[:, 2] * ob.half_length
        c = np.asarray(ob.center)
        return shapes.Capsule(c - axis, c + axis, ob.radius)
    if isinstance(ob, ps.HalfSpace):
        return shapes.HalfSpace(ob.normal, ob.offset)
    raise TypeError(f"unknown obstacle type {type(ob).__name__}")


CAPACITY = max(len(s.obstacles) for s in ps.SCENES)
"""Obstacle slots of the shaped metric: one build serves every scene (parameter writes)."""


class GeosynSetup:
    """What geosyn builds once per robot and obstacle capacity, before any query.

    Today: the panda (armature 0), its `KineticEnergyMetric` (for scenes without
    obstacles) and a `ShapedMetric` of it plus an `ObstacleTerm` (default profile, gain
    1e-3 kg m^2, cutoff 0.2 m, geosyn's 15 collision spheres) with `CAPACITY` slots, both
    compiled to C, and the log map's shooting functions of both (built by warm-up solves).
    ``build_time`` [s] is the first-use cost, reported apart.
    """

    def __init__(self, robot: Robot, steps: int = 100) -> None:
        t0 = time.perf_counter()
        self.robot = robot
        self.steps = steps
        self.term = shaping.ObstacleTerm((), capacity=CAPACITY)
        self.free_metric = KineticEnergyMetric(robot, compile=True)
        self.metric = shaping.ShapedMetric(self.free_metric, [self.term], compile=True)
        from geosyn.metrics.geodesic import exp, log_solve

        q0 = np.asarray(ps.PANDA_HOME)
        for metric in (self.free_metric, self.metric):
            try:  # builds (and compiles) the shooting maps at steps and 2 x steps
                log_solve(metric, q0, q0 + 0.01, steps=steps, max_iter=2, continuation=False)
            except Exception:  # noqa: BLE001 - only the build matters here
                pass
            exp(metric, q0, np.full(7, 0.01), 1.0, steps)
        self.build_time = time.perf_counter() - t0

    def metric_for(self, scene: ps.Scene):  # type: ignore[no-untyped-def]
        """The metric of ``scene``: kinetic energy alone without obstacles, else shaped."""
        if not scene.obstacles:
            return self.free_metric
        self.term.set_obstacles([to_geosyn(ob) for ob in scene.obstacles])
        return self.metric


def _current_log_child(setup: GeosynSetup, scene: ps.Scene, conn: Connection) -> None:
    """Child process of `solve_geosyn`: geosyn's current shaped-metric log, then exp."""
    from geosyn.metrics.geodesic import exp, log_solve

    try:
        metric = setup.metric_for(scene)
        res = log_solve(metric, np.array(scene.q_start), np.array(scene.q_goal), steps=setup.steps)
        geo = exp(metric, np.array(scene.q_start), res.v0, 1.0, setup.steps)
        conn.send(
            (
                "ok",
                geo.q,
                f"log: {res.method}, residual {res.residual:.1e} rad, "
                f"{res.iterations} Newton iterations",
                {
                    "residual": res.residual,
                    "iterations": res.iterations,
                    "discretization_error": res.discretization_error,
                },
            )
        )
    except Exception as err:  # noqa: BLE001 - reported to the parent, never swallowed
        extra = {"residual": getattr(err, "residual", None)}
        conn.send(("fail", None, f"{type(err).__name__}: {err}", extra))
    except BaseException:
        conn.send(("fail", None, traceback.format_exc()[-300:], {}))


# =====================================================================================
# solve_geosyn: THE geosyn SIDE OF THE BENCHMARK. The new boundary-value solver of
# issue 11 (deliver 1) replaces the body below; keep the signature and return a
# PlannerRun (solved, wall time without the first-use build, (T, 7) path, message).
# =====================================================================================
def solve_geosyn(scene: ps.Scene, setup: GeosynSetup, budget: float) -> PlannerRun:
    """Solve ``scene`` with geosyn within ``budget`` seconds of wall time.

    Today: geosyn's current `log_solve` on the obstacle-shaped metric (Newton shooting,
    then parameter and target continuation), straight-line initial guess, then `exp`
    with the same steps for the path. `log_solve` has no time budget of its own, so it
    runs in a forked child process (which inherits the built metric) and is killed after
    ``budget`` seconds; a timeout is reported as a failure.
    """
    ctx = mp.get_context("fork")
    recv, send = ctx.Pipe(duplex=False)
    t0 = time.perf_counter()
    proc = ctx.Process(target=_current_log_child, args=(setup, scene, send), daemon=True)
    proc.start()
    send.close()
    got = recv.poll(budget)
    wall = time.perf_counter() - t0
    if not got:
        proc.kill()
        proc.join()
        return PlannerRun(
            False, wall, None, f"timeout: no result within the {budget:g} s budget", {}
        )
    try:
        status, path, message, extra = recv.recv()
    except EOFError:
        status, path, message, extra = "fail", None, "child process died", {}
    wall = time.perf_counter() - t0
    proc.join()
    return PlannerRun(status == "ok", wall, path, message, extra)


# -- judging both paths the same way ----------------------------------------------------


class PathScore(NamedTuple):
    length: float  # metric length under geosyn's panda, armature 0 [sqrt(kg) m]
    clearance_geosyn: float  # min clearance, geosyn's 15 spheres [m]
    clearance_geodex: float  # min clearance, geodex's 59 spheres [m]
    geodex_collision_free: bool | None  # geodex's checker on the resampled path
    points: int


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
    p.add_argument("--budget", type=float, default=20.0, help="geosyn time budget per scene [s]")
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
    p.add_argument("--skip-geosyn", action="store_true", help="geodex only (no geosyn build)")
    p.add_argument("--out", default=str(ROOT / "runs" / "planning" / "planning.json"))
    args = p.parse_args(argv)
    scenes = (
        [ps.scene_by_name(n) for n in args.scenes.split(",")] if args.scenes else list(ps.SCENES)
    )
    robot = load_robot("panda", armature=0.0)
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
        print(
            f"  {sc.name:18s} start {'free' if c['start_valid'] else 'IN COLLISION'}, "
            f"goal {'free' if c['goal_valid'] else 'IN COLLISION'}; line: {line} "
            f"({100 * c['line_invalid_fraction']:.0f} % of it){flag}; clearance "
            + " / ".join(
                ", ".join(_fmt(x, ".3f") for x in c[k])
                for k in ("end_clearance_geosyn", "end_clearance_geodex")
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
        print("geosyn: building the shaped metric (first use) ...", flush=True)
        setup = GeosynSetup(robot)
        build_time = setup.build_time
        print(f"geosyn: build {build_time:.1f} s; solving ...", flush=True)
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
        start_goal = max(np.abs(path[0] - sc.q_start).max(), np.abs(path[-1] - sc.q_goal).max())
        if start_goal > 1e-3:
            print(f"  WARNING {key}: path ends {start_goal:.1e} rad from start/goal")
        scores[key] = PathScore(
            metric_length(metric, path),
            min_clearance(term_geosyn, path),
            min_clearance(term_geodex, path),
            gcheck[key]["collision_free"],
            int(path.shape[0]),
        )

    print(
        "\n(lengths under geosyn's panda, armature 0 [sqrt(kg) m]; clearances by exact "
        "sphere-obstacle distance [m] with geosyn's 15 / geodex's 59 spheres; 'own cost' = "
        "geodex's PlanResult.cost under its own M(q); "
        "'geodex chk' = geodex's checker on the path resampled every "
        f"{args.check_step:g} rad)"
    )
    if build_time is not None:
        print(f"geosyn first-use build (compile, cached on disk afterwards): {build_time:.1f} s")
    hdr = (
        f"{'scene':18s} {'planner':7s} {'solved':6s} {'wall [s]':>8s} {'length':>8s} "
        f"{'own cost':>8s} {'clr geosyn':>10s} {'clr geodex':>10s} {'geodex chk':>10s}"
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
                f"{_fmt(s and s.clearance_geodex, '10.4f'):>10s} {chk:>10s}"
            )

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
