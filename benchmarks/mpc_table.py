"""The result table of `benchmarks/mpc_vs_crocoddyl.py`: warm solves pooled over rounds,
geosyn against Crocoddyl per horizon and scenario (Markdown, as pasted into RESULTS.md)."""

from __future__ import annotations

import numpy as np
from mpc_plant import SCENARIOS


def pooled(runs: list[dict]) -> dict:
    """Pool the warm solves of several rounds of one configuration."""
    times = np.concatenate([np.asarray(r["solve_time"])[1:] for r in runs]) * 1e3
    cpu = np.concatenate([np.asarray(r["solve_cpu"])[1:] for r in runs]) * 1e3
    iters = np.concatenate([np.asarray(r["iterations"])[1:] for r in runs])
    return {
        "median": float(np.median(times)),
        "cpu": float(np.median(cpu)),
        "p99": float(np.percentile(times, 99)),
        "iters": float(np.median(iters)),
        "rms": float(np.median([r["tracking_rms"] for r in runs])),
        "over": max(int(r["ticks_over_limit"]) for r in runs),
        "excess": max(float(r["max_limit_excess_rel"]) for r in runs),
        "cold": float(np.median([r["cold_solve_ms"] for r in runs])),
    }


def table(
    results: dict[tuple[str, int, str], list[dict]],
    croc_version: str,
    geosyn_solver: str = "ddp",
    geosyn_control: str = "torque",
) -> str:
    rows = [
        "| solver | control level | N | scenario | median / p99 per solve [ms]"
        " | CPU median [ms] | iterations | tracking RMS [rad]"
        " | ticks over a torque limit (max excess) | geosyn / Crocoddyl median (p99); CPU |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    names = {"crocoddyl": f"Crocoddyl {croc_version} BoxFDDP", "geosyn": f"geosyn {geosyn_solver}"}
    levels = {"crocoddyl": "torque", "geosyn": geosyn_control}
    keys = sorted({(n, s) for _, n, s in results}, key=lambda k: (k[0], SCENARIOS.index(k[1])))
    for horizon, scenario in keys:
        croc = results.get(("crocoddyl", horizon, scenario))
        pc = pooled(croc) if croc else None
        for solver in ("crocoddyl", "geosyn"):
            runs = results.get((solver, horizon, scenario))
            if not runs:
                continue
            p = pooled(runs)
            ratio = ""
            if solver == "geosyn" and pc is not None:
                ratio = (
                    f"{p['median'] / pc['median']:.2f} ({p['p99'] / pc['p99']:.2f});"
                    f" CPU {p['cpu'] / pc['cpu']:.2f}"
                )
            rows.append(
                f"| {names[solver]} | {levels[solver]} | {horizon} | {scenario} | {p['median']:.2f} / "
                f"{p['p99']:.2f} | {p['cpu']:.2f} | {p['iters']:g} | {p['rms']:.2e} | {p['over']} "
                f"({100 * p['excess']:.2f} %) | {ratio} |"
            )
    return "\n".join(rows)
