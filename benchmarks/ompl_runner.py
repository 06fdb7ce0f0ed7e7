"""The OMPL side of `benchmarks/planning_ompl.py`; runs in the OMPL venv
(``bash benchmarks/setup_ompl.sh`` creates ``.venv-ompl``: ompl 2.0.1 and Pinocchio, no
geosyn).

``python ompl_runner.py --queries IN.json --out OUT.json --time T --inflate D``: for every
query of ``IN.json`` (written by ``planning_ompl.py``: the URDF, the joint limits, the
self-collision link pairs, boxes ``(name, centre, half extents)`` and the queries' ends),
OMPL's RRT-Connect searches ``T`` seconds for a path whose configurations are free for
Pinocchio's collision model of the URDF (coal): the given self pairs, and every robot
object but the base's against every box grown by ``D`` [m]. Motions are checked every
0.0005 of the joint box's diagonal (OMPL's resolution); a found path is shortened by
OMPL's simplifier (1 s) and checked again every 0.005 rad. Writes per query: found, wall
time, validity checks, waypoints, and the configurations of the dense check that collide.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import coal
import numpy as np
import pinocchio as pin

RESOLUTION = 0.0005  # OMPL's motion check step, a fraction of the joint box's diagonal
DENSE_STEP = 0.005  # [rad] the found path's re-check


def collision_model(spec: dict, inflate: float):
    """Pinocchio's model, geometry model (pairs set) and their data, from ``spec`` (the
    queries file's fields; also used by ``planning_ompl.py`` for the queries' ends)."""
    path = Path(spec["urdf"])
    share = [str(p) for p in path.parents if p.name == "share"] + [str(path.parent)]
    model = pin.buildModelFromUrdf(str(path))
    gm = pin.buildGeomFromUrdf(model, str(path), pin.GeometryType.COLLISION, package_dirs=share)
    link = {i: model.frames[g.parentFrame].name for i, g in enumerate(gm.geometryObjects)}
    n_robot = len(gm.geometryObjects)
    want = {frozenset(p) for p in spec["pairs"]}
    for i in range(n_robot):
        for j in range(i + 1, n_robot):
            if frozenset((link[i], link[j])) in want:
                gm.addCollisionPair(pin.CollisionPair(i, j))
    for name, centre, half in spec["boxes"]:
        shape = coal.Box(*(2.0 * (np.asarray(half) + inflate)))
        k = gm.addGeometryObject(
            pin.GeometryObject(name, 0, 0, pin.SE3(np.eye(3), np.asarray(centre)), shape)
        )
        for i in range(n_robot):
            if link[i] not in spec["base_links"]:
                gm.addCollisionPair(pin.CollisionPair(i, k))
    return model, gm, model.createData(), pin.GeometryData(gm)


def main() -> None:
    from ompl import base as ob  # only here: `collision_model` serves geosyn's venv too
    from ompl import geometric as og

    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--queries", required=True)
    p.add_argument("--out", required=True)
    p.add_argument("--time", type=float, default=60.0, help="search time per query [s]")
    p.add_argument("--inflate", type=float, default=0.0, help="boxes grown by [m]")
    args = p.parse_args()
    spec = json.loads(Path(args.queries).read_text())
    model, gm, md, gd = collision_model(spec, args.inflate)
    n = model.nq

    def collides(q: np.ndarray) -> bool:
        return bool(pin.computeCollisions(model, md, gm, gd, q, True))

    space = ob.RealVectorStateSpace(n)
    bounds = ob.RealVectorBounds(n)
    for i in range(n):
        bounds.setLow(i, spec["q_min"][i])
        bounds.setHigh(i, spec["q_max"][i])
    space.setBounds(bounds)
    calls = [0]

    def valid(state) -> bool:
        calls[0] += 1
        return not collides(np.array([state[i] for i in range(n)]))

    out = []
    for qu in spec["queries"]:
        ss = og.SimpleSetup(space)
        ss.setStateValidityChecker(valid)
        si = ss.getSpaceInformation()
        si.setStateValidityCheckingResolution(RESOLUTION)
        start, goal = space.allocState(), space.allocState()
        for i in range(n):
            start[i], goal[i] = qu["q0"][i], qu["q1"][i]
        ss.setStartAndGoalStates(start, goal)
        ss.setPlanner(og.RRTConnect(si))
        calls[0] = 0
        t0 = time.perf_counter()
        solved = ss.solve(args.time)
        row = {"wall": time.perf_counter() - t0, "checks": calls[0]}
        row["found"] = bool(solved) and bool(ss.haveExactSolutionPath())
        if row["found"]:
            ss.simplifySolution(1.0)
            sol = ss.getSolutionPath()
            Q = np.array(
                [[sol.getState(s)[i] for i in range(n)] for s in range(sol.getStateCount())]
            )
            dense = [Q[0]]
            for a, b in zip(Q[:-1], Q[1:], strict=True):
                m = max(int(np.ceil(np.abs(b - a).max() / DENSE_STEP)), 1)
                dense += [a + (b - a) * s for s in np.linspace(0.0, 1.0, m + 1)[1:]]
            row.update(
                waypoints=len(Q), dense=len(dense), dense_colliding=int(sum(map(collides, dense)))
            )
        out.append(row)
        print(
            f"query {len(out)}: {'found' if row['found'] else 'no path'} in {row['wall']:.2f} s",
            flush=True,
        )
    Path(args.out).write_text(json.dumps({"time": args.time, "inflate": args.inflate, "rows": out}))


if __name__ == "__main__":
    main()
